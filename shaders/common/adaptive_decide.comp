#version 450
// Adaptive image-space refinement, the decide pass over blocks of `size`
// (16: every block of the rectangle, a 2D dispatch with rows interleaved;
// 8 and 4: the listed blocks, an indirect dispatch). A block whose four
// corners, centre and edge mid-points were cast (common/adaptive.glsl) is
// filled, by the biquadratic through those nine rays, when
//   - no boundary silhouette that could hide something between its rays
//     projects into it (the silhouette bits, when the method has them:
//     two lines, a bend or an end in the block; algo/adaptive.rs,
//     Silhouettes),
//   - the nine rays have the same structural key (tet-raycast: boundary
//     entries taken; raycast: the occupied bricks met), unless one straight
//     silhouette chord crosses the block (the straight bits: the keys differ
//     on its two sides, and the colour test sees what it separates), and
//   - each test ray agrees with the bilinear interpolation of the corners
//     at its point within the tolerance, per premultiplied RGBA channel (the
//     image is nearly linear across the block: the biquadratic then adds
//     its curvature, at no ray's cost);
// otherwise the centres and edge mid-points of its four sub-blocks are
// listed for the next cast pass (each point once: the first block to claim
// it) and, above size 4, the sub-blocks for the next decide pass.
// A block owns its pixels [0, size)^2 from its corner; the ones on the
// lattice of size / 2 were cast and are not overwritten. Pixels go to the
// pixel buffer (adaptive_pixel), copied into the target after the passes.
#define WG_X 8
#define WG_Y 8
layout(local_size_x = WG_X, local_size_y = WG_Y) in;

// Rust: algo::adaptive::DecidePush (the reflection test checks the two).
layout(push_constant) uniform Decide {
    uvec4 rect;          // the frame's rectangle, inclusive pixel bounds
    uint block_size;     // 16, 8 or 4
    uint rows;           // size 16: rows of workgroups (interleaved_row); all: the device's runs
    uint runs;
    uint silhouettes;    // first word of this size's silhouette bits (0xFFFFFFFF: none)
    float tol;           // tolerance per premultiplied channel
    uint straight;       // first word of this size's straight-chord bits (0xFFFFFFFF: none)
} pc;

#include "common/dispatch.glsl"
#define ADAPTIVE_SET 0
#include "common/adaptive.glsl"
layout(std430, set = 0, binding = 4) readonly buffer Silhouettes { uint v[]; } a_sil;

bool agrees(vec4 ray, vec4 interpolated, float tol) {
    vec4 d = abs(ray - interpolated);
    return max(max(d.x, d.y), max(d.z, d.w)) <= tol;
}

