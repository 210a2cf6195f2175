// Test probe: evaluates the light model of lights.glsl at given points (transform feedback),
// so tests can check it against the numpy twin in shadowlab/lights.py.
#include "lights.glsl"

#ifdef VERTEX_SHADER
in vec3 in_pos;
out float out_footprint;
out vec3 out_dir;
void main() {
    out_footprint = light_footprint(in_pos);
    out_dir = light_dir_to(in_pos);
}
#endif
