#version 450
// One radix pass, step 3: move every pair to its slot. Stable: invocation t
// owns the ITEMS consecutive keys from g * TILE + t * ITEMS and places them
// in order, after the keys with the same digit in earlier invocations of
// the tile (an exclusive scan over invocations per digit, in shared memory)
// and in earlier tiles (the global scan). Equal keys therefore keep their
// order, and after every pass ties stay in cell-index order.
#include "cell_projection/radix_sort.glsl"
#include "common/dispatch.glsl"

layout(local_size_x = WG) in;

shared uint s_count[RADIX * uint(WG)]; // digit-major: s_count[d * WG + t]
shared uint s_base[RADIX];

void main() {
    uint g = linear_workgroup_id();
    if (g >= params.groups) {
        return; // the whole (padding) workgroup: barriers stay uniform
    }
    uint t = gl_LocalInvocationIndex;
    uint start = g * TILE + t * uint(ITEMS);
    uvec4 c = uvec4(0u);
    for (uint i = 0u; i < uint(ITEMS); i++) {
        uint idx = start + i;
        if (idx < params.n) {
            c += packed_one(digit_of(keys_src[idx]));
        }
    }
    for (uint d = 0u; d < RADIX; d++) {
        s_count[d * uint(WG) + t] = packed_get(c, d);
    }
    barrier();
    for (uint d = t; d < RADIX; d += uint(WG)) {
        uint acc = 0u;
        for (uint j = 0u; j < uint(WG); j++) {
            uint n_j = s_count[d * uint(WG) + j];
            s_count[d * uint(WG) + j] = acc;
            acc += n_j;
        }
        s_base[d] = counts[d * params.groups + g];
    }
    barrier();
    // Slot = the tile's first slot for the digit + the keys with it in
    // earlier invocations + those placed so far by this one.
    c = uvec4(0u);
    for (uint i = 0u; i < uint(ITEMS); i++) {
        uint idx = start + i;
        if (idx < params.n) {
            uint k = keys_src[idx];
            uint d = digit_of(k);
            uint dst = s_base[d] + s_count[d * uint(WG) + t] + packed_get(c, d);
            c += packed_one(d);
            keys_dst[dst] = k;
            vals_dst[dst] = vals_src[idx];
        }
    }
}
