#version 450
// resident-gpusort's vertex stage (resident itself expands the order into
// balanced's records in a compute pass, resident_expand.comp): the cells
// live in a storage texel buffer uploaded once; the sorted order (one u32
// per tet) is made on the device. Vertex 4k+i of the static strips is vertex i
// of the tet in slot k; the vertex stage runs what balanced's CPU does
// (cell_projection/stored_cell.glsl), for all four vertices since the tet's
// exit mask needs every c_j, then emits its own values exactly as
// balanced.vert does, so balanced.frag integrates them unchanged.
#include "common/frame.glsl"
#include "common/clip.glsl"
#define KNOWN_EXITS_VERTEX
#include "cell_projection/known_exits_io.glsl"
#include "cell_projection/stored_cell.glsl"

layout(std430, set = 1, binding = 1) readonly buffer Order { uint order[]; };

void main() {
    uint slot = uint(gl_VertexIndex) >> 2;
    int k = gl_VertexIndex & 3;
    uint t = order[slot];
    uint exits;
    vec4 c = cell_view_values(t, exits);
    vec4 pk = cell_pos(t, k);
    float b = cell_vertex_b(cell_gradient(t), pk.xyz, pk.w, c[k]);
    emit_vertex(pk.xyz, k, c[k], pk.w, b, exits);
}
