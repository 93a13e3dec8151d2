#version 450
// Hybrid terrain meshes: every triangle (grid NC cells, PC tessellations,
// TINs, skirts) is drawn from the one geometry buffer of world positions.
// A skirt vertex carries its drop in w: it is placed that much lower, and
// passes its border's height and the drop on (world.w > 0 marks skirts).
#include "terrain/common.glsl"

layout(location = 0) in vec4 position;
layout(location = 0) out vec4 world;

void main() {
    world = position;
    gl_Position = pc.view_proj * vec4(position.xy, position.z - position.w, 1.0);
}
