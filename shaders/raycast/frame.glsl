// The ray casters' per-frame constants (push constants).
// Rust: algo::raycast::Frame, and AdaptiveFrame with ADAPTIVE (the
// reflection test checks them).
layout(push_constant) uniform Frame {
    mat4 m;              // box pass: voxel -> clip; march: NDC -> voxel (homogeneous)
    uvec2 first_group;   // compute march: the first workgroup (x, y) (common/dispatch.glsl)
    uint rows;           // rows of workgroups
    uint runs;           // the device's runs of workgroups
    vec3 light;          // unit direction towards the light, world axes
#ifdef ADAPTIVE
    uint close;          // adaptive refinement's key: the brick distances it tells apart (raycast/common.glsl)
    uvec4 rect;          // adaptive refinement (compute): the frame's rectangle, inclusive pixel bounds
    uint cast_step;      // the cast pass's step (8, 4, 2, 1; common/adaptive.glsl)
#endif
} frame;
