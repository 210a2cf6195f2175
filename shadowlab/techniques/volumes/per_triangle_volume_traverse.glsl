// Per-triangle shadow volumes, passes 2 and 3: each caster triangle's shadow volume — its three
// edge planes through the light and its own plane (Sintorn, Olsson & Assarsson 2011) —
// against the hierarchy of view-sample boxes, top down. With TOP, one invocation per triangle
// (not culled: culled()) builds the planes and tests every node of the top level; without, one invocation per
// (triangle, node) pair of the level above (list_in) tests the node's children. Each test
// rejects the node (its box is outside one plane by a margin: no segment from its samples can
// meet the triangle), accepts it (inside all four by a margin that proves every sample's segment
// meets the triangle: one tile-level set, node_flag) or descends (appends the pair to list_out,
// the next level's list, or at the leaves the list of sample tests). Appends are counted even
// past the list's capacity, so a full list is known exactly: the Python side retries or fails.
//
// Why the margins make accept and reject exact against the leaf test (the truth's watertight
// float32 segment test; the module docstring of per_triangle_volume.py has the argument): the
// planes are built in double from the float32 data, kept in float32, and a tile decides only
// beyond a margin of at least u_theta · u_scale (world units, some 500 float32 ulps of the
// scene's coordinates, far above the float32 error of the tile test itself): a box outside a
// plane by the margin keeps every segment at least that far from the triangle, and a box inside
// all four planes by the margin puts every segment's crossing that far inside it and well before
// the segment's end.
#include "per_triangle_volume_common.glsl"

#ifdef COMPUTE_SHADER
layout(local_size_x = LOCAL_SIZE) in;
#define LIGHT_AT_POINT 0                 // point and spot lights: rays end at T_LIGHT of the way to u_light
#define LIGHT_AT_INFINITY 1              // directional: rays along u_light_dir, unbounded
#define LIGHT_TARGET_DIRECT 2            // rays along u_light_dir, ending on the light's plane
                                         // (through u_light, normal -u_light_dir)
#define REJECT 0
#define ACCEPT 1
#define DESCEND 2
uniform int u_light_kind;
uniform vec3 u_light;                    // the light's position, float32 as the truth's rays use it
uniform vec3 u_light_dir;                // towards the light (the rays' direction) for lights at infinity
uniform float u_scale;                   // an upper bound on every distance between two points of the scene
uniform float u_theta;                   // the margin, a fraction of u_scale
uniform float u_band;                    // planes within u_band · u_scale of the light (or within cosine
                                         // u_band of parallel to a light at infinity) are not used
uniform int u_triangles;
uniform int u_accept;                    // 0: no tile is accepted (every tile not rejected descends)
uniform int u_level;                     // the level whose nodes this pass tests
uniform int u_pairs;                     // list_in's pairs (without TOP)
uniform int u_capacity;                  // list_out's capacity, pairs
layout(std430, binding = 11) buffer Volumes { vec4 volume[]; };  // per triangle: VOLUME_VEC4S, written by the TOP pass
// Per triangle: 0, or the orientation (+1 outward, -1 inward) of the closed mesh it belongs to,
// the light outside it: such a triangle facing away from the light may be culled.
layout(std430, binding = 13) readonly buffer Cullable { int cullable[]; };
#define CULL_COSINE 0.0009765625         // 2^-10: culled only when facing away by more than this cosine

// A triangle's volume as built in double (volume_of) and kept in float32 for the tile tests.
struct Volume {
    vec4 plane[4];     // edge planes 0..2 (positive inside), the triangle's plane 3 (positive: the light's side)
    bool use[4];       // a plane too degenerate to decide anything is not used
    bool accept_ok;    // every plane used, and the crossing is provably before each segment's end
    float edge_margin_per_distance;  // point lights: the edge margin per unit of a box's distance from the light
    float margin;      // world units, added to every margin (it also covers the float32 tile arithmetic)
};
#define VOLUME_VEC4S 5                   // per triangle in `volume`: the four planes, then the margins and flags

