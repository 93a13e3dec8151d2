#version 450
// Sort keys from the camera: the depth of each cell's centroid (squared
// distance from the eye, or distance along the view direction for
// orthographic views), mapped to an order-preserving u32 and inverted so
// that ascending keys are farthest first; the values are the cell indices.
// The same f32 arithmetic as CentroidSort::sort on the CPU, term by term:
// `precise` forbids fusing the products and sums into FMAs, which would
// round differently and change the order of near ties.
#include "cell_projection/radix_sort.glsl"
#include "common/dispatch.glsl"

layout(local_size_x = WG) in;

// Rust: algo::cell_projection::device_sort::SortCamera (the reflection
// test checks the two).
layout(push_constant) uniform Camera {
    vec3 eye;            // eye relative to the render origin
    float perspective;   // 1 perspective, 0 orthographic
    vec3 dir;            // unit view direction
} cam;

// radix::float_key: ascending floats -> ascending keys.
uint float_key(float x) {
    uint b = floatBitsToUint(x);
    return (b & 0x80000000u) != 0u ? ~b : (b | 0x80000000u);
}

void main() {
    uint i = linear_invocation_id();
    if (i >= params.n) {
        return;
    }
    vec3 c = centroid_at(i).xyz;
    precise float dx = c.x - cam.eye.x;
    precise float dy = c.y - cam.eye.y;
    precise float dz = c.z - cam.eye.z;
    precise float depth;
    if (cam.perspective > 0.5) {
        depth = dx * dx + dy * dy + dz * dz;
    } else {
        depth = dx * cam.dir.x + dy * cam.dir.y + dz * cam.dir.z;
    }
    keys_src[i] = ~float_key(depth);
    vals_src[i] = i;
}
