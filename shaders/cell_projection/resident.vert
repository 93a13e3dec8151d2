#version 450
// Device-resident balanced cell projection: the cells live in a storage
// buffer uploaded once; per frame only the sorted order (one u32 per tet)
// crosses to the device. Vertex 4k+i of the static strips is vertex i of
// the tet in slot k; the vertex stage runs balanced's CPU half
// (IntersectBackFace: d and s_b, or u and g.(v - eye) with exact
// perspective) from the stored planes, then spreads the results exactly as
// balanced.vert does, so balanced.frag integrates them unchanged.
#include "common/frame.glsl"

struct Cell {
    vec4 pos[4];    // xyz: position relative to the render origin; w: scalar
    vec4 plane[4];  // xyz: 3-float plane of the face opposite vertex i
    vec4 gradient;  // xyz: scalar gradient
};
layout(std430, set = 1, binding = 0) readonly buffer Cells { Cell cells[]; };
layout(std430, set = 1, binding = 1) readonly buffer Order { uint order[]; };

layout(location = 0) out float out_sf;
layout(location = 1) out vec4 out_d;
layout(location = 2) out vec4 out_s;
layout(location = 3) out vec4 out_w;
layout(location = 4) out float out_g;
layout(location = 5) out vec3 out_rel;

void main() {
    uint slot = uint(gl_VertexIndex) >> 2;
    int k = gl_VertexIndex & 3;
    uint t = order[slot];
    vec3 pos = cells[t].pos[k].xyz;
    float sf = cells[t].pos[k].w;
    vec3 plane3 = cells[t].plane[k].xyz;
    vec3 g = cells[t].gradient.xyz;
    float a;
    float b;
#ifdef EXACT_PERSPECTIVE
    if (frame.eye.w > 0.5) {
        vec3 rel = pos - frame.eye.xyz;
        a = perspective_plane_ratio(plane3, rel);
        b = dot(g, rel);
    } else
#endif
    {
        vec3 dir = ray_direction(pos);
        a = distance_to_opposite_plane(plane3, dir);
        b = sf + dot(dir, g) * a;
    }
    vec4 d = vec4(0.0);
    vec4 s = vec4(sf);
    vec4 w = vec4(0.0);
    d[k] = a;
    s[k] = b;
    w[k] = 1.0;
    out_sf = sf;
    out_d = d;
    out_s = s;
    out_w = w;
    out_g = b;
    out_rel = pos - frame.eye.xyz;
    gl_Position = frame.view_proj * vec4(pos, 1.0);
}