// The point of triangle (a, b, c) closest to p (Ericson 2005, "Real-Time Collision Detection",
// §5.1.5); p itself for a triangle degenerate in its interior case (callers need a lower bound
// on the distance, and 0 is one).
dvec3 closest_on_triangle(dvec3 p, dvec3 a, dvec3 b, dvec3 c) {
    dvec3 ab = b - a, ac = c - a, ap = p - a;
    double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0lf && d2 <= 0.0lf) return a;
    dvec3 bp = p - b;
    double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0lf && d4 <= d3) return b;
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0lf && d1 >= 0.0lf && d3 <= 0.0lf) return a + ab * (d1 / (d1 - d3));
    dvec3 cp = p - c;
    double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0lf && d5 <= d6) return c;
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0lf && d2 >= 0.0lf && d6 <= 0.0lf) return a + ac * (d2 / (d2 - d6));
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0lf && (d4 - d3) >= 0.0lf && (d5 - d6) >= 0.0lf)
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    double denom = va + vb + vc;
    if (!(denom > 0.0lf)) return p;      // a degenerate triangle: distance 0, the safe lower bound
    double v = vb / denom, w = vc / denom;
    return a + ab * v + ac * w;
}

// The four planes and margins of triangle tri, built in double from its float32 corners.
Volume volume_of(int tri) {
    Volume vol;
    dvec4 plane[4];
    dvec3 v[3];
    for (int i = 0; i < 3; ++i) v[i] = dvec3(triangle_vertex[3 * tri + i].xyz);
    dvec3 L = dvec3(u_light), u = dvec3(u_light_dir);
    double scale = double(u_scale);
    bool at_point = u_light_kind == LIGHT_AT_POINT;
    // the edge planes: through the light (or along its direction) and each edge, the third corner inside
    for (int i = 0; i < 3; ++i) {
        dvec3 p0 = v[i], p1 = v[(i + 1) % 3], p2 = v[(i + 2) % 3];
        dvec3 n = at_point ? cross(p0 - L, p1 - L) : cross(p1 - p0, u);
        double side = dot(n, p2 - p0);
        double size = at_point ? length(p0 - L) * length(p1 - L) * length(p2 - L)
                               : length(p1 - p0) * length(p2 - p0);
        vol.use[i] = abs(side) > 1e-12lf * size && length(n) > 0.0lf;
        if (vol.use[i]) {
            n = (side > 0.0lf ? n : -n) / length(n);
            plane[i] = dvec4(n, -dot(n, p0));
        } else {
            plane[i] = dvec4(0.0lf);
        }
    }
    // the triangle's plane, positive on the light's side
    dvec3 n = cross(v[1] - v[0], v[2] - v[0]);
    vol.use[3] = length(n) > 0.0lf;
    vol.accept_ok = false;
    if (vol.use[3]) {
        n /= length(n);
        // point lights: the light's distance from the plane; at infinity: the cosine to the rays
        double light_side = at_point ? dot(n, L - v[0]) : dot(n, u);
        double band = at_point ? double(u_band) * scale : double(u_band);
        vol.use[3] = abs(light_side) >= band;
        n = light_side > 0.0lf ? n : -n;
        plane[3] = dvec4(n, -dot(n, v[0]));
        vol.accept_ok = u_accept != 0 && vol.use[0] && vol.use[1] && vol.use[2] && vol.use[3];
        if (u_light_kind == LIGHT_TARGET_DIRECT) {
            // the rays end on the light's plane: accept only a triangle wholly in front of it
            for (int i = 0; i < 3; ++i)
                if (dot(v[i] - L, -u) < double(u_band) * scale) vol.accept_ok = false;
        }
    } else {
        plane[3] = dvec4(0.0lf);
    }
    double theta = double(u_theta) * scale;
    vol.margin = float(theta);
    if (at_point) {
        // a segment that passes the edge plane at angle α passes the triangle's edges at least
        // α × (the triangle's distance from the light) away: the margin grows as the triangle
        // comes close to the light; a triangle touching the light uses no edge plane
        double r_min = distance(L, closest_on_triangle(L, v[0], v[1], v[2]));
        if (r_min > 0.0lf) {
            vol.edge_margin_per_distance = float(theta / r_min);
        } else {
            vol.use[0] = vol.use[1] = vol.use[2] = false;
            vol.accept_ok = false;
            vol.edge_margin_per_distance = 0.0;
        }
    } else {
        vol.edge_margin_per_distance = 0.0;
    }
    for (int i = 0; i < 4; ++i) vol.plane[i] = vec4(plane[i]);
    return vol;
}

