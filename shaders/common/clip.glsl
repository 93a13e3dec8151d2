// The camera's near and far planes in the fragment stage, where the
// rasterizer clips: clip-space z = 0 (near) and z = w (far), read from the
// rows of view_proj so that no extra constant is needed. Distances are
// along the viewing ray through the fragment (unit direction), from the
// fragment's point eye + rel. The f64 reference clips every ray to the same
// depth range, so a segment that crosses the far plane stops there, and a
// cell cut by the near plane is integrated from it (start_at_near).

vec4 clip_row(int r) {
    return vec4(frame.view_proj[0][r], frame.view_proj[1][r], frame.view_proj[2][r], frame.view_proj[3][r]);
}

// Signed distance to the plane where dot(plane, (p, 1)) = 0, increasing
// (plane value) along the ray: negative when the plane is behind.
float plane_distance(vec4 plane, vec3 rel, vec3 dir) {
    return -dot(plane, vec4(frame.eye.xyz + rel, 1.0)) / dot(plane.xyz, dir);
}

float near_distance(vec3 rel, vec3 dir) {
    return plane_distance(clip_row(2), rel, dir);
}

float far_distance(vec3 rel, vec3 dir) {
    return plane_distance(clip_row(2) - clip_row(3), rel, dir);
}

// The one clip plane of the cell pipelines (gl_ClipDistance[0] of the
// vertex stage), which draw without near/far clipping (depth clamp): just in
// front of the eye, at a ten-thousandth of the longest cell edge but at
// most half the near distance, so that no vertex at or behind the eye (clip
// w <= 0, e.g. the eye on a mesh vertex) reaches the rasterizer and nothing
// behind the near plane is clipped. Clip w is the depth along the view
// direction; orthographic views have no eye plane.
float eye_plane_distance(vec4 clip_pos) {
    if (frame.eye.w < 0.5) {
        return 1.0;
    }
    float near = near_distance(vec3(0.0), frame.view_dir.xyz);
    return clip_pos.w - min(1e-4 * frame.view_dir.w, 0.5 * near);
}

// Starts the segment [0, len] from the fragment at the near plane when the
// fragment lies in front of it, the scalar at its start moved alike. The
// cell pipelines draw without near/far clipping (depth clamp), so a cell
// cut by the near plane keeps all its entry-face fragments and each
// integrates from the later of its entry point and the near plane: the
// result is continuous across the section, where a clipped face (its
// vertices snapped to the rasterizer's sub-pixel grid) plus a cap for the
// cut part left single pixels with the cell twice or never. A fragment
// whose whole segment lies in front of the plane keeps length 0.
void start_at_near(vec3 rel, inout float s_front, inout float len, float s_back) {
    float t = near_distance(rel, ray_direction(frame.eye.xyz + rel));
    if (t > 0.0) {
        float cut = min(t, len);
        s_front += (s_back - s_front) * (len > 0.0 ? cut / len : 0.0);
        len -= cut;
    }
}

// Stops the segment [0, len] from the fragment at the far plane, the scalar
// at its end moved alike (linear along the segment). A NaN distance (ray in
// the plane) or one beyond the segment changes nothing.
void clamp_to_far(vec3 rel, float s_front, inout float len, inout float s_back) {
    float t = far_distance(rel, ray_direction(frame.eye.xyz + rel));
    if (t < len) {
        float keep = max(t, 0.0);
        s_back = s_front + (s_back - s_front) * (len > 0.0 ? keep / len : 0.0);
        len = keep;
    }
}
