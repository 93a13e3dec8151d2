#version 450
// Shaded terrain: flat normals from screen-space derivatives, a headlight
// raised above the view, colours by height (green, brown, white) or by
// class (push constant `tint`). Skirts (world.w > 0, see mesh.vert) are
// shaded as level ground at their border's height: lit by their own
// vertical faces they showed as dark lines along every block seam. With COVERAGE each fragment adds 1 to the
// red and alpha channels of a target blended additively: how many
// triangles cover each pixel centre.
#include "terrain/common.glsl"

layout(location = 0) in vec4 world;
layout(location = 0) out vec4 colour;

void main() {
#ifdef COVERAGE
    colour = vec4(1.0, 0.0, 0.0, 1.0);
#else
    // (A skirt's shading positions are a line: its own normal is zero.)
    vec3 c = cross(dFdx(world.xyz), dFdy(world.xyz));
    vec3 n = world.w > 0.0 || dot(c, c) == 0.0 ? vec3(0.0, 0.0, 1.0) : normalize(c);
    float lambert = abs(dot(n, pc.light));
    float t = clamp((world.z - pc.height_lo) / max(pc.height_hi - pc.height_lo, 1e-6), 0.0, 1.0);
    vec3 low = vec3(0.25, 0.5, 0.2), mid = vec3(0.55, 0.45, 0.3), high = vec3(0.95);
    vec3 base = t < 0.5 ? mix(low, mid, t * 2.0) : mix(mid, high, t * 2.0 - 1.0);
    base = mix(base, pc.tint, pc.tint_mix);
    colour = vec4(base * (0.25 + 0.75 * lambert), 1.0);
#endif
}
