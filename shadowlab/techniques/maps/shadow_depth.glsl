// Shadow-map depth pass (Williams 1978): casters rendered from the light into the faces of the
// depth atlas (per face or in one instanced draw, light_vertex.glsl); depth only. With PEEL defined (depth peeling, Everitt 2001), fragments not
// strictly behind the first layer are discarded, leaving the second-nearest surface.
#include "light_vertex.glsl"

#ifdef FRAGMENT_SHADER
#ifdef PEEL
uniform sampler2D u_first_layer;   // the first layer's depth, same atlas layout
uniform float u_peel_epsilon;      // one step of the depth format: what "the same surface" means
#endif
void main() {
#ifdef PEEL
    float first = texelFetch(u_first_layer, ivec2(gl_FragCoord.xy), 0).r;
    if (gl_FragCoord.z <= first + u_peel_epsilon) discard;
#endif
}
#endif
