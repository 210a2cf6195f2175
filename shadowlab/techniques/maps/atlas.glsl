// A shadow-map atlas: u_faces faces in one texture of u_atlas_size texels (width, height); face
// f has the light matrix u_light_matrix[f] = bias · projection · view and occupies
// u_face_rect[f] = (x0, y0, width, height) of the atlas, in texels. The includer declares those
// uniforms (the arrays sized by its MAX_FACES) before it includes this file.
#define HALF_TEXEL 0.5                   // texel centres are at integer + 0.5 (GL 4.5 core §8.14)

// (u, v, depth) of p in face f's map, in [0, 1] inside it (p in front of the light).
vec3 to_map(int f, vec3 p) {
    vec4 s = u_light_matrix[f] * vec4(p, 1.0);
    return s.xyz / s.w;
}

// c = (u, v, depth) of p in face f's map; false when p is behind the light's centre of
// projection (c is then left unset).
bool map_coordinates(int f, vec3 p, out vec3 c) {
    vec4 s = u_light_matrix[f] * vec4(p, 1.0);
    if (s.w <= 0.0) return false;
    c = s.xyz / s.w;
    return true;
}

// Texel coordinates in the atlas of the point uv ([0, 1]²) of face f.
vec2 atlas_texel(int f, vec2 uv) {
    return u_face_rect[f].xy + uv * u_face_rect[f].zw;
}

// Texel coordinates clamped so that the 2x2 footprint of a bilinear tap stays inside face f: a
// texel centre sits half a texel in from the face's edge, and taps beyond it would read the
// neighbouring face of the atlas.
vec2 bilinear_inside_face(int f, vec2 atlas) {
    vec2 inner = u_face_rect[f].xy + vec2(HALF_TEXEL);
    return clamp(atlas, inner, inner + u_face_rect[f].zw - vec2(2.0 * HALF_TEXEL));
}
