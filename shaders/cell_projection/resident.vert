#version 450
// Device-resident balanced cell projection: the cells live in a storage
// buffer uploaded once; per frame only the sorted order (one u32 per tet)
// crosses to the device. Vertex 4k+i of the static strips is vertex i of
// the tet in slot k; the vertex stage runs balanced's CPU half
// (IntersectBackFace, balanced.rs `cell_records`) from the stored planes,
// for all four vertices since the tet's exit mask needs every c_j, then
// emits its own values exactly as balanced.vert does, so balanced.frag
// integrates them unchanged.
#include "common/frame.glsl"
#include "common/clip.glsl"
#define KNOWN_EXITS_VERTEX
#include "cell_projection/known_exits_io.glsl"

// Cell t is texels 9t..9t+8 (resident.rs `stored`): pos[4] (xyz: position
// relative to the render origin; w: scalar), plane[4] (xyz: 3-float plane of
// the face opposite vertex i), gradient (xyz).
layout(set = 1, binding = 0) uniform samplerBuffer cells;
layout(std430, set = 1, binding = 1) readonly buffer Order { uint order[]; };
vec4 cell_pos(uint t, int i) { return texelFetch(cells, int(9u * t) + i); }
vec4 cell_plane(uint t, int i) { return texelFetch(cells, int(9u * t) + 4 + i); }
vec3 cell_gradient(uint t) { return texelFetch(cells, int(9u * t) + 8).xyz; }

void main() {
    uint slot = uint(gl_VertexIndex) >> 2;
    int k = gl_VertexIndex & 3;
    uint t = order[slot];
    bool exact = false;
#ifdef EXACT_PERSPECTIVE
    exact = frame.eye.w > 0.5;
#endif
    // c_j: the ray-plane distance t, or with exact perspective the plane ratio u.
    vec4 c;
    for (int j = 0; j < 4; ++j) {
        vec3 p = cell_pos(t, j).xyz;
        vec3 plane3 = cell_plane(t, j).xyz;
        c[j] = exact ? perspective_plane_ratio(plane3, p - frame.eye.xyz) : distance_to_opposite_plane(plane3, ray_direction(p));
    }
    float half_limit = 0.5 * (exact ? frame.limits.y : frame.limits.x);
    uvec4 bits = uvec4(greaterThan(c, vec4(0.0))) * uvec4(lessThan(c, vec4(half_limit))) * uvec4(1u, 2u, 4u, 8u);
    uint exits = bits.x | bits.y | bits.z | bits.w;

    vec4 pk = cell_pos(t, k);
    vec3 pos = pk.xyz;
    float sf = pk.w;
    vec3 g = cell_gradient(t);
    vec3 dir = ray_direction(pos);
#ifdef EXACT_PERSPECTIVE
    float b = exact ? dot(g, pos - frame.eye.xyz) : dot(g, dir);
#else
    float b = sf + dot(dir, g) * c[k];
#endif
    emit_vertex(pos, k, c[k], sf, b, exits);
}
