// Partitioned shadow volumes, pass 1: the TOP tree (ternary object partitioning: Gerhards et al.
// 2015, §4) built from the caster triangles, one invocation per triangle, in rounds that give the
// same tree on every run: each triangle walks down from where it stopped to the first empty child
// its volume goes to and asks for it (atomicMin of its index); the lowest index asking wins the
// child and hangs its chain there, the others walk on from that node in the next round (the papers
// let the first thread to arrive win, a tree that depends on scheduling). Each triangle's shadow
// volume is the intersection of four half-spaces, all oriented "inside is negative": the three
// shadow planes (through the light and an edge; for a light at infinity, through the edge along
// the light) and the capping plane (its own plane). At a plane node the volume goes to the
// negative child when it lies wholly on the negative side by the classification margin, to the
// positive child when wholly on the positive side, else to the intersection child; at a leaf it
// is dropped (it lies inside that leaf's volume) when the leaf allows it, else goes on through the
// leaf's intersection child. A chain: sides 0, 1, 2, cap, leaf, each linked to the next through
// its negative child. The margins (partitioned_volume.py's docstring) make every decision
// conservative: the query finds every triangle whose exact test can hit.
//
// u_stage: STAGE_PREPARE (each triangle's planes, once per build), STAGE_WALK (walk and ask),
// STAGE_HANG (the winners take nodes from the pool and link their chains).
#include "psv_common.glsl"

#ifdef COMPUTE_SHADER
#ifndef LOCAL_SIZE
#error "LOCAL_SIZE: invocations per work group (shadowlab.techniques.volumes.partitioned_volume)"
#endif
layout(local_size_x = LOCAL_SIZE) in;
#define STAGE_PREPARE 0
#define STAGE_WALK 1
#define STAGE_HANG 2
uniform int u_stage;
uniform int u_triangles;
uniform int u_pool;                      // nodes in the pool
uniform int u_target;                    // 1: a target-direct light; nothing behind its disc casts
uniform float u_near;                    // point lights: a triangle closer to the light culls nothing
uniform float u_direction_eps;           // angle covering the float32 rounding of a ray's direction
#define NO_EPS 1e20                      // a relative margin that makes every shadow-plane test ambiguous
#define CHAIN_SHIFT 4                    // Node.flags bits 4-5: the node's place in its chain (0-2 sides, 3 cap)
#define RELIABLE 9.313225746154785e-10   // 2^-30: below this relative size a sign in double is not trusted

// One triangle's shadow volume as the build needs it: corners, planes and flags of its chain,
// the relative margin of its shadow planes, and whether a volume inside it may be dropped.
struct Volume {
    vec3 v[3];
    vec4 plane[4];
    int flags[4];
    float rel;
    float depth;                         // the light depth of its nearest point (light_depth)
    bool cullable;
};

// Distance from p to triangle (a, b, c) (Ericson 2005, "Real-Time Collision Detection" §5.1.5,
// closest point by Voronoi regions), in double.
double triangle_distance(dvec3 p, dvec3 a, dvec3 b, dvec3 c) {
    dvec3 ab = b - a, ac = c - a, ap = p - a;
    double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0LF && d2 <= 0.0LF) return length(ap);
    dvec3 bp = p - b;
    double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0LF && d4 <= d3) return length(bp);
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0LF && d1 >= 0.0LF && d3 <= 0.0LF) return length(p - (a + d1 / (d1 - d3) * ab));
    dvec3 cp = p - c;
    double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0LF && d5 <= d6) return length(cp);
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0LF && d2 >= 0.0LF && d6 <= 0.0LF) return length(p - (a + d2 / (d2 - d6) * ac));
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0LF && (d4 - d3) >= 0.0LF && (d5 - d6) >= 0.0LF)
        return length(p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b)));
    double denom = 1.0LF / (va + vb + vc);
    return length(p - (a + ab * (vb * denom) + ac * (vc * denom)));
}

