// Per-frame constants shared by every cell-projection shader (push
// constants). Rust: algo::tet_mesh::FrameConstants (the reflection
// test checks the two).
#include "common/table_map.glsl"
layout(push_constant) uniform Frame {
    mat4 view_proj;         // world -> Vulkan clip space
    vec3 eye;               // eye position (relative to the render origin)
    float perspective;      // 1 perspective, 0 orthographic
    vec3 view_dir;          // unit viewing direction (orthographic rays)
    float max_segment;      // longest cell edge in the mesh (+1%): no segment through a cell is longer
    TableMap table;         // common/integrate.glsl
    float distance_clamp;   // clamp for ray-plane distances
    float plane_ratio_max;  // clamp for |u|
    float edge_eps;         // edge epsilon (ExitTolerances)
} frame;

// The viewing ray's unit direction through a point. A vertex exactly at the
// eye (stress case "eye-on-vertex") has no direction, normalize(0) = NaN,
// and NaN attributes would reach fragments through clipping: it takes the
// view direction instead, as the CPU's FrameSetup::ray_direction does.
vec3 ray_direction(vec3 p) {
    vec3 r = p - frame.eye;
    float len2 = dot(r, r);
    return frame.perspective > 0.5 && len2 > 0.0 ? r * inversesqrt(len2) : frame.view_dir;
}

// IntersectBackFace with the 3-float plane encoding n' = n / (n.v + a):
// distance along `dir` from vertex v to the plane of its opposite face.
// A ray parallel to the plane gives +-inf; clamping keeps the interpolated
// values finite (no real exit is farther than the clamp).
float distance_to_opposite_plane(vec3 plane3, vec3 dir) {
    float t = -1.0 / dot(plane3, dir);
    return clamp(t, -frame.distance_clamp, frame.distance_clamp);
}

// Exact perspective (EXACT_PERSPECTIVE): u = h/e for the plane opposite v,
// with h = n.v + a (v's distance to it) and e = n.eye + a (the eye's), from
// the same 3-float plane: e/h = 1 - n'.(v - eye). Along the ray from the eye
// through a point p of a face, the plane is met at eye + mu (p - eye) with
// 1/mu = 1 - lambda_v u, which is affine across the face, so interpolating
// lambda_v u is exact where interpolating the distance is not.
// |u| is large only when the eye is nearly in the plane (seen edge-on); the
// plane can then be an exit only where lambda_v < 1/u, next to an edge, and
// rasterizer rounding of lambda_v (~1e-7) times a huge u would turn into
// whole-cell errors (specks). Clamping |u| (plane_ratio_max) bounds that noise, at
// the cost of a shortened exit in the sliver lambda_v < 1/u (and no
// inf * 0 = NaN when the eye is on the plane).
float perspective_plane_ratio(vec3 plane3, vec3 rel) {
    return clamp(1.0 / (1.0 - dot(plane3, rel)), -frame.plane_ratio_max, frame.plane_ratio_max);
}
