// Moment soft shadow mapping (Peters, Münstermann, Wetzstein & Klein, I3D 2016), the summed-area
// table (Crow 1984) of the moment map: S[x, y] = Σ_{i <= x, j <= y} m[i, j] over the four stored
// moments (the 16-bit optimised basis of Peters & Klein 2015, in [0, 1]), built in two passes
// of prefix sums — u_pass ROW_PASS: one invocation per row sums along x from the moments
// texture into the table; COLUMN_PASS: one invocation per column sums the table along y, in
// place (each invocation reads and writes its own column only).
//
// SAT_FIXED (a define; the paper's remedy for the precision of the table): each moment is
// converted to fixed point, round(m · u_fixed_scale), and summed in 32-bit unsigned integers.
// Integer sums wrap modulo 2³², but a rectangle's sum S[a] - S[b] - S[c] + S[d] taken in the same
// modular arithmetic is exact as long as the true sum is below 2³²: the Python side picks
// u_fixed_scale = floor((2³² - 1) / the largest rectangle, in texels, that any lookup reads).
// Without SAT_FIXED the table is float32 (the classic table): the sums grow to ~0.5 · W · H and
// a rectangle far from the origin loses the low bits of its moments — the known artefact.
//! glsl 430

#ifdef COMPUTE_SHADER
#ifndef LOCAL_SIZE
#error "LOCAL_SIZE: invocations per work group (shadowlab.techniques.maps.moment_soft)"
#endif
#define ROW_PASS 0
#define COLUMN_PASS 1
layout(local_size_x = LOCAL_SIZE) in;

uniform sampler2D u_moments;             // the moment map (RGBA32F), read by the row pass
uniform int u_pass;                      // ROW_PASS or COLUMN_PASS
uniform ivec2 u_size;                    // the map's width and height in texels
#ifdef SAT_FIXED
uniform float u_fixed_scale;             // fixed-point steps per unit moment
layout(rgba32ui) uniform coherent uimage2D u_sat;
#define SAT_VALUE uvec4
#else
layout(rgba32f) uniform coherent image2D u_sat;
#define SAT_VALUE vec4
#endif

// One texel's moments as the table sums them.
SAT_VALUE table_value(ivec2 t) {
    vec4 m = texelFetch(u_moments, t, 0);
#ifdef SAT_FIXED
    // round to nearest; the moments of a depth in [0, 1] lie in [0, 1] in the optimised basis
    return uvec4(round(clamp(m, 0.0, 1.0) * u_fixed_scale));
#else
    return m;
#endif
}

void main() {
    int line = int(gl_GlobalInvocationID.x);
    SAT_VALUE sum = SAT_VALUE(0);
    if (u_pass == ROW_PASS) {
        if (line >= u_size.y) return;
        for (int x = 0; x < u_size.x; ++x) {
            ivec2 t = ivec2(x, line);
            sum += table_value(t);
            imageStore(u_sat, t, sum);
        }
    } else {
        if (line >= u_size.x) return;
        for (int y = 0; y < u_size.y; ++y) {
            ivec2 t = ivec2(line, y);
            sum += imageLoad(u_sat, t);
            imageStore(u_sat, t, sum);
        }
    }
}
#endif
