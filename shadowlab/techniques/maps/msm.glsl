// The four-moment (Hamburger 4MSM) reconstruction of Peters & Klein 2015 ("Moment Shadow
// Mapping", I3D 2015, Algorithm 2), shared by the filtered shadow maps (filtered_lookup.glsl,
// variant msm) and moment soft shadow mapping (moment_soft.glsl, Peters et al. 2016). The
// includer passes biased moments b = (b1, b2, b3, b4) = E[(z, z², z³, z⁴)] of a depth
// distribution in [0, 1] (b0 = 1) and a receiver depth t.
//
// Given b and t, the Hankel system B c = (1, t, t²), B = [[1, b1, b2], [b1, b2, b3], [b2, b3, b4]],
// is solved through B = L D Lᵀ (L unit lower triangular: l21 = b1, l31 = b2, l32; D = diag(1,
// d22, d33)); c gives the quadratic c3 z² + c2 z + c1 whose roots z2 <= z3 are, with t, the
// support of the three-point distribution matching the moments (the canonical representation
// with one point at t).
#define MSM_TOTAL_MASS 1.0               // b0 = E[z⁰] of any depth distribution

// The two support points z2 <= z3 besides t of the canonical three-point distribution.
void msm_support(vec4 b, float t, out float z2, out float z3) {
    // B = L D Lᵀ
    float d22 = b.y - b.x * b.x;
    float l32 = (b.z - b.x * b.y) / d22;
    float d33 = b.w - b.y * b.y - l32 * l32 * d22;
    // L y = (1, t, t²); D w = y; Lᵀ c = w
    float y2 = t - b.x;
    float y3 = t * t - b.y - l32 * y2;
    float c3 = y3 / d33;
    float c2 = y2 / d22 - l32 * c3;
    float c1 = MSM_TOTAL_MASS - b.x * c2 - b.y * c3;
    // roots of c3 z² + c2 z + c1: z = -p/2 ∓ sqrt(p²/4 - q), p = c2 / c3, q = c1 / c3
    float half_p = c2 / (c3 + c3);
    float r = sqrt(max(half_p * half_p - c1 / c3, 0.0));
    z2 = -half_p - r;
    z3 = -half_p + r;
}

// The shadow intensity G of Algorithm 2, step 4 (not clamped): the weight of the canonical
// distribution strictly in front of t — 0 (t <= z2), the weight at z2 (z2 < t <= z3), or all but
// the weight at t (t > z3).
float msm_shadow_intensity(vec4 b, float t) {
    float z2, z3;
    msm_support(b, t, z2, z3);
    float shadow;
    if (t <= z2) {
        shadow = 0.0;
    } else if (t <= z3) {                // the weight at z2
        shadow = (t * z3 - b.x * (t + z3) + b.y) / ((z3 - z2) * (t - z2));
    } else {                             // the weights at z2 and z3: all but the one at t
        shadow = MSM_TOTAL_MASS - (z2 * z3 - b.x * (z2 + z3) + b.y) / ((t - z2) * (t - z3));
    }
    return shadow;
}
