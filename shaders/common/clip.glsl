// The camera's near and far planes in the fragment stage, where the
// rasterizer clips: clip-space z = 0 (near) and z = w (far), read from the
// rows of view_proj so that no extra constant is needed. Distances are
// along the viewing ray through the fragment (unit direction), from the
// fragment's point eye + rel. The f64 reference clips every ray to the same
// depth range, so a segment that crosses the far plane stops there, and a
// cell cut by the near plane is integrated from it (near caps, cap.frag).

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
