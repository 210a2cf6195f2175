// Screen-space contact shadows, Bend Studio's formulation (Days Gone; "Inside Bend: screen space
// shadows", Graham Aldridge 2023, Apache-2.0 reference code), one invocation per pixel: from the
// pixel, march `u_samples` steps of one pixel along the major axis of the screen-space line to
// the light's projected point, reading the depth buffer, and shadow the pixel when a sample's
// surface lies in front of the ray (nearer the camera) by about the surface thickness.
// shadowlab.techniques.maps.contact says how this maps onto Bend's waves and dispatches.
//
// Why the ray's depth is affine along the screen line: a 3D line projects to a 2D line, and its
// window depth z/w and screen position x/w share the denominator w, so along the projected line
// window depth is an affine function of screen position. At the light's projected point it is
// the light's own window depth lz, so at major-axis distance s from that point the ray's depth
// is lz + (d0 - lz) · s / s0 (d0: the start pixel's depth, s0 its distance). Bend stores
// (D - lz) / s per sample, which is constant along a ray ("all light rays become parallel");
// the difference below is the same quantity written with the ray's depth.
//
// The thickness window (our reading of Bend's shader): u = (ray depth - D) · (s0 / s) · m / (1 - d0),
// m = min(s0 - 1, 1 / thickness) — the thickness is a fraction of the depth left to the far plane
// (1 - d0), and near the light's point the window narrows with s0. A sample shadows fully when
// |u - 1| <= (contrast - 1) / contrast: the surface is in front of the ray by 0.25 to 1.75
// thicknesses at the default contrast 4; a surface on the ray (u = 0) never shadows itself.
//! glsl 430

#ifdef COMPUTE_SHADER
layout(local_size_x = 8, local_size_y = 8) in;

uniform sampler2D u_depth;               // window depth of the G-buffer (R32F), 1 where nothing was drawn
layout(r32f) uniform writeonly image2D u_contact;
uniform ivec2 u_origin;                  // this dispatch's rectangle of pixels: origin ...
uniform ivec2 u_extent;                  // ... and size
uniform ivec2 u_size;                    // the frame's size in pixels
uniform vec4 u_light;                    // the light's projected point: pixel x, y, window depth, +1 in front of the camera / -1 behind
uniform int u_samples;                   // samples per pixel = the shadow's maximum length in pixels
uniform int u_hard;                      // the first samples: a single one may shadow the pixel fully
uniform int u_fade;                      // the last samples: their shadow fades out
uniform float u_thickness;               // surface thickness, a fraction of the depth left to the far plane
uniform float u_bilinear;                // depth step (same fraction) above which the minor-axis pair is an edge
uniform float u_contrast;                // how sharply the window's edge turns to full shadow

const float FAR = 1.0;                   // window depth of the far plane (GL's [0, 1], not reversed)
const float IGNORED = 1e20;              // a sample past the light or off the screen: never shadows

float depth_at(ivec2 p) {
    return texelFetch(u_depth, p, 0).r;
}

// The shadowing depth of the sample at screen point q (major-axis coordinate at a pixel centre):
// the pixel below q and its neighbour on the minor axis, on the side q leans to. A pair that
// differs by more than u_bilinear (of the depth left to the far plane) is an edge: the pixel's own
// depth; else the pair's farther depth (Bend's non-offset mode: conservative, never nearer).
float shadowing_depth(vec2 q, bool x_major) {
    ivec2 p = ivec2(floor(q));
    if (any(lessThan(p, ivec2(0))) || any(greaterThanEqual(p, u_size)))
        return IGNORED;
    float minor = x_major ? q.y : q.x;
    int lean = fract(minor) - 0.5 > 0.0 ? 1 : -1;
    ivec2 n = clamp(p + (x_major ? ivec2(0, lean) : ivec2(lean, 0)), ivec2(0), u_size - 1);
    float a = depth_at(p), b = depth_at(n);
    bool edge = abs(a - b) > abs(FAR - a) * u_bilinear;
    return edge ? a : a + abs(a - b);
}

void main() {
    ivec2 local = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(local, u_extent)))
        return;
    ivec2 pix = u_origin + local;
    float d0 = depth_at(pix);
    vec2 p = vec2(pix) + 0.5;
    bool in_front = u_light.w > 0.0;
    // towards the light's point when it is in front of the camera, away from it when behind
    vec2 to = in_front ? u_light.xy - p : p - u_light.xy;
    bool x_major = abs(to.x) > abs(to.y);
    float s0 = max(abs(to.x), abs(to.y));
    if (d0 >= FAR || s0 < 1.0) {         // nothing drawn, or the pixel holds the light's point
        imageStore(u_contact, pix, vec4(1.0));
        return;
    }
    vec2 step_xy = to / s0;              // one pixel along the major axis
    float direction = in_front ? -1.0 : 1.0;  // how s changes per step
    float m = min(s0 + direction, 1.0 / u_thickness);
    float scale = m / abs(FAR - d0);
    float hard = 1.0;
    vec4 grouped = vec4(1.0);
    for (int i = 0; i < u_samples; ++i) {
        float k = float(i + 1);
        float s = s0 + direction * k;
        float delta = IGNORED;
        if (s > 0.0) {
            float D = shadowing_depth(p + k * step_xy, x_major);
            if (D < IGNORED) {
                float ray = u_light.z + (d0 - u_light.z) * s / s0;
                delta = abs((ray - D) * (s0 / s) * scale - 1.0);
            }
        }
        if (i < u_hard) {
            hard = min(hard, delta);
        } else if (i < u_samples - u_fade) {
            grouped[i & 3] = min(grouped[i & 3], delta);
        } else {
            float fade = float(i + 1 - (u_samples - u_fade)) / float(u_fade + 1) * 0.75;
            grouped[i & 3] = min(grouped[i & 3], delta + fade);
        }
    }
    grouped = clamp(grouped * u_contrast + (1.0 - u_contrast), 0.0, 1.0);
    hard = clamp(hard * u_contrast + (1.0 - u_contrast), 0.0, 1.0);
    // four interleaved groups averaged (one sample cannot shadow fully), the hard samples on top
    float result = min(hard, dot(grouped, vec4(0.25)));
    imageStore(u_contact, pix, vec4(result));
}
#endif
