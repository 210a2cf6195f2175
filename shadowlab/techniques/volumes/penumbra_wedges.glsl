// Penumbra wedges (Assarsson & Akenine-Möller, SIGGRAPH 2003, §3-4; Assarsson, Dougherty,
// Mounier & Akenine-Möller, Graphics Hardware 2003, §3): one conservative wedge per silhouette
// edge (silhouette seen from the light's centre), drawn as the back faces of its convex hull
// with additive blending into a float target. Every pixel whose view ray crosses the hull gets
// exactly one fragment (a convex hull has one exit point per ray; the rasterisation rules give
// shared edges to one triangle), and the fragment adds the signed fraction of the light that the
// edge moves across the hard shadow's decision at the light's centre:
//
//   V(P) = V_hard(P) + Σ_e sign_e · area(R_e) / area(L),
//   R_e = {x ∈ L : the segment centre → x crosses the edge projected from P onto the light},
//
// sign_e = +1 when the centre lies inside the projected silhouette (the crossing leaves the
// shadow: visible light is added), −1 otherwise. For one closed silhouette loop this is exact
// (signed crossings of the segment centre → x count [c ∈ S] − [x ∈ S]); integrating over L gives
// the paper's "area between the clipped projected edge and the centre", one edge at a time.
// A pixel outside the edge's true wedge has R_e = ∅ (the light is convex and holds its centre),
// so a conservative hull is enough.

uniform mat4 u_view;
uniform mat4 u_proj;

#ifdef VERTEX_SHADER
in vec3 in_pos;      // a corner of the wedge's hull (world)
in vec3 in_edge_a;   // the silhouette edge a -> b (world), walked as a light-facing face walks it
in vec3 in_edge_b;
in vec4 in_plane_ab;  // plane (n, n·v) of the face walking the edge a -> b
in vec4 in_plane_ba;  // ... and of the face walking it b -> a
flat out vec3 v_a;
flat out vec3 v_b;
flat out vec4 v_plane_ab;
flat out vec4 v_plane_ba;
void main() {
    v_a = in_edge_a;
    v_b = in_edge_b;
    v_plane_ab = in_plane_ab;
    v_plane_ba = in_plane_ba;
    gl_Position = u_proj * (u_view * vec4(in_pos, 1.0));
}
#endif

#ifdef FRAGMENT_SHADER
#include "gbuffer_fetch.glsl"
#define HALF_EDGE 0.5           // the light is s, t in [-1/2, 1/2] (full edges u, v)
#define SIDE (2.0 * HALF_EDGE)  // the square's side
#define PERIMETER (4.0 * SIDE)

uniform vec3 u_light_centre;
uniform vec3 u_light_normal;     // unit, towards the emitting side
uniform vec3 u_light_du;         // dual basis of the edges u, v: s = (x − c)·du, t = (x − c)·dv
uniform vec3 u_light_dv;
uniform float u_slab_margin;     // the edge is cut to heights [m·h_P, (1 − m)·h_P] (see below)
uniform float u_coplanar;        // an edge within this × its distance of P's tangent plane lies in it
flat in vec3 v_a;
flat in vec3 v_b;
flat in vec4 v_plane_ab;
flat in vec4 v_plane_ba;
out float out_value;

float cross2(vec2 a, vec2 b) { return a.x * b.y - a.y * b.x; }

// Liang-Barsky: the segment a -> b cut to the light square; false when none of it is inside.
bool clip_to_square(inout vec2 a, inout vec2 b) {
    vec2 d = b - a;
    float t0 = 0.0, t1 = 1.0;
    for (int axis = 0; axis < 2; ++axis) {
        float p = d[axis], lo = -HALF_EDGE - a[axis], hi = HALF_EDGE - a[axis];
        if (p == 0.0) {
            if (lo > 0.0 || hi < 0.0) return false;
        } else {
            float ta = lo / p, tb = hi / p;
            t0 = max(t0, min(ta, tb));
            t1 = min(t1, max(ta, tb));
        }
    }
    if (t0 >= t1) return false;
    vec2 a0 = a;
    a = a0 + t0 * d;
    b = a0 + t1 * d;
    return true;
}

// Where the ray from the centre through p leaves the square, as a distance along its perimeter
// walked counter-clockwise from the corner (h, −h): sides x = h, y = h, x = −h, y = −h in turn.
float perimeter_coordinate(vec2 p) {
    vec2 q = p * (HALF_EDGE / max(abs(p.x), abs(p.y)));
    float h = HALF_EDGE;  // side k starts at k · SIDE
    if (abs(p.x) >= abs(p.y)) return p.x > 0.0 ? q.y + h : 2.0 * SIDE + (h - q.y);
    return p.y > 0.0 ? SIDE + (h - q.x) : 3.0 * SIDE + (q.x + h);
}

