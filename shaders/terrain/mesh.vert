#version 450
// Hybrid terrain meshes: every triangle (grid NC cells, PC tessellations,
// TINs) is drawn from the one geometry buffer of world positions.
#include "terrain/common.glsl"

layout(location = 0) in vec4 position;
layout(location = 0) out vec3 world;

void main() {
    world = position.xyz;
    gl_Position = pc.view_proj * vec4(position.xyz, 1.0);
}
