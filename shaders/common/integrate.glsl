// Ray integration through one cell, shared by every cell-projection method.
// Emission-absorption with colour L and attenuation tau linear along the
// segment, evaluated with partial pre-integration (Moreland & Angel 2004):
//   zeta = exp(-D (tau_f + tau_b) / 2)
//   C    = L_b (Psi - zeta) + L_f (1 - Psi),  alpha = 1 - zeta
// with Psi the average transmittance, tabulated once (independent of the
// transfer function) over gamma = tau D / (tau D + 1) in [0, 1].
// Output is premultiplied RGBA for back-to-front "over" blending.

layout(std430, set = 0, binding = 0) readonly buffer TransferTable { vec4 tf[]; };   // rgb = L, a = tau
layout(std430, set = 0, binding = 1) readonly buffer PsiTable { vec4 psi[]; };     // cell corners, [back][front]

vec4 transfer(float s) {
    float n = frame.tf_range.z;
    float x = clamp((s - frame.tf_range.x) * frame.tf_range.y, 0.0, 1.0) * (n - 1.0);
    float i = min(floor(x), n - 2.0);
    int k = int(i);
    return mix(tf[k], tf[k + 1], x - i);
}

float psi_lookup(float gamma_f, float gamma_b) {
    float m = frame.tf_range.w;
    vec2 x = clamp(vec2(gamma_f, gamma_b), 0.0, 1.0) * (m - 1.0);
    vec2 i = min(floor(x), vec2(m - 2.0));
    vec2 f = x - i;
    vec4 q = psi[int(i.y) * int(m - 1.0) + int(i.x)];  // (f0b0, f1b0, f0b1, f1b1)
    vec2 along_f = mix(q.xz, q.yw, f.x);
    return mix(along_f.x, along_f.y, f.y);
}

vec4 integrate_segment(float s_front, float s_back, float len) {
    vec4 front = transfer(s_front);
    vec4 back = transfer(s_back);
    float tf_d = max(front.a, 0.0) * len;
    float tb_d = max(back.a, 0.0) * len;
    float zeta = exp(-0.5 * (tf_d + tb_d));
    float p = psi_lookup(tf_d / (tf_d + 1.0), tb_d / (tb_d + 1.0));
    // Psi lies between the transmittances at both ends; keep it there after
    // table interpolation so no channel can go negative.
    p = clamp(p, zeta, 1.0);
    vec3 c = back.rgb * (p - zeta) + front.rgb * (1.0 - p);
    return vec4(c, 1.0 - zeta);
}
