// Shared by both ray casters: bindings, frame constants and the march
// (src/algo/raycast/mod.rs describes the conventions).
//
// Coordinates: "voxel coordinates" u = (p - origin) / spacing, sample
// (i, j, k) at u = (i, j, k) (node-centred, as the f64 reference); the box
// is [0, dims - 1]. The 3D texture has its texel centres at the samples:
// texture coordinate (u + 0.5) / dims.
//
// Build-time defines: SKIP (empty-space
// skipping over the brick grid), SHADE (Blinn-Phong), PREINT (pre-integrated
// segments instead of point samples).

#ifndef RAYCAST_COMMON_GLSL
#define RAYCAST_COMMON_GLSL

// Early termination's tail: steps per sample past the `ert` threshold, and
// the fraction of 1 - ert left when the ray stops.
#define TAIL_STRIDE 4
#define TAIL_STOP 0.01

#include "raycast/params.glsl"

#ifdef VOLUME_LOADS
// Read with imageLoad and blended here (option `reads`): on lavapipe a
// texture sample is an out-of-line call whose filter weights have 8 bits,
// an imageLoad is inlined.
layout(set = 0, binding = 1, VOLUME_FORMAT) uniform readonly image3D volume_img;
#else
layout(set = 0, binding = 1) uniform sampler3D volume_tex;
#endif
// The brick map: per brick 0 when some sample in it may have attenuation
// > 0, else the Chebyshev distance in bricks to the nearest such brick (at
// most 255); with COARSE_STRIDE a second byte, the distance to the nearest
// dense brick (option `coarse`). With VOLUME_LOADS the table and the map are
// read with loads too (the map's bytes as words): on lavapipe a texture
// lookup is an out-of-line call, around which the march spills its SIMD
// registers.
#ifdef VOLUME_LOADS
layout(set = 0, binding = 2, rgba32f) uniform readonly imageBuffer tf_table;
layout(set = 0, binding = 3, r32ui) uniform readonly uimageBuffer brick_words;
#else
layout(set = 0, binding = 2) uniform sampler1D tf_tex;
layout(set = 0, binding = 3) uniform usamplerBuffer brick_map;
#endif

// Brick i's entry: its distance in bits 0..7, with COARSE_STRIDE the
// distance to a dense brick in bits 8..15.
uint brick_entry(int i) {
#if defined(VOLUME_LOADS) && defined(COARSE_STRIDE)
    return (imageLoad(brick_words, i >> 1).r >> (16 * (i & 1))) & 0xFFFFu;
#elif defined(VOLUME_LOADS)
    return (imageLoad(brick_words, i >> 2).r >> (8 * (i & 3))) & 0xFFu;
#elif defined(COARSE_STRIDE)
    uvec2 e = texelFetch(brick_map, i).rg;
    return e.x | (e.y << 8);
#else
    return texelFetch(brick_map, i).r;
#endif
}
// Counters, cleared every frame: samples taken, largest per ray, bricks
// stepped over, rays, leaps, and of them the leaps over the ray's empty ends
// (trim_empty_ends).
layout(std430, set = 0, binding = 4) buffer Counters { uint total_samples; uint max_samples; uint skipped_bricks; uint rays; uint leaps; uint end_leaps; } counters;
layout(set = 0, binding = 5) uniform sampler2D preint_tex;

#include "raycast/frame.glsl"

#ifdef ADAPTIVE
// Adaptive refinement's structural key (algo/raycast/mod.rs, KEY_NEAR;
// docs/methods.md, "Structural keys"): the runs the last march made through
// bricks within ADAPTIVE_NEAR bricks of one with visible samples (0
// without SKIP), and the nearest such brick's distance it saw, up to
// frame.close (the bricks the coarse test rays' spacing spans). Dilated,
// structure closer together than 2 * ADAPTIVE_NEAR + 1 bricks is one run,
// not a key that differs between neighbouring rays almost everywhere (as
// the occupied bricks' own runs did on the chest CT); the distance tells
// apart rays that pass a small feature at different distances, so the
// blocks around a speck their rays straddle refine.
uint march_runs = 0u;
uint march_closest = 0xFFu;
bool march_in_run = false;   // the last brick looked up was within ADAPTIVE_NEAR
#endif

