// Virtual shadow map, pass `request` (compute; UE5's page marking from the depth buffer): every
// evaluated G-buffer pixel marks, in one uint per page per level, the page of the level it wants
// (virtual_common.glsl: wanted_level) and the page of the coarsest level — in the face the point
// looks up (a point light's cube: six virtual maps) — so that a dropped page
// always has a resident ancestor to fall back to. Plain stores of one value: no atomics needed.
//! glsl 430
#ifdef COMPUTE_SHADER
#ifndef LOCAL_SIZE
#error "LOCAL_SIZE: invocations per work-group side (shadowlab.techniques.maps.virtual_map)"
#endif
layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
#define REQUESTED 1u
#include "lights.glsl"
uniform int u_faces;
uniform mat4 u_light_matrix[MAX_FACES];  // per face: BIAS · projection · view of its level 0
uniform vec4 u_face_rect[MAX_FACES];     // unused here (atlas.glsl's functions name it)
uniform vec2 u_atlas_size;
#include "cube_face.glsl"
#include "atlas.glsl"
#include "virtual_common.glsl"
uniform sampler2D u_position;            // G-buffer world position, w = 1 where covered
uniform usampler2D u_evaluated;          // 1 where the pixel is evaluated for this light (docs/metrics.md)
uniform int u_mask_offset[MAX_LEVELS];   // first word of level m of face 0 in `request`
uniform int u_face_words;                // words of one face's levels: face f starts at f × this
layout(std430, binding = BINDING_REQUESTS) buffer Requests { uint request[]; };

void mark(int f, int m, vec2 uv) {
    ivec2 p = page_of(m, uv);
    request[f * u_face_words + u_mask_offset[m] + p.y * level_pages(m) + p.x] = REQUESTED;
}

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, textureSize(u_position, 0)))) return;
    if (texelFetch(u_evaluated, pixel, 0).r == 0u) return;
    vec3 P = texelFetch(u_position, pixel, 0).xyz;
    vec3 c;
    int f = face_of(P);                  // a point light's cube: the face of the major axis
    if (!map_coordinates(f, P, c) || !on_virtual_map(c)) return;  // lit: needs no page
    mark(f, covering_level(P, c.xy), c.xy);
    mark(f, u_levels - 1, c.xy);
}
#endif
