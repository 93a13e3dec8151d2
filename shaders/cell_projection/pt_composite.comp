#version 450
// Projected tetrahedra in compute (pt-compute): one invocation per pixel,
// TILE_W x TILE_H pixels per workgroup. Each pixel's list holds the cells
// covering it (decided on the CPU by the rasterizer's rule: pt_compute.rs
// `rasterize`) in visibility order, back to front; the invocation walks it
// from the back, i.e. front to back, and composites under what it has, so
// it stops once its pixel is opaque (early termination). Every entry is a
// segment to integrate, so a vector's lanes do not idle on cells that miss
// them (llvmpipe runs both sides of a branch). Per cell, the pixel's ray is
// clipped by the tet's four planes; where it enters, the tet's barycentric
// weights give exactly what the rasterizer interpolates there for
// balanced's entry face, and balanced's fragment colour
// (known_exits_io.glsl `segment_color`) integrates it unchanged. Entries
// with PLANE_TEST_BIT (cells through the eye plane) are listed for their
// whole pixel box and tested here by their planes.
#ifndef TILE_W
#define TILE_W 4
#define TILE_H 2
#endif
layout(local_size_x = TILE_W, local_size_y = TILE_H) in;

#ifndef ERT_TRANSMITTANCE
#define ERT_TRANSMITTANCE 1e-5
#endif
#include "common/frame.glsl"
#include "common/integrate.glsl"
#include "common/clip.glsl"
#define EXIT_VEC vec4
#define EXIT_N 4
#define KNOWN_EXITS_ONLY
#include "common/exit.glsl"
#define KNOWN_EXITS_COMPUTE
#include "cell_projection/known_exits_io.glsl"
#include "cell_projection/stored_cell.glsl"

// Pixel i's entries (row-major) are [first[i], first[i + 1]); an entry is a
// cell, with PLANE_TEST_BIT where its coverage is decided here.
layout(set = 1, binding = 1, r32ui) uniform readonly uimageBuffer pixel_first;
layout(set = 1, binding = 2, r32ui) uniform readonly uimageBuffer entries;
const uint PLANE_TEST_BIT = 0x80000000u;
layout(std430, set = 1, binding = 3) buffer Counters {
    uint integrated_lo;    // (pixel, cell) segments integrated (64 bits: lo, hi)
    uint integrated_hi;
    uint terminated;       // pixels that stopped early (opaque)
    uint covered;          // pixels with at least one segment
} counters;
layout(set = 2, binding = 0, rgba32f) uniform writeonly image2D target;

const float INF = 3.0e38;

// The ray through NDC (x, y), i.e. the pixel centre the rasterizer samples,
// from the rows of view_proj: under perspective the line through the eye
// where clip x = x w and clip y = y w (the eye has clip x = y = w = 0), so
// its direction is normal to both planes' normals; orthographic views have
// w = 1 and the planes x, y are the image axes, perpendicular to each other.
void pixel_ray(vec2 ndc, out vec3 o, out vec3 d) {
    vec4 r0 = clip_row(0);
    vec4 r1 = clip_row(1);
    vec4 r3 = clip_row(3);
    vec3 fwd = frame.view_dir;
    if (frame.perspective > 0.5) {
        o = frame.eye;
        d = normalize(cross(r0.xyz - ndc.x * r3.xyz, r1.xyz - ndc.y * r3.xyz));
    } else {
        vec4 e = vec4(frame.eye, 1.0);
        o = frame.eye + (ndc.x - dot(r0, e)) * r0.xyz / dot(r0.xyz, r0.xyz) + (ndc.y - dot(r1, e)) * r1.xyz / dot(r1.xyz, r1.xyz);
        d = fwd;
    }
    d = dot(d, fwd) < 0.0 ? -d : d;
}

