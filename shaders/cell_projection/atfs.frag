#version 450
// Adaptive transfer function sampling: balanced's exit search, then the
// ray segment clipped to this piece's scalar interval [lo, hi] (the scalar
// is linear along the segment, so the clip is two divisions). Inside the
// interval colour and attenuation are exactly linear in the scalar, so the
// integrators that assume them linear along the segment (average, ppi,
// linear-exact) get the piece's exact end values instead of table lookups;
// pre-integration looks its table up with the clipped scalars and length.
#include "common/frame.glsl"
#include "common/integrate.glsl"
#define EXIT_VEC vec4
#define EXIT_N 4
#include "common/exit.glsl"

layout(location = 0) in float in_sf;
layout(location = 1) in vec4 in_d;
layout(location = 2) in vec4 in_s;
layout(location = 3) in vec4 in_w;
layout(location = 4) in float in_g;
layout(location = 5) in vec3 in_rel;
layout(location = 6) flat in vec3 in_bounds;
layout(location = 7) flat in vec4 in_base;
layout(location = 8) flat in vec4 in_slope;
layout(location = 0) out vec4 out_color;

void main() {
    out_color = vec4(0.0);
    float len;
    float sb;
    if (!exit_point(in_d, in_s, in_w, in_sf, in_g, in_rel, len, sb)) {
        return;
    }
    float lo = in_bounds.x;
    float hi = in_bounds.y;
    float ds = sb - in_sf;
    // The part of the segment, as fractions [a, b] of it, where lo <= s <= hi.
    float a = 0.0;
    float b = 1.0;
    if (ds != 0.0) {
        float t_lo = (lo - in_sf) / ds;
        float t_hi = (hi - in_sf) / ds;
        a = clamp(min(t_lo, t_hi), 0.0, 1.0);
        b = clamp(max(t_lo, t_hi), 0.0, 1.0);
    } else if (!(lo <= in_sf && in_sf < hi)) {
        // A ray along an isosurface belongs to one piece: [lo, hi).
        return;
    }
    if (b <= a) {
        return;
    }
    float s0 = in_sf + a * ds;
    float s1 = in_sf + b * ds;
    float piece_len = (b - a) * len;
#ifdef INTEGRATOR_PREINT
    out_color = integrate_segment(s0, s1, piece_len);
#else
    vec4 front = in_base + in_slope * (s0 - in_bounds.z);
    vec4 back = in_base + in_slope * (s1 - in_bounds.z);
    out_color = integrate_values(front, back, piece_len);
#endif
}
