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
    return -dot(plane, vec4(frame.eye + rel, 1.0)) / dot(plane.xyz, dir);
}

float near_distance(vec3 rel, vec3 dir) {
    return plane_distance(clip_row(2), rel, dir);
}

float far_distance(vec3 rel, vec3 dir) {
    return plane_distance(clip_row(2) - clip_row(3), rel, dir);
}

// Clip-space position of world point `pos`. Under perspective it is taken
// relative to the eye: view_proj (x, y, w rows) vanishes at the eye exactly,
// but in f32 view_proj * (eye, 1) leaves rounding of ~1e-7 of the
// coordinates' magnitude in x, y and w. A vertex at or next to the eye is
// clipped at the eye plane (eye_plane_distance), w ~ 1e-5 there, and that
// rounding divided by w moved clipped points by up to half a pixel at
// 128x128: a face through the eye (seen edge-on, no area) became a sliver
// that covered pixel centres along its line and added its cell a second
// time (stress case "eye-on-vertex", single pixels off by 5e-2). From
// pos - eye the rounding is relative to the distance from the eye and the
// projection of a point near it keeps its direction. The eye's own depth
// (row 2) is the one coordinate that does not vanish there.
vec4 clip_position(vec3 pos) {
    if (frame.perspective < 0.5) {
        return frame.view_proj * vec4(pos, 1.0);
    }
    vec4 c = frame.view_proj * vec4(pos - frame.eye, 0.0);
    c.z += dot(clip_row(2), vec4(frame.eye, 1.0));
    return c;
}

// The one clip plane of the cell pipelines (gl_ClipDistance[0] of the
// vertex stage), which draw without near/far clipping (depth clamp): just in
// front of the eye, at a ten-thousandth of the longest cell edge but at
// most half the near distance, so that no vertex at or behind the eye (clip
// w <= 0, e.g. the eye on a mesh vertex) reaches the rasterizer and nothing
// behind the near plane is clipped. Clip w is the depth along the view
// direction; orthographic views have no eye plane.
float eye_plane_distance(vec4 clip_pos) {
    if (frame.perspective < 0.5) {
        return 1.0;
    }
    float near = near_distance(vec3(0.0), frame.view_dir);
    return clip_pos.w - min(1e-4 * frame.max_segment, 0.5 * near);
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
    float t = near_distance(rel, ray_direction(frame.eye + rel));
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
    float t = far_distance(rel, ray_direction(frame.eye + rel));
    if (t < len) {
        float keep = max(t, 0.0);
        s_back = s_front + (s_back - s_front) * (len > 0.0 ? keep / len : 0.0);
        len = keep;
    }
}
