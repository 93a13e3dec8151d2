// Near caps (cap.vert): this fragment lies on the section, just behind the
// near plane, of a cell that holds the eye (near.rs): the ray starts in the
// cell, none of whose faces is drawn, and its segment is integrated here,
// from the near plane to the exit (stopped at the far plane).
#include "common/frame.glsl"
#include "common/integrate.glsl"
#include "common/clip.glsl"
#define EXIT_VEC vec4
#define EXIT_N 4
#include "common/exit.glsl"
#ifdef CAP_PIECES
#include "cell_projection/atfs.glsl"
#endif

layout(location = 0) in float in_sf;
layout(location = 1) in vec4 in_d;
layout(location = 2) in vec4 in_s;
layout(location = 3) in vec4 in_w;
layout(location = 4) in float in_g;
layout(location = 5) in vec3 in_rel;
layout(location = 0) out vec4 out_color;

void main() {
    out_color = vec4(0.0);
    float len;
    float sb;
    if (!exit_point(in_d, in_s, in_w, in_sf, in_g, in_rel, len, sb)) {
        return;
    }
    vec3 dir = ray_direction(frame.eye + in_rel);
    // Distance back to the near plane (the cap lies just behind it).
    float back = max(-near_distance(in_rel, dir), 0.0);
    // Extend the segment back to the near plane (the scalar is linear).
    float rate = len > 0.0 ? (sb - in_sf) / len : 0.0;
    float sf = in_sf - rate * back;
    len += back;
    // The far plane, measured from the near plane's point.
    float t_far = far_distance(in_rel, dir) + back;
    if (t_far < len) {
        float keep = max(t_far, 0.0);
        sb = sf + (sb - sf) * (len > 0.0 ? keep / len : 0.0);
        len = keep;
    }
#ifdef CAP_PIECES
    out_color = integrate_piece(sf, sb, len);
#else
    out_color = integrate_segment(sf, sb, len);
#endif
}
