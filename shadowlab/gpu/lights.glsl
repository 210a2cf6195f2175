// Light model shared by every GL program. Numpy twin: shadowlab/lights.py (a test checks that
// both give the same footprint and light direction). Footprint λ as in docs/architecture.md#the-shading-pass-shadowlabgpushadingpy.
#define LIGHT_POINT 0
#define LIGHT_DIRECTIONAL 1
#define LIGHT_SPOT 2
#define LIGHT_TARGET_DIRECT 3
#define LIGHT_AREA 4          // rect, disc, sphere: shaded as a point light at the centre (docs/metrics.md)

uniform int light_type;
uniform vec3 light_position;      // point, spot, target-direct, area (the centre)
uniform vec3 light_direction;     // unit; the direction the light travels
uniform vec3 light_color;         // diffuse and specular intensity
uniform float light_ambient;      // ambient intensity
uniform float light_cos_outer;    // spot: cos(alpha / 2)
uniform float light_cos_inner;    // spot: cos(beta / 2)
uniform float light_radius_outer; // target-direct: R
uniform float light_radius_inner; // target-direct: r
uniform float light_range;        // point, spot: > 0 = distance falloff to 0 at this distance; 0 = none
uniform float light_inverse_square_near; // point, spot without range: > 0 = 1/max(d^2, near^2) falloff; 0 = none
uniform int light_cone_squared;   // spot: 1 = the cone ramp squared (KHR_lights_punctual), 0 = linear

// Unit vector from p towards the light.
vec3 light_dir_to(vec3 p) {
    if (light_type == LIGHT_DIRECTIONAL || light_type == LIGHT_TARGET_DIRECT)
        return -light_direction;
    return normalize(light_position - p);
}

// Distance attenuation of a light with a range (Karis's squared window over inverse-square falloff;
// KHR_lights_punctual recommends the window unsquared): clamp(1 - (d/range)^4, 0, 1)^2 / max(d^2, (0.01 range)^2). Numpy twin:
// range_attenuation() in shadowlab/scene/lights.py (RANGE_NEAR = 0.01), operation for operation.
float light_attenuation(vec3 p) {
    vec3 v = p - light_position;
    float d2 = dot(v, v);
    float r2 = light_range * light_range;
    float x = d2 / r2;                       // (d / range)^2
    float window = clamp(1.0 - x * x, 0.0, 1.0);
    return window * window / max(d2, (0.01 * 0.01) * r2);
}

// Inverse-square falloff of a light without a range that asks for it (KHR_lights_punctual's light
// without a range): 1 / max(d^2, near^2). Numpy twin: inverse_square_attenuation() in
// shadowlab/scene/lights.py (INVERSE_SQUARE_NEAR), operation for operation.
float light_inverse_square(vec3 p) {
    vec3 v = p - light_position;
    float d2 = dot(v, v);
    return 1.0 / max(d2, light_inverse_square_near * light_inverse_square_near);
}

// Shape factor of λ: the spot's cone, the target-direct cylinder, else 1.
float light_shape_footprint(vec3 p) {
    if (light_type == LIGHT_SPOT) {
        float cos_phi = dot(normalize(p - light_position), light_direction);
        float width = light_cos_inner - light_cos_outer;
        if (width > 0.0) {
            float ramp = clamp((cos_phi - light_cos_outer) / width, 0.0, 1.0);
            return light_cone_squared != 0 ? ramp * ramp : ramp;
        }
        return float(cos_phi >= light_cos_outer);
    }
    if (light_type == LIGHT_TARGET_DIRECT) {
        vec3 v = p - light_position;
        float t = dot(v, light_direction);
        if (t <= 0.0) return 0.0;
        float rho = length(v - t * light_direction);
        float width = light_radius_outer - light_radius_inner;
        return width > 0.0 ? clamp((light_radius_outer - rho) / width, 0.0, 1.0)
                           : float(rho <= light_radius_outer);
    }
    return 1.0;
}

// Footprint factor λ >= 0 at p: the shape factor, times the distance attenuation when the light
// has a range (then λ may exceed 1: the colour is the intensity at distance 1); without a range
// exactly the shape factor, in [0, 1], unless the light asks for inverse-square falloff.
float light_footprint(vec3 p) {
    float lam = light_shape_footprint(p);
    if (light_range > 0.0) return lam * light_attenuation(p);
    return light_inverse_square_near > 0.0 ? lam * light_inverse_square(p) : lam;
}
