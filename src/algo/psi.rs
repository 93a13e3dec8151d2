//! Ψ for the tables the GPU reads, in f64 and in closed form (the
//! Williams–Max–Stein form that the `linear-exact` integrator evaluates in
//! f32, `shaders/common/integrate.glsl`):
//!
//! ```text
//!     Ψ(a, b) = ∫₀¹ exp(−a·u − c·u²) du,   c = (b − a)/2,   a = τ_f·D, b = τ_b·D
//!     c > 0:  Ψ = √π/(2r) · [erfcx(a/2r) − ζ·erfcx(b/2r)],   r = √c
//!     c < 0:  Ψ = 1/r · [F(a/2r) − ζ·F(b/2r)],               r = √−c
//! ```
//!
//! with ζ = exp(−(a + b)/2), erfcx(x) = exp(x²)·erfc(x) and Dawson's
//! integral F. Both forms subtract two terms; for |c| < [`C_SERIES`] the
//! series in c, `Ψ = Σₖ (−c)ᵏ/k! · E₂ₖ(a)` with the moments
//! `Eₙ(a) = ∫₀¹ uⁿ e^{−a·u} du`, is used instead.
//!
//! This is deliberately not the reference's algorithm (`reference::psi`
//! integrates the same Ψ by Gauss–Legendre quadrature on pieces of bounded
//! exponent): the two are written apart so that a mistake in one shows as a
//! disagreement with the other (`tests/reference_agrees.rs`).
//!
//! **Error bound** ([`PSI_REL_ERROR`]). Each term carries a relative error
//! δ of a few ulp (erfc from `libm`, the continued fraction, Rybicki's sum,
//! one `exp`); the subtraction turns it into δ·(T₁ + ζT₂)/Ψ ≤ 2δ·T₁/Ψ. For
//! c > 0, T₁ = ∫₀^∞ and ∫₁^∞ ≤ e^{−(a+c)}·√π/(2√c) while ∫₀¹ ≥ e^{−(a+c)}, so
//! T₁/Ψ ≤ 1 + √π/(2√c); for c < 0, T₁ = ∫₀^{u*} with u* = a/(a − b) ≥ 1,
//! and T₁/Ψ ≤ 1 + min(u* − 1, 2/b) ≤ 1 + 1/√|c|. With |c| ≥ C_SERIES that is
//! at most 1 + 1/√C_SERIES ≈ 32.6; with δ = 16 ε the bound is 2·32.6·16ε ≈
//! 1.2e-13. The series is truncated after the c⁵ term (|c|⁶/6!·E₁₂ < 1e-21).

/// |c| below which the series in c replaces the closed form.
pub const C_SERIES: f64 = 1e-3;

/// A bound on Ψ's relative error here (module docs: derived, not fitted).
pub const PSI_REL_ERROR: f64 = 2.0 * (1.0 + 31.7) * 16.0 * f64::EPSILON;

/// 1/√π (exact: half of 2/√π).
const FRAC_1_SQRT_PI: f64 = std::f64::consts::FRAC_2_SQRT_PI / 2.0;

/// Ψ(a, b) for a = τ_f·D, b = τ_b·D (negative values taken as 0; an
/// infinite one gives 0, the limit; NaN gives NaN).
pub fn psi(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        return f64::NAN;
    }
    let (a, b) = (a.max(0.0), b.max(0.0));
    if a.is_infinite() || b.is_infinite() {
        return 0.0;
    }
    let c = 0.5 * (b - a);
    if c.abs() < C_SERIES {
        let e = moments(a);
        // Σ (−c)^k / k! · E_{2k}, k = 0..=5.
        let (mut sum, mut coef) = (0.0, 1.0);
        for k in 0..=5 {
            sum += coef * e[2 * k];
            coef *= -c / (k + 1) as f64;
        }
        return sum;
    }
    let zeta = (-0.5 * (a + b)).exp();
    let r = c.abs().sqrt();
    let (x_a, x_b) = (0.5 * a / r, 0.5 * b / r);
    if c > 0.0 {
        0.5 / (FRAC_1_SQRT_PI * r) * (erfcx(x_a) - zeta * erfcx(x_b))
    } else {
        (dawson(x_a) - zeta * dawson(x_b)) / r
    }
}

