#version 450
// GPU HM (Paredes et al., GRAPP 2012, §3): one invocation per active PC-list
// entry tessellates its cell against the TB chains (terrain/tessellate.glsl)
// and emits the triangles, read from the geometry texel buffer. An
// invocation may emit at most MAX_TRIS triangles (the device's
// maxGeometryOutputVertices and maxGeometryTotalOutputComponents, 8
// components a vertex): a cell with more has one entry per slice of
// MAX_TRIS triangles (its part, entry.z >> 8), and each invocation emits
// only its slice. With CAPTURE every emitted triangle is also appended to
// a storage buffer, so tests compare them with the CPU's exactly.
#include "terrain/common.glsl"

#ifndef MAX_TRIS
#define MAX_TRIS 16
#endif
#define MAX_VERTICES (3 * MAX_TRIS)

layout(points) in;
layout(triangle_strip, max_vertices = MAX_VERTICES) out;
layout(location = 0) in flat uvec4 v_entry[];
layout(location = 0) out vec4 world;
// Only the position among the built-ins, so a vertex is 8 output
// components, gl_Position and world (the budget counts every declared one).
out gl_PerVertex {
    vec4 gl_Position;
};

layout(set = 0, binding = 0) uniform samplerBuffer geometry;
#ifdef CAPTURE
layout(std430, set = 0, binding = 3) buffer Capture {
    uint count;
    uint errors;
    uint capacity;
    uint pad;
    uint tris[];
} cap;
#endif

uint tess_grid_base() {
    return pc.grid_base;
}

uint tess_grid_width() {
    return pc.grid_width;
}

uint tri_index;
uint slice_first;

void emit_vertex(uint v) {
    vec4 p = texelFetch(geometry, int(v));
    world = p;
    gl_Position = pc.view_proj * vec4(p.xy, p.z - p.w, 1.0);
    EmitVertex();
}

void emit_triangle(uint a, uint b, uint c) {
    if (tri_index >= slice_first && tri_index < slice_first + MAX_TRIS) {
        emit_vertex(a);
        emit_vertex(b);
        emit_vertex(c);
        EndPrimitive();
#ifdef CAPTURE
        uint at = atomicAdd(cap.count, 3u);
        if (at + 3u <= cap.capacity) {
            cap.tris[at] = a;
            cap.tris[at + 1u] = b;
            cap.tris[at + 2u] = c;
        }
#endif
    }
    tri_index++;
}

#define TESS_BINDING 1
#include "terrain/tessellate.glsl"

void main() {
    uvec4 e = v_entry[0];
    tri_index = 0u;
    slice_first = (e.z >> 8) * uint(MAX_TRIS);
    bool ok = tessellate(e);
#ifdef CAPTURE
    if (!ok || tri_index != e.w) {
        atomicAdd(cap.errors, 1u);
    }
#endif
}
