#version 450
// Resident's per-frame expansion (resident.rs): one invocation per slot of
// the sorted order reads its cell once from the stored cells (9 texels) and
// writes the cell's 4 vertex records, exactly what balanced's CPU writes
// (balanced.rs `cell_records`: v, c, s_f, b, code), so balanced.vert and
// balanced.frag draw them unchanged. Before, resident.vert did this per
// vertex: every cell was read and its four c_j computed four times, in the
// draw's serial vertex stage; here once per cell, on every core.
layout(local_size_x = 64) in;

#include "common/frame.glsl"
#include "common/dispatch.glsl"
#define CELL_SET 0
#include "cell_projection/stored_cell.glsl"

// This piece of the order: `count` cells, farthest first.
layout(std430, set = 0, binding = 1) readonly buffer Order {
    uint count;
    uint order[];
};
// 4 records of 7 floats per slot (balanced.rs FLOATS_PER_CELL), written as
// 7 vec4 (one store each, not 28 scalar ones).
layout(std430, set = 0, binding = 2) writeonly buffer Records { vec4 records[]; };

void main() {
    uint slot = linear_invocation_id();
    if (slot >= count) {
        return;
    }
    uint t = order[slot];
    uint exits;
    vec4 c = cell_view_values(t, exits);
    vec3 g = cell_gradient(t);
    // Record k: position, c_k, s_f, b, code (record.glsl: k | exits << 2,
    // exact in f32).
    float r[28];
    for (int k = 0; k < 4; ++k) {
        vec4 pk = cell_pos(t, k);
        r[7 * k + 0] = pk.x;
        r[7 * k + 1] = pk.y;
        r[7 * k + 2] = pk.z;
        r[7 * k + 3] = c[k];
        r[7 * k + 4] = pk.w;
        r[7 * k + 5] = cell_vertex_b(g, pk.xyz, pk.w, c[k]);
        r[7 * k + 6] = float(uint(k) | (exits << 2));
    }
    uint base = slot * 7u;
    for (int i = 0; i < 7; ++i) {
        records[base + uint(i)] = vec4(r[4 * i], r[4 * i + 1], r[4 * i + 2], r[4 * i + 3]);
    }
}
