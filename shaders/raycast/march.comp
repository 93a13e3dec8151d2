#version 450
#ifdef SUBGROUP_COUNTERS
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_basic : require
#endif
// The whole integral in one compute pass: per pixel the viewing ray between
// the near and far planes, clipped analytically to the box, then marched
// exactly as the fragment variant does. Workgroup WG_X x WG_Y (defines).
#include "raycast/common.glsl"
#include "common/dispatch.glsl"

#ifndef WG_X
#define WG_X 8
#define WG_Y 8
#endif
layout(local_size_x = WG_X, local_size_y = WG_Y) in;
layout(set = 1, binding = 0, rgba32f) uniform writeonly image2D target;
#ifdef ADAPTIVE
// Adaptive refinement (algo/adaptive.rs): this pass casts the lattice
// points of step frame.cast_step, storing each ray's colour and its
// structural key (raycast/common.glsl: its runs near visible bricks and
// the nearest one's distance up to frame.close; 0 for a ray that missed the
// box, and always 0 without SKIP) for the decide passes.
#define ADAPTIVE_SET 2
#include "common/adaptive.glsl"
#endif

void main() {
    ivec2 size = imageSize(target);
#ifdef ADAPTIVE
    uint pass_step = frame.cast_step;
    uvec2 at;
    if (!adaptive_point(pass_step, frame.rect, frame.rows, frame.runs, at)) return;
    ivec2 px = ivec2(at + frame.rect.xy);
    if (!adaptive_in_rect(frame.rect, at)) {
        // Lattice padding past the rectangle: no ray meets the box there.
        adaptive_store(pass_step, frame.rect, at, vec4(0.0), 0u, false);
        return;
    }
#else
    // The workgroup's tile, rows interleaved over the device's runs of
    // workgroups (common/dispatch.glsl), from the first tile over the box.
    uint row = interleaved_row(frame.rows, frame.runs);
    uvec2 tile = uvec2(gl_WorkGroupID.x, row) + frame.first_group;
    ivec2 px = ivec2(tile * uvec2(WG_X, WG_Y) + gl_LocalInvocationID.xy);
    // Padding rows (row >= rows) run nothing.
    if (px.x >= size.x || px.y >= size.y || row >= frame.rows) return;
#endif
    vec2 ndc = (vec2(px) + 0.5) / vec2(size) * 2.0 - 1.0;
    vec3 a, b;
    ndc_ray(ndc, a, b);
    vec4 color = vec4(0.0);
    uint key = 0u;
    if (clip_to_box(a, b)) {
        uint samples;
        color = march(a, b, samples);
#ifdef ADAPTIVE
        key = march_runs * 256u + min(march_closest, frame.close);
#endif
    }
#ifdef ADAPTIVE
    adaptive_store(pass_step, frame.rect, at, color, key, true);
    adaptive_pixel(frame.rect, at, color);
#else
    imageStore(target, px, color);
#endif
}
