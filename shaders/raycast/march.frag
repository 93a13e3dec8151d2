#version 450
// Pass 3 of the lab: march the pixel's ray from the entry point (front-face
// target) to the exit point (back-face target). A missing entry with an exit
// present means the eye is inside the box (the front faces were clipped by
// the near plane): the ray starts on the near plane. A missing exit with an
// entry present means the far plane cuts the box: the ray ends there.
#include "raycast/common.glsl"

layout(set = 1, binding = 0) uniform sampler2D entry_tex;
layout(set = 1, binding = 1) uniform sampler2D exit_tex;
layout(location = 0) out vec4 color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 entry = texelFetch(entry_tex, px, 0);
    vec4 exit_ = texelFetch(exit_tex, px, 0);
    if (entry.a == 0.0 && exit_.a == 0.0) { color = vec4(0.0); return; }
    vec2 ndc = gl_FragCoord.xy / vec2(textureSize(entry_tex, 0)) * 2.0 - 1.0;
    vec3 p_near, p_far;
    ndc_ray(ndc, p_near, p_far);
    vec3 a = entry.a > 0.0 ? entry.xyz : p_near;
    vec3 b = exit_.a > 0.0 ? exit_.xyz : p_far;
    uint samples;
    color = march(a, b, samples);
}
