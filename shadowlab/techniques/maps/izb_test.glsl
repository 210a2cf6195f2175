// Irregular z-buffer, pass 3: one invocation per (triangle, texel) pair of izb_raster.glsl walks
// the texel's list and tests the triangle exactly against each listed ray, setting the blocked
// bit of the ray's sample. Rays already blocked are skipped (another triangle decided them).
//
// A walk visits at most WALK_BUDGET nodes per dispatch: llvmpipe ends a shader invocation
// silently after 65535 loop iterations (Mesa's LP_MAX_TGSI_LOOP_ITERATIONS), and a coarse grid
// can list more rays than that in one texel. The node where a walk stopped goes into
// continuation[i] (NO_NODE: done) and is counted; the Python side dispatches the pass again
// with u_resume = 1 for the pairs still pending until none is (as psv_query.glsl does).
//
// The exact test is the watertight ray/triangle test of Woop, Benthin & Wald 2013 ("Watertight
// ray/triangle intersection", JCGT 2(1)), on the ray the truth traces (origin, direction, tfar:
// shadowlab.truth.tracing, the truth's offset rule), in float32 with contraction forbidden (precise)
// and the paper's double-precision fallback when an edge function is exactly 0: shared with the
// shadow-volume family in shadowlab/gpu/watertight.glsl.
#include "izb_common.glsl"
#include "watertight.glsl"

#ifdef COMPUTE_SHADER
#ifndef LOCAL_SIZE
#error "LOCAL_SIZE: invocations per work group (shadowlab.techniques.maps.irregular_zbuffer)"
#endif
layout(local_size_x = LOCAL_SIZE) in;
uniform int u_pairs;
uniform int u_resume;                    // 0: every pair from its texel's head; 1: pending pairs, where they stopped
#ifndef WALK_BUDGET
#error "WALK_BUDGET: list nodes per invocation and dispatch (shadowlab.techniques.maps.irregular_zbuffer)"
#endif

void main() {
    int i = INVOCATION_INDEX;
    if (i >= u_pairs) return;
    ivec2 work = pair[i];
    int n = u_resume == 1 ? continuation[i] : head[work.y];
    if (u_resume == 1 && n == NO_NODE) return;  // finished in an earlier dispatch
    vec3 a = triangle_vertex[3 * work.x].xyz;
    vec3 b = triangle_vertex[3 * work.x + 1].xyz;
    vec3 c = triangle_vertex[3 * work.x + 2].xyz;
    uint tests = 0u, hits = 0u;
    for (int steps = 0; n != NO_NODE && steps < WALK_BUDGET; ++steps) {
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
    continuation[i] = n;                 // where the next dispatch goes on (NO_NODE: done)
    if (n != NO_NODE) atomicAdd(counter[COUNTER_PENDING], 1u);
    atomicAdd(counter[COUNTER_TESTS], tests);
    atomicAdd(counter[COUNTER_HITS], hits);
}
#endif