/// E₀ … E₁₀ of `Eₙ(a) = ∫₀¹ uⁿ e^{−a·u} du`, a ≥ 0.
fn moments(a: f64) -> [f64; 11] {
    let mut e = [0.0; 11];
    if a < 2.0 {
        // Eₙ = Σₖ (−a)ᵏ / (k!·(n + k + 1)): terms below 2 in size, so no
        // digits are lost; 40 terms reach 2⁴⁰/40! ≈ 1e-36.
        for (n, en) in e.iter_mut().enumerate() {
            let (mut term, mut sum) = (1.0, 0.0);
            for k in 0..40 {
                sum += term / (n + k + 1) as f64;
                term *= -a / (k + 1) as f64;
            }
            *en = sum;
        }
    } else {
        // Upward recurrence Eₙ = (n·Eₙ₋₁ − e^{−a}) / a, from E₀ = (1 − e^{−a})/a.
        let ea = (-a).exp();
        e[0] = -(-a).exp_m1() / a;
        for n in 1..e.len() {
            e[n] = (n as f64 * e[n - 1] - ea) / a;
        }
    }
    e
}

/// erfcx(x) = exp(x²)·erfc(x) for x ≥ 0.
fn erfcx(x: f64) -> f64 {
    if x < 10.0 {
        // exp(x²) with x² split exactly into hi + lo (fma), so the rounding
        // of x² does not cost x²·ε.
        let hi = x * x;
        let lo = x.mul_add(x, -hi);
        hi.exp() * (1.0 + lo) * libm::erfc(x)
    } else {
        // Laplace's continued fraction erfcx(x) = 1/√π · 1/(x + ½/(x + 1/(x + (3/2)/(x + …)))),
        // evaluated from the tail: 40 levels are far beyond convergence at x ≥ 10.
        let mut t = x;
        for k in (1..=40).rev() {
            t = x + 0.5 * k as f64 / t;
        }
        FRAC_1_SQRT_PI / t
    }
}

