// The G-buffer (gbuffer.glsl) read at this fragment's own pixel, for the full-screen passes over
// it: include it in the fragment stage (it reads gl_FragCoord). A technique declares the channels
// it samples (READS) and Technique.bind_gbuffer binds them, setting u_position, u_normal and u_ids
// to their units; a pass that reads only some of them leaves the others unused (the compiler
// drops them, and bind_gbuffer skips them).
uniform sampler2D u_position;            // G-buffer world position, w = 1 where covered
uniform sampler2D u_normal;              // G-buffer geometric normal, as stored (either side)
uniform isampler2D u_ids;                // G-buffer (object id, triangle id); -1 where uncovered

// The G-buffer texel of this fragment (gl_FragCoord.xy is its centre, integer + 0.5).
ivec2 gbuffer_pixel() {
    return ivec2(gl_FragCoord.xy);
}

// P: the world position of the surface seen in this pixel; false where none is (w = 0).
bool gbuffer_position(out vec3 P) {
    vec4 p4 = texelFetch(u_position, gbuffer_pixel(), 0);
    P = p4.xyz;
    return p4.w != 0.0;
}

// The unit geometric normal seen in this pixel, turned to the side `towards` points to
// (surfaces are two-sided).
vec3 gbuffer_normal_towards(vec3 towards) {
    vec3 N = normalize(texelFetch(u_normal, gbuffer_pixel(), 0).xyz);
    return dot(N, towards) < 0.0 ? -N : N;
}

// (object id, triangle id) seen in this pixel; negative where nothing was drawn.
ivec2 gbuffer_ids() {
    return texelFetch(u_ids, gbuffer_pixel(), 0).xy;
}