// Area (a fraction of the light: the square has area 1 in s, t) of R_e for the clipped projected
// edge a -> b, counter-clockwise about the centre (cross2(a, b) > 0), both inside the square:
// the square's sector between the rays through a and b minus the triangle (centre, a, b), which
// lies inside the square. The sector is a fan of triangles from the centre over the square's
// boundary, each of height HALF_EDGE, so its area is HALF_EDGE / 2 · the perimeter it spans.
float region_area(vec2 a, vec2 b) {
    float span = mod(perimeter_coordinate(b) - perimeter_coordinate(a), PERIMETER);
    return max(0.5 * HALF_EDGE * span - 0.5 * cross2(a, b), 0.0);
}

void main() {
    out_value = 0.0;
    vec3 P;
    if (!gbuffer_position(P)) return;
    float hp = dot(P - u_light_centre, u_light_normal);   // P's height below the light
    if (hp <= 0.0) return;                                // behind a one-sided light: V = 0 anyway
    // Per-pixel silhouette (Assarsson & Akenine-Möller 2003 §6 name the centre's silhouette as the
    // approximation; Laine et al. 2005 count P's own): the projection of a closed caster from P
    // is bounded by the edges whose faces face P differently. For P in the edge's wedge, the
    // light points behind the edge lie across both face planes from P, so the face turned away
    // from P is the one facing them: it walks the edge as a light-facing face does. The fixed
    // planes of the centre's silhouette (FIXED_PLANES) make every P keep the direction a -> b.
    bool sees_ab = dot(v_plane_ab.xyz, P) - v_plane_ab.w > 0.0;
    bool sees_ba = dot(v_plane_ba.xyz, P) - v_plane_ba.w > 0.0;
    if (sees_ab == sees_ba) return;                       // not a silhouette edge seen from P
    vec3 ea = sees_ab ? v_b : v_a, eb = sees_ab ? v_a : v_b;
    // Only the part of the edge strictly between the light's plane and P's parallel plane can
    // project onto the light from P (central projection; the oracle's slab, tests/soft_oracle.py).
    float ha = dot(ea - u_light_centre, u_light_normal);
    float hb = dot(eb - u_light_centre, u_light_normal);
    float lo = u_slab_margin * hp, hi = (1.0 - u_slab_margin) * hp;
    float t0 = 0.0, t1 = 1.0;
    float dh = hb - ha;
    if (dh == 0.0) {
        if (ha < lo || ha > hi) return;
    } else {
        float tl = (lo - ha) / dh, th = (hi - ha) / dh;
        t0 = max(t0, min(tl, th));
        t1 = min(t1, max(tl, th));
        if (t0 >= t1) return;
    }
    vec3 a = mix(ea, eb, t0), b = mix(ea, eb, t1);
    // An edge in P's own tangent plane (P on a planar caster, the edge on its rim) projects onto
    // the horizon line: it hides nothing above P's horizon, and the chain of such edges, cut at
    // P's parallel plane, would otherwise close "at infinity" over one side of that line — the
    // light below the horizon, which the truth already counts as hidden by P's own surface.
    vec3 N = gbuffer_normal_towards(u_light_centre - P);
    if (abs(dot(a - P, N)) <= u_coplanar * length(a - P) && abs(dot(b - P, N)) <= u_coplanar * length(b - P))
        return;
    // Central projection from P onto the light's plane: q = P + (e − P)·h_P / (h_P − h_e).
    vec3 qa = P + (a - P) * (hp / (hp - dot(a - u_light_centre, u_light_normal)));
    vec3 qb = P + (b - P) * (hp / (hp - dot(b - u_light_centre, u_light_normal)));
    vec2 sa = vec2(dot(qa - u_light_centre, u_light_du), dot(qa - u_light_centre, u_light_dv));
    vec2 sb = vec2(dot(qb - u_light_centre, u_light_du), dot(qb - u_light_centre, u_light_dv));
    // det(a − P, b − P, c − P) = −(h_P / λ_a λ_b) · |u × v| · cross2(s_a, s_b): the centre is
    // inside the projected silhouette (sign +1, light added) exactly when cross2 < 0. One
    // quantity decides both the sign and the region, so they never disagree.
    float cr = cross2(sa, sb);
    if (cr == 0.0 || !clip_to_square(sa, sb)) return;  // the edge's projection misses the light
    if (cr > 0.0) out_value = -region_area(sa, sb);
    else out_value = region_area(sb, sa);
}
#endif
