// The entry of the viewing ray into a cell, seen from a point inside it:
// exit.glsl's search mirrored (include exit.glsl first). Plane k crosses the
// ray behind the point where its exit classification is negative, so the
// planes exit_planes classifies as exits for -d are the entry planes, and
// the entry is the nearest of them behind the point. Returns the distance
// back to it and the scalar there; false when no entry plane lies in front
// of the eye (the eye is inside the cell: the ray starts in it).
bool entry_point(EXIT_VEC d, EXIT_VEC s, EXIT_VEC w, float s_here, float g_rel, vec3 rel,
                 out float len, out float s_entry) {
    len = frame.limits.x;
    s_entry = s_here;
    bool found = false;
#ifdef EXACT_PERSPECTIVE
    if (frame.eye.w > 0.5) {
        // d[k] = lambda_k u_k; the plane is met at mu = 1 / (1 - d[k]) times
        // eye-to-point, behind the point (0 < mu < 1) when d[k] < 0: at
        // distance (1 - mu) |rel| = u / (1 + u) |rel| with u = -d[k].
        EXIT_VEC entries = exit_planes(-d, w, 0.5 * frame.limits.y);
        float r = length(rel);
        for (int k = 0; k < EXIT_N; ++k) {
            float u = max(-d[k], 0.0);
            float m = u / (1.0 + u);
            if (exit_candidate(entries[k], w[k]) && m * r < len) {
                len = m * r;
                s_entry = s_here - m * g_rel;
                found = true;
            }
        }
        return found;
    }
#endif
    EXIT_VEC entries = exit_planes(-d, w, 0.5 * frame.limits.x);
    for (int k = 0; k < EXIT_N; ++k) {
        float dk = max(-d[k], 0.0);
        if (exit_candidate(entries[k], w[k]) && dk < len) {
            len = dk;
            s_entry = s[k];
            found = true;
        }
    }
    return found;
}
