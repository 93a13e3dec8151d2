// Per-frame constants shared by every cell-projection method (push constants).
layout(push_constant) uniform Frame {
    mat4 view_proj;   // world -> Vulkan clip space
    vec4 eye;         // xyz: eye position (world); w: 1 perspective, 0 orthographic
    vec4 view_dir;    // xyz: unit viewing direction (orthographic rays)
    vec4 tf_range;    // x: lowest tabulated scalar, y: 1/(highest - lowest), z: TF entries, w: Psi table side
    vec4 limits;      // x: clamp for ray-plane distances (a few mesh diagonals)
} frame;

// The viewing ray's unit direction through a world-space point.
vec3 ray_direction(vec3 p) {
    return frame.eye.w > 0.5 ? normalize(p - frame.eye.xyz) : frame.view_dir.xyz;
}

// IntersectBackFace with the 3-float plane encoding n' = n / (n.v + a):
// distance along `dir` from vertex v to the plane of its opposite face.
// A ray parallel to the plane gives +-inf; clamping keeps the interpolated
// values finite (no real exit is farther than the clamp).
float distance_to_opposite_plane(vec3 plane3, vec3 dir) {
    float t = -1.0 / dot(plane3, dir);
    return clamp(t, -frame.limits.x, frame.limits.x);
}
