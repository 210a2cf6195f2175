// Virtual shadow map (UE5's virtual shadow maps, Epic Games 2022, "Virtual Shadow Maps" in the
// Unreal Engine 5 documentation): what the request pass (virtual_request.glsl) and the lookup
// (virtual_lookup.glsl) must compute identically — the mip level a point wants and the page of
// that level its light-space uv falls in. Python twin: shadowlab/techniques/maps/virtual_map.py.
// Levels are a mip pyramid over one view (level m: level 0's uv, (V/P) >> m pages a side) or,
// fit=clipmap, UE5's clipmap: level k a full virtual map of twice level k−1's side, centred on the
// camera — its uv is level 0's × 2^−k plus an offset of whole pages (u_level_uv), and a point
// outside level k's square uses a coarser level.
// The includer includes lights.glsl (light_position) and atlas.glsl (face f = face f's level 0)
// first, and defines MAX_LEVELS (the size of the per-level arrays). A point light's cube is six
// virtual maps, one per face (atlas.glsl's faces), sharing these levels and page sizes.
#ifndef MAX_LEVELS
#error "MAX_LEVELS: per-level array size (shadowlab.techniques.maps.virtual_map.MAX_LEVELS)"
#endif
#define NOT_RESIDENT (-1)                // page-table entry of a page with no physical page
#define FIRST_INSIDE 0.0                 // the virtual map covers uv in [0, 1)
#define PAST_INSIDE 1.0
#define NEAR_DEPTH 0.0                   // window depths of the near and far planes
#define FAR_DEPTH 1.0

uniform int u_levels;                    // levels M
uniform vec4 u_level_uv[MAX_LEVELS];     // level m's uv = level-0 uv × .x + .yz (mips: 1, 0, 0)
uniform int u_level_pages[MAX_LEVELS];   // pages per side of level m (mips: V/P >> m; clipmaps: V/P)
uniform float u_texel_world;             // level 0, orthographic maps: world size of a texel (else 0)
uniform float u_texel_angle;             // level 0, perspective maps: world size of a texel per unit distance
uniform vec3 u_camera_eye;               // the frame's camera position, world
uniform float u_pixel_angle;             // world size of a screen pixel per unit distance from the eye
uniform float u_lod_bias;                // added to log2(pixel / texel) before flooring: < 0 finer

// World size of a level-0 texel at P (perspective maps: texel angle × distance from the light).
float level0_texel(vec3 P) {
    return u_texel_world > 0.0 ? u_texel_world : u_texel_angle * distance(P, light_position);
}

// The level whose texels are about as large as a screen pixel at P: floor(log2(pixel world
// footprint / level-0 texel) + u_lod_bias), clamped to the pyramid.
int wanted_level(vec3 P) {
    float footprint = distance(P, u_camera_eye) * u_pixel_angle;
    float m = floor(log2(footprint / level0_texel(P)) + u_lod_bias);
    return int(clamp(m, 0.0, float(u_levels - 1)));
}

// Pages per side of level m.
int level_pages(int m) {
    return u_level_pages[m];
}

// Level m's uv of the level-0 uv `uv`.
vec2 level_uv(int m, vec2 uv) {
    return uv * u_level_uv[m].x + u_level_uv[m].yz;
}

// True when level m covers the point of level-0 uv `uv` (mips: every level covers level 0).
bool level_contains(int m, vec2 uv) {
    vec2 l = level_uv(m, uv);
    return all(greaterThanEqual(l, vec2(FIRST_INSIDE))) && all(lessThan(l, vec2(PAST_INSIDE)));
}

// The page (x, y) of level m that the level-0 uv `uv` falls in.
ivec2 page_of(int m, vec2 uv) {
    int n = level_pages(m);
    return clamp(ivec2(floor(level_uv(m, uv) * float(n))), ivec2(0), ivec2(n - 1));
}

// The level a point at P (level-0 uv `uv`) requests: the wanted level, walked up to the finest
// level that covers it (clipmaps: UE5 uses the finest clipmap level containing the point).
int covering_level(vec3 P, vec2 uv) {
    int m = wanted_level(P);
    while (m < u_levels - 1 && !level_contains(m, uv)) ++m;
    return m;
}

// True when map coordinates c = (u, v, window depth) lie on the virtual map and within its depth
// range (as shadow_lookup.glsl: a point past the far plane, fitted just beyond the farthest
// receiver that can be shadowed, is lit).
// c.xy is level-0 uv; on the map is inside the coarsest level (mips: level 0 itself).
bool on_virtual_map(vec3 c) {
    return level_contains(u_levels - 1, c.xy) && c.z >= NEAR_DEPTH && c.z <= FAR_DEPTH;
}
