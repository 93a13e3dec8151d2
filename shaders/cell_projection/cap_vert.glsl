// Near caps: where the near plane cuts a cell, the rasterizer clips the
// cell's entry faces, and the rays that enter the cell in front of the
// near plane would lose the cell. The CPU cuts such cells with a plane just
// behind the near plane (near.rs) and sends the section's polygon with
// every record the fragment stage needs spelled out at its corners (the
// balanced vertex stage spreads one value per vertex instead): all are
// affine in the point, so they interpolate exactly. With CAP_PIECES the
// record's code selects an atfs interval as atfs.vert does.
#include "common/frame.glsl"
#include "common/clip.glsl"
#include "cell_projection/record.glsl"

layout(location = 0) in vec3 in_pos;
layout(location = 1) in float in_sf;
layout(location = 2) in vec4 in_d;
layout(location = 3) in vec4 in_s;
layout(location = 4) in vec4 in_w;
layout(location = 5) in float in_g;
layout(location = 6) in float in_code;  // atfs: flags and piece as in record.glsl

layout(location = 0) out float out_sf;
layout(location = 1) out vec4 out_d;
layout(location = 2) out vec4 out_s;
layout(location = 3) out vec4 out_w;
layout(location = 4) out float out_g;
layout(location = 5) out vec3 out_rel;

#ifdef CAP_PIECES
struct Interval {
    vec4 base;
    vec4 slope;
    vec4 bounds;
};
layout(std430, set = 1, binding = 0) readonly buffer Intervals { Interval intervals[]; };
layout(location = 6) flat out vec3 out_bounds;
layout(location = 7) flat out vec4 out_base;
layout(location = 8) flat out vec4 out_slope;
const float UNBOUNDED = 1e30;
#endif

void main() {
    out_sf = in_sf;
    out_d = in_d;
    out_s = in_s;
    out_w = in_w;
    out_g = in_g;
    out_rel = in_pos - frame.eye;
#ifdef CAP_PIECES
    int code = record_code(in_code);
    int flags = record_flags(code);
    Interval iv = intervals[record_piece(code)];
    out_bounds = vec3((flags & 1) != 0 ? -UNBOUNDED : iv.bounds.x, (flags & 2) != 0 ? UNBOUNDED : iv.bounds.y, iv.bounds.z);
    out_base = iv.base;
    out_slope = iv.slope;
#endif
    gl_Position = clip_position(in_pos);
}