void store_volume(int tri, Volume vol) {
    for (int i = 0; i < 4; ++i) volume[VOLUME_VEC4S * tri + i] = vol.plane[i];
    int flags = (vol.use[0] ? 1 : 0) | (vol.use[1] ? 2 : 0) | (vol.use[2] ? 4 : 0) | (vol.use[3] ? 8 : 0)
              | (vol.accept_ok ? 16 : 0);
    volume[VOLUME_VEC4S * tri + 4] = vec4(vol.edge_margin_per_distance, vol.margin, 0.0, float(flags));
}

Volume load_volume(int tri) {
    Volume vol;
    for (int i = 0; i < 4; ++i) vol.plane[i] = volume[VOLUME_VEC4S * tri + i];
    vec4 m = volume[VOLUME_VEC4S * tri + 4];
    int flags = int(m.w);
    for (int i = 0; i < 4; ++i) vol.use[i] = (flags & (1 << i)) != 0;
    vol.accept_ok = (flags & 16) != 0;
    vol.edge_margin_per_distance = m.x;
    vol.margin = m.y;
    return vol;
}

// The volume being tested, in plain variables (no arrays: llvmpipe keeps dynamically indexed
// arrays in per-invocation memory).
vec4 g_plane0, g_plane1, g_plane2, g_plane3;
int g_flags;                             // bits 0..3: planes used, bit 4: accept allowed
float g_margin_per_distance, g_margin;

void set_volume(Volume vol) {
    g_plane0 = vol.plane[0]; g_plane1 = vol.plane[1]; g_plane2 = vol.plane[2]; g_plane3 = vol.plane[3];
    g_flags = (vol.use[0] ? 1 : 0) | (vol.use[1] ? 2 : 0) | (vol.use[2] ? 4 : 0) | (vol.use[3] ? 8 : 0)
            | (vol.accept_ok ? 16 : 0);
    g_margin_per_distance = vol.edge_margin_per_distance;
    g_margin = vol.margin;
}

// The box [lo, hi] of a node's ray origins against the volume, in float32: the planes' rounding
// to float32 and this arithmetic err by a few ulps of the scene's coordinates, far inside the
// margin (u_theta · u_scale, some 500 ulps of them).
int classify(vec3 lo, vec3 hi) {
    vec3 c = (lo + hi) * 0.5;
    vec3 h = (hi - lo) * 0.5;
    float me = g_margin + g_margin_per_distance * (distance(c, u_light) + length(h));
    // signed distances of the centre, and the box's reach, for the four planes
    vec4 s = vec4(dot(g_plane0.xyz, c) + g_plane0.w, dot(g_plane1.xyz, c) + g_plane1.w,
                  dot(g_plane2.xyz, c) + g_plane2.w, dot(g_plane3.xyz, c) + g_plane3.w);
    vec4 r = vec4(dot(abs(g_plane0.xyz), h), dot(abs(g_plane1.xyz), h), dot(abs(g_plane2.xyz), h),
                  dot(abs(g_plane3.xyz), h));
    bvec4 use = bvec4((g_flags & 1) != 0, (g_flags & 2) != 0, (g_flags & 4) != 0, (g_flags & 8) != 0);
    // wholly outside an edge plane, or wholly on the light's side of the triangle
    bvec4 out_ = bvec4(lessThan(s.xyz + r.xyz, vec3(-me)), s.w - r.w > g_margin);
    if (any(bvec4(use.x && out_.x, use.y && out_.y, use.z && out_.z, use.w && out_.w))) return REJECT;
    bool inside = (g_flags & 16) != 0 && all(greaterThan(s.xyz - r.xyz, vec3(me))) && s.w + r.w < -g_margin;
    return inside ? ACCEPT : DESCEND;
}