/// Dawson's integral F(x) = exp(−x²)·∫₀ˣ exp(t²) dt for x ≥ 0.
fn dawson(x: f64) -> f64 {
    if x < 0.5 {
        // F(x) = Σₖ (−2x²)ᵏ·x / (1·3·…·(2k + 1)).
        let (mut term, mut sum) = (x, 0.0);
        for k in 0..20 {
            sum += term;
            term *= -2.0 * x * x / (2 * k + 3) as f64;
        }
        sum
    } else if x > 50.0 {
        // Asymptotic: F(x) = 1/(2x) · Σₖ (2k − 1)!! / (2x²)ᵏ.
        let (mut term, mut sum) = (1.0, 0.0);
        for k in 0..12 {
            sum += term;
            term *= (2 * k + 1) as f64 / (2.0 * x * x);
        }
        0.5 * sum / x
    } else {
        // Rybicki: F(x) ≈ 1/√π · Σ_{n odd} exp(−(x − n·h)²) / n, exact up to
        // exp(−(π/2h)²) ≈ 2e-27 for h = 0.2; taken around the even n₀·h
        // nearest x, 17 pairs of terms reach exp(−46).
        const H: f64 = 0.2;
        let n0 = 2.0 * (0.5 * x / H + 0.5).floor();
        let xp = x - n0 * H;
        let mut e1 = (2.0 * xp * H).exp();
        let e2 = e1 * e1;
        let (mut d1, mut d2) = (n0 + 1.0, n0 - 1.0);
        let mut sum = 0.0;
        for i in 0..17 {
            let odd = (2 * i + 1) as f64;
            sum += (-odd * odd * H * H).exp() * (e1 / d1 + 1.0 / (d2 * e1));
            d1 += 2.0;
            d2 -= 2.0;
            e1 *= e2;
        }
        FRAC_1_SQRT_PI * (-xp * xp).exp() * sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn rel(x: f64, y: f64) -> f64 {
        if x == y {
            0.0
        } else {
            (x - y).abs() / y.abs()
        }
    }

    /// Closed forms Ψ has on its own lines: constant attenuation
    /// (1 − e⁻ˣ)/x, and a = 0, b → ∞ (√(π/2b)).
    #[test]
    fn closed_form_special_lines() {
        for x in [1e-9, 1e-4, 0.3, 1.0, 7.0, 60.0, 1e4, 1e12] {
            assert!(rel(psi(x, x), -(-x).exp_m1() / x) < 1e-15, "x={x}");
        }
        assert!(rel(psi(0.0, 1e12), (PI / 2e12).sqrt()) < 1e-14);
        assert_eq!(psi(0.0, 0.0), 1.0);
        assert_eq!(psi(f64::INFINITY, 1.0), 0.0);
        assert!(psi(1.0, f64::NAN).is_nan());
    }

    /// erfcx and Dawson against values of their own definitions (Abramowitz
    /// & Stegun tables, 10 digits), on each side of every branch.
    #[test]
    fn special_functions() {
        // erfcx(x) = exp(x²) erfc(x): erfc(0.5) = 0.4795001222, erfc(2) = 0.004677734981.
        assert!(rel(erfcx(0.5), 0.25f64.exp() * 0.479_500_122_2) < 1e-9);
        assert!(rel(erfcx(2.0), 4f64.exp() * 0.004_677_734_981) < 1e-9);
        // Both branches meet at 10, against the asymptotic series
        // erfcx(x) = 1/(x√π)·Σₖ (−1)ᵏ (2k − 1)!!/(2x²)ᵏ (12 terms: error < 1e-17 at 10).
        let asym = |x: f64| {
            let (mut term, mut sum) = (1.0, 0.0);
            for k in 0..12 {
                sum += term;
                term *= -((2 * k + 1) as f64) / (2.0 * x * x);
            }
            FRAC_1_SQRT_PI / x * sum
        };
        assert!(rel(erfcx(10.0 - 1e-12), asym(10.0)) < 1e-13);
        assert!(rel(erfcx(10.0), asym(10.0)) < 1e-13);
        // Dawson: F(0.5) = 0.4244363835, F(1) = 0.5380795069, F(2) = 0.3013403889, F(5) = 0.1021340744.
        for (x, f) in [(0.5, 0.424_436_383_5), (1.0, 0.538_079_506_9), (2.0, 0.301_340_388_9), (5.0, 0.102_134_074_4)] {
            assert!(rel(dawson(x), f) < 1e-9, "F({x}) = {}", dawson(x));
        }
        // Branch seams: the series and Rybicki at 0.5, Rybicki and the asymptote at 50.
        // (F' = 1 − 2x·F, so F(0.5 − h) = F(0.5) − h·(1 − F(0.5)) to O(h²).)
        let f = dawson(0.5);
        assert!(rel(dawson(0.5 - 1e-9), f - 1e-9 * (1.0 - f)) < 1e-14);
        assert!(rel(dawson(50.0), dawson(50.0 + 1e-12)) < 1e-13);
    }

    /// The series and the closed form agree across |c| = C_SERIES.
    #[test]
    fn series_meets_closed_form() {
        for a in [0.0, 0.1, 1.0, 1.9, 2.1, 10.0, 300.0] {
            for sign in [1.0, -1.0] {
                let b_in = (a + sign * 2.0 * C_SERIES * 0.999f64).max(0.0);
                let b_out = (a + sign * 2.0 * C_SERIES * 1.001f64).max(0.0);
                let (p_in, p_out) = (psi(a, b_in), psi(a, b_out));
                // Ψ moves by at most |∂Ψ/∂b|·Δb ≤ Δb/2 between the two.
                assert!((p_in - p_out).abs() <= 0.5 * (b_out - b_in).abs() + 1e-14, "a={a} {p_in} {p_out}");
            }
        }
    }
}
