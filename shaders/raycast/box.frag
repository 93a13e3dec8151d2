#version 450
// Entry or exit point (voxel coordinates) of the pixel's ray; alpha 1 marks
// a covered pixel (the target is cleared to 0).
layout(location = 0) in vec3 vox;
layout(location = 0) out vec4 point;
void main() { point = vec4(vox, 1.0); }
