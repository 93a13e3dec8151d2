//! Ψ, the average transmittance of a ray segment whose attenuation is linear in
//! depth (Moreland & Angel's partial pre-integration, SPEC §2):
//!
//! ```text
//!     Ψ(a, b) = ∫₀¹ exp(−a·u − (b − a)·u²/2) du,    a = τ_f·D,  b = τ_b·D
//! ```
//!
//! and ζ = exp(−(a + b)/2), the transmittance of the whole segment. A segment
//! with colour linear from L_f (front) to L_b (back) then contributes
//! `L_b·(Ψ − ζ) + L_f·(1 − Ψ)` with opacity `1 − ζ`.
//!
//! # Method
//! The integrand `exp(−φ(u))`, `φ(u) = a·u + c·u²`, `c = (b − a)/2`, is
//! monotone because `φ' = a + (b − a)·u ≥ 0` on `[0, 1]` when `a, b ≥ 0`. We cut
//! `[0, 1]` where φ crosses fixed levels (the cut points solve the quadratic in
//! closed form, with the cancellation-free root formula), so every piece sees
//! the exponent vary by a bounded amount λ, and integrate each piece with an
//! n-point Gauss–Legendre rule, n picked from λ. The thresholds below were
//! calibrated in 40-digit arithmetic (mpmath) over the whole family
//! `exp(−(αx + βx²))`, `α + β = λ`, that a piece can produce, for a relative
//! quadrature error below 5e-17 (with a 25 % margin on λ). Beyond φ = 45 the
//! rest of the integral is below 1e-17 of the total (a convexity/concavity
//! bound on φ) and is dropped; the stretch φ ∈ [30, 45] weighs at most e⁻³⁰ and
//! gets a cheaper rule. Consequences:
//! - no closed form with erf/Dawson (and its cancellation at b ≈ a, or its
//!   overflow for large τD) is needed; b < a (negative curvature) is just
//!   another exponent shape;
//! - cost is one `exp` per node: 4–12 nodes for the optically thin segments of
//!   a real mesh (λ ≤ 1), at most 48 for any input;
//! - accuracy: Ψ, 1 − Ψ and Ψ − ζ within 1e-15 relative of 40-digit values at
//!   600 random points over [1e-10, 1e7]² (plus a = 0, b = 0, b ≈ a), and
//!   within 1e-14 of an independent brute-force quadrature on a dense grid
//!   (the tests).
//!
//! `psi_terms` additionally returns `1 − Ψ` and `Ψ − ζ` without cancellation
//! for optically thin segments (they are integrated directly, with `expm1`),
//! which the reference renderer composites; `psi` is the fast scalar used to
//! build the GPU table.
//!
//! Domain: `a, b ∈ [0, ∞]`. Negative inputs are clamped to 0 (τ is never
//! negative); an infinite input gives Ψ = 0, ζ = 0; NaN propagates.

use super::gauss_legendre::{Rule, RULES};

/// Ψ, ζ and the two differences the emission term needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PsiTerms {
    /// Average transmittance over the segment, Ψ.
    pub psi: f64,
    /// Transmittance of the whole segment, ζ = exp(−(a + b)/2).
    pub zeta: f64,
    /// `1 − Ψ`, accurate to relative precision even when Ψ ≈ 1.
    pub one_minus_psi: f64,
    /// `Ψ − ζ`, accurate to relative precision even when Ψ ≈ ζ ≈ 1.
    pub psi_minus_zeta: f64,
}

/// Largest exponent variation λ that `gauss_legendre::RULES[i]` integrates to
/// ≤ 5e-17 relative error over the family `exp(−(αx + βx²))`, `α + β = λ`,
/// and (for λ ≤ 1) over the two difference integrands of `psi_terms`
/// (calibrated in 40-digit arithmetic, then multiplied by 0.75 for margin).
const MAX_LAMBDA: [f64; 10] = [0.0002, 0.03, 0.26, 0.85, 1.8, 4.75, 9.1, 14.9, 30.5, 51.0];

/// The first piece covers φ ∈ [0, FIRST_SPAN].
const FIRST_SPAN: f64 = 30.0;
/// Integration stops at φ = PHI_STOP: the remainder is < 1e-17 of Ψ.
const PHI_STOP: f64 = 45.0;
/// Rule (index into `RULES`, 16 points) for the piece φ ∈ [FIRST_SPAN,
/// PHI_STOP]: it weighs at most e⁻³⁰ ≈ 1e-13 of Ψ and this rule is good to
/// 1e-8 there (calibrated like the others).
const SECOND_RULE: usize = 5;

