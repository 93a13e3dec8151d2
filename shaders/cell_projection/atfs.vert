#version 450
// Adaptive transfer function sampling (Moreland, thesis §4.3): balanced cell
// projection drawn once per transfer-function interval a cell's scalar
// range overlaps. The record is balanced's, its code (record.glsl) also
// naming interval j of the transfer function and flags saying that this is
// the cell's lowest (1) or highest (2) piece, whose outer bound is then
// infinite (the cell has no scalars beyond it; f32 interpolation that
// overshoots the cell's range by a rounding must not be clipped away). The
// interval's bounds and its exactly linear colour and attenuation go to the
// fragment stage flat.
#include "common/frame.glsl"
#include "common/clip.glsl"
#include "cell_projection/record.glsl"
#define KNOWN_EXITS_VERTEX
#include "cell_projection/known_exits_io.glsl"

struct Interval {
    vec4 base;    // colour and attenuation at scalar bounds.z
    vec4 slope;   // their change per unit scalar (0 for the outer intervals)
    vec4 bounds;  // x, y: lowest and highest scalar; z: scalar of `base`
};
layout(std430, set = 1, binding = 0) readonly buffer Intervals { Interval intervals[]; };

layout(location = 0) in vec3 in_pos;     // v
layout(location = 1) in float in_c;      // t or u (view-dependent, from the CPU)
layout(location = 2) in float in_sf;     // s_f = s_v
layout(location = 3) in float in_b;      // s_b, or the gradient term (exact)
layout(location = 4) in float in_code;   // record.glsl

layout(location = 6) flat out vec3 out_bounds;  // lo, hi (widened by the flags), scalar of base
layout(location = 7) flat out vec4 out_base;
layout(location = 8) flat out vec4 out_slope;

// Beyond every scalar the device sees (scalars arrive mapped to [0, 1]).
const float UNBOUNDED = 1e30;

void main() {
    int code = record_code(in_code);
    int flags = record_flags(code);
    Interval iv = intervals[record_piece(code)];
    emit_vertex(in_pos, record_vertex(code), in_c, in_sf, in_b, record_exits(code));
    out_bounds = vec3((flags & 1) != 0 ? -UNBOUNDED : iv.bounds.x, (flags & 2) != 0 ? UNBOUNDED : iv.bounds.y, iv.bounds.z);
    out_base = iv.base;
    out_slope = iv.slope;
}
