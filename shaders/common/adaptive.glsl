// Adaptive image-space refinement (algo/adaptive.rs, docs/methods.md
// "Adaptive refinement"): the state every pass of it shares, and what a
// ray caster's cast passes need. Included after the shader's
// `layout(local_size_x = WG_X, local_size_y = WG_Y) in;` and
// common/dispatch.glsl, with ADAPTIVE_SET the descriptor set of the state.
//
// Lattice points are pixels relative to the frame's rectangle corner
// (rect.xy); the lattice spans 16 * blocks + 1 points per side, blocks of 16
// covering the rectangle (points past its far edges are padding: zero, no
// ray). Point (x, y) is entry y * (16 * blocks.x + 1) + x of the samples and
// keys.

#ifndef VOLBENCH_ADAPTIVE_GLSL
#define VOLBENCH_ADAPTIVE_GLSL

layout(std430, set = ADAPTIVE_SET, binding = 0) buffer AdaptiveSamples { vec4 v[]; } a_samples;  // premultiplied RGBA per point
layout(std430, set = ADAPTIVE_SET, binding = 1) buffer AdaptiveKeys { uint v[]; } a_keys;        // 0: not cast; A_LISTED; A_CAST | structural key
// The blocks of 8 listed (x | y << 16, from the refined blocks of 16), the
// blocks of 4 listed, then the points listed for the step-4 cast, the
// step-2 cast and the step-1 cast (point indices; adaptive_blocks_at,
// adaptive_points_at).
layout(std430, set = ADAPTIVE_SET, binding = 2) buffer AdaptiveLists { uint v[]; } a_lists;
layout(std430, set = ADAPTIVE_SET, binding = 3) buffer AdaptiveCounters { uint v[]; } a_counters;
// The frame's pixels, rows of the rectangle's width from its corner: cast
// rays and filled blocks are written here, not to the target image (on
// llvmpipe an image store costs a call per SIMD vector, a buffer store a
// plain store), and copied into the target's rectangle after the passes.
layout(std430, set = ADAPTIVE_SET, binding = 5) writeonly buffer AdaptivePixels { vec4 v[]; } a_pixels;

const uint A_CAST = 0x80000000u;
const uint A_LISTED = 0x40000000u;
const uint A_KEY_MASK = 0x3FFFFFFFu;
// Counter words (algo/adaptive.rs, Counts): the indirect arguments first.
// Per level the words follow each other: blocks of 16, 8, 4 (a_size_level)
// or cast steps 8, 4, 2, 1 (a_step_level).
const uint A_ARGS_DECIDE8 = 0u;  // x, y, z: the decide passes over the listed blocks of 8, of 4
const uint A_ARGS_DECIDE4 = 3u;
const uint A_ARGS_CAST4 = 6u;    // x, y, z: the cast passes over the listed points (steps 4, 2, 1)
const uint A_ARGS_CAST2 = 9u;
const uint A_ARGS_CAST1 = 12u;
const uint A_COUNT8 = 15u;       // blocks listed: of 8, of 4; blocks of 2 refined to pixels
const uint A_COUNT4 = 16u;
const uint A_COUNT2 = 17u;
const uint A_POINTS4 = 18u;      // points listed for the step-4, step-2 and step-1 casts
const uint A_RAYS8 = 21u;        // rays cast per pass: step 8, 4, 2, 1
const uint A_FILLED16 = 25u;     // blocks filled: of 16, 8, 4
const uint A_SIL16 = 28u;        // blocks refined: a silhouette (16, 8, 4), the structure, the colour
const uint A_STRUCT16 = 31u;
const uint A_COLOUR16 = 34u;
const uint A_COVERED_FILLED = 37u;  // filled pixels with alpha > 0
const uint A_COVERED_CAST = 38u;    // rays cast with alpha > 0
const uint A_PADDING = 39u;         // lattice points past the rectangle (no ray)
// The coarsest block and the step of the first cast pass (its lattice).
const uint A_BLOCK = 16u;
const uint A_LATTICE_STEP = 8u;
// Invocations per workgroup of the list passes (1D over a list).
const uint A_GROUP = uint(WG_X * WG_Y);

// Blocks of 16 across and down the rectangle (inclusive pixel bounds).
uvec2 adaptive_blocks(uvec4 rect) {
    return (rect.zw - rect.xy + A_BLOCK) / A_BLOCK;
}

