// CC shadow volumes (Lloyd, Wendt, Govindaraju & Manocha 2004), the receiver map: every covered
// G-buffer pixel's world point goes into a coarse light-space grid that keeps, per texel, the
// largest light-space key of the points that fall in it (atomicMax on order-preserving bits).
// Keys: for a light at infinity, the depth along its direction (an orthographic grid over the
// scene's bounds); for a light at a position, the distance to the light (six cube faces, the
// face of the point's major axis). Also kept: the largest distance of a point from the eye (the
// depth-buffer margin) and how many points fell in no face (only a point at the light itself).
// Python twin of the layout, the faces and the key encoding: shadowlab/techniques/volumes/cc_volume.py.
//! glsl 430

#ifdef COMPUTE_SHADER
#ifndef LOCAL_SIZE
#error "LOCAL_SIZE: invocations per work group side (shadowlab.techniques.volumes.cc_volume)"
#endif
#ifndef BLOCK
#error "BLOCK: pixels per invocation side (shadowlab.techniques.volumes.cc_volume)"
#endif
layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

#define HEADER_EYE_DISTANCE 0          // float bits of the largest eye distance (non-negative: uint order)
#define HEADER_POINTS 1                // covered pixels mapped
#define HEADER_UNMAPPED 2              // covered pixels in no face (at the light's position)
layout(std430, binding = 0) buffer Header { uint header[]; };
// Per face and texel (row-major, face after face): 0 = empty, else floatBitsToUint(key) + 1 with
// key >= 0, so that unsigned order is the order of the keys.
layout(std430, binding = 1) buffer ReceiverMap { uint texel_key[]; };

uniform sampler2D u_position;          // G-buffer world position, w = 1 where covered
uniform ivec2 u_size;                  // G-buffer width, height
uniform int u_grid;                    // texels per face side
uniform bool u_cube;                   // true: six faces around u_light_position; false: orthographic
uniform vec3 u_eye;
uniform vec3 u_light_position;
uniform vec3 u_axis_u;                 // orthographic: the grid's two axes across the light ...
uniform vec3 u_axis_v;
uniform vec3 u_axis_d;                 // ... and its unit direction of travel (depth)
uniform vec3 u_origin;                 // orthographic: (u, v, depth) of the grid's corner and depth 0
uniform vec2 u_texels_per_unit;        // orthographic: texels per world unit along u and v

uint encode(float key) {
    return floatBitsToUint(max(key, 0.0)) + 1u;
}

// The texel (index into texel_key) and key of one covered point; false for a point in no face.
bool texel_of(vec3 p, out int index, out float key) {
    int face = 0;
    vec2 uv;
    if (u_cube) {
        // Face 2k (+axis k) or 2k + 1 (−axis k) of the major axis k; its coordinates are the other
        // two axes in increasing order, divided by the distance along axis k (in [−1, 1]).
        vec3 v = p - u_light_position;
        vec3 a = abs(v);
        float z;
        if (a.x >= a.y && a.x >= a.z) {
            face = v.x > 0.0 ? 0 : 1; z = a.x; uv = v.yz;
        } else if (a.y >= a.z) {
            face = v.y > 0.0 ? 2 : 3; z = a.y; uv = v.xz;
        } else {
            face = v.z > 0.0 ? 4 : 5; z = a.z; uv = v.xy;
        }
        if (!(z > 0.0)) return false;
        uv = (uv / z * 0.5 + 0.5) * float(u_grid);
        key = length(v);
    } else {
        uv = (vec2(dot(p, u_axis_u), dot(p, u_axis_v)) - u_origin.xy) * u_texels_per_unit;
        key = dot(p, u_axis_d) - u_origin.z;
    }
    // Points outside the grid (float rounding at the scene's bounds) go to the border texel;
    // the casters' texel ranges are clamped the same way, so nothing is lost.
    ivec2 t = clamp(ivec2(floor(uv)), ivec2(0), ivec2(u_grid - 1));
    index = (face * u_grid + t.y) * u_grid + t.x;
    return true;
}

// Each invocation takes a BLOCK x BLOCK block of pixels and keeps the largest key of the run of
// points that fall in one texel, writing it with one atomicMax when the texel changes (or at the
// end): neighbouring pixels mostly share a texel, so this spares most of the atomics (which a
// software rasteriser serialises), and every point's key still reaches its texel.
void main() {
    ivec2 base = ivec2(gl_GlobalInvocationID.xy) * BLOCK;
    float farthest = 0.0;
    uint points = 0u, unmapped = 0u;
    int run = -1;
    float best = 0.0;
    for (int j = 0; j < BLOCK; ++j) {
        for (int i = 0; i < BLOCK; ++i) {
            ivec2 px = base + ivec2(i, j);
            if (px.x >= u_size.x || px.y >= u_size.y) continue;
            vec4 p4 = texelFetch(u_position, px, 0);
            if (p4.w == 0.0) continue;
            farthest = max(farthest, distance(p4.xyz, u_eye));
            points += 1u;
            int index;
            float key;
            if (!texel_of(p4.xyz, index, key)) {
                unmapped += 1u;
                continue;
            }
            if (index != run) {
                if (run >= 0) atomicMax(texel_key[run], encode(best));
                run = index;
                best = key;
            } else {
                best = max(best, key);
            }
        }
    }
    if (run >= 0) atomicMax(texel_key[run], encode(best));
    if (points > 0u) {
        atomicMax(header[HEADER_EYE_DISTANCE], floatBitsToUint(farthest));
        atomicAdd(header[HEADER_POINTS], points);
    }
    if (unmapped > 0u) atomicAdd(header[HEADER_UNMAPPED], unmapped);
}
#endif