#[inline]
fn rule_for(lambda: f64) -> &'static Rule {
    for (i, &max_lambda) in MAX_LAMBDA.iter().enumerate() {
        if lambda <= max_lambda {
            return &RULES[i];
        }
    }
    &RULES[RULES.len() - 1]
}

/// The u in [0, 1] where φ(u) = a·u + c·u² reaches `level` (0 < level ≤
/// φ(1)): the cancellation-free root 2·level / (a + √(a² + 4·c·level)),
/// evaluated scaled so that nothing overflows even for a, b near f64::MAX.
#[inline]
fn u_at(a: f64, c: f64, level: f64) -> f64 {
    let q = 2.0 * c.abs().sqrt() * level.sqrt(); // √(4·|c|·level)
    let s = a.max(q);
    if s.is_nan() || s <= 0.0 {
        return 1.0;
    }
    let (x, y) = (a / s, q / s);
    let disc = (x * x + c.signum() * y * y).max(0.0);
    (2.0 * level / (a + s * disc.sqrt())).min(1.0)
}

/// ∫_{u0}^{u1} exp(−φ(u)) du with the given rule.
#[inline]
fn piece(a: f64, c: f64, u0: f64, u1: f64, rule: &Rule) -> f64 {
    let h = u1 - u0;
    let mut s = 0.0;
    for (&x, &w) in rule.x.iter().zip(rule.w.iter()) {
        let u = u0 + h * x;
        s += w * (-(u * (a + c * u))).exp();
    }
    s * h
}

/// Ψ(a, b) with a = τ_f·D, b = τ_b·D. See the module docs.
pub fn psi(tau_f_d: f64, tau_b_d: f64) -> f64 {
    let (a, b) = (clamp_input(tau_f_d), clamp_input(tau_b_d));
    if a.is_nan() || b.is_nan() {
        return f64::NAN;
    }
    if a.is_infinite() || b.is_infinite() {
        return 0.0;
    }
    psi_finite(a, b)
}

#[inline]
fn clamp_input(v: f64) -> f64 {
    if v < 0.0 {
        0.0
    } else {
        v
    }
}

fn psi_finite(a: f64, b: f64) -> f64 {
    let c = 0.5 * (b - a);
    let phi1 = 0.5 * (a + b);
    if phi1 == 0.0 {
        return 1.0;
    }
    if phi1 <= FIRST_SPAN {
        return piece(a, c, 0.0, 1.0, rule_for(phi1));
    }
    let u1 = u_at(a, c, FIRST_SPAN);
    let mut s = piece(a, c, 0.0, u1, rule_for(FIRST_SPAN));
    let u2 = if phi1 <= PHI_STOP {
        1.0
    } else {
        u_at(a, c, PHI_STOP)
    };
    if u2 > u1 {
        s += piece(a, c, u1, u2, &RULES[SECOND_RULE]);
    }
    s
}

/// Ψ, ζ, 1 − Ψ and Ψ − ζ for a = τ_f·D, b = τ_b·D (see [`PsiTerms`]).
pub fn psi_terms(tau_f_d: f64, tau_b_d: f64) -> PsiTerms {
    let (a, b) = (clamp_input(tau_f_d), clamp_input(tau_b_d));
    if a.is_nan() || b.is_nan() {
        return PsiTerms {
            psi: f64::NAN,
            zeta: f64::NAN,
            one_minus_psi: f64::NAN,
            psi_minus_zeta: f64::NAN,
        };
    }
    if a.is_infinite() || b.is_infinite() {
        return PsiTerms {
            psi: 0.0,
            zeta: 0.0,
            one_minus_psi: 1.0,
            psi_minus_zeta: 0.0,
        };
    }
    let c = 0.5 * (b - a);
    let phi1 = 0.5 * (a + b);
    let zeta = (-phi1).exp();
    if phi1 == 0.0 {
        return PsiTerms {
            psi: 1.0,
            zeta: 1.0,
            one_minus_psi: 0.0,
            psi_minus_zeta: 0.0,
        };
    }
    if phi1 > 1.0 {
        // No cancellation worth guarding against: 1 − Ψ ≥ ~0.25, Ψ − ζ ≥ ~0.1·Ψ.
        let psi = psi_finite(a, b);
        return PsiTerms {
            psi,
            zeta,
            one_minus_psi: 1.0 - psi,
            psi_minus_zeta: psi - zeta,
        };
    }
    // Optically thin: integrate the three integrands directly on one piece,
    // with m(x) = expm1(−x) (one transcendental per node):
    //   Ψ     = ∫ 1 + m(φ(u)) du
    //   1 − Ψ = ∫ −m(φ(u)) du
    //   Ψ − ζ = ∫ m(φ(u)) − m(φ(1)) du
    // The last difference loses at most a few ulp of φ(1), and the integral is
    // at least φ(1)/3 (it is ≈ a/6 + b/3), so all three keep ~1e-16 relative.
    let rule = rule_for(phi1);
    let m1 = (-phi1).exp_m1();
    let mut m_sum = 0.0;
    for (&u, &w) in rule.x.iter().zip(rule.w.iter()) {
        m_sum += w * (-(u * (a + c * u))).exp_m1();
    }
    let (p, omp, pmz) = (1.0 + m_sum, -m_sum, m_sum - m1);
    PsiTerms {
        psi: p,
        zeta,
        one_minus_psi: omp,
        psi_minus_zeta: pmz,
    }
}