// Triangle t's volume; false when it casts nothing (no area; wholly behind a target light's disc).
// Planes in double, rounded to float32 once normalised. A plane whose orientation double
// precision cannot be sure of (the light almost in the triangle's plane, or on an edge's line)
// makes the whole chain transparent: visited on both sides, decided by the exact test alone.
bool make_volume(int t, out Volume V) {
    for (int i = 0; i < 3; ++i) V.v[i] = triangle_vertex[3 * t + i].xyz;
    dvec3 A = dvec3(V.v[0]), B = dvec3(V.v[1]), C = dvec3(V.v[2]);
    dvec3 N = cross(B - A, C - A);
    double area2 = length(N);
    if (area2 == 0.0LF) return false;            // the watertight test never hits it either
    dvec3 n = N / area2;
    bool transparent = false;
    V.cullable = true;
    V.rel = 0.0;
    dvec3 corner[3] = dvec3[3](A, B, C);
    if (u_point == 1) {
        dvec3 L = dvec3(u_light_position);
        double h = dot(n, L - A);
        if (h < 0.0LF) { n = -n; h = -h; }       // the light on the positive side
        transparent = h <= RELIABLE * length(L - A);
        double dmin = triangle_distance(L, A, B, C);
        // The angle within which a ray's exact test is uncertain, seen from the light: the
        // absolute margin at the triangle's nearest point, plus the direction's rounding.
        if (dmin <= 2.0LF * double(u_delta)) {
            V.rel = NO_EPS;
            transparent = true;
        } else {
            // rounded up to a power of two: neighbours in a mesh then share it (see classify)
            int e;
            float mant = frexp(float(double(u_delta) / (dmin - double(u_delta))) + u_direction_eps, e);
            V.rel = mant == 0.5 ? ldexp(mant, e) : ldexp(1.0, e);
        }
        V.cullable = dmin > double(u_near);
        V.depth = float(dmin);
        for (int i = 0; i < 3; ++i) {
            dvec3 P = corner[i], Q = corner[(i + 1) % 3], O = corner[(i + 2) % 3];
            dvec3 S = cross(P - L, Q - L);
            double len = length(S);
            if (len == 0.0LF) { transparent = true; V.plane[i] = vec4(0.0); continue; }
            dvec3 s = S / len;
            double side = dot(s, O - L);
            if (side > 0.0LF) s = -s;            // the triangle on the negative side
            transparent = transparent || abs(side) <= RELIABLE * length(O - L);
            V.plane[i] = vec4(vec3(s), float(-dot(s, L)));
        }
    } else {
        dvec3 D = dvec3(u_light_direction);
        V.depth = min(min(dot(V.v[0], u_light_direction), dot(V.v[1], u_light_direction)),
                      dot(V.v[2], u_light_direction));
        double h = dot(n, -D);
        if (h < 0.0LF) { n = -n; h = -h; }       // towards the light is positive
        transparent = h <= RELIABLE;
        if (u_target == 1) {                     // only what lies in front of the disc casts
            double lo = 1e300LF, hi = -1e300LF;
            for (int i = 0; i < 3; ++i) {
                double z = dot(corner[i] - dvec3(u_light_position), D);
                lo = min(lo, z);
                hi = max(hi, z);
            }
            if (hi < -2.0LF * double(u_delta)) return false;
            V.cullable = lo > 2.0LF * double(u_delta);
        }
        for (int i = 0; i < 3; ++i) {
            dvec3 P = corner[i], Q = corner[(i + 1) % 3], O = corner[(i + 2) % 3];
            dvec3 S = cross(Q - P, D);
            double len = length(S);
            if (len == 0.0LF) { transparent = true; V.plane[i] = vec4(0.0); continue; }
            dvec3 s = S / len;
            double side = dot(s, O - P);
            if (side > 0.0LF) s = -s;
            transparent = transparent || abs(side) <= RELIABLE * length(O - P);
            V.plane[i] = vec4(vec3(s), float(-dot(s, P)));
        }
    }
    V.plane[3] = vec4(vec3(n), float(-dot(n, A)));  // the light's side positive, the volume negative
    for (int i = 0; i < 4; ++i)
        V.flags[i] = (i == 3 ? KIND_CAP : KIND_SIDE) | (transparent ? FLAG_TRANSPARENT : 0);
    return true;
}

