// Which face of a shadow-map atlas a point looks up: 0 for a single-face map, else the cube face
// of the major axis of the light-to-point vector, in the order of CUBE_FACES in
// shadowlab/geometry/frusta.py (+x, -x, +y, -y, +z, -z). Needs `uniform int u_faces;` and
// lights.glsl (light_position) declared before it is included.
int face_of(vec3 p) {
    if (u_faces == 1) return 0;
    vec3 d = p - light_position;
    vec3 a = abs(d);
    if (a.x >= a.y && a.x >= a.z) return d.x > 0.0 ? 0 : 1;
    if (a.y >= a.z) return d.y > 0.0 ? 2 : 3;
    return d.z > 0.0 ? 4 : 5;
}
