// Choosing the exit plane in the fragment stage, shared by VICP (3 planes)
// and balanced (4 planes). Define EXIT_VEC (vec3/vec4) and EXIT_N first.
//
// d[k] interpolates lambda_k * t_k: t_k is the ray-plane distance computed at
// vertex k for the plane opposite it (0 at the other vertices), lambda_k the
// fragment's barycentric weight of vertex k. The paper's rule takes the
// smallest positive d[k]. Near the edge where lambda_k -> 0 the exit through
// plane k is at distance ~0, and rasterizer rounding (lambda_k = -1e-7) can
// make d[k] slightly negative: the paper's rule then skips that plane and picks
// the next one, possibly a whole cell too far (bright specks along edges seen
// edge-on). The robust rule (default) also interpolates w[k] = lambda_k: the
// ratio d[k]/w[k] = t_k exactly, so its sign tells an exit plane (t_k > 0)
// from an entry plane whatever the rounding of d[k], and an exit plane's
// distance is clamped at 0 (how t_k's sign is found where lambda_k ~ 0:
// exit_planes below). Build with PAPER_EXIT_RULE for the paper's rule.
// Optionally, a plane with |lambda_k| < frame.edge_eps (edge epsilon, off by
// default) passes through the fragment's ray to within rounding and counts
// as an exit at distance 0, whatever t_k's sign. Near an edge shared by two
// entry faces that loses one cell's contribution to a pixel (at most ~1e-5 of
// a face's area); choosing the next plane instead could add a whole cell, or
// with a nearly edge-on plane many (bright specks). The plane of the face
// being drawn (balanced) has w = 0 exactly at all three vertices, hence
// exactly 0 everywhere, and is never an exit.
//
// Whatever the rule, the same rounding near a nearly edge-on plane can still
// reject the true exit and accept one far away. No segment through a cell is
// longer than the mesh's longest cell edge (view_dir.w), so a longer exit
// distance can only come from such rounding: that fragment contributes
// nothing rather than an arbitrarily opaque speck.
//
// With EXACT_PERSPECTIVE under perspective, d[k] interpolates lambda_k * u_k
// instead (see perspective_plane_ratio): the plane is met at
// mu = 1 / (1 - d[k]) times the eye-to-fragment vector, an exit when mu > 1,
// i.e. 0 < d[k] < 1; the exit distance is (mu - 1) |p - eye| and the scalar
// there s_f + (mu - 1) g.(p - eye), with g.(p - eye) = g_rel interpolated
// (affine, so exact too).

// Compute stages (no derivatives) define KNOWN_EXITS_ONLY: only
// exit_point_known below.
#ifndef KNOWN_EXITS_ONLY
// Classifying planes through the fragment (stress case "axis-ortho": pixel
// centres exactly on edges). d[k] and w[k] are both 0 at a fragment on an
// edge of the face, exactly so when coordinates are exact in binary, and
// sign(d * w) then says nothing; llvmpipe interpolates each attribute from
// its own plane equation, so near 0 the two signs can also disagree. Either
// way an exit plane through the fragment was rejected and the next plane, a
// cell or more away, taken instead (max error 0.165 in that case).
// Whether plane k is an exit does not depend on where on the face the
// fragment lies: it is the sign of the per-vertex value c_k = d[k] / w[k]
// (t_k, or u_k for exact perspective), since d[k] = c_k w[k] as functions
// over the face. Where |w[k]| is small that ratio is 0/0, but the screen-space
// derivatives keep it: grad d[k] = c_k grad w[k], and over a pixel w[k]
// changes by ~1/(face size in pixels), far above rounding. The plane of the
// face being drawn (balanced: w = 0 everywhere, grad w = 0) gets c = 0 and is
// never an exit. A |c| at the clamp (ray parallel to the plane, n.d = 0,
// or the eye in the plane) is no crossing at all: the ray lies in the plane
// or never reaches it, so the plane cannot end the segment.
// Returns, per plane, +1 for an exit plane (c > 0 and below `parallel`), 0
// otherwise; computed without divisions (sign(c) = sign(d w), and
// |c| < parallel <=> |d| < parallel |w|), from the derivatives where w ~ 0.
EXIT_VEC exit_planes(EXIT_VEC d, EXIT_VEC w, float parallel) {
    EXIT_VEC ddx = dFdx(d), ddy = dFdy(d), wdx = dFdx(w), wdy = dFdy(w);
    EXIT_VEC near_edge = step(abs(w), EXIT_VEC(1e-3));  // 1 where |w| < 1e-3
    // Where |w| is small use the gradients: d ~ c w and grad d = c grad w.
    EXIT_VEC num = mix(d * w, ddx * wdx + ddy * wdy, near_edge);
    EXIT_VEC den = mix(w * w, wdx * wdx + wdy * wdy, near_edge);  // c = num / den, den >= 0
    EXIT_VEC is_exit = EXIT_VEC(greaterThan(num, EXIT_VEC(0.0))) * EXIT_VEC(greaterThan(den, EXIT_VEC(0.0)))
        * EXIT_VEC(lessThan(num, parallel * den));
    return is_exit;
}

