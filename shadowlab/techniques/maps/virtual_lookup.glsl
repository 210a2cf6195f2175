// Virtual shadow map, pass `lookup`: one full-screen pass over the G-buffer. Each point takes the
// level it wants (virtual_common.glsl, as the request pass computed it), walks up to the finest
// resident level at or above it through the page table (UE5 falls back to a coarser mip where a
// page is missing), and compares its window depth, less a constant and a slope-scaled bias (as
// shadow_lookup.glsl's `slope` variant, with that level's texel; the constant part in window depth
// or, u_bias_world, a world distance converted at the receiver), with the physical page's texel.
// Points off the virtual map, or behind a perspective map's centre of projection, are lit.
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "lights.glsl"
#define LIT 1.0
#define SHADOWED 0.0
#include "gbuffer_fetch.glsl"
uniform int u_faces;
uniform mat4 u_light_matrix[MAX_FACES];  // per face: BIAS · projection · view of its level 0
uniform vec4 u_face_rect[MAX_FACES];     // unused here (atlas.glsl's functions name it)
uniform vec2 u_atlas_size;
#include "cube_face.glsl"
#include "atlas.glsl"
#include "receiver_plane.glsl"
#include "world_bias.glsl"
#include "virtual_common.glsl"
uniform sampler2D u_pool;                // the physical page pool: window depth
uniform isampler2D u_page_table;         // face f, level m, page (x, y) at texel (x, f × u_face_rows + u_table_row[m] + y): slot or NOT_RESIDENT
uniform int u_table_row[MAX_LEVELS];
uniform int u_face_rows;                 // page-table rows of one face's levels
uniform int u_pool_side;                 // pages per side of the pool
uniform int u_page_size;                 // texels per side of a page
uniform float u_virtual_resolution;      // texels per side of level 0
uniform float u_bias;                    // window depth
uniform float u_bias_world;              // world distance towards the light (0: none; world_bias.glsl)
uniform float u_slope_scale;             // multiple of the receiver's depth change over one texel
out float out_visibility;

void main() {
    out_visibility = LIT;
    vec3 P;
    if (!gbuffer_position(P)) return;
    vec3 N = gbuffer_normal_towards(light_dir_to(P));  // two-sided receivers: the side facing the light
    vec3 c;
    int f = face_of(P);                  // a point light's cube: the face of the major axis
    if (!map_coordinates(f, P, c) || !on_virtual_map(c)) return;
    int slot = NOT_RESIDENT;
    int m = wanted_level(P);
    for (; m < u_levels; ++m) {
        if (!level_contains(m, c.xy)) continue;  // clipmaps: a coarser level beyond this one's square
        ivec2 page = page_of(m, c.xy);
        slot = texelFetch(u_page_table, ivec2(page.x, f * u_face_rows + u_table_row[m] + page.y), 0).r;
        if (slot != NOT_RESIDENT) break;
    }
    if (slot == NOT_RESIDENT) return;   // never: the coarsest page is requested and kept first
    float pages = float(level_pages(m));
    vec2 in_page = level_uv(m, c.xy) * pages - vec2(page_of(m, c.xy));
    ivec2 texel = clamp(ivec2(floor(in_page * float(u_page_size))), ivec2(0), ivec2(u_page_size - 1));
    ivec2 origin = ivec2(slot % u_pool_side, slot / u_pool_side) * u_page_size;
    float stored = texelFetch(u_pool, origin + texel, 0).r;
    // Slope-scaled bias with this level's texel (shadow_lookup.glsl's slope variant).
    float scale = float(1 << m);
    float texel_uv = scale / u_virtual_resolution;
    vec2 dz, edge;
    float extra;
    if (receiver_plane_gradient(f, P, N, c, level0_texel(P) * scale, dz, edge))
        extra = u_slope_scale * (abs(dz.x) + abs(dz.y)) * texel_uv;
    else
        extra = u_slope_scale * max(abs(edge.x), abs(edge.y));  // edge-on to the light
    // Level 0's matrix converts the world bias: the levels crop it sideways, their depth is its.
    out_visibility = c.z - (u_bias + world_bias(f, P, u_bias_world) + extra) <= stored ? LIT : SHADOWED;
}
#endif
