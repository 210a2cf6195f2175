// Irregular z-buffer, pass 3: one invocation per (triangle, texel) pair of izb_raster.glsl walks
// the texel's list and tests the triangle exactly against each listed ray, setting the blocked
// bit of the ray's sample. Rays already blocked are skipped (another triangle decided them).
//
// The exact test is the watertight ray/triangle test of Woop, Benthin & Wald 2013 ("Watertight
// ray/triangle intersection", JCGT 2(1)), on the ray the truth traces (origin, direction, tfar:
// shadowlab.truth.tracing, the truth's offset rule), in float32 with contraction forbidden (precise)
// and the paper's double-precision fallback when an edge function is exactly 0.
#include "izb_common.glsl"

#ifdef COMPUTE_SHADER
#ifndef LOCAL_SIZE
#error "LOCAL_SIZE: invocations per work group (shadowlab.techniques.maps.irregular_zbuffer)"
#endif
layout(local_size_x = LOCAL_SIZE) in;
uniform int u_pairs;

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

void main() {
    int i = INVOCATION_INDEX;
    if (i >= u_pairs) return;
    ivec2 work = pair[i];
    vec3 a = triangle_vertex[3 * work.x].xyz;
    vec3 b = triangle_vertex[3 * work.x + 1].xyz;
    vec3 c = triangle_vertex[3 * work.x + 2].xyz;
    uint tests = 0u, hits = 0u;
    for (int n = head[work.y]; n != NO_NODE; ) {
        ivec2 entry = node[n];
        int s = ray_sample[entry.x];
        uint word = uint(s / u_samples_per_pixel);
        uint bit = 1u << uint(s % u_samples_per_pixel);
        if ((blocked[word] & bit) == 0u) {  // a benign race: at worst a test too many
            ++tests;
            vec4 o = ray_origin[entry.x];
            if (segment_hits(o.xyz, ray_direction[entry.x].xyz, o.w, a, b, c)) {
                atomicOr(blocked[word], bit);
                ++hits;
            }
        }
        n = entry.y;
    }
    atomicAdd(counter[COUNTER_TESTS], tests);
    atomicAdd(counter[COUNTER_HITS], hits);
}
#endif
