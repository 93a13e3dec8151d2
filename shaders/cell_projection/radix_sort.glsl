// The device radix sort's layout, shared by its four kernels
// (src/algo/cell_projection/device_sort.rs): a stable LSD sort of
// (u32 key, u32 cell index) pairs, RADIX_BITS bits per pass. WG, ITEMS and
// RADIX_BITS are defines set by the Rust side (one place). No subgroup
// operations: only shared memory and barriers, so it runs the same on any
// subgroup size (lavapipe's is 4 or 8).
//
// Set 0, one set per pass (binding 0 differs: the pass's shift; bindings
// 2-5 swap between passes, so the sorted pairs end where they started):
//   0 params    n, workgroups per histogram/scatter dispatch, digit shift
//   1 centroids cell centroids relative to the render origin (xyz)
//   2 keys_src  3 vals_src   the pass's input pairs
//   4 keys_dst  5 vals_dst   its output pairs
//   6 counts    digit-major counts per workgroup (counts[d * groups + g]),
//               turned by the scan into each (digit, workgroup)'s first slot
//   7-13        the centroids' further buffers, when they are split at
//               the device's limits (CENTROID_CHUNKS buffers of
//               CENTROID_PER_CHUNK; algo/chunks.rs): read with centroid_at

#ifndef VOLBENCH_RADIX_SORT_GLSL
#define VOLBENCH_RADIX_SORT_GLSL

// Defaults only for compiling the file on its own (`every_shader_compiles`);
// device_sort.rs always sets all three.
#ifndef WG
#define WG 128
#endif
#ifndef ITEMS
#define ITEMS 16
#endif
#ifndef RADIX_BITS
#define RADIX_BITS 4
#endif

#define RADIX (1u << RADIX_BITS)
#define TILE (uint(WG) * uint(ITEMS))

// One pass's parameters (static, one buffer per pass). Rust:
// algo::cell_projection::device_sort::PassParams (the reflection test
// checks the two).
layout(std430, set = 0, binding = 0) readonly buffer Params {
    uint n;        // keys
    uint groups;   // workgroups of TILE keys
    uint shift;    // the pass's digit: (key >> shift) & (RADIX - 1)
} params;
layout(std430, set = 0, binding = 1) readonly buffer Centroids { vec4 centroids[]; };
layout(std430, set = 0, binding = 2) buffer KeysSrc { uint keys_src[]; };
layout(std430, set = 0, binding = 3) buffer ValsSrc { uint vals_src[]; };
layout(std430, set = 0, binding = 4) buffer KeysDst { uint keys_dst[]; };
layout(std430, set = 0, binding = 5) buffer ValsDst { uint vals_dst[]; };
layout(std430, set = 0, binding = 6) buffer Counts { uint counts[]; };

// Split centroids: chunk k (1..7) at binding 6 + k. All seven are declared
// and bound (the Rust side repeats the last buffer in the unused ones);
// CENTROID_CHUNKS only says that there is a split.
#ifndef CENTROID_CHUNKS
#define CENTROID_CHUNKS 1
#endif
#if CENTROID_CHUNKS > 1
#define CENTROID_CHUNK(k) layout(std430, set = 0, binding = 6 + k) readonly buffer Centroids##k { vec4 centroids_##k[]; };
CENTROID_CHUNK(1) CENTROID_CHUNK(2) CENTROID_CHUNK(3) CENTROID_CHUNK(4) CENTROID_CHUNK(5) CENTROID_CHUNK(6) CENTROID_CHUNK(7)
#endif

// Cell i's centroid, from the buffer holding it.
vec4 centroid_at(uint i) {
#if CENTROID_CHUNKS > 1
    uint c = i / uint(CENTROID_PER_CHUNK);
    uint j = i - c * uint(CENTROID_PER_CHUNK);
    switch (c) {
    case 1u: return centroids_1[j]; case 2u: return centroids_2[j]; case 3u: return centroids_3[j];
    case 4u: return centroids_4[j]; case 5u: return centroids_5[j]; case 6u: return centroids_6[j];
    case 7u: return centroids_7[j]; default: return centroids[j];
    }
#else
    return centroids[i];
#endif
}

uint digit_of(uint key) {
    return (key >> params.shift) & (RADIX - 1u);
}

// One invocation's count of each of the 16 digits among its ITEMS keys,
// packed 8 bits per digit into a uvec4 (digit d: byte d % 4 of component
// d / 4). Updated and read with vector compares and selects: a private
// array indexed by a per-invocation digit would become scratch memory
// (per-lane loads and stores on lavapipe).
#if RADIX_BITS != 4 || ITEMS > 255
#error "the packed digit counters hold 16 digits of up to 255 keys"
#endif

uvec4 packed_one(uint d) {
    return uvec4(equal(uvec4(d >> 2u), uvec4(0u, 1u, 2u, 3u))) << ((d & 3u) * 8u);
}

uint packed_get(uvec4 c, uint d) {
    uint q = d >> 2u;
    uint w = q == 0u ? c.x : (q == 1u ? c.y : (q == 2u ? c.z : c.w));
    return (w >> ((d & 3u) * 8u)) & 0xffu;
}

#endif
