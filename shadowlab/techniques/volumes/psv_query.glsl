// Partitioned shadow volumes, pass 2: one invocation per shadow ray locates the ray's origin in
// the TOP tree of psv_build.glsl (Gerhards et al. 2015, §5; Mora et al. 2016, §4-5). At a plane
// node it visits the child on its side of the plane — both sides when it lies within the node's
// margin — and always the intersection child, in the order negative, positive, intersection.
// At a leaf it runs the watertight test of the leaf's triangle on the truth's own ray (origin,
// direction, tfar): a hit ends the query in shadow; a miss (the origin within the margins of the
// volume but not in it) goes on through the leaf's intersection child.
//
// QUERY_STACK: depth first with a stack of STACK_SIZE nodes; a query whose stack would overflow
// is counted and goes on without it (the hybrid of Mora et al. 2016, §5). Otherwise stackless:
// the walk goes back up through the parent links and, at each node it comes back to, recomputes
// the children it visits there and takes the one after the child it came from (Mora et al. 2016,
// §4). Both enter the same nodes in the same order, so they give the same visibility and the
// same count of nodes entered. A query stops after STEP_BUDGET steps (llvmpipe ends an invocation
// silently after 65535 loop iterations), saves its stackless state and is resumed by the next
// dispatch (u_resume).
#include "psv_common.glsl"
#include "watertight.glsl"

#ifdef COMPUTE_SHADER
#ifndef LOCAL_SIZE
#error "LOCAL_SIZE: invocations per work group (shadowlab.techniques.volumes.partitioned_volume)"
#endif
layout(local_size_x = LOCAL_SIZE) in;
uniform int u_rays;
uniform int u_resume;                    // 0: every ray from the root; 1: the pending rays, where they stopped
#ifndef STEP_BUDGET
#error "STEP_BUDGET: loop steps per invocation and dispatch (shadowlab.techniques.volumes.partitioned_volume)"
#endif

// The children of N that a query at p (distance r to a point light, light depth q plus the
// margin) visits, as bits 1 << CHILD_*: none when the whole subtree lies deeper than p.
int visit_mask(Node N, vec3 p, float r, float q) {
    if (key_depth(N.depth) > q) return 0;
    int kind = N.flags & KIND_MASK;
    if (kind == KIND_LEAF) return 1 << CHILD_INTER;
    if ((N.flags & FLAG_TRANSPARENT) != 0) return 7;
    float s = plane_distance(N, p);
    float m = (kind == KIND_SIDE ? N.rel * r : 0.0) + u_delta;
    return (1 << CHILD_INTER) | (s < m ? 1 << CHILD_NEG : 0) | (s > -m ? 1 << CHILD_POS : 0);
}

// The first child slot after `after` (-1: the first) that the mask visits and that exists; -1:
// none. Written out without a loop, like the child lists below: llvmpipe stops a shader after
// 65535 loop iterations in all (LP_MAX_TGSI_LOOP_ITERATIONS), so the walks count their own steps
// (STEP_BUDGET) and nothing else in them loops.
int next_slot(Node N, int mask, int after) {
    if (after < CHILD_NEG && (mask & (1 << CHILD_NEG)) != 0 && N.link.x != NONE) return CHILD_NEG;
    if (after < CHILD_POS && (mask & (1 << CHILD_POS)) != 0 && N.link.y != NONE) return CHILD_POS;
    if (after < CHILD_INTER && (mask & (1 << CHILD_INTER)) != 0 && N.link.z != NONE) return CHILD_INTER;
    return -1;
}

// The exact test at a leaf: does the ray meet the leaf's triangle?
bool leaf_hits(Node N, vec4 o, vec3 d, inout uint tests) {
    ++tests;
    return segment_hits(o.xyz, d, o.w, triangle_vertex[3 * N.tri].xyz, triangle_vertex[3 * N.tri + 1].xyz,
                        triangle_vertex[3 * N.tri + 2].xyz);
}

