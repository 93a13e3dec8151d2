#version 450
// hm-compute: the same tessellation (terrain/tessellate.glsl) in a compute
// pass, one invocation per active PC cell, writing triangles (indices into
// the static geometry) into a device buffer whose indexed draw arguments
// it also writes (the count, by atomics), for an indirect draw afterwards.
// A cell's output range is allocated by its triangle count from the table.
layout(local_size_x = 64) in;

// Rust: algo::terrain::compute::TessPush (the reflection test checks the two).
layout(push_constant) uniform Push {
    uint count;
    uint grid_base;
    uint grid_width;
    uint capacity;
} pcs;

layout(std430, set = 0, binding = 0) readonly buffer Cells {
    uvec4 cells[];
};
layout(std430, set = 0, binding = 1) readonly buffer Active {
    uint active_cells[];
};
layout(std430, set = 0, binding = 4) buffer Draw {
    uint index_count;
    uint instance_count;
    uint first_index;
    int vertex_offset;
    uint first_instance;
    uint errors;
} draw;
layout(std430, set = 0, binding = 5) writeonly buffer Out {
    uint indices[];
};

uint tess_grid_base() {
    return pcs.grid_base;
}

uint tess_grid_width() {
    return pcs.grid_width;
}

uint out_at;
uint out_end;

void emit_triangle(uint a, uint b, uint c) {
    if (out_at + 3u <= out_end) {
        indices[out_at] = a;
        indices[out_at + 1u] = b;
        indices[out_at + 2u] = c;
    }
    out_at += 3u;
}

#define TESS_BINDING 2
#include "terrain/tessellate.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pcs.count) {
        return;
    }
    uvec4 e = cells[active_cells[i]];
    uint n = e.w * 3u;
    uint base = atomicAdd(draw.index_count, n);
    if (base + n > pcs.capacity) {
        // Cannot happen (the buffer holds the largest frame); never draw
        // past the buffer.
        atomicAdd(draw.errors, 1u);
        atomicMin(draw.index_count, pcs.capacity);
        return;
    }
    out_at = base;
    out_end = base + n;
    bool ok = tessellate(e);
    if (!ok || out_at != out_end) {
        atomicAdd(draw.errors, 1u);
        // Whatever was not written becomes degenerate triangles.
        for (uint k = min(out_at, out_end); k < out_end; k++) {
            indices[k] = pcs.grid_base;
        }
    }
}
