#version 450
// View-independent cell projection (Weiler, Kraus, Ertl): each tet arrives as
// 12 vertex records (4 faces x 3 vertices) of 11 floats. The vertex stage
// intersects the view ray with the plane of the face opposite this vertex;
// the vertex lies on the face's two other planes (distance 0, scalar s_v).
#include "common/frame.glsl"
#include "common/clip.glsl"

layout(location = 0) in vec3 in_pos;     // v
layout(location = 1) in float in_s;      // s_v
layout(location = 2) in vec3 in_plane;   // P_v: n' of the plane opposite v
layout(location = 3) in vec3 in_grad;    // g
layout(location = 4) in float in_index;  // i: v's index within the face (0..2)

layout(location = 0) out float out_sf;
layout(location = 1) out vec3 out_d;
layout(location = 2) out vec3 out_s;
layout(location = 3) out vec3 out_w;    // barycentric weight of each face vertex (see common/exit.glsl)
layout(location = 4) out float out_g;   // exact perspective: g . (v - eye)
layout(location = 5) out vec3 out_rel;  // exact perspective: v - eye

void main() {
    int k = int(in_index + 0.5);
    vec3 d = vec3(0.0);
    vec3 s = vec3(in_s);
    vec3 rel = in_pos - frame.eye;
#ifdef EXACT_PERSPECTIVE
    if (frame.perspective > 0.5) {
        d[k] = perspective_plane_ratio(in_plane, rel);
    } else
#endif
    {
        vec3 dir = ray_direction(in_pos);
        float t = distance_to_opposite_plane(in_plane, dir);
        d[k] = t;
        s[k] = in_s + dot(dir, in_grad) * t;
    }
    vec3 w = vec3(0.0);
    w[k] = 1.0;
    out_sf = in_s;
    out_d = d;
    out_s = s;
    out_w = w;
    out_g = dot(in_grad, rel);
    out_rel = rel;
    gl_Position = clip_position(in_pos);
    gl_ClipDistance[0] = eye_plane_distance(gl_Position);
}