uint tests = 0u, accepted = 0u, rejected = 0u;

// Does triangle tri face away from the light, on a closed mesh with the light outside? Every
// segment that a closed, consistently oriented mesh blocks (the light outside it) leaves the
// mesh through a triangle facing the light — with the watertight test too, whose edge functions
// agree on shared edges — so the others may be skipped (module docstring). Nearly edge-on
// triangles are kept.
bool culled(int tri) {
    int orientation = cullable[tri];
    if (orientation == 0) return false;
    dvec3 a = dvec3(triangle_vertex[3 * tri].xyz);
    dvec3 n = cross(dvec3(triangle_vertex[3 * tri + 1].xyz) - a, dvec3(triangle_vertex[3 * tri + 2].xyz) - a)
              * double(orientation);
    dvec3 towards = u_light_kind == LIGHT_AT_POINT ? dvec3(u_light) - a : dvec3(u_light_dir);
    return dot(n, towards) < -double(CULL_COSINE) * length(n) * length(towards);
}

// Test node n (level u_level) of triangle tri: accept, reject or append the pair.
void visit(int tri, int n) {
    vec4 lo = node_box[2 * n];
    if (lo.w == 0.0) return;  // an empty node holds no sample: nothing to test
    ++tests;
    int verdict = classify(lo.xyz, node_box[2 * n + 1].xyz);
    if (verdict == REJECT) {
        ++rejected;
    } else if (verdict == ACCEPT) {
        ++accepted;
        atomicOr(node_flag[n], 1u);  // the tile-level set: every sample below is blocked
    } else {
        uint i = atomicAdd(counter[COUNTER_DESCENDED(u_level)], 1u);
        if (i < uint(u_capacity)) list_out[i] = ivec2(tri, n);
    }
}

void main() {
    int index = INVOCATION_INDEX;
#ifdef TOP
    if (index >= u_triangles) return;
    int tri = index;
    if (culled(tri)) {
        atomicAdd(counter[COUNTER_CULLED], 1u);
        return;
    }
    Volume vol = volume_of(tri);
    store_volume(tri, vol);
    set_volume(vol);
    ivec2 size = u_level_size[u_level];
    for (int t = 0; t < size.x * size.y; ++t)
        for (int k = 0; k < u_level_per_tile[u_level]; ++k)
            visit(tri, node_index(u_level, ivec2(t % size.x, t / size.x), k));
#else
    if (index >= u_pairs) return;
    ivec2 pair = list_in[index];
    int tri = pair.x;
    set_volume(load_volume(tri));
    int above = u_level + 1;
    int local = pair.y - u_level_offset[above];
    ivec2 tile = ivec2(local % u_level_size[above].x, local / u_level_size[above].x);
    ivec2 size = u_level_size[u_level];
    int fanout = u_level_fanout[above];
    for (int j = 0; j < fanout; ++j) {
        for (int i = 0; i < fanout; ++i) {
            ivec2 c = tile * fanout + ivec2(i, j);
            if (c.x >= size.x || c.y >= size.y) continue;
            for (int k = 0; k < u_level_per_tile[u_level]; ++k) visit(tri, node_index(u_level, c, k));
        }
    }
#endif
    atomicAdd(counter[COUNTER_TESTS(u_level)], tests);
    atomicAdd(counter[COUNTER_ACCEPTED(u_level)], accepted);
    atomicAdd(counter[COUNTER_REJECTED(u_level)], rejected);
}
#endif
