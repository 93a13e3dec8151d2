// Ray integration through one cell, shared by every cell-projection method.
// Emission-absorption: colour L and attenuation tau per unit length from the
// transfer function; the result is premultiplied RGBA for back-to-front
// "over" blending. One integrator is compiled in (a build-time parameter):
//   INTEGRATOR_AVERAGE      average colour and attenuation (Shirley-Tuchman)
//   INTEGRATOR_PREINT       classic pre-integration: table over (s_f, s_b, D)
//   INTEGRATOR_LINEAR_EXACT L, tau linear along the segment; Psi in closed form
//   (default)               partial pre-integration (Moreland & Angel 2004):
//                           L, tau linear, Psi from a table over
//                           gamma = tau D / (tau D + 1)
// With L and tau linear from front (f) to back (b) over length D:
//   zeta = exp(-D (tau_f + tau_b) / 2)
//   C    = L_b (Psi - zeta) + L_f (1 - Psi),  alpha = 1 - zeta
// where Psi is the segment's average transmittance.
// Every integrator defines integrate_segment(s_front, s_back, len); all but
// INTEGRATOR_PREINT also integrate_values(front, back, len) from the colour
// and attenuation at the two ends (rgb = L, a = tau).

// Both tables are storage texel buffers of RGBA32F, read with imageLoad
// (integrate.rs says why neither storage buffers nor texelFetch).
layout(set = 0, binding = 0, rgba32f) uniform readonly imageBuffer tf;      // rgb = L, a = tau
layout(set = 0, binding = 1, rgba32f) uniform readonly imageBuffer table;

// Transfer-function table entries are clamped to 1e30 when the table is
// built (TransferFunction::table): an Inf entry would make
// mix(Inf, Inf, t) = Inf + t (Inf - Inf) = NaN (stress case "opaque-3e38").
// Largest optical depth integrated: tau * D overflows to Inf for tau near
// f32's maximum (and Inf * 0 = NaN on a zero-length segment; Inf / Inf = NaN
// in gamma); beyond 1e4 the transmittance exp(-tau D) is 0 in f32 anyway.
const float DEPTH_MAX = 1e4;

vec4 transfer(float s) {
    float n = frame.table.tf_entries;
    float x = clamp((s - frame.table.tf_lo) * frame.table.tf_inv_range, 0.0, 1.0) * (n - 1.0);
    float i = min(floor(x), n - 2.0);
    int k = int(i);
    return mix(imageLoad(tf, k), imageLoad(tf, k + 1), x - i);
}

// Optical depth tau * len, finite and in [0, DEPTH_MAX] (len >= 0, tau <= 1e30).
float optical_depth(float tau, float len) {
    return min(max(tau, 0.0) * len, DEPTH_MAX);
}

vec4 linear_segment(vec4 front, vec4 back, float zeta, float psi) {
    // Psi lies between the transmittances at both ends; keep it there after
    // table interpolation or f32 rounding so no channel can go negative.
    psi = clamp(psi, zeta, 1.0);
    vec3 c = back.rgb * (psi - zeta) + front.rgb * (1.0 - psi);
    return vec4(c, 1.0 - zeta);
}

#if defined(INTEGRATOR_AVERAGE)

vec4 integrate_values(vec4 front, vec4 back, float len) {
    float alpha = 1.0 - exp(-optical_depth(0.5 * (max(front.a, 0.0) + max(back.a, 0.0)), len));
    return vec4(0.5 * (front.rgb + back.rgb) * alpha, alpha);
}

#elif defined(INTEGRATOR_PREINT)

// table[(d * n + b) * n + f]: the exact segment integral for front scalar f,
// back scalar b (n samples over the transfer function's range each) and
// length index d (n_d samples of x = D / (D + D_half) in [0, 1]).
vec4 preint_at(int f, int b, int d, int n) {
    return imageLoad(table, (d * n + b) * n + f);
}

vec4 integrate_segment(float s_front, float s_back, float len) {
    float n = frame.table.table_side;
    float nd = max(floor(n / 4.0), 2.0);
    vec2 s = clamp((vec2(s_front, s_back) - frame.table.tf_lo) * frame.table.tf_inv_range, 0.0, 1.0) * (n - 1.0);
    float xd = len / (len + frame.table.preint_length) * (nd - 1.0);
    vec3 x = vec3(s, xd);
    vec3 i = min(floor(x), vec3(n - 2.0, n - 2.0, nd - 2.0));
    vec3 t = x - i;
    ivec3 k = ivec3(i);
    int m = int(n);
    vec4 c00 = mix(preint_at(k.x, k.y, k.z, m), preint_at(k.x + 1, k.y, k.z, m), t.x);
    vec4 c10 = mix(preint_at(k.x, k.y + 1, k.z, m), preint_at(k.x + 1, k.y + 1, k.z, m), t.x);
    vec4 c01 = mix(preint_at(k.x, k.y, k.z + 1, m), preint_at(k.x + 1, k.y, k.z + 1, m), t.x);
    vec4 c11 = mix(preint_at(k.x, k.y + 1, k.z + 1, m), preint_at(k.x + 1, k.y + 1, k.z + 1, m), t.x);
    return mix(mix(c00, c10, t.y), mix(c01, c11, t.y), t.z);
}

#elif defined(INTEGRATOR_LINEAR_EXACT)

// erfcx(x) = exp(x^2) erfc(x) for x >= 0, relative error < 1.2e-7 (the
// Chebyshev fit of Numerical Recipes' erfcc, without its exp(-x^2) factor,
// so it neither underflows nor loses accuracy for large x).
float erfcx_pos(float x) {
    float t = 1.0 / (1.0 + 0.5 * x);
    return t * exp(-1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 + t * (-0.18628806
        + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 + t * (-0.82215223 + t * 0.17087277)))))))));
}