void main() {
    uint size = pc.block_size;
    uint level = a_size_level(size);
    uvec2 nb = adaptive_blocks(pc.rect);
    uvec2 b;
    if (size == A_BLOCK) {
        if (gl_WorkGroupID.x == 0u && gl_WorkGroupID.y == 0u && gl_LocalInvocationIndex == 0u) {
            // The indirect arguments that do not grow with the lists: y and
            // z of the two decide passes that follow (x: workgroups), x and
            // z of the three cast passes (y: rows of workgroups).
            for (uint a = A_ARGS_DECIDE8; a <= A_ARGS_DECIDE4; a += 3u) {
                a_counters.v[a + 1u] = 1u;
                a_counters.v[a + 2u] = 1u;
            }
            for (uint a = A_ARGS_CAST4; a <= A_ARGS_CAST1; a += 3u) {
                a_counters.v[a] = 1u;
                a_counters.v[a + 2u] = 1u;
            }
        }
        b = uvec2(gl_WorkGroupID.x, interleaved_row(pc.rows, pc.runs)) * uvec2(WG_X, WG_Y) + gl_LocalInvocationID.xy;
        if (b.x >= nb.x || b.y >= nb.y) return;
    } else {
        uint idx = gl_WorkGroupID.x * A_GROUP + gl_LocalInvocationIndex;
        if (idx >= a_counters.v[A_COUNT8 + level - 1u]) return;
        uint e = a_lists.v[adaptive_blocks_at(pc.rect, size) + idx];
        b = uvec2(e & 0xFFFFu, e >> 16);
    }
    uint h = size / 2u;
    uvec2 o = b * size;
    uint lw = adaptive_row(pc.rect);
    uint i00 = o.y * lw + o.x;
    // The nine points: corners, edge mid-points, centre.
    uint i10 = i00 + size;
    uint i01 = i00 + size * lw;
    uint i11 = i01 + size;
    uint it = i00 + h;
    uint il = i00 + h * lw;
    uint ic = il + h;
    uint ir = il + size;
    uint ib = i01 + h;
    uint k = a_keys.v[i00];
    bool same = a_keys.v[i10] == k && a_keys.v[i01] == k && a_keys.v[i11] == k && a_keys.v[it] == k
        && a_keys.v[il] == k && a_keys.v[ic] == k && a_keys.v[ir] == k && a_keys.v[ib] == k;
    bool silhouette = false;
    uint bit = b.y * (nb.x << level) + b.x;
    if (pc.silhouettes != 0xFFFFFFFFu) {
        silhouette = ((a_sil.v[pc.silhouettes + bit / 32u] >> (bit % 32u)) & 1u) != 0u;
    }
    uint straight_at = pc.straight;
    if (straight_at != 0xFFFFFFFFu && ((a_sil.v[straight_at + bit / 32u] >> (bit % 32u)) & 1u) != 0u) {
        same = true;
    }
    uint reason;
    vec4 c00 = a_samples.v[i00];
    vec4 c10 = a_samples.v[i10];
    vec4 c01 = a_samples.v[i01];
    vec4 c11 = a_samples.v[i11];
    float tol = pc.tol;
    if (silhouette) {
        reason = A_SIL16;
    } else if (!same) {
        reason = A_STRUCT16;
    } else if (agrees(a_samples.v[ic], 0.25 * (c00 + c10 + c01 + c11), tol)
               && agrees(a_samples.v[it], 0.5 * (c00 + c10), tol)
               && agrees(a_samples.v[ib], 0.5 * (c01 + c11), tol)
               && agrees(a_samples.v[il], 0.5 * (c00 + c01), tol)
               && agrees(a_samples.v[ir], 0.5 * (c10 + c11), tol)) {
        reason = A_FILLED16;
    } else {
        reason = A_COLOUR16;
    }
    atomicAdd(a_counters.v[reason + level], 1u);
    if (reason == A_FILLED16) {
        uint covered = 0u;
        float inv = 1.0 / float(size);
        vec4 ct = a_samples.v[it], cl = a_samples.v[il], cc = a_samples.v[ic], cr = a_samples.v[ir], cb = a_samples.v[ib];
        // Column by column: the biquadratic through the nine rays (Lagrange
        // weights on the nodes 0, 1/2, 1 per axis), its three rows' values
        // at the column once, then each pixel's, clamped to [0, 1]. The
        // block's pixels on the lattice of h (a power of two) were cast.
        uvec2 last = min(o + uvec2(size - 1u), pc.rect.zw - pc.rect.xy);
        for (uint u = 0u; u <= last.x - o.x; ++u) {
            float fx = float(u) * inv;
            vec3 lx = vec3((2.0 * fx - 1.0) * (fx - 1.0), 4.0 * fx * (1.0 - fx), fx * (2.0 * fx - 1.0));
            vec4 r0 = lx.x * c00 + lx.y * ct + lx.z * c10;
            vec4 r1 = lx.x * cl + lx.y * cc + lx.z * cr;
            vec4 r2 = lx.x * c01 + lx.y * cb + lx.z * c11;
            bool on_column = (u & (h - 1u)) == 0u;
            for (uint v = 0u; v <= last.y - o.y; ++v) {
                if (on_column && (v & (h - 1u)) == 0u) continue;
                float fy = float(v) * inv;
                vec3 ly = vec3((2.0 * fy - 1.0) * (fy - 1.0), 4.0 * fy * (1.0 - fy), fy * (2.0 * fy - 1.0));
                vec4 c = clamp(ly.x * r0 + ly.y * r1 + ly.z * r2, vec4(0.0), vec4(1.0));
                adaptive_pixel(pc.rect, o + uvec2(u, v), c);
                covered += c.a > 0.0 ? 1u : 0u;
            }
        }
        if (covered > 0u) atomicAdd(a_counters.v[A_COVERED_FILLED], covered);
        return;
    }
    // Refine: the sub-blocks with a pixel in the rectangle have their
    // centres and edge mid-points listed for the next cast pass (a point
    // two of them share, by whichever claims it first) and, above size 4,
    // are listed for the next decide pass (size 4 counts its blocks of 2).
    uvec2 s0 = b * 2u;
    uint q = size / 4u;
    uint n = 0u;
    uint subs[4];
    uint np = 0u;
    uint points[20];
    for (uint j = 0u; j < 2u; ++j) {
        for (uint i = 0u; i < 2u; ++i) {
            uvec2 sb = s0 + uvec2(i, j);
            uvec2 px = pc.rect.xy + sb * h;
            if (px.x <= pc.rect.z && px.y <= pc.rect.w) {
                uint c = (sb.y * h + q) * lw + sb.x * h + q;
                uint five[5] = uint[5](c - q * lw, c - q, c, c + q, c + q * lw);
                for (uint m = 0u; m < 5u; ++m) {
                    if (atomicCompSwap(a_keys.v[five[m]], 0u, A_LISTED) == 0u) {
                        points[np] = five[m];
                        np += 1u;
                    }
                }
                subs[n] = sb.x | (sb.y << 16);
                n += 1u;
            }
        }
    }
    uint first = atomicAdd(a_counters.v[A_COUNT8 + level], n);
    if (size > 4u) {
        uint blocks_at = adaptive_blocks_at(pc.rect, h);
        for (uint j = 0u; j < n; ++j) {
            a_lists.v[blocks_at + first + j] = subs[j];
        }
        // The next decide pass's workgroups: one invocation per block.
        atomicMax(a_counters.v[A_ARGS_DECIDE8 + 3u * level], (first + n + A_GROUP - 1u) / A_GROUP);
    }
    // The next cast pass, of step size / 4.
    uint pass_step = q;
    uint at = atomicAdd(a_counters.v[A_POINTS4 + level], np);
    uint list = adaptive_points_at(pc.rect, pass_step);
    for (uint j = 0u; j < np; ++j) {
        a_lists.v[list + at + j] = points[j];
    }
    // The cast pass's rows of workgroups: the list's workgroups, rounded
    // up to the device's runs (algo::screen::interleaved_rows).
    uint runs = max(pc.runs, 1u);
    uint groups = (at + np + A_GROUP - 1u) / A_GROUP;
    atomicMax(a_counters.v[A_ARGS_CAST4 + 3u * level + 1u], (groups + runs - 1u) / runs * runs);
}
