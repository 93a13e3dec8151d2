#version 450
// GPU-CPU balanced cell projection (Moreland): the CPU has already computed,
// per frame, the distance d from this vertex to its opposite face and the
// scalar s_b there. The vertex stage spreads them into 4-vectors indexed by
// the vertex's index in the tet, so the same 4 records serve all 4 faces.
// (With EXACT_PERSPECTIVE under perspective the CPU sends, in the same two
// slots, the plane ratio u and g . (v - eye) instead; see common/exit.glsl.)
#include "common/frame.glsl"

layout(location = 0) in vec3 in_pos;     // v
layout(location = 1) in float in_d;      // d (view-dependent, from the CPU)
layout(location = 2) in float in_sf;     // s_f = s_v
layout(location = 3) in float in_sb;     // s_b on the opposite face
layout(location = 4) in float in_index;  // i: index in the tet (0..3)

layout(location = 0) out float out_sf;
layout(location = 1) out vec4 out_d;
layout(location = 2) out vec4 out_s;
layout(location = 3) out vec4 out_w;    // barycentric weight of each vertex (see common/exit.glsl)
layout(location = 4) out float out_g;   // exact perspective: g . (v - eye)
layout(location = 5) out vec3 out_rel;  // exact perspective: v - eye

void main() {
    int k = int(in_index + 0.5);
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
    gl_Position = frame.view_proj * vec4(in_pos, 1.0);
}
