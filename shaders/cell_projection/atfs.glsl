// One piece of adaptive transfer function sampling (atfs.frag, and cap.frag
// built with CAP_PIECES): the segment clipped to the piece's scalar
// interval [lo, hi] (the scalar is linear along the segment, so the clip is
// two divisions). Inside the interval colour and attenuation are exactly
// linear in the scalar, so the integrators that assume them linear along
// the segment (average, ppi, linear-exact) get the piece's exact end values
// instead of table lookups; pre-integration looks its table up with the
// clipped scalars and length.

layout(location = 6) flat in vec3 in_bounds;  // lo, hi (widened by atfs.vert's flags), scalar of base
layout(location = 7) flat in vec4 in_base;    // colour and attenuation at in_bounds.z
layout(location = 8) flat in vec4 in_slope;   // their change per unit scalar

vec4 integrate_piece(float s_front, float s_back, float len) {
    float lo = in_bounds.x;
    float hi = in_bounds.y;
    float ds = s_back - s_front;
    // The part of the segment, as fractions [a, b] of it, where lo <= s <= hi.
    float a = 0.0;
    float b = 1.0;
    if (ds != 0.0) {
        float t_lo = (lo - s_front) / ds;
        float t_hi = (hi - s_front) / ds;
        a = clamp(min(t_lo, t_hi), 0.0, 1.0);
        b = clamp(max(t_lo, t_hi), 0.0, 1.0);
    } else if (!(lo <= s_front && s_front < hi)) {
        // A ray along an isosurface belongs to one piece: [lo, hi).
        return vec4(0.0);
    }
    if (b <= a) {
        return vec4(0.0);
    }
    float s0 = s_front + a * ds;
    float s1 = s_front + b * ds;
    float piece_len = (b - a) * len;
#ifdef INTEGRATOR_PREINT
    return integrate_segment(s0, s1, piece_len);
#else
    vec4 front = in_base + in_slope * (s0 - in_bounds.z);
    vec4 back = in_base + in_slope * (s1 - in_bounds.z);
    return integrate_values(front, back, piece_len);
#endif
}
