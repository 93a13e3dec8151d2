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
// 4 records of 7 floats per slot (balanced.rs FLOATS_PER_CELL).
layout(std430, set = 0, binding = 2) writeonly buffer Records { float records[]; };

void main() {
    uint slot = linear_invocation_id();
    if (slot >= count) {
        return;
    }
    uint t = order[slot];
    uint exits;
    vec4 c = cell_view_values(t, exits);
    vec3 g = cell_gradient(t);
    uint base = slot * 28u;
    for (int k = 0; k < 4; ++k) {
        vec4 pk = cell_pos(t, k);
        float b = cell_vertex_b(g, pk.xyz, pk.w, c[k]);
        uint r = base + uint(7 * k);
        records[r + 0u] = pk.x;
        records[r + 1u] = pk.y;
        records[r + 2u] = pk.z;
        records[r + 3u] = c[k];
        records[r + 4u] = pk.w;
        records[r + 5u] = b;
        // record.glsl: i | exits << 2, exact in f32.
        records[r + 6u] = float(uint(k) | (exits << 2));
    }
}
