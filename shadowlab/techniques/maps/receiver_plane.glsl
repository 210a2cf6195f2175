// The receiver's plane in a shadow map's space (Isidoro 2006, "Shadow mapping: GPU-based tips
// and techniques", GDC: receiver plane depth bias): the depth gradient along the map's axes,
// for slope-scaled and receiver-plane bias. Shared by shadow_lookup.glsl and
// virtual_lookup.glsl; the includer includes atlas.glsl (to_map) first.
#define BASIS_SWITCH 0.9                 // tangent t1 = N × x while |N.x| < this, else N × y

// dz/du, dz/dv of the receiver plane at Q (normal N, map coordinates c in face f) in map space,
// from two tangent points `texel` apart (Cramer's rule): true, or false when the plane is edge-on
// to the light (then `edge` holds the two tangent points' depth changes).
bool receiver_plane_gradient(int f, vec3 Q, vec3 N, vec3 c, float texel, out vec2 dz, out vec2 edge) {
    vec3 t1 = normalize(abs(N.x) < BASIS_SWITCH ? cross(N, vec3(1.0, 0.0, 0.0)) : cross(N, vec3(0.0, 1.0, 0.0)));
    vec3 t2 = cross(N, t1);
    vec3 a = to_map(f, Q + t1 * texel) - c;
    vec3 b = to_map(f, Q + t2 * texel) - c;
    float det = a.x * b.y - a.y * b.x;
    edge = vec2(a.z, b.z);
    dz = vec2(0.0);
    if (!(abs(det) > 0.0)) return false;
    dz = vec2(a.z * b.y - b.z * a.y, a.x * b.z - b.x * a.z) / det;
    return true;
}
