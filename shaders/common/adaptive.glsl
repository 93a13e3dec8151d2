// Adaptive image-space refinement (algo/adaptive.rs, docs/methods.md
// "Adaptive refinement"): the state every pass of it shares, and what a
// ray caster's cast passes need. Included after the shader's
// `layout(local_size_x = WG_X, local_size_y = WG_Y) in;` and
// common/dispatch.glsl, with ADAPTIVE_SET the descriptor set of the state.
//
// Lattice points are pixels relative to the frame's rectangle corner
// (rect.xy); the lattice spans 8 * blocks + 1 points per side, blocks of 8
// covering the rectangle (points past its far edges are padding: zero, no
// ray). Point (x, y) is entry y * (8 * blocks.x + 1) + x of the samples and
// keys.

#ifndef VOLBENCH_ADAPTIVE_GLSL
#define VOLBENCH_ADAPTIVE_GLSL

layout(std430, set = ADAPTIVE_SET, binding = 0) buffer AdaptiveSamples { vec4 v[]; } a_samples;  // premultiplied RGBA per point
layout(std430, set = ADAPTIVE_SET, binding = 1) buffer AdaptiveKeys { uint v[]; } a_keys;        // 0: not cast; A_LISTED; A_CAST | structural key
// The refined blocks of 8's blocks of 4 (x | y << 16), then the points
// listed for the step-2 cast, then those for the step-1 cast (point
// indices; adaptive_lists).
layout(std430, set = ADAPTIVE_SET, binding = 2) buffer AdaptiveLists { uint v[]; } a_lists;
layout(std430, set = ADAPTIVE_SET, binding = 3) buffer AdaptiveCounters { uint v[]; } a_counters;

const uint A_CAST = 0x80000000u;
const uint A_LISTED = 0x40000000u;
const uint A_KEY_MASK = 0x3FFFFFFFu;
// Counter words (algo/adaptive.rs, Counter): the indirect arguments first.
const uint A_ARGS_DECIDE4 = 0u;  // x, y, z: the decide pass over the blocks of 4
const uint A_ARGS_CAST2 = 3u;    // x, y, z: the cast passes over the listed points (step 2, step 1)
const uint A_ARGS_CAST1 = 6u;
const uint A_COUNT4 = 9u;        // blocks of 4 listed
const uint A_COUNT2 = 10u;       // blocks of 2 refined to pixels
const uint A_POINTS2 = 11u;      // points listed for the step-2 cast, the step-1 cast
const uint A_POINTS1 = 12u;
const uint A_RAYS4 = 13u;        // rays cast per pass: step 4, 2, 1
const uint A_FILLED8 = 16u;      // blocks filled: of 8, of 4
const uint A_SIL8 = 18u;         // blocks refined: a silhouette (8, 4), the structure (8, 4), the colour (8, 4)
const uint A_STRUCT8 = 20u;
const uint A_COLOUR8 = 22u;
const uint A_COVERED_FILLED = 24u;  // filled pixels with alpha > 0
const uint A_COVERED_CAST = 25u;    // rays cast with alpha > 0
const uint A_PADDING = 26u;         // lattice points past the rectangle (no ray)
// Invocations per workgroup of the list passes (1D over a list).
const uint A_GROUP = uint(WG_X * WG_Y);

// Blocks of 8 across and down the rectangle (inclusive pixel bounds).
uvec2 adaptive_blocks(uvec4 rect) {
    return (rect.zw - rect.xy + 8u) / 8u;
}

// Lattice points per row, and in all.
uint adaptive_row(uvec4 rect) {
    return 8u * adaptive_blocks(rect).x + 1u;
}

uint adaptive_index(uvec4 rect, uvec2 lat) {
    return lat.y * adaptive_row(rect) + lat.x;
}

// Where the step-2 and step-1 point lists begin in a_lists.
uint adaptive_points_at(uvec4 rect, uint pass_step) {
    uvec2 nb = adaptive_blocks(rect);
    uint points = adaptive_row(rect) * (8u * nb.y + 1u);
    return 4u * nb.x * nb.y + (pass_step == 2u ? 0u : points);
}

// The lattice point this invocation of a cast pass of `pass_step` takes, and
// whether it casts it: step 4, a 2D dispatch over every point of the
// 4-lattice (rows of workgroups interleaved: common/dispatch.glsl); steps 2
// and 1, one invocation per point the decide pass before listed (each
// once, a refined block's points together), the list's workgroups
// interleaved over the device's threads the same way (the indirect
// dispatch's rows are the list's workgroups, rounded up to the runs).
bool adaptive_point(uint pass_step, uvec4 rect, uint rows, uint runs, out uvec2 lat) {
    uvec2 nb = adaptive_blocks(rect);
    lat = uvec2(0u);
    if (pass_step == 4u) {
        uvec2 p = uvec2(gl_WorkGroupID.x, interleaved_row(rows, runs)) * uvec2(WG_X, WG_Y) + gl_LocalInvocationID.xy;
        if (p.x > 2u * nb.x || p.y > 2u * nb.y) return false;
        lat = p * 4u;
        return true;
    }
    uint count = a_counters.v[pass_step == 2u ? A_POINTS2 : A_POINTS1];
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

// Records point `lat`'s sample and structural key (below A_CLAIM); `cast`:
// a ray was cast (else padding).
void adaptive_store(uint pass_step, uvec4 rect, uvec2 lat, vec4 c, uint key, bool was_cast) {
    uint i = adaptive_index(rect, lat);
    a_samples.v[i] = c;
    a_keys.v[i] = A_CAST | min(key, A_KEY_MASK);
    if (was_cast) {
        atomicAdd(a_counters.v[A_RAYS4 + (pass_step == 4u ? 0u : (pass_step == 2u ? 1u : 2u))], 1u);
        if (c.a > 0.0) atomicAdd(a_counters.v[A_COVERED_CAST], 1u);
    } else {
        atomicAdd(a_counters.v[A_PADDING], 1u);
    }
}

#endif
