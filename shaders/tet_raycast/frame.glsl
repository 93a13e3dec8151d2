// tet-raycast's per-frame constants (push constants of walk.comp).
// Rust: algo::tet_raycast::WalkFrame (the reflection test checks the two).
#include "common/table_map.glsl"
layout(push_constant) uniform Frame {
    vec3 eye;            // eye relative to the render origin
    float perspective;   // 1 perspective, 0 orthographic
    vec3 forward;        // unit view direction
    float near;          // near plane (view depth)
    vec3 right;          // right, scaled so that ndc x = 1 is the image's edge
    float far;           // far plane (view depth)
    vec3 up;             // up, scaled alike
    float ert;           // early-termination opacity (>= 1: off)
    TableMap table;      // common/integrate.glsl
    float entry_tol;     // entry tolerance (world units)
    uint step_budget;    // cells a ray may visit
    uint stall_limit;    // cells without progress in depth that abandon a walk
    uvec4 rect;          // the pixels whose rays may meet the mesh: x0, y0, x1, y1 inclusive
                         // (tet_raycast.rs, pixel_rect); the dispatch starts at x0, y0
    uint rows;           // rows of workgroups (common/dispatch.glsl, interleaved_row)
    uint runs;           // the device's runs of workgroups (idem)
    uint cast_step;      // adaptive refinement's cast step (ADAPTIVE: 8, 4, 2 or 1)
} frame;