// The stackless walk from node n (entered next when from == NONE, else reached back from its
// child `from`) to the end of the tree: RAY_SHADOW when a leaf's exact test hits, RAY_LIT at the
// end, RAY_PENDING (the state saved in query_state[k]) when `steps` reaches STEP_BUDGET.
uint walk_stackless(int k, int n, int from, vec4 o, vec3 d, float r, float q, inout int steps, inout uint entered,
                    inout uint tests) {
    while (n != NONE) {
        if (steps++ >= STEP_BUDGET) {
            query_state[k] = ivec2(n, from);
            return RAY_PENDING;
        }
        Node N = node[n];
        int s;
        if (from == NONE) {
            ++entered;
            if ((N.flags & KIND_MASK) == KIND_LEAF && key_depth(N.depth) <= q && leaf_hits(N, o, d, tests))
                return RAY_SHADOW;
            s = next_slot(N, visit_mask(N, o.xyz, r, q), -1);
        } else {
            int came = from == N.link.x ? CHILD_NEG : (from == N.link.y ? CHILD_POS : CHILD_INTER);
            s = next_slot(N, visit_mask(N, o.xyz, r, q), came);
        }
        if (s >= 0) {
            n = N.link[s];
            from = NONE;
        } else {
            from = n;
            n = N.link.w;
        }
    }
    return RAY_LIT;
}

void main() {
    int k = INVOCATION_INDEX;
    if (k >= u_rays) return;
    if (u_resume == 1 && blocked[k] != RAY_PENDING) return;
    vec4 o = ray_origin[k];
    vec3 d = ray_direction[k].xyz;
    float r = light_distance(o.xyz);
    float q = light_depth(o.xyz) + 2.0 * u_delta;
    uint entered = 0u, tests = 0u;
    int steps = 0;
    uint result;
    if (u_resume == 1) {
        ivec2 state = query_state[k];
        result = walk_stackless(k, state.x, state.y, o, d, r, q, steps, entered, tests);
    } else {
        int root = int(counter[COUNTER_ROOT]) - 1;
#ifdef QUERY_STACK
        int stack[STACK_SIZE];
        int sp = 0, n = root, resume = NONE;
        result = RAY_LIT;
        while (n != NONE) {
            if (steps++ >= STEP_BUDGET) {        // out of steps: saved as a stackless walk entering n
                resume = n;
                break;
            }
            Node N = node[n];
            ++entered;
            if ((N.flags & KIND_MASK) == KIND_LEAF && key_depth(N.depth) <= q && leaf_hits(N, o, d, tests)) {
                result = RAY_SHADOW;
                break;
            }
            int mask = visit_mask(N, o.xyz, r, q);
            int kids[3] = int[3](NONE, NONE, NONE);
            int count = 0;
            if ((mask & (1 << CHILD_NEG)) != 0 && N.link.x != NONE) kids[count++] = N.link.x;
            if ((mask & (1 << CHILD_POS)) != 0 && N.link.y != NONE) kids[count++] = N.link.y;
            if ((mask & (1 << CHILD_INTER)) != 0 && N.link.z != NONE) kids[count++] = N.link.z;
            if (count == 0) {
                n = sp > 0 ? stack[--sp] : NONE;
                continue;
            }
            if (sp + count - 1 > STACK_SIZE) {   // full: the rest of the walk goes without the stack
                resume = kids[0];
                atomicAdd(counter[COUNTER_STACK_OVERFLOWS], 1u);
                break;
            }
            if (count == 3) stack[sp++] = kids[2];
            if (count >= 2) stack[sp++] = kids[1];
            n = kids[0];
        }
        // Entering `resume` without the stack: the walk back up through the parents visits
        // exactly the nodes the stack still held, in the same order.
        if (resume != NONE) result = walk_stackless(k, resume, NONE, o, d, r, q, steps, entered, tests);
#else
        result = walk_stackless(k, root, NONE, o, d, r, q, steps, entered, tests);
#endif
    }
    if (result == RAY_PENDING) atomicAdd(counter[COUNTER_PENDING], 1u);
    blocked[k] = result;
    visits[k] = (u_resume == 1 ? visits[k] : 0u) + entered;
    atomicAdd(counter[COUNTER_LEAF_TESTS], tests);
}
#endif