// The parameters the march reads in its loops, copied once per ray
// (load_march_constants, first thing in march): read from the uniform
// block inside the loop, llvmpipe loaded and converted them again every
// iteration (with the brick size's reciprocal for its divisions: 5 % of
// the chest CT's counted instructions, 9 % with quads).
struct MarchConstants {
    vec3 box_max;
    float tf_scale;
    float tf_offset;
    float table_entries;
    float brick;
    float inv_brick;   // exact for a power of two; else a point within an ulp of a brick face may find the brick beside it, whose flag covers the face too
    ivec3 brick_grid;
    float ert;
    vec3 inv_dims;
    float preint_length;
};
MarchConstants mc;

void load_march_constants() {
    mc = MarchConstants(params.box_max, params.tf_scale, params.tf_offset, params.table_entries, params.brick, 1.0 / params.brick,
                        ivec3(params.brick_grid), params.ert, params.inv_dims, params.preint_length);
}

// Samples are taken with an explicit level (single-level textures): the
// march loop is non-uniform control flow, where implicit derivatives are
// undefined, and the explicit level spares llvmpipe computing them.
#ifdef VOLUME_LOADS
// The trilinear field at voxel coordinate u, clamped to the box as the
// sampler's clamp-to-edge does (every axis has at least 2 samples).
float volume_at(vec3 u) {
    vec3 uc = clamp(u, vec3(0.0), mc.box_max);
    vec3 i = min(floor(uc), mc.box_max - 1.0);
    vec3 f = uc - i;
    ivec3 k = ivec3(i);
#ifdef VOLUME_QUADS
    // Each texel holds its sample and the +x, +y, +x+y neighbours
    // (reads=quads): two loads, the same blend as the eight below.
    vec4 q0 = imageLoad(volume_img, k);
    vec4 q1 = imageLoad(volume_img, k + ivec3(0, 0, 1));
    vec2 y0 = mix(vec2(q0.x, q1.x), vec2(q0.y, q1.y), f.x);
    vec2 y1 = mix(vec2(q0.z, q1.z), vec2(q0.w, q1.w), f.x);
#else
    float c000 = imageLoad(volume_img, k).r;
    float c100 = imageLoad(volume_img, k + ivec3(1, 0, 0)).r;
    float c010 = imageLoad(volume_img, k + ivec3(0, 1, 0)).r;
    float c110 = imageLoad(volume_img, k + ivec3(1, 1, 0)).r;
    float c001 = imageLoad(volume_img, k + ivec3(0, 0, 1)).r;
    float c101 = imageLoad(volume_img, k + ivec3(1, 0, 1)).r;
    float c011 = imageLoad(volume_img, k + ivec3(0, 1, 1)).r;
    float c111 = imageLoad(volume_img, k + ivec3(1, 1, 1)).r;
    vec2 y0 = mix(vec2(c000, c001), vec2(c100, c101), f.x);
    vec2 y1 = mix(vec2(c010, c011), vec2(c110, c111), f.x);
#endif
    vec2 z = mix(y0, y1, f.y);
    return mix(z.x, z.y, f.z);
}
#else
float volume_at(vec3 u) {
    return textureLod(volume_tex, (u + 0.5) * mc.inv_dims, 0.0).r;
}
#endif

float table_coord(vec3 u) {
    float v = volume_at(u);
    return clamp(mc.tf_scale * (v - mc.tf_offset), 0.0, 1.0);
}

// Table lookup at coordinate t in [0, 1], texel centres at the ends.
vec4 classify(float t) {
    float n = mc.table_entries;
#ifdef VOLUME_LOADS
    float x = t * (n - 1.0);
    float i = min(floor(x), n - 2.0);
    int k = int(i);
    return mix(imageLoad(tf_table, k), imageLoad(tf_table, k + 1), x - i);
#else
    return textureLod(tf_tex, (t * (n - 1.0) + 0.5) / n, 0.0);
#endif
}