// A block size's level (16: 0, 8: 1, 4: 2) and a cast step's (8: 0, 4: 1,
// 2: 2, 1: 3).
uint a_size_level(uint size) {
    return 4u - uint(findLSB(size));
}
uint a_step_level(uint pass_step) {
    return 3u - uint(findLSB(pass_step));
}

// Lattice points per row, and in all.
uint adaptive_row(uvec4 rect) {
    return A_BLOCK * adaptive_blocks(rect).x + 1u;
}

uint adaptive_index(uvec4 rect, uvec2 lat) {
    return lat.y * adaptive_row(rect) + lat.x;
}

// Where the list of blocks of `size` (8 or 4) begins in a_lists: up to 4
// blocks of 8 and 16 blocks of 4 per block of 16.
uint adaptive_blocks_at(uvec4 rect, uint size) {
    uvec2 nb = adaptive_blocks(rect);
    return size == 8u ? 0u : 4u * nb.x * nb.y;
}

// Where the point list of the cast of `pass_step` (4, 2 or 1) begins.
uint adaptive_points_at(uvec4 rect, uint pass_step) {
    uvec2 nb = adaptive_blocks(rect);
    uint points = adaptive_row(rect) * (A_BLOCK * nb.y + 1u);
    return 20u * nb.x * nb.y + (a_step_level(pass_step) - 1u) * points;
}

// The lattice point this invocation of a cast pass of `pass_step` takes, and
// whether it casts it: step 8, a 2D dispatch over every point of the
// 8-lattice (rows of workgroups interleaved: common/dispatch.glsl); steps
// 4, 2 and 1, one invocation per point the decide pass before listed (each
// once, a refined block's points together), the list's workgroups
// interleaved over the device's threads the same way (the indirect
// dispatch's rows are the list's workgroups, rounded up to the runs).
bool adaptive_point(uint pass_step, uvec4 rect, uint rows, uint runs, out uvec2 lat) {
    uvec2 nb = adaptive_blocks(rect);
    lat = uvec2(0u);
    if (pass_step == A_LATTICE_STEP) {
        uvec2 p = uvec2(gl_WorkGroupID.x, interleaved_row(rows, runs)) * uvec2(WG_X, WG_Y) + gl_LocalInvocationID.xy;
        if (p.x > 2u * nb.x || p.y > 2u * nb.y) return false;
        lat = p * A_LATTICE_STEP;
        return true;
    }
    uint count = a_counters.v[A_POINTS4 + a_step_level(pass_step) - 1u];
    uint groups = (count + A_GROUP - 1u) / A_GROUP;
    uint idx = interleaved_row(groups, runs) * A_GROUP + gl_LocalInvocationIndex;
    if (idx >= count) return false;
    uint point = a_lists.v[adaptive_points_at(rect, pass_step) + idx];
    uint lw = adaptive_row(rect);
    lat = uvec2(point % lw, point / lw);
    return true;
}

// Whether lattice point `lat` is a pixel of the rectangle (else padding).
bool adaptive_in_rect(uvec4 rect, uvec2 lat) {
    uvec2 px = rect.xy + lat;
    return px.x <= rect.z && px.y <= rect.w;
}

// Writes pixel `rel` (relative to the rectangle's corner, within it).
void adaptive_pixel(uvec4 rect, uvec2 rel, vec4 c) {
    a_pixels.v[rel.y * (rect.z - rect.x + 1u) + rel.x] = c;
}

// Records point `lat`'s sample and structural key (below A_CLAIM); `cast`:
// a ray was cast (else padding).
void adaptive_store(uint pass_step, uvec4 rect, uvec2 lat, vec4 c, uint key, bool was_cast) {
    uint i = adaptive_index(rect, lat);
    a_samples.v[i] = c;
    a_keys.v[i] = A_CAST | min(key, A_KEY_MASK);
    if (was_cast) {
        atomicAdd(a_counters.v[A_RAYS8 + a_step_level(pass_step)], 1u);
        if (c.a > 0.0) atomicAdd(a_counters.v[A_COVERED_CAST], 1u);
    } else {
        atomicAdd(a_counters.v[A_PADDING], 1u);
    }
}

#endif
