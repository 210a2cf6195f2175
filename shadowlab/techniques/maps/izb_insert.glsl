// Irregular z-buffer, pass 1: every ray's origin (the truth's offset surface point) goes into the
// list of the light-space texel it projects to — its face of the atlas (a point light's cube: the
// major axis of light-to-point), head pointers swapped in with atomicExchange, nodes taken from
// a pool of u_node_capacity by atomicAdd. A full pool and a point outside every face are counted,
// never dropped silently: the Python side reads the counters and retries or fails.
#include "izb_common.glsl"

#ifdef COMPUTE_SHADER
#ifndef MAX_FACES
#error "MAX_FACES: the map toolkit's atlas size (shadowlab.techniques.maps.toolkit.ATLAS_DEFINES)"
#endif
#ifndef LOCAL_SIZE
#error "LOCAL_SIZE: invocations per work group (shadowlab.techniques.maps.irregular_zbuffer)"
#endif
layout(local_size_x = LOCAL_SIZE) in;
#include "lights.glsl"
uniform int u_rays;
uniform int u_node_capacity;
uniform int u_faces;
uniform mat4 u_light_matrix[MAX_FACES];
uniform vec4 u_face_rect[MAX_FACES];
#include "cube_face.glsl"
#include "atlas.glsl"

void main() {
    int k = INVOCATION_INDEX;
    if (k >= u_rays) return;
    ray_texel[k] = NO_NODE;
    vec4 o = ray_origin[k];
    if (o.w == NO_RAY) return;
    int f = face_of(o.xyz);
    vec3 c;
    // The segment from the origin to the light projects to the origin's own texel: every point
    // of it lies on the origin's line through the light (parallel projection: along the light).
    if (!map_coordinates(f, o.xyz, c) || any(lessThan(c.xy, vec2(0.0))) || any(greaterThanEqual(c.xy, vec2(1.0)))) {
        atomicAdd(counter[COUNTER_OUTSIDE], 1u);
        return;
    }
    ivec2 t = ivec2(floor(atlas_texel(f, c.xy)));
    int texel = t.y * int(u_atlas_size.x) + t.x;
    ray_texel[k] = texel;
    uint n = atomicAdd(counter[COUNTER_NODES], 1u);
    if (n >= uint(u_node_capacity)) {
        atomicAdd(counter[COUNTER_NODE_OVERFLOW], 1u);
        return;
    }
    node[n] = ivec2(k, atomicExchange(head[texel], int(n)));
}
#endif