vec3 gradient(vec3 u) {
    vec3 g;
    g.x = table_coord(u + vec3(1, 0, 0)) - table_coord(u - vec3(1, 0, 0));
    g.y = table_coord(u + vec3(0, 1, 0)) - table_coord(u - vec3(0, 1, 0));
    g.z = table_coord(u + vec3(0, 0, 1)) - table_coord(u - vec3(0, 0, 1));
    // Differences over 2 voxels; per world unit along world axes (anisotropic
    // spacing), the frame the light and eye directions are given in. The
    // common factor 1/2 does not change the normal.
    return g / params.spacing;
}

// Blinn-Phong with the central-difference gradient as normal; light and eye
// directions in the same (world-scaled voxel) frame.
vec3 shade(vec3 color, vec3 u, vec3 to_eye) {
    vec3 g = gradient(u);
    float len = length(g);
    if (len < 1e-6) return color * (params.ambient + params.diffuse);
    vec3 n = -g / len;
    vec3 l = frame.light;
    vec3 v = normalize(to_eye);
    // Two-sided: a surface seen from behind is lit as well.
    if (dot(n, v) < 0.0) n = -n;
    vec3 h = normalize(l + v);
    float diff = max(dot(n, l), 0.0);
    float spec = pow(max(dot(n, h), 0.0), params.shininess);
    return color * (params.ambient + params.diffuse * diff) + vec3(params.specular * spec);
}

#ifdef SKIP
// A ray a + s * dir (voxel coordinates, |dir| = 1) cut into steps of h
// voxels, step k's middle at s = (k + 0.5) h, as the brick map is looked
// up. Axes the ray is parallel to never bound a leap (`moving`).
struct MarchRay { vec3 a; vec3 dir; vec3 inv_dir; bvec3 moving; float h; };

vec3 step_middle(MarchRay r, int k) {
    return r.a + r.dir * (r.h * (float(k) + 0.5));
}

// The map entry of the brick holding u (clamped to the grid), and the brick.
uint brick_at(vec3 u, out ivec3 bc) {
    ivec3 g = mc.brick_grid;
    bc = clamp(ivec3(floor(u * mc.inv_brick)), ivec3(0), g - 1);
    return brick_entry(bc.x + g.x * (bc.y + g.y * bc.z));
}

// The cube of bricks within `reach` voxels of brick bc: [lo, lo + edge]
// on every axis. A brick's flag covers its samples and the next layer, so
// a middle on the far face of an unflagged cube is empty too.
vec3 cube_low(ivec3 bc, float reach) {
    return vec3(bc) * mc.brick - reach;
}

// The first step whose middle lies past the ray's exit from the cube
// (a middle at or before it inside the cube), at most `steps`.
int step_past_cube(MarchRay r, vec3 lo, float edge, int steps) {
    vec3 far_face = mix(lo, lo + edge, greaterThan(r.dir, vec3(0.0)));
    vec3 s_axis = mix(vec3(1e30), (far_face - r.a) * r.inv_dir, r.moving);
    float s_exit = min(min(s_axis.x, s_axis.y), s_axis.z);
    return min(int(floor(s_exit / r.h - 0.5)) + 1, steps);
}

// The first step whose middle lies at or past the ray's entry into the
// cube (a middle after it inside the cube), at least `k`.
int step_into_cube(MarchRay r, vec3 lo, float edge, int k) {
    vec3 near_face = mix(lo + edge, lo, greaterThan(r.dir, vec3(0.0)));
    vec3 s_axis = mix(vec3(-1e30), (near_face - r.a) * r.inv_dir, r.moving);
    float s_in = max(max(s_axis.x, s_axis.y), s_axis.z);
    return max(int(ceil(s_in / r.h - 0.5)), k);
}

// The bricks a run of skipped steps passes through: one plus the brick
// faces crossed between its first and last middles.
uint bricks_between(vec3 first, vec3 last) {
    ivec3 crossed = abs(ivec3(floor(last * mc.inv_brick)) - ivec3(floor(first * mc.inv_brick)));
    return uint(1 + crossed.x + crossed.y + crossed.z);
}

