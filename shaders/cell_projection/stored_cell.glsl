// The balanced family's cells stored once on the device (resident.rs
// `stored`), and balanced's per-frame CPU half (IntersectBackFace,
// balanced.rs `cell_records`) run from them: resident.vert per vertex,
// pt_composite.comp per cell. Include common/frame.glsl first.
//
// Cell t is texels 9t..9t+8: pos[4] (xyz: position relative to the render
// origin; w: scalar), plane[4] (xyz: 3-float plane of the face opposite
// vertex i), gradient (xyz).
layout(set = 1, binding = 0) uniform samplerBuffer cells;
vec4 cell_pos(uint t, int i) { return texelFetch(cells, int(9u * t) + i); }
vec4 cell_plane(uint t, int i) { return texelFetch(cells, int(9u * t) + 4 + i); }
vec3 cell_gradient(uint t) { return texelFetch(cells, int(9u * t) + 8).xyz; }

bool stored_exact_perspective() {
#ifdef EXACT_PERSPECTIVE
    return frame.eye.w > 0.5;
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
        c[j] = exact ? perspective_plane_ratio(plane3, p - frame.eye.xyz) : distance_to_opposite_plane(plane3, ray_direction(p));
    }
    float half_limit = 0.5 * (exact ? frame.limits.y : frame.limits.x);
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
    return stored_exact_perspective() ? dot(g, pos - frame.eye.xyz) : dot(g, dir);
#else
    return sf + dot(dir, g) * ck;
#endif
}
