// Vertex stage of a pass drawn from a light's view. Include it first in programs that draw the
// scene's casters (an #extension line must come before any declaration).
//
// Without FACE_ARRAY: world positions through u_light_view_proj (projection · view of the one
// view drawn), set by the caller before each draw.
//
// With FACE_ARRAY (the map toolkit's depth_pass, shadowlab/techniques/maps/toolkit.py): the
// per-face matrices of a map atlas in u_face_view_proj[MAX_FACES], and the face of a vertex is
// u_face_base + gl_InstanceID. Drawn per face (u_face_base = the face, one instance, the face's
// rect set as every viewport) or in one instanced draw (u_face_base = 0, one instance per face,
// viewport i = face i's rect): with VIEWPORT_INDEX the vertex shader writes gl_ViewportIndex =
// the face, so each instance lands in its own rect — GL_ARB_shader_viewport_layer_array
// (VIEWPORT_INDEX = 1) or GL_AMD_vertex_shader_viewport_index (VIEWPORT_INDEX = 2). Both ways
// compute the same product for the same vertex, so the atlas is the same texel for texel.
#if defined(FACE_ARRAY) && defined(VIEWPORT_INDEX)
#if VIEWPORT_INDEX == 1
#extension GL_ARB_shader_viewport_layer_array : require
#else
#extension GL_AMD_vertex_shader_viewport_index : require
#endif
#endif

#ifdef FACE_ARRAY
uniform mat4 u_face_view_proj[MAX_FACES];  // per face: projection · view
uniform int u_face_base;                   // the face of instance 0
#else
uniform mat4 u_light_view_proj;
#endif

#ifdef VERTEX_SHADER
in vec3 in_pos;
void main() {
#ifdef FACE_ARRAY
    int face = u_face_base + gl_InstanceID;
    gl_Position = u_face_view_proj[face] * vec4(in_pos, 1.0);
#ifdef VIEWPORT_INDEX
    gl_ViewportIndex = face;
#endif
#else
    gl_Position = u_light_view_proj * vec4(in_pos, 1.0);
#endif
}
#endif