// Which child volume V goes to at plane node N (of another triangle u): CHILD_NEG or CHILD_POS
// only when every point of the volume lies on that side, else CHILD_INTER. Shadow planes: the
// volume is the cone (prism) of its corners, so the corners decide, each beyond the sum of both
// triangles' margins (which grow with the distance to a point light as the query's do) — or
// exactly on the plane: a corner that is one of the corners u's plane goes through (a mesh's
// shared edge) lies on it in exact arithmetic, and the volume then touches the plane there;
// touching is allowed when V's relative margin is no larger than N's, which then covers V's
// uncertainty at the query. Capping plane: the volume runs from the triangle away from the
// light, so it is negative when its corners are (or lie on u's plane); positive only for a
// point light when every corner is farther from the plane than the light (the volume then
// moves away from it). `strict`: one-sided without touching (only such volumes may be dropped).
int classify(Node N, Volume V, out bool strict) {
    strict = false;
    if ((N.flags & FLAG_TRANSPARENT) != 0) return CHILD_INTER;
    int j = (N.flags >> CHAIN_SHIFT) & 3;        // which of u's planes: shadow plane of edge j, or 3: cap
    vec3 u0 = triangle_vertex[3 * N.tri].xyz, u1 = triangle_vertex[3 * N.tri + 1].xyz;
    vec3 u2 = triangle_vertex[3 * N.tri + 2].xyz;
    vec3 ea = j == 1 ? u1 : (j == 2 ? u2 : u0);  // the edge (ea, eb) of shadow plane j
    vec3 eb = j == 0 ? u1 : (j == 1 ? u2 : u0);
    bool neg = true, pos = true, touching = false;
    if ((N.flags & KIND_MASK) == KIND_SIDE) {
        for (int i = 0; i < 3; ++i) {
            if (V.v[i] == ea || V.v[i] == eb) { touching = true; continue; }
            float s = plane_distance(N, V.v[i]);
            float m = (N.rel + V.rel) * light_distance(V.v[i]) + 2.0 * u_delta;
            neg = neg && s < -m;
            pos = pos && s > m;
        }
        if (touching && V.rel > N.rel) return CHILD_INTER;
    } else {
        float hl = u_point == 1 ? plane_distance(N, u_light_position) : 0.0;
        for (int i = 0; i < 3; ++i) {
            bool on = V.v[i] == u0 || V.v[i] == u1 || V.v[i] == u2;
            touching = touching || on;
            float s = plane_distance(N, V.v[i]);
            neg = neg && (on || s < -2.0 * u_delta);
            pos = pos && !on && u_point == 1 && s > 2.0 * u_delta && s - hl > 2.0 * u_delta;
        }
    }
    strict = !touching;
    return neg ? CHILD_NEG : (pos ? CHILD_POS : CHILD_INTER);
}

// Triangle t's volume as staged by STAGE_PREPARE.
void load_volume(int t, out Volume V) {
    for (int i = 0; i < 3; ++i) V.v[i] = triangle_vertex[3 * t + i].xyz;
    for (int i = 0; i < 4; ++i) V.plane[i] = staged[STAGED_PER_TRIANGLE * t + i];
    vec4 extra = staged[STAGED_PER_TRIANGLE * t + 4];
    V.rel = extra.x;
    V.depth = extra.w;
    int flags = floatBitsToInt(extra.y);
    for (int i = 0; i < 4; ++i) V.flags[i] = (i == 3 ? KIND_CAP : KIND_SIDE) | flags;
    V.cullable = extra.z != 0.0;
}

void prepare(int t) {
    Volume V;
    if (!make_volume(t, V)) {
        walk[t] = ivec4(NONE, 0, NONE, STATUS_SKIPPED);
        atomicAdd(counter[COUNTER_SKIPPED], 1u);
        return;
    }
    for (int i = 0; i < 4; ++i) staged[STAGED_PER_TRIANGLE * t + i] = V.plane[i];
    staged[STAGED_PER_TRIANGLE * t + 4] = vec4(V.rel, intBitsToFloat(V.flags[0] & FLAG_TRANSPARENT),
                                               V.cullable ? 1.0 : 0.0, V.depth);
    walk[t] = ivec4(NONE, 0, NONE, STATUS_ACTIVE);
}

