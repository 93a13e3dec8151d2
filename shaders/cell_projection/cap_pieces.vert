#version 450
// Near caps of a method drawn in pieces (atfs).
#define CAP_PIECES 1
#include "cell_projection/cap_vert.glsl"
