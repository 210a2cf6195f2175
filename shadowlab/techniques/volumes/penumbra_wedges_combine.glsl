// Penumbra wedges, the last pass: V = V_hard + Σ wedge contributions, clamped to [0, 1]
// (Assarsson & Akenine-Möller 2003, §4: the hard shadow from the light's centre plus the
// signed light fractions the wedges accumulated). Drawn twice under a stencil test on the hard
// shadow volume's counts: once for count == 0 (u_hard = 1), once for count != 0 (u_hard = 0).
//
// u_horizon (not in the paper): the receiver's own tangent plane treated as one more occluder
// in the same additive scheme. Its "edge" is the line where the plane meets the light's; its
// centre term [centre below the plane] and its edge term ([centre below] − f_below) add up to
// −f_below, the fraction of the light below P's tangent plane (which the truth counts as
// occluded, docs/metrics.md): V = V_hard + Σ wedges − f_below. Exact alone; where a caster hides part
// of the light that is also below the horizon, it is subtracted twice (the SS1 approximation).
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "gbuffer_fetch.glsl"
#define SQUARE_CORNERS 4
#define MAX_CORNERS 5           // the square cut by one line
#define HALF_EDGE 0.5           // the light is s, t in [-1/2, 1/2] (full edges u, v)

uniform sampler2D u_wedges;      // the wedges' sum, R32F
uniform float u_hard;            // visibility of the light's centre (the stencil test decides)
uniform bool u_clamp;            // clamp to [0, 1] (the paper); false shows the raw sum
uniform bool u_horizon;          // subtract the light's fraction below P's tangent plane
uniform vec3 u_light_centre;
uniform vec3 u_light_normal;     // unit, towards the emitting side
uniform vec3 u_light_u;          // the rect's full edges
uniform vec3 u_light_v;
uniform vec3 u_eye;              // the camera: the tangent plane's normal is turned towards it
out float out_value;

// The fraction of the light square where alpha·s + beta·t + gamma < 0 (Sutherland-Hodgman on
// the square against one line, then the shoelace formula; the square's area is 1).
float fraction_below(float alpha, float beta, float gamma) {
    vec2 sq[SQUARE_CORNERS] = vec2[SQUARE_CORNERS](vec2(-HALF_EDGE, -HALF_EDGE), vec2(HALF_EDGE, -HALF_EDGE),
                                                   vec2(HALF_EDGE, HALF_EDGE), vec2(-HALF_EDGE, HALF_EDGE));
    vec2 poly[MAX_CORNERS];
    int n = 0;
    for (int i = 0; i < SQUARE_CORNERS; ++i) {
        vec2 p = sq[i], q = sq[(i + 1) % SQUARE_CORNERS];
        float dp = -(alpha * p.x + beta * p.y + gamma), dq = -(alpha * q.x + beta * q.y + gamma);
        if (dp >= 0.0) poly[n++] = p;
        if ((dp >= 0.0) != (dq >= 0.0)) poly[n++] = p + (dp / (dp - dq)) * (q - p);
    }
    float twice = 0.0;
    for (int i = 0; i < n; ++i) {
        vec2 p = poly[i], q = poly[(i + 1) % n];
        twice += p.x * q.y - p.y * q.x;
    }
    return 0.5 * abs(twice);
}

void main() {
    vec3 P;
    gbuffer_position(P);
    float v = u_hard + texelFetch(u_wedges, gbuffer_pixel(), 0).r;
    if (u_horizon) {
        // light point x = c + s·u + t·v is above P's tangent plane when (x − P)·N > 0
        vec3 N = gbuffer_normal_towards(u_eye - P);
        v -= fraction_below(dot(u_light_u, N), dot(u_light_v, N), dot(u_light_centre - P, N));
    }
    if (dot(P - u_light_centre, u_light_normal) <= 0.0) v = 0.0;  // behind a one-sided light
    out_value = u_clamp ? clamp(v, 0.0, 1.0) : v;
}
#endif