// Walk down from where the last round stopped to the first empty child, and ask for it.
void walk_down(int t) {
    ivec4 w = walk[t];
    if (w.w != STATUS_ACTIVE) return;
    int root = int(counter[COUNTER_ROOT]) - 1;
    if (root == NONE) {
        walk[t] = ivec4(NONE, 0, ROOT_SLOT, STATUS_ACTIVE);
        atomicMin(claim[0], uint(t));
        atomicAdd(counter[COUNTER_WANTING], 1u);
        return;
    }
    Volume V;
    load_volume(t, V);
    int n = w.x == NONE ? root : w.x;
    int depth = w.x == NONE ? 1 : w.y;           // the depth of n (the root: 1)
    int streak = 0;                              // strictly negative decisions in a row (a leaf's four planes)
    while (true) {
        Node N = node[n];
        int slot;
        if ((N.flags & KIND_MASK) == KIND_LEAF) {
            if ((N.flags & FLAG_CULLABLE) != 0 && streak >= 4) {
                walk[t] = ivec4(n, depth, NONE, STATUS_CULLED);
                atomicAdd(counter[COUNTER_CULLED], 1u);
                return;
            }
            slot = CHILD_INTER;
            streak = 0;
        } else {
            bool strict;
            slot = classify(N, V, strict);
            streak = slot == CHILD_NEG && strict ? streak + 1 : 0;
        }
        int child = N.link[slot];
        if (child == NONE) {
            walk[t] = ivec4(n, depth, 3 * n + slot, STATUS_ACTIVE);
            atomicMin(claim[1 + 3 * n + slot], uint(t));
            atomicAdd(counter[COUNTER_WANTING], 1u);
            return;
        }
        n = child;
        ++depth;
    }
}

// The winner of each child slot takes five nodes and hangs its chain there; the others walk on
// from the same node next round (the child is no longer empty).
void hang(int t) {
    ivec4 w = walk[t];
    if (w.w != STATUS_ACTIVE || w.z == NONE) return;
    bool at_root = w.z == ROOT_SLOT;
    if (claim[at_root ? 0 : 1 + w.z] != uint(t)) return;
    int first = int(atomicAdd(counter[COUNTER_NODES], 5u));
    if (first + 5 > u_pool) {                    // the tree would be incomplete: counted, the build stops
        walk[t] = ivec4(w.x, w.y, NONE, STATUS_NO_POOL);
        atomicAdd(counter[COUNTER_OVERFLOW], 1u);
        return;
    }
    Volume V;
    load_volume(t, V);
    int parent = at_root ? NONE : w.x;
    for (int i = 0; i < 4; ++i) {
        int k = first + i;
        node[k].plane = V.plane[i];
        node[k].rel = i == 3 ? 0.0 : V.rel;
        node[k].tri = t;
        node[k].flags = V.flags[i] | (i << CHAIN_SHIFT);
        node[k].depth = depth_key(V.depth);
        node[k].link = ivec4(k + 1, NONE, NONE, i == 0 ? parent : k - 1);
    }
    int leaf = first + 4;
    node[leaf].plane = vec4(0.0);
    node[leaf].rel = 0.0;
    node[leaf].tri = t;
    node[leaf].flags = KIND_LEAF | (V.cullable ? FLAG_CULLABLE : 0);
    node[leaf].depth = depth_key(V.depth);
    node[leaf].link = ivec4(NONE, NONE, NONE, first + 3);
    if (at_root) counter[COUNTER_ROOT] = uint(first + 1);
    else node[w.x].link[w.z % 3] = first;        // each child slot has one winner: no race
    // The ancestors' depths: up until one is already as shallow (whoever made it so went on up).
    int key = depth_key(V.depth);
    for (int p = parent; p != NONE; p = node[p].link.w)
        if (atomicMin(node[p].depth, key) <= key) break;
    walk[t] = ivec4(first, w.y + 5, NONE, STATUS_INSERTED);
    atomicAdd(counter[COUNTER_INSERTED], 1u);
    atomicMax(counter[COUNTER_DEPTH], uint((at_root ? 0 : w.y) + 5));
}

void main() {
    int t = INVOCATION_INDEX;
    if (t >= u_triangles) return;
    if (u_stage == STAGE_PREPARE) prepare(t);
    else if (u_stage == STAGE_WALK) walk_down(t);
    else hang(t);
}
#endif
