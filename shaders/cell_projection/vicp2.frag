#version 450
// The exit point is the nearest plane in front of the entry point.
#include "common/frame.glsl"
#include "common/integrate.glsl"
#include "common/clip.glsl"
#define EXIT_VEC vec3
#define EXIT_N 3
#include "common/exit.glsl"

layout(location = 0) in float in_sf;
layout(location = 1) in vec3 in_d;
layout(location = 2) in vec3 in_s;
layout(location = 3) in vec3 in_w;
layout(location = 4) in float in_g;
layout(location = 5) in vec3 in_rel;
layout(location = 0) out vec4 out_color;

void main() {
    float len;
    float sb;
    if (exit_point(in_d, in_s, in_w, in_sf, in_g, in_rel, len, sb)) {
        clamp_to_far(in_rel, in_sf, len, sb);
        float sf = in_sf;
        start_at_near(in_rel, sf, len, sb);
        out_color = integrate_segment(sf, sb, len);
    } else {
        out_color = vec4(0.0);
    }
}
