// World distances as window depth in a face's map (shadow_lookup.glsl, virtual_lookup.glsl): the
// includer declares u_light_matrix[MAX_FACES] (BIAS · projection · view per face) and includes
// lights.glsl. A window-depth bias is stretched by z² / near in a perspective map; a distance
// converted at each receiver means the same everywhere (issue 35).

#define WORLD_PAST_LIGHT 2.0             // a window-depth bias past every depth: the comparison lights

// The window-depth change of face f's map when the world point X moves by delta (exact, no
// cancellation between two nearly equal depths): d(X + δ) − d(X) = (m.z s.w − s.z m.w) /
// (s.w (s.w + m.w)), s = M X, m = M δ.
float window_change(int f, vec3 X, vec3 delta) {
    vec4 s = u_light_matrix[f] * vec4(X, 1.0);
    vec4 m = u_light_matrix[f] * vec4(delta, 0.0);
    return (m.z * s.w - s.z * m.w) / (s.w * (s.w + m.w));
}

// The window-depth bias of moving Q a world distance towards the light in face f's map; 0 for no
// distance. A move that reaches the light's plane of projection (w <= 0) lifts the point past
// every caster: WORLD_PAST_LIGHT, which lights it.
float world_bias(int f, vec3 Q, float distance) {
    if (distance <= 0.0) return 0.0;
    vec3 delta = light_dir_to(Q) * distance;
    return (u_light_matrix[f] * vec4(Q + delta, 1.0)).w > 0.0 ? -window_change(f, Q, delta) : WORLD_PAST_LIGHT;
}

// The window-depth increase of moving Q a world distance away from the light in face f's map (the
// oriented bias of a point facing away from the light); 0 for no distance. Moving away never
// reaches the light's plane of projection.
float world_bias_away(int f, vec3 Q, float distance) {
    if (distance <= 0.0) return 0.0;
    return window_change(f, Q, -light_dir_to(Q) * distance);
}
