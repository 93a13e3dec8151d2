#version 450
// One radix pass, step 1: how many keys of each workgroup's tile have each
// digit, written digit-major (counts[d * groups + g]) for the scan. Each
// invocation counts its keys in packed registers; the tile's totals are
// summed from shared memory (no shared atomics, which lavapipe runs lane
// by lane).
#include "cell_projection/radix_sort.glsl"
#include "common/dispatch.glsl"

layout(local_size_x = WG) in;

shared uint s_count[RADIX * uint(WG)]; // digit-major: s_count[d * WG + t]

void main() {
    uint g = linear_workgroup_id();
    if (g >= params.groups) {
        return; // the whole (padding) workgroup: barriers stay uniform
    }
    uint t = gl_LocalInvocationIndex;
    // Order does not matter for counting: neighbouring invocations read
    // neighbouring keys.
    uvec4 c = uvec4(0u);
    for (uint i = 0u; i < uint(ITEMS); i++) {
        uint idx = g * TILE + i * uint(WG) + t;
        if (idx < params.n) {
            c += packed_one(digit_of(keys_src[idx]));
        }
    }
    for (uint d = 0u; d < RADIX; d++) {
        s_count[d * uint(WG) + t] = packed_get(c, d);
    }
    barrier();
    for (uint d = t; d < RADIX; d += uint(WG)) {
        uint sum = 0u;
        for (uint j = 0u; j < uint(WG); j++) {
            sum += s_count[d * uint(WG) + j];
        }
        counts[d * params.groups + g] = sum;
    }
}