#ifdef ADAPTIVE
// The key's bookkeeping at a lookup of a brick at distance `dist`: its
// runs are entries into bricks within ADAPTIVE_NEAR of an occupied one. A
// leap from outside them is shortened so its cube holds none of them (each
// brick of it is at least dist - reach bricks from an occupied one): the
// reach (voxels) of the leap's cube.
float adaptive_reach(uint dist) {
    bool near = dist <= ADAPTIVE_NEAR;
    if (near && !march_in_run) march_runs += 1u;
    march_closest = min(march_closest, dist);
    march_in_run = near;
    return float(near ? max(dist, 1u) - 1u : dist - 1u - ADAPTIVE_NEAR) * mc.brick;
}
#endif

// The empty ends of the ray, in loops of their own before the march: leaps
// from the first step over empty cubes up to the first visible brick, and
// from the last step back to the last one. In the march's loop a leap costs
// an iteration as dear as a sample (llvmpipe runs the sample code masked),
// here only the lookup. Steps in empty bricks add nothing, so the image is
// the march's over all steps: the march's segments keep their lengths
// (a tail or coarse segment begun before `end` still runs past it) and
// only the loop stops at `end`. With ADAPTIVE the forward loop takes the
// march's own leaps with the key's bookkeeping (the same lookups, so the
// same key); the backward one is left out, as the key counts runs in the
// march's order.
void trim_empty_ends(MarchRay r, int steps, inout int k, inout int end, inout uint skipped, inout uint leaps) {
    while (k < end) {
        ivec3 bc;
        vec3 um = step_middle(r, k);
        uint dist = brick_at(um, bc) & 0xFFu;
        if (dist == 0u) break;
#ifdef ADAPTIVE
        float reach = adaptive_reach(dist);
#else
        float reach = float(dist - 1u) * mc.brick;
#endif
        int last = max(k + 1, step_past_cube(r, cube_low(bc, reach), mc.brick + 2.0 * reach, end));
        skipped += bricks_between(um, step_middle(r, last - 1));
        leaps += 1u;
        k = last;
    }
#ifndef ADAPTIVE
    while (end > k) {
        ivec3 bc;
        vec3 um = step_middle(r, end - 1);
        uint dist = brick_at(um, bc) & 0xFFu;
        if (dist == 0u) break;
        float reach = float(dist - 1u) * mc.brick;
        int first = min(end - 1, step_into_cube(r, cube_low(bc, reach), mc.brick + 2.0 * reach, k));
        skipped += bricks_between(step_middle(r, first), um);
        leaps += 1u;
        end = first;
    }
#endif
}
#endif