// Plane k bounds the segment: an exit plane, or with the optional edge
// epsilon any plane through the fragment.
bool exit_candidate(float is_exit, float w) {
    return is_exit > 0.5 || (w != 0.0 && abs(w) < frame.edge_eps);
}

bool exit_point(EXIT_VEC d, EXIT_VEC s, EXIT_VEC w, float s_front, float g_rel, vec3 rel,
                out float len, out float s_back) {
    len = frame.distance_clamp;
    s_back = s_front;
    bool found = false;
#ifdef EXACT_PERSPECTIVE
    if (frame.perspective > 0.5) {
        EXIT_VEC exits = exit_planes(d, w, 0.5 * frame.plane_ratio_max);
        float r = length(rel);
        for (int k = 0; k < EXIT_N; ++k) {
            bool is_exit = exit_candidate(exits[k], w[k]) && d[k] < 1.0;
            float u = max(d[k], 0.0);
            float mu_minus_1 = u / (1.0 - u);
            float dk = mu_minus_1 * r;
            if (is_exit && dk < len) {
                len = dk;
                s_back = s_front + mu_minus_1 * g_rel;
                found = true;
            }
        }
        return found && len <= frame.max_segment;
    }
#endif
    EXIT_VEC exits = exit_planes(d, w, 0.5 * frame.distance_clamp);
    for (int k = 0; k < EXIT_N; ++k) {
#ifdef PAPER_EXIT_RULE
        bool is_exit = d[k] > 0.0;
        float dk = d[k];
#else
        bool is_exit = exit_candidate(exits[k], w[k]);
        float dk = max(d[k], 0.0);
#endif
        if (is_exit && dk < len) {
            len = dk;
            s_back = s[k];
            found = true;
        }
    }
    return found && len <= frame.max_segment;
}

#endif  // KNOWN_EXITS_ONLY

// The balanced family knows each tet's exit planes: `exits` bit k says
// plane k is one for every ray through the tet (balanced.rs `exit_mask`:
// the sign test exit_planes makes, on the per-vertex value c_k itself), so
// the fragment only takes the nearest, with no derivatives and nothing for
// rounding to flip: near an edge d[k] = lambda_k c_k rounds to about 0,
// which is where that exit is. The farther-than-any-cell guard stays.
const float NO_EXIT = 3.0e38;

#ifdef EXACT_PERSPECTIVE
// Perspective: plane k is met at mu = 1 / (1 - d[k]) times p - eye, ahead
// only when d[k] < 1 (beyond, the ray moves away from the plane); with
// m = mu - 1 = d / (1 - d), the exit is m |p - eye| away and its scalar
// s_f + m g.(p - eye). Orthographic: d[k] is the distance and the scalar
// changes by g.view_dir per unit length. `g` is the matching gradient term.
// The segment also stops at the far plane, measured in the same m (the ray
// from the fragment is p + m (p - eye), or p + m view_dir): far_distance of
// common/clip.glsl (include it first) along that unnormalised direction,
// which needs no square root or division per fragment beyond its own.
bool exit_point_known(vec4 d, uint exits, float s_front, float g, vec3 rel, out float len, out float s_back) {
    bool perspective = frame.perspective > 0.5;
    uvec4 known = uvec4(notEqual(uvec4(exits) & uvec4(1u, 2u, 4u, 8u), uvec4(0u)));
    uvec4 ahead = uvec4(lessThan(d, vec4(perspective ? 1.0 : NO_EXIT)));
    vec4 x = mix(vec4(NO_EXIT), max(d, 0.0), bvec4(known & ahead));
    float p = min(min(x.x, x.y), min(x.z, x.w));
    float m = perspective ? p / (1.0 - p) : p;
    float r = perspective ? length(rel) : 1.0;
    bool found = p < NO_EXIT && m * r <= frame.max_segment;
    // A NaN (ray in the far plane) or farther distance changes nothing.
    float m_far = far_distance(rel, perspective ? rel : frame.view_dir);
    if (m_far < m) {
        m = max(m_far, 0.0);
    }
    len = m * r;
    s_back = s_front + m * g;
    return found;
}
#else
// The papers' records: d[k] is the distance, s[k] the scalar there.
bool exit_point_known(vec4 d, uint exits, vec4 s, float s_front, out float len, out float s_back) {
    len = NO_EXIT;
    s_back = s_front;
    for (int k = 0; k < 4; ++k) {
        float dk = max(d[k], 0.0);
        if (((exits >> uint(k)) & 1u) != 0u && dk < len) {
            len = dk;
            s_back = s[k];
        }
    }
    return len <= frame.max_segment;
}
#endif
