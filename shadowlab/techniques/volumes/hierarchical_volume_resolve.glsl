// Hierarchical shadow volumes, visibility: one full-screen pass under the stencil test
// "stencil == 0". Boundary tiles were counted per pixel: lit where the stencil is 0 (the
// fragments that pass the test). Other tiles were never touched by the per-pixel pass (their
// stencil is still 0): lit where the tile's count is 0 modulo 256, the stencil's own wrapping
// arithmetic, so that the verdict is the plain volume's even for 256 volumes.
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "hierarchical_volume_common.glsl"
out float out_visibility;
void main() {
    int t = tile_of_pixel(ivec2(gl_FragCoord.xy));
    out_visibility = (tile_boundary[t] != 0u || (tile_count[t] & 255) == 0) ? 1.0 : 0.0;
}
#endif
