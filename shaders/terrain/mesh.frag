#version 450
// Shaded terrain: flat normals from screen-space derivatives, a headlight
// raised above the view, colours by height (green, brown, white) or by
// class (push constant `tint`). With COVERAGE each fragment adds 1 to the
// red and alpha channels of a target blended additively: how many
// triangles cover each pixel centre.
#include "terrain/common.glsl"

layout(location = 0) in vec3 world;
layout(location = 0) out vec4 colour;

void main() {
#ifdef COVERAGE
    colour = vec4(1.0, 0.0, 0.0, 1.0);
#else
    vec3 n = normalize(cross(dFdx(world), dFdy(world)));
    float lambert = abs(dot(n, pc.light.xyz));
    float t = clamp((world.z - pc.range.x) / max(pc.range.y - pc.range.x, 1e-6), 0.0, 1.0);
    vec3 low = vec3(0.25, 0.5, 0.2), mid = vec3(0.55, 0.45, 0.3), high = vec3(0.95);
    vec3 base = t < 0.5 ? mix(low, mid, t * 2.0) : mix(mid, high, t * 2.0 - 1.0);
    base = mix(base, pc.tint.rgb, pc.tint.a);
    colour = vec4(base * (0.25 + 0.75 * lambert), 1.0);
#endif
}