// Dawson's integral F(x) = exp(-x^2) int_0^x exp(t^2) dt for x >= 0 (Rybicki's
// method, relative error ~2e-7).
float dawson_pos(float x) {
    if (x < 0.2) {
        float x2 = x * x;
        return x * (1.0 - 2.0 / 3.0 * x2 * (1.0 - 0.4 * x2 * (1.0 - 2.0 / 7.0 * x2)));
    }
    const float H = 0.4;
    float n0 = 2.0 * floor(0.5 * x / H + 0.5);
    float xp = x - n0 * H;
    float e1 = exp(2.0 * xp * H);
    float e2 = e1 * e1;
    float d1 = n0 + 1.0;
    float d2 = d1 - 2.0;
    float sum = 0.0;
    for (int i = 0; i < 6; ++i) {
        float ci = exp(-float((2 * i + 1) * (2 * i + 1)) * H * H);
        sum += ci * (e1 / d1 + 1.0 / (d2 * e1));
        d1 += 2.0;
        d2 -= 2.0;
        e1 *= e2;
    }
    return 0.5641895835 * exp(-xp * xp) * sum;
}

// Psi(a, b) = int_0^1 exp(-a u - c u^2) du, c = (b - a) / 2, in closed form:
//   c > 0: sqrt(pi)/(2 sqrt c) [erfcx(a/(2 sqrt c)) - e^{-(a+b)/2} erfcx(b/(2 sqrt c))]
//   c < 0: 1/sqrt(-c) [F(a/(2 sqrt -c)) - e^{-(a+b)/2} F(b/(2 sqrt -c))]
// Both subtract nearly equal terms as c -> 0, so for |c| < C_MIN the
// expansion Psi = E0 - c E2 + c^2/2 E4 (E_n = int_0^1 u^n e^{-a u} du) is
// used instead; its truncation error is below C_MIN^3 / 42 = 2.4e-8.
const float C_MIN = 0.01;

vec3 moments_024(float a) {
    if (a < 4.0) {
        // sum_k (-a)^k / (k! (n + k + 1)); terms peak near 10, so ~2 digits of
        // f32 are lost at worst (relative error ~3e-6).
        vec3 sum = vec3(0.0);
        float term = 1.0;
        for (int k = 0; k < 32; ++k) {
            sum += term / vec3(float(k + 1), float(k + 3), float(k + 5));
            term *= -a / float(k + 1);
        }
        return sum;
    }
    // n!/a^{n+1} (1 - e^{-a} sum_{j<=n} a^j/j!): no cancellation for a >= 4.
    float ia = 1.0 / a;
    float p0 = exp(-a);
    float p1 = p0 * a;
    float p2 = p1 * a / 2.0;
    float p3 = p2 * a / 3.0;
    float p4 = p3 * a / 4.0;
    float ia3 = ia * ia * ia;
    return vec3(ia * (1.0 - p0), 2.0 * ia3 * (1.0 - (p0 + p1 + p2)), 24.0 * ia3 * ia * ia * (1.0 - (p0 + p1 + p2 + p3 + p4)));
}

float psi_exact(float a, float b) {
    float c = 0.5 * (b - a);
    if (c >= C_MIN) {
        float r = sqrt(c);
        return 0.8862269255 / r * (erfcx_pos(0.5 * a / r) - exp(-0.5 * (a + b)) * erfcx_pos(0.5 * b / r));
    }
    if (c <= -C_MIN) {
        float r = sqrt(-c);
        return (dawson_pos(0.5 * a / r) - exp(-0.5 * (a + b)) * dawson_pos(0.5 * b / r)) / r;
    }
    vec3 e = moments_024(a);
    return e.x - c * e.y + 0.5 * c * c * e.z;
}

vec4 integrate_values(vec4 front, vec4 back, float len) {
    float a = optical_depth(front.a, len);
    float b = optical_depth(back.a, len);
    float zeta = exp(-0.5 * (a + b));
    return linear_segment(front, back, zeta, psi_exact(a, b));
}

#else  // partial pre-integration

float psi_lookup(float gamma_f, float gamma_b) {
    float m = frame.table.table_side;
    vec2 x = clamp(vec2(gamma_f, gamma_b), 0.0, 1.0) * (m - 1.0);
    vec2 i = min(floor(x), vec2(m - 2.0));
    vec2 f = x - i;
    vec4 q = imageLoad(table, int(i.y) * int(m - 1.0) + int(i.x));  // corners (f0b0, f1b0, f0b1, f1b1)
    vec2 along_f = mix(q.xz, q.yw, f.x);
    return mix(along_f.x, along_f.y, f.y);
}

vec4 integrate_values(vec4 front, vec4 back, float len) {
    float tf_d = optical_depth(front.a, len);
    float tb_d = optical_depth(back.a, len);
    float zeta = exp(-0.5 * (tf_d + tb_d));
    float psi = psi_lookup(tf_d / (tf_d + 1.0), tb_d / (tb_d + 1.0));
    return linear_segment(front, back, zeta, psi);
}

#endif

#ifndef INTEGRATOR_PREINT
// The integrators that take colour and attenuation linear along the
// segment need only their values at its two ends: `integrate_values` above,
// from the transfer-function table here, or from a piece of the transfer
// function that is exactly linear (atfs.frag).
vec4 integrate_segment(float s_front, float s_back, float len) {
    return integrate_values(transfer(s_front), transfer(s_back), len);
}
#endif
