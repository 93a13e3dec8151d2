#version 450
// Adaptive transfer function sampling: balanced's exit, the segment stopped
// at the far plane, then clipped to this piece's scalar interval
// (cell_projection/atfs.glsl).
#include "common/frame.glsl"
#include "common/integrate.glsl"
#include "common/clip.glsl"
#define EXIT_VEC vec4
#define EXIT_N 4
#include "common/exit.glsl"
#include "cell_projection/known_exits_io.glsl"
#include "cell_projection/atfs.glsl"

layout(location = 0) out vec4 out_color;

void main() {
    float len;
    float sb;
    if (known_exit(len, sb)) {
        float sf = v_sf;
        start_at_near(v_rel, sf, len, sb);
        out_color = integrate_piece(sf, sb, len);
    } else {
        out_color = vec4(0.0);
    }
}
