// Imperfect shadow maps (Ritschel et al. 2008), the pull-push pass that fills the splat's holes
// (the pull-push of Grossman & Dally 1998 and Gortler et al. 1996, as Ritschel et al. use it):
// one dispatch per pyramid level, one invocation per texel of the level written.
// - PULL (levels 1 .. L, finest first): texel t of level k is the average of the valid depths
//   among its four children 2t + {0, 1}² in level k - 1 (u_finer); a hole when none is valid.
//   The average of the valid ones only, as Ritschel et al. pull (not the nearest: a hole on a
//   silhouette gets a depth between the caster's and the background's).
// - PUSH (levels L - 1 .. 0, coarsest first): a valid texel of level k (u_finer: the level's own
//   pulled depths) is kept; a hole takes the bilinear interpolation of the four nearest texels
//   of level k + 1 (u_coarser, already pushed), over the valid ones only (weights renormalised).
// Validity: a depth below HOLE (the splat's clear value). Faces: the atlas holds 1 or 6 faces of
// u_face texels a side at the level written; at a power-of-two resolution a face's children lie
// in the same face at every level, and the push's bilinear taps are clamped to the face, so no
// face reads another's depths. Writes go to a texture other than the ones read (u_target).
//! glsl 430

#ifdef COMPUTE_SHADER
#ifndef LOCAL_SIZE
#error "LOCAL_SIZE: invocations per work group side (shadowlab.techniques.maps.imperfect_map)"
#endif
#define PULL 0
#define PUSH 1
#define HOLE 1.0                         // the splat's clear value: no point reached the texel
layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

uniform sampler2D u_finer;               // PULL: level k - 1; PUSH: level k's pulled depths
uniform sampler2D u_coarser;             // PUSH: level k + 1, pushed
layout(r32f) uniform writeonly image2D u_target;  // level k
uniform int u_mode;                      // PULL or PUSH
uniform ivec2 u_size;                    // the written level's size (the whole atlas), texels
uniform int u_face;                      // a face's side at the written level, texels

bool valid(float depth) { return depth < HOLE; }

float pull(ivec2 t) {
    float sum = 0.0;
    int n = 0;
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            float d = texelFetch(u_finer, 2 * t + ivec2(dx, dy), 0).r;
            if (valid(d)) {
                sum += d;
                ++n;
            }
        }
    return n > 0 ? sum / float(n) : HOLE;
}

float push(ivec2 t) {
    float own = texelFetch(u_finer, t, 0).r;
    if (valid(own)) return own;
    // t's centre in the coarser level's texel coordinates (centres at integer + 0.5 there)
    int side = u_face / 2;                               // the face's side one level up
    ivec2 lo = (t / u_face) * side, hi = lo + ivec2(side - 1);
    vec2 p = (vec2(t) + 0.5) * 0.5 - 0.5;
    ivec2 base = ivec2(floor(p));
    vec2 f = p - vec2(base);
    float sum = 0.0, weight = 0.0;
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
            float d = texelFetch(u_coarser, clamp(base + ivec2(i, j), lo, hi), 0).r;
            float w = (i == 1 ? f.x : 1.0 - f.x) * (j == 1 ? f.y : 1.0 - f.y);
            if (valid(d) && w > 0.0) {
                sum += w * d;
                weight += w;
            }
        }
    return weight > 0.0 ? sum / weight : HOLE;
}

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(t, u_size))) return;
    imageStore(u_target, t, vec4(u_mode == PULL ? pull(t) : push(t)));
}
#endif
