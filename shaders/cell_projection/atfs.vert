#version 450
// Adaptive transfer function sampling (Moreland, thesis §4.3): balanced cell
// projection drawn once per transfer-function interval a cell's scalar
// range overlaps. The record is balanced's (v, d, s_f, s_b) with the last
// float coding i + 4 * flags + 16 * j: vertex index i in the tet, interval j
// of the transfer function, and flags saying that this is the cell's lowest
// (1) or highest (2) piece, whose outer bound is then infinite (the cell
// has no scalars beyond it; f32 interpolation that overshoots the cell's
// range by a rounding must not be clipped away). The interval's bounds and
// its exactly linear colour and attenuation go to the fragment stage flat.
#include "common/frame.glsl"

struct Interval {
    vec4 base;    // colour and attenuation at scalar bounds.z
    vec4 slope;   // their change per unit scalar (0 for the outer intervals)
    vec4 bounds;  // x, y: lowest and highest scalar; z: scalar of `base`
};
layout(std430, set = 1, binding = 0) readonly buffer Intervals { Interval intervals[]; };

layout(location = 0) in vec3 in_pos;     // v
layout(location = 1) in float in_d;      // d (view-dependent, from the CPU)
layout(location = 2) in float in_sf;     // s_f = s_v
layout(location = 3) in float in_sb;     // s_b on the opposite face
layout(location = 4) in float in_code;   // i + 4 * flags + 16 * j

layout(location = 0) out float out_sf;
layout(location = 1) out vec4 out_d;
layout(location = 2) out vec4 out_s;
layout(location = 3) out vec4 out_w;
layout(location = 4) out float out_g;
layout(location = 5) out vec3 out_rel;
layout(location = 6) flat out vec3 out_bounds;  // lo, hi (widened by the flags), scalar of base
layout(location = 7) flat out vec4 out_base;
layout(location = 8) flat out vec4 out_slope;

// Beyond every scalar the device sees (scalars arrive mapped to [0, 1]).
const float UNBOUNDED = 1e30;

void main() {
    int code = int(in_code + 0.5);
    int k = code & 3;
    int flags = (code >> 2) & 3;
    Interval iv = intervals[code >> 4];
    vec4 d = vec4(0.0);
    vec4 s = vec4(in_sf);
    vec4 w = vec4(0.0);
    d[k] = in_d;
    s[k] = in_sb;
    w[k] = 1.0;
    out_sf = in_sf;
    out_d = d;
    out_s = s;
    out_w = w;
    out_g = in_sb;
    out_rel = in_pos - frame.eye.xyz;
    out_bounds = vec3((flags & 1) != 0 ? -UNBOUNDED : iv.bounds.x, (flags & 2) != 0 ? UNBOUNDED : iv.bounds.y, iv.bounds.z);
    out_base = iv.base;
    out_slope = iv.slope;
    gl_Position = frame.view_proj * vec4(in_pos, 1.0);
}
