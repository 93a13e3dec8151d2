// Linear ids for compute dispatches of any size.
//
// CommandRecorder::dispatch_groups(n) folds n workgroups into a grid of at
// most maxComputeWorkGroupCount per dimension (vk::fold_groups): the grid may
// hold a few more than n groups (fewer than gl_NumWorkGroups.y *
// gl_NumWorkGroups.z extra), so every shader dispatched that way must begin
//
//     uint group = linear_workgroup_id();
//     if (group >= GROUP_COUNT) return;   // GROUP_COUNT: n, e.g. a push constant
//
// or, per invocation, compare linear_invocation_id() with its element count
// (which also skips the tail of the last real group). Both are exact for a
// plain dispatch([x, y, z]) as well.

#ifndef VOLBENCH_DISPATCH_GLSL
#define VOLBENCH_DISPATCH_GLSL

// The group's position in the linear order x fastest, then y, then z.
uint linear_workgroup_id() {
    return (gl_WorkGroupID.z * gl_NumWorkGroups.y + gl_WorkGroupID.y) * gl_NumWorkGroups.x + gl_WorkGroupID.x;
}

// The invocation's position: groups in linear order, invocations within a
// group by gl_LocalInvocationIndex. A macro, not a function: glslang fixes
// gl_WorkGroupSize where it is used, and a function in this include would
// see (1, 1, 1) when the include precedes `layout(local_size_x = ...) in;`.
// 32-bit: the dispatch must hold fewer than 2^32 invocations.
#define linear_invocation_id() \
    (linear_workgroup_id() * (gl_WorkGroupSize.x * gl_WorkGroupSize.y * gl_WorkGroupSize.z) + gl_LocalInvocationIndex)

// The tile row of this workgroup when a pass over `rows` rows of
// workgroups is dispatched as algo::screen::interleaved_rows(rows, runs)
// rows: dispatch row y is tile row (y % len) * runs + y / len, len =
// ceil(rows / runs), so each of the device's `runs` contiguous runs of
// workgroups (lavapipe gives each compute thread one) takes every runs-th
// row of the whole image, not one band of it. A result >= rows is padding:
// the caller returns.
uint interleaved_row(uint rows, uint runs) {
    if (runs <= 1u || rows == 0u) return gl_WorkGroupID.y;
    uint len = (rows + runs - 1u) / runs;
    return gl_WorkGroupID.y % len * runs + gl_WorkGroupID.y / len;
}

#endif
