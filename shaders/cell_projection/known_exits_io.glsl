// The varyings of the balanced family (balanced.vert, resident.vert and
// atfs.vert feed balanced.frag and atfs.frag), declared once for both
// stages: define KNOWN_EXITS_VERTEX in the vertex stage (which includes
// common/clip.glsl first); the fragment stage includes common/exit.glsl
// first. The exit planes are known per tet (a
// flat mask, cell_projection/record.glsl), so only what the exit distance
// and scalar need is interpolated: 9 floats with exact interpolation, 12
// with the papers' (the robust choice from derivatives needed 17).
// A compute stage (pt_composite.comp) defines KNOWN_EXITS_COMPUTE: the
// same names are then plain globals it sets per pixel before known_exit.
#if defined(KNOWN_EXITS_VERTEX)
#define IO(n) layout(location = n) out
#define FLAT_IO(n) layout(location = n) flat out
#elif defined(KNOWN_EXITS_COMPUTE)
#define IO(n)
#define FLAT_IO(n)
#else
#define IO(n) layout(location = n) in
#define FLAT_IO(n) layout(location = n) flat in
#endif
IO(0) float v_sf;         // s_f: the scalar at the fragment
IO(1) vec4 v_d;           // lambda_k c_k (c: the vertex's t, or u with exact perspective)
#ifdef EXACT_PERSPECTIVE
IO(2) float v_g;          // g.(p - eye) under perspective, g.view_dir orthographic
#else
IO(2) vec4 v_s;           // s_b where each vertex's ray meets its plane (the papers')
#endif
IO(3) vec3 v_rel;         // p - eye
FLAT_IO(4) uint v_exits;  // bit k: plane k is an exit plane
#undef IO
#undef FLAT_IO

#ifdef KNOWN_EXITS_VERTEX
// Vertex k of its tet at `pos` with its view-dependent value c, scalar s_f,
// the record's b (balanced.rs `cell_records`) and the tet's exit mask: each
// vector holds this vertex's value in slot k and 0 (d) or s_f (s) elsewhere,
// so that interpolated over a face slot k carries lambda_k times it.
void emit_vertex(vec3 pos, int k, float c, float sf, float b, uint exits) {
    vec4 d = vec4(0.0);
    d[k] = c;
    v_sf = sf;
    v_d = d;
#ifdef EXACT_PERSPECTIVE
    v_g = b;
#else
    vec4 s = vec4(sf);
    s[k] = b;
    v_s = s;
#endif
    v_rel = pos - frame.eye;
    v_exits = exits;
    gl_Position = clip_position(pos);
    gl_ClipDistance[0] = eye_plane_distance(gl_Position);
}
#else
// This fragment's exit, stopped at the far plane: distance and scalar
// (common/exit.glsl; include common/clip.glsl and it first).
bool known_exit(out float len, out float s_back) {
#ifdef EXACT_PERSPECTIVE
    return exit_point_known(v_d, v_exits, v_sf, v_g, v_rel, len, s_back);
#else
    bool found = exit_point_known(v_d, v_exits, v_s, v_sf, len, s_back);
    clamp_to_far(v_rel, v_sf, len, s_back);
    return found;
#endif
}

// Balanced's fragment colour (also pt-compute's per pixel and cell): the
// nearest known exit, the segment started at the near plane, integrated
// (include common/integrate.glsl first).
vec4 segment_color() {
    float len;
    float sb;
    if (!known_exit(len, sb)) {
        return vec4(0.0);
    }
    float sf = v_sf;
    start_at_near(v_rel, sf, len, sb);
    return integrate_segment(sf, sb, len);
}
#endif
