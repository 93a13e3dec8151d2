// The balanced family's cells stored once on the device (resident.rs
// `stored`), and balanced's per-frame CPU half (IntersectBackFace,
// balanced.rs `cell_records`) run from them: resident_expand.comp and
// pt_composite.comp per cell, resident.vert (resident-gpusort) per vertex.
// Include common/frame.glsl first.
//
// Cell t is texels 9t..9t+8: pos[4] (xyz: position relative to the render
// origin; w: scalar), plane[4] (xyz: 3-float plane of the face opposite
// vertex i), gradient (xyz).
//
// A mesh larger than one texel buffer may hold (algo/chunks.rs) comes in
// CELL_CHUNKS buffers of CELL_PER_CHUNK cells: chunk 0 at binding 0, chunk
// k at binding CELL_CHUNK_BINDING + k - 1.
#ifndef CELL_CHUNKS
#define CELL_CHUNKS 1
#endif
// The set holding the cells (resident_expand.comp: 0).
#ifndef CELL_SET
#define CELL_SET 1
#endif
layout(set = CELL_SET, binding = 0, rgba32f) uniform readonly imageBuffer cells;
#if CELL_CHUNKS > 1
layout(set = CELL_SET, binding = CELL_CHUNK_BINDING + 0, rgba32f) uniform readonly imageBuffer cells_1;
#endif
#if CELL_CHUNKS > 2
layout(set = CELL_SET, binding = CELL_CHUNK_BINDING + 1, rgba32f) uniform readonly imageBuffer cells_2;
#endif
#if CELL_CHUNKS > 3
layout(set = CELL_SET, binding = CELL_CHUNK_BINDING + 2, rgba32f) uniform readonly imageBuffer cells_3;
#endif
#if CELL_CHUNKS > 4
layout(set = CELL_SET, binding = CELL_CHUNK_BINDING + 3, rgba32f) uniform readonly imageBuffer cells_4;
#endif
#if CELL_CHUNKS > 5
layout(set = CELL_SET, binding = CELL_CHUNK_BINDING + 4, rgba32f) uniform readonly imageBuffer cells_5;
#endif
#if CELL_CHUNKS > 6
layout(set = CELL_SET, binding = CELL_CHUNK_BINDING + 5, rgba32f) uniform readonly imageBuffer cells_6;
#endif
#if CELL_CHUNKS > 7
layout(set = CELL_SET, binding = CELL_CHUNK_BINDING + 6, rgba32f) uniform readonly imageBuffer cells_7;
#endif

// Texel k (0..8) of cell t.
vec4 cell_texel(uint t, int k) {
#if CELL_CHUNKS > 1
    uint c = t / uint(CELL_PER_CHUNK);
    int i = int(9u * (t - c * uint(CELL_PER_CHUNK))) + k;
    switch (c) {
#if CELL_CHUNKS > 1
    case 1u: return imageLoad(cells_1, i);
#endif
#if CELL_CHUNKS > 2
    case 2u: return imageLoad(cells_2, i);
#endif
#if CELL_CHUNKS > 3
    case 3u: return imageLoad(cells_3, i);
#endif
#if CELL_CHUNKS > 4
    case 4u: return imageLoad(cells_4, i);
#endif
#if CELL_CHUNKS > 5
    case 5u: return imageLoad(cells_5, i);
#endif
#if CELL_CHUNKS > 6
    case 6u: return imageLoad(cells_6, i);
#endif
#if CELL_CHUNKS > 7
    case 7u: return imageLoad(cells_7, i);
#endif
    default: return imageLoad(cells, i);
    }
#else
    return imageLoad(cells, int(9u * t) + k);
#endif
}
vec4 cell_pos(uint t, int i) { return cell_texel(t, i); }
vec4 cell_plane(uint t, int i) { return cell_texel(t, 4 + i); }
vec3 cell_gradient(uint t) { return cell_texel(t, 8).xyz; }

bool stored_exact_perspective() {
#ifdef EXACT_PERSPECTIVE
    return frame.perspective > 0.5;
#else
    return false;
#endif
}

// c_j for the four vertices (the ray-plane distance t, or with exact
// perspective the plane ratio u) and the tet's exit mask (balanced.rs
// `exit_mask`).
vec4 cell_view_values(uint t, out uint exits) {
    bool exact = stored_exact_perspective();
    vec4 c;
    for (int j = 0; j < 4; ++j) {
        vec3 p = cell_pos(t, j).xyz;
        vec3 plane3 = cell_plane(t, j).xyz;
        c[j] = exact ? perspective_plane_ratio(plane3, p - frame.eye) : distance_to_opposite_plane(plane3, ray_direction(p));
    }
    float half_limit = 0.5 * (exact ? frame.plane_ratio_max : frame.distance_clamp);
    uvec4 bits = uvec4(greaterThan(c, vec4(0.0))) * uvec4(lessThan(c, vec4(half_limit))) * uvec4(1u, 2u, 4u, 8u);
    exits = bits.x | bits.y | bits.z | bits.w;
    return c;
}

// The record's b of a vertex at `pos` with scalar `sf` and value `ck`: s_b
// where its ray meets the opposite plane (the papers'), or with exact
// interpolation the gradient term.
float cell_vertex_b(vec3 g, vec3 pos, float sf, float ck) {
    vec3 dir = ray_direction(pos);
#ifdef EXACT_PERSPECTIVE
    return stored_exact_perspective() ? dot(g, pos - frame.eye) : dot(g, dir);
#else
    return sf + dot(dir, g) * ck;
#endif
}
