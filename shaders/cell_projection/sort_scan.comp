#version 450
// One radix pass, step 2 (one workgroup): exclusive prefix sum over the
// digit-major counts, in place, so counts[d * groups + g] becomes the first
// output slot of workgroup g's keys with digit d. Each invocation sums a
// contiguous chunk; the chunk totals are scanned in shared memory.
#include "cell_projection/radix_sort.glsl"

layout(local_size_x = WG) in;

shared uint s_sum[WG];

void main() {
    uint t = gl_LocalInvocationIndex;
    uint total = RADIX * params.groups;
    uint chunk = (total + uint(WG) - 1u) / uint(WG);
    uint begin = min(t * chunk, total);
    uint end = min(begin + chunk, total);
    uint sum = 0u;
    for (uint i = begin; i < end; i++) {
        sum += counts[i];
    }
    s_sum[t] = sum;
    barrier();
    if (t == 0u) {
        uint acc = 0u;
        for (uint j = 0u; j < uint(WG); j++) {
            uint c = s_sum[j];
            s_sum[j] = acc;
            acc += c;
        }
    }
    barrier();
    uint acc = s_sum[t];
    for (uint i = begin; i < end; i++) {
        uint c = counts[i];
        counts[i] = acc;
        acc += c;
    }
}
