// Irregular z-buffer, pass 2: each caster triangle is rasterised conservatively into each face of
// the light's atlas, and every fragment whose texel holds samples appends the pair (triangle,
// texel) to the work list that izb_test.glsl tests exactly (Johnson et al. 2005 §3; Wyman,
// Hoetzlein & Lefohn 2015 rasterise the same way with hardware conservative rasterisation). The
// fragment stage only appends: on llvmpipe a fragment shader that walks a list costs about 1000×
// what a compute shader does per step (measured: 3.5 µs against 2 ns), so the walk is a compute
// pass. A full work list is counted (the pairs asked for), never dropped silently.
//
// Conservative coverage without GL_NV_conservative_raster (llvmpipe has none): the geometry
// stage emits the triangle's light-space bounding box grown by u_margin_ndc (COVERAGE_MARGIN
// texels) on every side, so every texel the triangle's projection touches has its centre inside
// the quad — a superset of the exact coverage (more pairs, the same answer: the exact test
// decides). Perspective faces: the triangle is first clipped to w >= u_w_min, a plane between
// the light and every ray's end (rays stop short of the light, shadowlab.scene.lights.T_LIGHT),
// so the part left out cannot meet any ray; what is left projects to a bounded box.
#include "izb_common.glsl"

#ifdef VERTEX_SHADER
in vec3 in_position;                     // a caster triangle's vertex, world, float32
out vec3 v_world;
void main() {
    v_world = in_position;
}
#endif

#ifdef GEOMETRY_SHADER
#define CORNERS 4
#define UNBOUNDED 3.0e38                 // the empty box's corners (float32's range: 3.4e38)
layout(triangles) in;
layout(triangle_strip, max_vertices = CORNERS) out;
in vec3 v_world[];
flat out int g_triangle;
uniform mat4 u_face_view_proj;           // this face's projection · view
uniform float u_w_min;                   // perspective: clip plane w = u_w_min (orthographic: w = 1)
uniform vec2 u_margin_ndc;               // the coverage margin, NDC units (x, y)

void extend(inout vec2 lo, inout vec2 hi, vec4 p) {
    vec2 q = p.xy / p.w;
    lo = min(lo, q);
    hi = max(hi, q);
}

void main() {
    vec4 c[3];
    for (int i = 0; i < 3; ++i) c[i] = u_face_view_proj * vec4(v_world[i], 1.0);
    vec2 lo = vec2(UNBOUNDED), hi = vec2(-UNBOUNDED);
    bool any_kept = false;
    // Sutherland-Hodgman against w >= u_w_min: the kept corners and the crossings.
    for (int i = 0; i < 3; ++i) {
        vec4 a = c[i], b = c[(i + 1) % 3];
        bool ka = a.w >= u_w_min, kb = b.w >= u_w_min;
        if (ka) { extend(lo, hi, a); any_kept = true; }
        if (ka != kb) {
            vec4 p = mix(a, b, (u_w_min - a.w) / (b.w - a.w));
            p.w = u_w_min;               // on the plane, whatever the rounding of the mix
            extend(lo, hi, p);
            any_kept = true;
        }
    }
    if (!any_kept) return;
    lo = max(lo - u_margin_ndc, vec2(-1.0));
    hi = min(hi + u_margin_ndc, vec2(1.0));
    if (any(greaterThanEqual(lo, hi))) return;  // wholly outside this face
    g_triangle = gl_PrimitiveIDIn;
    gl_Position = vec4(lo.x, lo.y, 0.0, 1.0); EmitVertex();
    gl_Position = vec4(hi.x, lo.y, 0.0, 1.0); EmitVertex();
    gl_Position = vec4(lo.x, hi.y, 0.0, 1.0); EmitVertex();
    gl_Position = vec4(hi.x, hi.y, 0.0, 1.0); EmitVertex();
    EndPrimitive();
}
#endif

#ifdef FRAGMENT_SHADER
flat in int g_triangle;
uniform int u_pair_capacity;

void main() {
    ivec2 texel = ivec2(gl_FragCoord.xy);  // the framebuffer is the atlas
    int index = texel.y * int(u_atlas_size.x) + texel.x;
    if (head[index] == NO_NODE) return;    // no sample here: nothing to test
    uint i = atomicAdd(counter[COUNTER_PAIRS], 1u);
    if (i < uint(u_pair_capacity)) pair[i] = ivec2(g_triangle, index);
}
#endif
