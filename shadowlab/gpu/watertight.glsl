// The watertight ray/triangle test of Woop, Benthin & Wald 2013 ("Watertight ray/triangle
// intersection", JCGT 2(1)) as a segment test, on the ray the truth traces (origin, direction,
// tfar: shadowlab.truth.tracing, the truth's offset rule), in float32 with contraction forbidden
// (precise) and the paper's double-precision fallback when an edge function is exactly 0.
// Shared by the techniques that decide a shadow ray exactly as the ray-traced truth does: the
// irregular z-buffer (shadowlab/techniques/maps/izb_test.glsl), the per-triangle shadow volumes
// (shadowlab/techniques/volumes/per_triangle_volume_samples.glsl) and the partitioned shadow
// volumes' query (shadowlab/techniques/volumes/psv_query.glsl).
//! glsl 430

// Woop et al. 2013, listing 1: does org + t·dir, 0 < t <= tfar, meet triangle (a, b, c)?
bool segment_hits(vec3 org, vec3 dir, float tfar, vec3 a, vec3 b, vec3 c) {
    vec3 ad = abs(dir);
    int kz = ad.x > ad.y ? (ad.x > ad.z ? 0 : 2) : (ad.y > ad.z ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    if (dir[kz] < 0.0) { int swap = kx; kx = ky; ky = swap; }  // keep the winding
    precise float sx = dir[kx] / dir[kz];
    precise float sy = dir[ky] / dir[kz];
    precise float sz = 1.0 / dir[kz];
    precise vec3 pa = a - org;
    precise vec3 pb = b - org;
    precise vec3 pc = c - org;
    precise float ax = pa[kx] - sx * pa[kz];
    precise float ay = pa[ky] - sy * pa[kz];
    precise float bx = pb[kx] - sx * pb[kz];
    precise float by = pb[ky] - sy * pb[kz];
    precise float cx = pc[kx] - sx * pc[kz];
    precise float cy = pc[ky] - sy * pc[kz];
    precise float u = cx * by - cy * bx;
    precise float v = ax * cy - ay * cx;
    precise float w = bx * ay - by * ax;
    if (u == 0.0 || v == 0.0 || w == 0.0) {  // on an edge in float32: decide in double
        u = float(double(cx) * double(by) - double(cy) * double(bx));
        v = float(double(ax) * double(cy) - double(ay) * double(cx));
        w = float(double(bx) * double(ay) - double(by) * double(ax));
    }
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) return false;
    precise float det = u + v + w;
    if (det == 0.0) return false;        // degenerate, or the ray in the triangle's plane
    precise float t = u * (sz * pa[kz]) + v * (sz * pb[kz]) + w * (sz * pc[kz]);
    if (det < 0.0) { t = -t; det = -det; }
    return t > 0.0 && t <= tfar * det;
}