#[cfg(test)]
mod tests {
    use super::super::gauss_legendre::ORDERS;
    use super::*;

    /// n-point Gauss–Legendre on [0, 1] by f64 Newton iteration: independent
    /// of the tables; its ~1e-16 absolute node error is harmless in `brute`,
    /// whose cells are small against the integrand's decay length.
    fn newton_gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
        let legendre = |z: f64| {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let k = k as f64;
                let p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
                p0 = p1;
                p1 = p2;
            }
            (p1, n as f64 * (z * p1 - p0) / (z * z - 1.0))
        };
        let (mut x, mut w) = (Vec::new(), Vec::new());
        for i in 0..n {
            let mut z = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            for _ in 0..50 {
                let (p, dp) = legendre(z);
                z -= p / dp;
            }
            let (_, dp) = legendre(z);
            x.push(0.5 * (1.0 - z));
            w.push(1.0 / ((1.0 - z * z) * dp * dp));
        }
        (x, w)
    }

    /// Brute force, independent of the piece/rule logic above: composite
    /// 20-point Gauss–Legendre on a geometrically graded mesh of [0, 1]
    /// (cells of width 1/(8·max(1, a, b, √|b−a|)) at 0, growing ×1.05), no
    /// truncation of the tail, small terms summed first.
    fn brute(a: f64, b: f64) -> f64 {
        let c = 0.5 * (b - a);
        let (rx, rw) = newton_gauss_legendre(20);
        let scale = 1.0f64.max(a).max(b).max(c.abs().sqrt());
        let mut h = 1.0 / (8.0 * scale);
        let mut u0 = 0.0f64;
        let mut cells = Vec::new();
        while u0 < 1.0 {
            let u1 = (u0 + h).min(1.0);
            cells.push((u0, u1));
            u0 = u1;
            h *= 1.05;
        }
        let mut s = 0.0;
        for &(u0, u1) in cells.iter().rev() {
            let mut t = 0.0;
            for (&x, &w) in rx.iter().zip(&rw) {
                let u = u0 + (u1 - u0) * x;
                t += w * (-(a * u + c * u * u)).exp();
            }
            s += t * (u1 - u0);
        }
        s
    }

    fn rel(x: f64, y: f64) -> f64 {
        if x == y {
            0.0
        } else {
            (x - y).abs() / y.abs()
        }
    }

    /// The brief's grid (0, 1e-8, 1, 50, 1e4) and more.
    const GRID: [f64; 21] = [
        0.0, 1e-300, 1e-12, 1e-8, 1e-4, 1e-3, 0.01, 0.1, 0.5, 1.0, 1.5, 2.0, 3.0, 7.5, 10.0, 29.0,
        50.0, 90.0, 1e3, 1e4, 1e6,
    ];

    #[test]
    fn tables_are_gauss_legendre_rules() {
        for (rule, &n) in RULES.iter().zip(ORDERS.iter()) {
            assert_eq!(rule.x.len(), n);
            let s: f64 = rule.w.iter().sum();
            assert!((s - 1.0).abs() < 1e-15, "n={n} sum={s}");
            // Exact for degree 2n−1: ∫ u^k = 1/(k+1).
            for k in [1, n, 2 * n - 1] {
                let q: f64 = rule
                    .x
                    .iter()
                    .zip(rule.w)
                    .map(|(x, w)| w * x.powi(k as i32))
                    .sum();
                assert!(rel(q, 1.0 / (k + 1) as f64) < 1e-14, "n={n} k={k} q={q}");
            }
            let (nx, nw) = newton_gauss_legendre(n);
            for i in 0..n {
                assert!((nx[i] - rule.x[i]).abs() < 1e-15 && (nw[i] - rule.w[i]).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn psi_matches_brute_force_on_grid() {
        let mut worst = (0.0, 0.0, 0.0);
        for &a in &GRID {
            for &b in &GRID {
                let e = rel(psi(a, b), brute(a, b));
                if e > worst.0 {
                    worst = (e, a, b);
                }
            }
        }
        assert!(
            worst.0 < 1e-14,
            "worst relative error {:e} at a={} b={}",
            worst.0,
            worst.1,
            worst.2
        );
    }

    #[test]
    fn psi_matches_brute_force_dense() {
        // 121² log-spaced points over [1e-6, 1e6]: crosses every rule threshold
        // and both piece boundaries, b < a and b > a.
        let mut worst = (0.0, 0.0, 0.0);
        let vals: Vec<f64> = (0..=120)
            .map(|i| 1e-6 * 10f64.powf(i as f64 / 10.0))
            .collect();
        for &a in &vals {
            for &b in &vals {
                let e = rel(psi(a, b), brute(a, b));
                if e > worst.0 {
                    worst = (e, a, b);
                }
            }
        }
        assert!(
            worst.0 < 1e-14,
            "worst relative error {:e} at a={} b={}",
            worst.0,
            worst.1,
            worst.2
        );
    }

    /// (a, b, Ψ, 1 − Ψ, Ψ − ζ) computed with mpmath at 50 digits
    /// (`mp.quad(lambda u: exp(-a*u-(b-a)*u*u/2), [0, 1e-16, …, 0.1, 0.25, …, 1])`).
    #[allow(clippy::excessive_precision)] // 20 digits on purpose
    const MPMATH: [(f64, f64, f64, f64, f64); 27] = [
        (0.0, 0.0, 1.0, 0.0, 0.0),
        (
            1e-08,
            1e-08,
            0.99999999500000001667,
            4.9999999833333334796e-9,
            4.9999999666666668963e-9,
        ),
        (
            1e-08,
            0.0,
            0.99999999666666667333,
            3.3333333266666667459e-9,
            1.6666666608333333795e-9,
        ),
        (
            0.0,
            1e-08,
            0.99999999833333333583,
            1.6666666641666667045e-9,
            3.3333333233333334209e-9,
        ),
        (
            1e-08,
            1.0,
            0.85562438920292406639,
            0.14437561079707593361,
            0.24909373252294393377,
        ),
        (
            1.0,
            1e-08,
            0.72477845794176973625,
            0.27522154205823026375,
            0.11824780126178960362,
        ),
        (
            1.0,
            1.0,
            0.6321205588285576784,
            0.3678794411714423216,
            0.26424111765711535681,
        ),
        (
            1.0,
            50.0,
            0.16033365583297371324,
            0.83966634416702628676,
            0.16033365582455024948,
        ),
        (
            50.0,
            1.0,
            0.020417689211909953495,
            0.97958231078809004651,
            0.02041768920348648974,
        ),
        (50.0, 50.0, 0.02, 0.98, 0.02),
        (
            10000.0,
            1.0,
            0.00010001000200090063057,
            0.99989998999799909937,
            0.00010001000200090063057,
        ),
        (
            1.0,
            10000.0,
            0.012434381508909544164,
            0.98756561849109045584,
            0.012434381508909544164,
        ),
        (10000.0, 10000.0, 0.0001, 0.9999, 0.0001),
        (
            0.0,
            10000.0,
            0.012533141373155002512,
            0.98746685862684499749,
            0.012533141373155002512,
        ),
        (
            10000.0,
            0.0,
            0.00010001000300150105095,
            0.99989998999699849895,
            0.00010001000300150105095,
        ),
        (
            0.3,
            2.7,
            0.63068073143373892713,
            0.36931926856626107287,
            0.40755057128530911677,
        ),
        (
            2.7,
            0.3,
            0.42887791006914223029,
            0.57112208993085776971,
            0.20574774992071241994,
        ),
        (
            29.9,
            30.1,
            0.033437339091240368452,
            0.96656266090875963155,
            0.033437339091146792222,
        ),
        (
            59.0,
            61.0,
            0.016939431185377962653,
            0.98306056881462203735,
            0.016939431185377962653,
        ),
        (
            100.0,
            0.0,
            0.010103161564918598872,
            0.98989683843508140113,
            0.010103161564918598872,
        ),
        (
            0.0,
            100.0,
            0.12533141373155002512,
            0.87466858626844997488,
            0.12533141373155002512,
        ),
        (
            7.0,
            300000.0,
            0.0022651065164912728213,
            0.99773489348350872718,
            0.0022651065164912728213,
        ),
        (1000000.0, 1000000.0, 1.0e-6, 0.999999, 1.0e-6),
        (
            0.001,
            0.25,
            0.95953519511597622247,
            0.040464804884023777527,
            0.077479430688943348442,
        ),
        (
            0.5,
            1.5,
            0.68660648771857712099,
            0.31339351228142287901,
            0.3187270465471347994,
        ),
        (
            44.0,
            46.0,
            0.022703866530806792126,
            0.97729613346919320787,
            0.022703866530806792097,
        ),
        (
            12.0,
            13.0,
            0.082766001502731798919,
            0.91723399849726820108,
            0.082762274849559720248,
        ),
    ];

    #[test]
    fn psi_matches_high_precision_values() {
        for (a, b, p, omp, pmz) in MPMATH {
            assert!(
                rel(psi(a, b), p) < 1e-15,
                "psi({a}, {b}) = {} vs {p}",
                psi(a, b)
            );
            let t = psi_terms(a, b);
            assert!(
                rel(t.psi, p) < 1e-15,
                "terms({a}, {b}).psi = {} vs {p}",
                t.psi
            );
            assert!(
                rel(t.one_minus_psi, omp) < 1e-14 || (omp == 0.0 && t.one_minus_psi == 0.0),
                "1-psi({a}, {b}) = {} vs {omp}",
                t.one_minus_psi
            );
            assert!(
                rel(t.psi_minus_zeta, pmz) < 1e-14 || (pmz == 0.0 && t.psi_minus_zeta == 0.0),
                "psi-zeta({a}, {b}) = {} vs {pmz}",
                t.psi_minus_zeta
            );
        }
    }

    #[test]
    fn special_cases() {
        assert_eq!(psi(0.0, 0.0), 1.0);
        assert_eq!(psi(-1.0, 0.0), 1.0);
        assert_eq!(psi(f64::INFINITY, 1.0), 0.0);
        assert_eq!(psi(1.0, f64::INFINITY), 0.0);
        assert!(psi(f64::NAN, 1.0).is_nan());
        // Constant attenuation: Ψ = (1 − e^−x)/x = −expm1(−x)/x.
        for &x in &[
            1e-8f64, 1e-3, 0.3, 1.0, 5.0, 8.0, 20.0, 29.0, 31.0, 40.0, 60.0, 1e4, 1e12,
        ] {
            let exact = -(-x).exp_m1() / x;
            assert!(
                rel(psi(x, x), exact) < 5e-16,
                "x={x}: {} vs {exact}",
                psi(x, x)
            );
        }
        // Huge: Ψ ≈ 1/a for a = b ≫ 1; Gaussian limit √(π/(2b)) for a = 0.
        let a = 1e15;
        assert!(rel(psi(a, a), 1.0 / a) < 5e-16);
        let b = 1e12;
        assert!(rel(psi(0.0, b), (std::f64::consts::PI / (2.0 * b)).sqrt()) < 5e-16);
        // Near overflow: no inf/NaN, same asymptotics.
        assert!(rel(psi(1e300, 1e300), 1e-300) < 5e-16);
        assert!(rel(psi(1e300, 0.0), 1e-300) < 1e-15);
        assert!(rel(psi(0.0, 1e300), (std::f64::consts::PI / 2e300).sqrt()) < 5e-16);
        let p = psi(f64::MAX, f64::MAX); // ≈ 1/MAX, subnormal
        assert!((0.0..1e-307).contains(&p));
    }

    #[test]
    fn terms_are_consistent() {
        for &a in &GRID {
            for &b in &GRID {
                let t = psi_terms(a, b);
                let p = brute(a, b);
                assert!(rel(t.psi, p) < 1e-14, "psi a={a} b={b}");
                assert!(rel(t.zeta, (-(0.5 * (a + b))).exp()) < 1e-15);
                if 0.5 * (a + b) > 1.0 {
                    assert!(rel(t.one_minus_psi, 1.0 - p) < 1e-13, "1-psi a={a} b={b}");
                    assert!(
                        rel(t.psi_minus_zeta, p - t.zeta) < 1e-13,
                        "psi-zeta a={a} b={b}"
                    );
                }
            }
        }
        // Thin segments: 1 − Ψ ≈ a/3 + b/6 and Ψ − ζ ≈ a/6 + b/3 to first order.
        for &(a, b) in &[(1e-12, 3e-12), (2e-12, 0.0), (0.0, 5e-13), (1e-11, 1e-11)] {
            let t = psi_terms(a, b);
            assert!(
                rel(t.one_minus_psi, a / 3.0 + b / 6.0) < 1e-10,
                "{a} {b} {t:?}"
            );
            assert!(
                rel(t.psi_minus_zeta, a / 6.0 + b / 3.0) < 1e-10,
                "{a} {b} {t:?}"
            );
        }
    }
}
