#version 450
// The volume's bounding box, 12 triangles generated from gl_VertexIndex (no
// vertex buffer), in voxel coordinates; the fragment stage writes them out
// as the entry (front faces) or exit (back faces) point of the pixel's ray.
#include "raycast/common.glsl"

layout(location = 0) out vec3 vox;

// Corner c of the unit cube: bit 0 = x, bit 1 = y, bit 2 = z.
const int FACES[36] = int[36](
    0, 2, 1, 1, 2, 3,   // z = 0
    4, 5, 6, 5, 7, 6,   // z = 1
    0, 1, 4, 1, 5, 4,   // y = 0
    2, 6, 3, 3, 6, 7,   // y = 1
    0, 4, 2, 2, 4, 6,   // x = 0
    1, 3, 5, 3, 7, 5    // x = 1
);

void main() {
    int c = FACES[gl_VertexIndex];
    vec3 corner = vec3(c & 1, (c >> 1) & 1, (c >> 2) & 1);
    vox = corner * params.box_max;
    gl_Position = frame.m * vec4(vox, 1.0);
}
