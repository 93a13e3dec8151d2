#version 450
// GPU-CPU balanced cell projection (Moreland): the CPU has already computed,
// per frame, each vertex's ray-plane distance c to its opposite face and
// the scalar s_b there, plus the tet's exit mask (balanced.rs
// `cell_records`). The vertex stage spreads them into 4-vectors indexed by
// the vertex's index in the tet, so the same 4 records serve all 4 faces.
// (With EXACT_PERSPECTIVE the CPU sends, in the same two slots, the plane
// ratio u and the gradient term; see common/exit.glsl.)
#include "common/frame.glsl"
#include "common/clip.glsl"
#include "cell_projection/record.glsl"
#define KNOWN_EXITS_VERTEX
#include "cell_projection/known_exits_io.glsl"

layout(location = 0) in vec3 in_pos;     // v
layout(location = 1) in float in_c;      // t or u (view-dependent, from the CPU)
layout(location = 2) in float in_sf;     // s_f = s_v
layout(location = 3) in float in_b;      // s_b, or the gradient term (exact)
layout(location = 4) in float in_code;   // record.glsl

void main() {
    int code = record_code(in_code);
    emit_vertex(in_pos, record_vertex(code), in_c, in_sf, in_b, record_exits(code));
}