void main() {
    uvec2 tile = gl_WorkGroupID.xy;
    uvec2 local = gl_LocalInvocationID.xy;
    ivec2 px = ivec2(tile * uvec2(TILE_W, TILE_H) + local);
    ivec2 size = imageSize(target);
    bool inside = px.x < size.x && px.y < size.y;
    vec3 ray_o;
    vec3 ray_d;
    pixel_ray((vec2(px) + 0.5) / vec2(size) * 2.0 - 1.0, ray_o, ray_d);
    vec4 w_row = clip_row(3);
    // A direction in the image plane, generic (no face of a regular grid
    // is normal to it): the tie rule's.
    vec3 nudge = clip_row(0).xyz + 1e-3 * clip_row(1).xyz;
    vec4 lambda_a;
    vec4 lambda_b;

    uint k = uint(px.y) * uint(size.x) + uint(px.x);
    uint first = inside ? imageLoad(pixel_first, int(k)).x : 0u;
    uint last = inside ? imageLoad(pixel_first, int(k) + 1).x : 0u;
    vec3 acc = vec3(0.0);
    float trans = 1.0;
    uint integrated = 0u;
    bool done = !inside;
    for (uint e = last; e > first && !done; --e) {
        uint entry = imageLoad(entries, int(e - 1u)).x;
        uint t = entry & ~PLANE_TEST_BIT;
        bool plane_test = entry >= PLANE_TEST_BIT;
        // lambda_j along the ray: a_j + s b_j (1 at vertex j, 0 on its
        // opposite plane, resident.rs `stored`: plane3 . (x - v_j) + 1).
        // Entered where the last entering plane (b > 0) is crossed, left
        // where the first leaving one is. Listed cells cover the pixel by
        // the rasterizer's rule; only PLANE_TEST_BIT entries decide it here:
        // a plane parallel to the ray keeps it inside where a > 0; a ray in
        // such a plane (a face or edge seen edge-on) is on the boundary of
        // every cell around it, and goes to the cell the ray moved a little
        // along `nudge` would be in. A flat cell (zero planes) is never
        // entered.
        float t_in = -INF;
        float t_out = INF;
        bool miss = false;
        for (int j = 0; j < 4; ++j) {
            vec3 n = cell_plane(t, j).xyz;
            float offset = dot(n, ray_o - cell_pos(t, j).xyz);
            float a = 1.0 + offset;
            float b = dot(n, ray_d);
            lambda_a[j] = a;
            lambda_b[j] = b;
            float scale = length(n);
            if (abs(b) <= 1e-6 * scale) {
                bool on_plane = abs(a) <= 1e-6 * (1.0 + abs(offset));
                miss = miss || (on_plane ? dot(n, nudge) <= 0.0 : a < 0.0);
            } else if (b > 0.0) {
                t_in = max(t_in, -a / b);
            } else {
                t_out = min(t_out, -a / b);
            }
        }
        if (!(t_in > -INF) || (plane_test && (miss || !(t_in < t_out)))) {
            continue;
        }
        vec3 p = ray_o + t_in * ray_d;
        // balanced clips its faces at the eye plane (common/clip.glsl); the
        // near caps (drawn after this pass) integrate what lies before it.
        if (eye_plane_distance(vec4(0.0, 0.0, 0.0, dot(w_row, vec4(p, 1.0)))) < 0.0) {
            continue;
        }
        vec4 lambda = max(lambda_a + t_in * lambda_b, vec4(0.0));
        lambda /= lambda.x + lambda.y + lambda.z + lambda.w;
        uint exits;
        vec4 c = cell_view_values(t, exits);
        vec4 sv = vec4(cell_pos(t, 0).w, cell_pos(t, 1).w, cell_pos(t, 2).w, cell_pos(t, 3).w);
        vec3 g = cell_gradient(t);
        vec4 bv;
        for (int j = 0; j < 4; ++j) {
            bv[j] = cell_vertex_b(g, cell_pos(t, j).xyz, sv[j], c[j]);
        }
        // What the rasterizer interpolates at p (known_exits_io.glsl's
        // emit_vertex: slot j carries lambda_j times vertex j's value).
        v_sf = dot(lambda, sv);
        v_d = lambda * c;
#ifdef EXACT_PERSPECTIVE
        v_g = dot(lambda, bv);
#else
        v_s = vec4(v_sf) + lambda * (bv - sv);
#endif
        v_rel = p - frame.eye;
        v_exits = exits;
        vec4 color = segment_color();
        integrated += 1u;
        // Front to back: this segment lies behind what is composited so far.
        acc += trans * color.rgb;
        trans *= 1.0 - color.a;
        done = trans < ERT_TRANSMITTANCE;
    }
    if (inside) {
        imageStore(target, px, vec4(acc, 1.0 - trans));
        if (integrated > 0u) {
            uint old = atomicAdd(counters.integrated_lo, integrated);
            if (old > 0xFFFFFFFFu - integrated) atomicAdd(counters.integrated_hi, 1u);
            atomicAdd(counters.covered, 1u);
        }
        if (done) atomicAdd(counters.terminated, 1u);
    }
}