// The segment [a, b] (voxel coordinates, a nearer the eye) marched with a step
// of at most `step` voxels: n = ceil(L / step) equal steps, one sample at the
// middle of each, opacity 1 - exp(-tau * world length of the step), i.e. the
// lab's alpha' = 1 - (1 - alpha)^(ds / ds0) with alpha given by tau. Past
// the `ert` threshold one sample covers TAIL_STRIDE steps (its middle, or
// its end for PREINT) until the opacity passes 1 - TAIL_STOP (1 - ert). Returns
// premultiplied RGBA; `samples` counts texture samples of the volume.
vec4 march(vec3 a, vec3 b, out uint samples) {
    load_march_constants();
    samples = 0u;
    vec4 acc = vec4(0.0);
    vec3 d = b - a;
    float len = length(d);
    if (!(len > 0.0)) return acc;
    vec3 dir = d / len;
    float n = ceil(len / params.step);
    float h = len / n;
    float world_h = h * length(dir * params.spacing);
    vec3 to_eye_world = -dir * params.spacing;
    int steps = int(n);
    int k = 0;
    int end = steps;   // the loop's last step + 1 (trim_empty_ends)
#ifdef SKIP
    float bsize = mc.brick;
    MarchRay ray = MarchRay(a, dir, 1.0 / dir, notEqual(dir, vec3(0.0)), h);
    uint skipped = 0u;
    uint leaps = 0u;
    uint end_leaps = 0u;
    int check_at = 0;   // the next step whose brick must be looked up
#ifdef COARSE_STRIDE
    bool coarse = false;   // the steps up to check_at lie in a thin cube
#endif
#ifdef ADAPTIVE
    march_in_run = false;
    march_runs = 0u;
    march_closest = 0xFFu;
#endif
    trim_empty_ends(ray, steps, k, end, skipped, end_leaps);
    leaps = end_leaps;
#endif
#ifdef PREINT
    // The first segment's front (after a trimmed start, read as after a leap).
    float t_prev = -1.0;
    float t_prev2 = -1.0;
    if (k == 0) {
        t_prev = table_coord(a);
        samples += 1u;
    }
#endif
    int stride = 1;   // steps one sample covers: 1, or the tail stride past the ert threshold
    float tail_stop = 1.0 - (1.0 - mc.ert) * TAIL_STOP;
    while (k < end) {
        int m = min(stride, steps - k);
#ifdef SKIP
        // The brick holding the step's middle, looked up once per brick. At
        // distance d it is the centre of an empty cube of 2d - 1 bricks (the
        // brick alone for d = 0, 1): the steps up to the first middle past
        // the cube's exit lie in it (a box is convex). An empty cube's steps
        // (their trilinear neighbourhoods have zero attenuation) are skipped
        // in one iteration, the same steps as one by one; a flagged brick's
        // are sampled without further lookups.
        if (k >= check_at) {
            ivec3 bc;
            vec3 um = step_middle(ray, k);
            uint entry = brick_at(um, bc);
            uint dist = entry & 0xFFu;
#ifdef ADAPTIVE
            float reach = adaptive_reach(dist);
#elif defined(COARSE_STRIDE)
            // A visible brick at distance d >= 1 from a dense one is the
            // centre of a cube of 2d - 1 bricks with no dense brick: its
            // steps up to the cube's exit are marched coarse (option
            // `coarse`), without looking their bricks up.
            uint to_dense = entry >> 8;
            coarse = dist == 0u && to_dense >= 1u;
            float reach = float(max(dist == 0u ? to_dense : dist, 1u) - 1u) * bsize;
#else
            float reach = float(max(dist, 1u) - 1u) * bsize;
#endif
            int next = step_past_cube(ray, cube_low(bc, reach), bsize + 2.0 * reach, steps);
            if (dist != 0u) {
                int last = max(k + 1, next);
                skipped += bricks_between(um, step_middle(ray, last - 1));
                leaps += 1u;
#ifdef PREINT
                t_prev = -1.0;
                t_prev2 = -1.0;
#endif
                k = last;
                continue;
            }
            check_at = max(next, k + 1);
        }
#endif
#ifdef COARSE_STRIDE
        // One sample for up to COARSE_STRIDE steps, every step's middle in
        // the thin cube (check_at <= steps).
        if (coarse) m = min(max(stride, COARSE_STRIDE), check_at - k);
#endif
        float seg_world = world_h * float(m);
#ifdef PREINT
        vec3 u = a + dir * (h * float(k + m));
#else
        vec3 u = a + dir * (h * (float(k) + 0.5 * float(m)));
#endif
        float t = table_coord(u);
        samples += 1u;
#ifdef PREINT
        // After a skip: the segment's front, and for a unit step the sample
        // before it (the curvature term's), as the march without skipping
        // has them, so skipping leaves the image unchanged.
        if (t_prev < 0.0) {
            t_prev = table_coord(u - dir * (h * float(m)));
            samples += 1u;
            if (m == 1 && k >= 1) { t_prev2 = table_coord(u - dir * (h * 2.0)); samples += 1u; }
        }
        // Table over (front, back) for a segment of preint_length world
        // units: colour premultiplied and optical depth, scaled to this step.
        vec2 fb = vec2(t_prev, t);
        // Curvature: the scalar along the ray is not linear between samples
        // (trilinear field). The parabola through this and the two previous
        // samples has, over this segment, the mean of the linear one minus
        // D / 12 (D the second difference): both ends are moved by that, so
        // the segment's mean scalar is second-order right. Without it the
        // linear segment's error (s'' h^2 / 12) is twice the midpoint rule's
        // and point sampling beats pre-integration on smooth data.
        if (t_prev2 >= 0.0) fb = clamp(fb - (t - 2.0 * t_prev + t_prev2) / 12.0, 0.0, 1.0);
        vec4 seg = textureLod(preint_tex, fb * (mc.table_entries - 1.0) / mc.table_entries + 0.5 / mc.table_entries, 0.0);
        t_prev2 = m == 1 ? t_prev : -1.0;
        t_prev = t;
        float scale = seg_world / mc.preint_length;
        float alpha = 1.0 - exp(-seg.a * scale);
        // Colour per unit opacity from the table (exact when the step matches the table's length).
        float table_alpha = 1.0 - exp(-seg.a);
        vec3 c = table_alpha > 1e-7 ? seg.rgb / table_alpha : vec3(0.0);
#else
        vec4 tf = classify(t);
        float alpha = 1.0 - exp(-max(tf.a, 0.0) * seg_world);
        vec3 c = tf.rgb;
#endif
#ifdef SHADE
        if (alpha > 0.0) c = shade(c, u, to_eye_world);
#endif
        acc.rgb += (1.0 - acc.a) * alpha * c;
        acc.a += (1.0 - acc.a) * alpha;
        k += m;
        // Early ray termination (run-time threshold `ert`; 1 never
        // triggers). Past the threshold the rest of the ray is not dropped
        // but estimated: marched TAIL_STRIDE steps per sample until the
        // remaining transmittance is below 1% of 1 - ert (see the module note).
        if (acc.a > mc.ert) {
            if (acc.a > tail_stop) break;
            stride = TAIL_STRIDE;
        }
    }
    // The ray's counts, added to the counters once.
#ifdef SKIP
    uint n_skipped = skipped;
    uint n_leaps = leaps;
    uint n_end_leaps = end_leaps;
#endif
    uint n_samples = samples;
    uint n_max = samples;
    uint n_rays = 1u;
    bool adds = true;
#ifdef SUBGROUP_COUNTERS
    // One atomic per counter and subgroup, not per ray (compute only,
    // where the device has subgroup arithmetic: raycast/compute.rs): on
    // lavapipe a per-ray atomic is a loop over the SIMD lanes, each lane's
    // add a locked instruction on the one cache line both threads update.
#ifdef SKIP
    n_skipped = subgroupAdd(n_skipped);
    n_leaps = subgroupAdd(n_leaps);
    n_end_leaps = subgroupAdd(n_end_leaps);
#endif
    n_samples = subgroupAdd(n_samples);
    n_max = subgroupMax(n_max);
    n_rays = subgroupAdd(n_rays);
    adds = subgroupElect();
#endif
    if (adds) {
#ifdef SKIP
        atomicAdd(counters.skipped_bricks, n_skipped);
        atomicAdd(counters.leaps, n_leaps);
        atomicAdd(counters.end_leaps, n_end_leaps);
#endif
        atomicAdd(counters.total_samples, n_samples);
        atomicMax(counters.max_samples, n_max);
        atomicAdd(counters.rays, n_rays);
    }
    return acc;
}

// The viewing ray through NDC (x, y): its points on the near and far planes
// in voxel coordinates (the depth range the reference clips to).
void ndc_ray(vec2 ndc, out vec3 p_near, out vec3 p_far) {
    vec4 a = frame.m * vec4(ndc, 0.0, 1.0);
    vec4 b = frame.m * vec4(ndc, 1.0, 1.0);
    p_near = a.xyz / a.w;
    p_far = b.xyz / b.w;
}

// Clip the segment [p, q] to the box [0, box_max] (slab test); false when it misses.
bool clip_to_box(inout vec3 p, inout vec3 q) {
    vec3 d = q - p;
    float t0 = 0.0, t1 = 1.0;
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0) {
            if (p[a] < 0.0 || p[a] > params.box_max[a]) return false;
            continue;
        }
        float ta = (0.0 - p[a]) / d[a];
        float tb = (params.box_max[a] - p[a]) / d[a];
        t0 = max(t0, min(ta, tb));
        t1 = min(t1, max(ta, tb));
    }
    if (t0 >= t1) return false;
    vec3 p0 = p;
    p = p0 + d * t0;
    q = p0 + d * t1;
    return true;
}

#endif
