#version 450
// One radix pass, step 1: how many keys of each workgroup's tile have each
// digit, written digit-major (counts[d * groups + g]) for the scan.
#include "cell_projection/radix_sort.glsl"
#include "common/dispatch.glsl"

layout(local_size_x = WG) in;

shared uint s_hist[RADIX];

void main() {
    uint g = linear_workgroup_id();
    if (g >= params.groups) {
        return; // the whole (padding) workgroup: barriers stay uniform
    }
    uint t = gl_LocalInvocationIndex;
    for (uint d = t; d < RADIX; d += uint(WG)) {
        s_hist[d] = 0u;
    }
    barrier();
    // Order does not matter for counting: neighbouring invocations read
    // neighbouring keys.
    for (uint i = 0u; i < uint(ITEMS); i++) {
        uint idx = g * TILE + i * uint(WG) + t;
        if (idx < params.n) {
            atomicAdd(s_hist[digit_of(keys_src[idx])], 1u);
        }
    }
    barrier();
    for (uint d = t; d < RADIX; d += uint(WG)) {
        counts[d * params.groups + g] = s_hist[d];
    }
}
