// Irregular z-buffer, pass 2: each caster triangle is rasterised conservatively into each face of
// the light's atlas, and every fragment whose texel holds samples appends the pair (triangle,
// texel) to the work list that izb_test.glsl tests exactly (Johnson et al. 2005 §3; Wyman,
// Hoetzlein & Lefohn 2015 rasterise the same way with hardware conservative rasterisation). The
// fragment stage only appends: on llvmpipe a fragment shader that walks a list costs orders of
// magnitude more per step than a compute shader (docs/irregular-zbuffer.md), so the walk is a
// compute pass. A full work list is counted (the pairs asked for), never dropped silently.
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

// With COVERAGE_POLYGON the fragment stage keeps only the texels whose square, grown by
// u_edge_pad texels, overlaps the clipped polygon (the separating-axis test on the polygon's
// edges: the box's own axes are the quad's), as in Hasselgren, Akenine-Möller & Ohlsson 2005
// (GPU Gems 2 ch. 42): fewer pairs for long thin triangles across the grid (wires), but on
// llvmpipe the per-fragment test costs more than the pairs it saves on dense meshes.
#define MAX_CORNERS 4                    // a triangle clipped by one plane: at most 4 corners

#ifdef GEOMETRY_SHADER
#define UNBOUNDED 3.0e38                 // the empty box's corners (float32's range: 3.4e38)
layout(triangles) in;
layout(triangle_strip, max_vertices = MAX_CORNERS) out;
in vec3 v_world[];
flat out int g_triangle;
flat out int g_corners;
flat out vec2 g_polygon[MAX_CORNERS];    // the clipped polygon in window coordinates (texels)
uniform mat4 u_face_view_proj;           // this face's projection · view
uniform float u_w_min;                   // perspective: clip plane w = u_w_min (orthographic: w = 1)
uniform vec2 u_margin_ndc;               // the coverage margin, NDC units (x, y)
uniform vec4 u_viewport;                 // this face's rect in the atlas: x0, y0, width, height

void main() {
    vec4 c[3];
    for (int i = 0; i < 3; ++i) c[i] = u_face_view_proj * vec4(v_world[i], 1.0);
    vec2 lo = vec2(UNBOUNDED), hi = vec2(-UNBOUNDED);
    vec2 poly[MAX_CORNERS];
    int n = 0;
    // Sutherland-Hodgman against w >= u_w_min: the kept corners and the crossings, in order.
    for (int i = 0; i < 3; ++i) {
        vec4 a = c[i], b = c[(i + 1) % 3];
        bool ka = a.w >= u_w_min, kb = b.w >= u_w_min;
        if (ka) poly[n++] = a.xy / a.w;
        if (ka != kb) {
            vec4 p = mix(a, b, (u_w_min - a.w) / (b.w - a.w));
            poly[n++] = p.xy / u_w_min;  // on the plane, whatever the rounding of the mix
        }
    }
    if (n == 0) return;
    for (int i = 0; i < n; ++i) {
        lo = min(lo, poly[i]);
        hi = max(hi, poly[i]);
        g_polygon[i] = u_viewport.xy + (poly[i] * 0.5 + 0.5) * u_viewport.zw;
    }
    lo = max(lo - u_margin_ndc, vec2(-1.0));
    hi = min(hi + u_margin_ndc, vec2(1.0));
    if (any(greaterThanEqual(lo, hi))) return;  // wholly outside this face
    g_triangle = gl_PrimitiveIDIn;
    g_corners = n;
    gl_Position = vec4(lo.x, lo.y, 0.0, 1.0); EmitVertex();
    gl_Position = vec4(hi.x, lo.y, 0.0, 1.0); EmitVertex();
    gl_Position = vec4(lo.x, hi.y, 0.0, 1.0); EmitVertex();
    gl_Position = vec4(hi.x, hi.y, 0.0, 1.0); EmitVertex();
    EndPrimitive();
}
#endif

#ifdef FRAGMENT_SHADER
#define TEXEL 1.0                        // a texel's side in window coordinates
flat in int g_triangle;
flat in int g_corners;
flat in vec2 g_polygon[MAX_CORNERS];
uniform int u_pair_capacity;
uniform float u_edge_pad;                // texels added around each texel's square
uniform float u_edge_test_limit;         // polygons reaching further (texels) keep their whole box

float cross2(vec2 a, vec2 b) { return a.x * b.y - a.y * b.x; }

// Does the square [lo, hi] overlap the convex polygon g_polygon? Conservative: a degenerate or
// far-reaching polygon (float32 edge functions no longer trustworthy) says yes.
bool overlaps(vec2 lo, vec2 hi) {
    float area = 0.0;
    for (int i = 0; i < g_corners; ++i) {
        vec2 p = g_polygon[i];
        if (any(greaterThan(abs(p), vec2(u_edge_test_limit)))) return true;
        area += cross2(p, g_polygon[(i + 1) % g_corners]);
    }
    if (!(abs(area) > 0.0)) return true;  // a line seen edge-on: keep the box
    float side = sign(area);
    for (int i = 0; i < g_corners; ++i) {
        vec2 p = g_polygon[i], e = g_polygon[(i + 1) % g_corners] - p;
        // the square's corner furthest inside this edge; outside even there: separated
        vec2 q = vec2(-side * e.y > 0.0 ? hi.x : lo.x, side * e.x > 0.0 ? hi.y : lo.y);
        if (side * cross2(e, q - p) < 0.0) return false;
    }
    return true;
}

void main() {
    ivec2 texel = ivec2(gl_FragCoord.xy);  // the framebuffer is the atlas
    int index = texel.y * int(u_atlas_size.x) + texel.x;
    if (head[index] == NO_NODE) return;    // no sample here: nothing to test
#ifdef COVERAGE_POLYGON
    vec2 corner = vec2(texel);
    if (!overlaps(corner - vec2(u_edge_pad), corner + vec2(TEXEL + u_edge_pad))) return;
#endif
    uint i = atomicAdd(counter[COUNTER_PAIRS], 1u);
    if (i < uint(u_pair_capacity)) pair[i] = ivec2(g_triangle, index);
}
#endif
