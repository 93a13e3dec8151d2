#version 450
#include "cell_projection/cap_frag.glsl"
