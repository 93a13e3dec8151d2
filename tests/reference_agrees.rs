//! The method side and the CPU reference compute the same integrals with
//! separate code (issue 23 item 3): Ψ in closed form (`algo::psi`) against
//! Gauss–Legendre quadrature (`reference::psi`), the method's segment
//! integral and tables (`algo::segment`, `algo::integrate`) against the
//! reference's (`reference::integrate`), the ray casters' brick flags
//! (`algo::raycast::bricks`) against the reference's cell flags
//! (`reference::volume`). Each comparison holds within a tolerance derived
//! from the two sides' error bounds, stated where it is used; the worst
//! disagreement seen is printed (`cargo test --test reference_agrees -- --nocapture`).

use volbench::algo::integrate::{preint_table, psi_table};
use volbench::algo::psi::{psi as method_psi, C_SERIES, PSI_REL_ERROR};
use volbench::algo::raycast::bricks;
use volbench::algo::segment;
use volbench::reference;
use volbench::scene::{ControlPoint, TransferFunction};
use volbench::volume::{Samples, Volume};

/// The reference's Ψ is within 1e-15 relative of 40-digit values
/// (`reference/psi.rs`, its tests).
const REFERENCE_REL_ERROR: f64 = 1e-15;

/// Both sides' bounds on Ψ's relative error, added.
const PSI_TOLERANCE: f64 = PSI_REL_ERROR + REFERENCE_REL_ERROR;

fn rel(x: f64, y: f64) -> f64 {
    if x == y {
        0.0
    } else {
        (x - y).abs() / y.abs()
    }
}

/// Every value the reference's own tests use, plus both sides of the
/// method's series/closed-form seam and of the reference's piece seams.
fn psi_arguments() -> Vec<f64> {
    let mut v = vec![
        0.0, 1e-300, 1e-12, 1e-8, 1e-4, 1e-3, 0.01, 0.1, 0.5, 1.0, 1.5, 2.0, 3.0, 7.5, 10.0, 29.0, 30.0, 45.0, 50.0, 90.0, 1e3, 1e4, 1e6, 1e12,
    ];
    v.extend((0..=120).map(|i| 1e-6 * 10f64.powf(i as f64 / 10.0)));
    v
}

#[test]
fn psi_agrees_on_a_grid() {
    let args = psi_arguments();
    let mut pairs: Vec<(f64, f64)> = args.iter().flat_map(|&a| args.iter().map(move |&b| (a, b))).collect();
    // Across |c| = C_SERIES, c = (b − a)/2, on both sides and both signs.
    for &a in &[0.0, 1e-3, 0.5, 1.9, 2.0, 2.1, 40.0, 5e3] {
        for f in [0.5, 0.999, 1.0, 1.001, 2.0] {
            pairs.push((a, a + 2.0 * C_SERIES * f));
            pairs.push((a + 2.0 * C_SERIES * f, a));
        }
    }
    let mut worst = (0.0, 0.0, 0.0);
    for (a, b) in pairs {
        let (m, r) = (method_psi(a, b), reference::psi(a, b));
        let e = rel(m, r);
        if e > worst.0 {
            worst = (e, a, b);
        }
        assert!(e <= PSI_TOLERANCE, "Ψ({a}, {b}): method {m:e}, reference {r:e}, relative {e:e} > {PSI_TOLERANCE:e}");
    }
    eprintln!("Ψ: worst relative disagreement {:e} at a={} b={} (tolerance {PSI_TOLERANCE:e})", worst.0, worst.1, worst.2);
}

/// The Ψ table the GPU reads (f32) at two sizes: each entry within the
/// method's bound of the reference plus the f32 rounding (half an ulp,
/// 2⁻²⁴ relative).
#[test]
fn psi_tables_agree_at_two_sizes() {
    for m in [65usize, 512] {
        let table = psi_table(m).unwrap();
        let tau_d = |j: usize| {
            let g = j as f64 / (m - 1) as f64;
            if g >= 1.0 {
                f64::INFINITY
            } else {
                g / (1.0 - g)
            }
        };
        let mut worst = 0.0f64;
        for jb in 0..m {
            for jf in 0..m {
                let r = reference::psi(tau_d(jf), tau_d(jb));
                let t = table[jb * m + jf] as f64;
                let tol = r * (PSI_TOLERANCE + 2f64.powi(-24));
                worst = worst.max((t - r).abs() / r.max(f64::MIN_POSITIVE));
                assert!((t - r).abs() <= tol, "m={m} (front {jf}, back {jb}): table {t:e}, reference {r:e}");
            }
        }
        eprintln!("Ψ table {m}²: worst relative disagreement {worst:e}");
    }
}

fn tf(name: &str, points: &[(f64, [f64; 3], f64)]) -> TransferFunction {
    TransferFunction {
        name: name.into(),
        points: points.iter().map(|&(scalar, color, attenuation)| ControlPoint { scalar, color, attenuation }).collect(),
    }
}

/// Transfer functions with what a segment integral must get right: linear
/// pieces, steps (also a step to zero), a transparent stretch, colours
/// above 1, steep attenuation, one control point.
fn transfer_functions() -> Vec<TransferFunction> {
    vec![
        TransferFunction::constant([0.2, 0.5, 1.0], 3.0),
        tf("ramp", &[(0.0, [0.0, 0.0, 1.0], 0.0), (1.0, [1.0, 0.5, 0.0], 8.0)]),
        tf(
            "steps",
            &[
                (0.1, [0.0, 0.0, 1.0], 0.0),
                (0.3, [0.0, 1.0, 0.0], 2.0),
                (0.5, [1.0, 0.0, 0.0], 6.0),
                (0.5, [0.2, 0.2, 0.2], 0.5),
                (0.9, [1.0, 1.0, 0.0], 9.0),
                (0.9, [1.0, 1.0, 1.0], 0.0),
            ],
        ),
        tf("bright", &[(0.0, [4.0, 2.0, 0.5], 1e-3), (0.4, [0.0, 3.0, 1.0], 40.0), (0.6, [2.0, 0.0, 1.0], 1e4), (1.0, [0.1, 0.1, 0.1], 0.2)]),
        tf("one point", &[(0.5, [0.3, 0.6, 0.9], 1.5)]),
    ]
}

/// Segment integrals over a grid of (length, s_front, s_back) that includes
/// the control points' scalars exactly, values outside the transfer
/// function's range and constant segments. Tolerance per colour channel:
/// each of the ≤ n pieces (n − 1 control points crossed) contributes
/// L_b(Ψ − ζ) + L_f(1 − Ψ) with both Ψs within their bounds and a few
/// roundings, so |Δ| ≤ n·2·L_max·(PSI_TOLERANCE + 8ε); opacity
/// 1 − exp(−Σ depth) differs by roundings of the depth sum only, ≤ 8·n·ε.
#[test]
fn segment_integrals_agree_on_a_grid() {
    let lengths = [1e-9, 1e-4, 0.01, 0.3, 1.0, 7.0, 100.0, 1e5];
    let mut worst = 0.0f64;
    for tf in transfer_functions() {
        let mut scalars: Vec<f64> = (0..=14).map(|i| -0.2 + 0.1 * i as f64).collect();
        scalars.extend(tf.points.iter().map(|p| p.scalar));
        let l_max = tf.points.iter().flat_map(|p| p.color).fold(0.0, |m: f64, c| m.max(c.abs()));
        let pieces = (tf.points.len() + 1) as f64;
        let tol_color = pieces * 2.0 * l_max * (PSI_TOLERANCE + 8.0 * f64::EPSILON);
        let tol_alpha = 8.0 * pieces * f64::EPSILON;
        for &len in &lengths {
            for &sf in &scalars {
                for &sb in &scalars {
                    let m = segment::integrate_segment(&tf, sf, sb, len).rgba();
                    let r = reference::integrate_segment(&tf, sf, sb, len).rgba();
                    for k in 0..4 {
                        let tol = if k == 3 { tol_alpha } else { tol_color };
                        let d = (m[k] - r[k]).abs();
                        worst = worst.max(d);
                        assert!(d <= tol, "'{}' {sf}->{sb} length {len} channel {k}: method {:e}, reference {:e} (|Δ| {d:e} > {tol:e})", tf.name, m[k], r[k]);
                    }
                }
            }
        }
    }
    eprintln!("segments: worst absolute disagreement {worst:e}");
}

/// The cell-projection pre-integration table (f32) at two sizes: every
/// entry as above plus f32 rounding (2⁻²⁴ of the larger of value and 1e-30).
#[test]
fn preint_tables_agree_at_two_sizes() {
    for tf in transfer_functions() {
        let l_max = tf.points.iter().flat_map(|p| p.color).fold(0.0, |m: f64, c| m.max(c.abs()));
        let pieces = (tf.points.len() + 1) as f64;
        for n in [8usize, 24] {
            let (range, scale) = ((-0.1, 1.1), 0.25);
            let table = preint_table(&tf, range, n, scale).unwrap();
            let nd = (n / 4).max(2);
            for d in 0..nd {
                let x = d as f64 / (nd - 1) as f64;
                let len = if x >= 1.0 { 1e6 * scale } else { scale * x / (1.0 - x) };
                for b in 0..n {
                    for f in 0..n {
                        let s = |i: usize| range.0 + (range.1 - range.0) * i as f64 / (n - 1) as f64;
                        let r = reference::integrate_segment(&tf, s(f), s(b), len).rgba();
                        let t = table[(d * n + b) * n + f];
                        for k in 0..4 {
                            let tol = if k == 3 { 8.0 * pieces * f64::EPSILON } else { pieces * 2.0 * l_max * (PSI_TOLERANCE + 8.0 * f64::EPSILON) };
                            let tol = tol + r[k].abs().max(1e-30) * 2f64.powi(-24);
                            assert!((t[k] as f64 - r[k]).abs() <= tol, "'{}' n={n} entry ({f}, {b}, {d}) channel {k}: {} vs {}", tf.name, t[k], r[k]);
                        }
                    }
                }
            }
        }
    }
}

fn hashed_volume(dims: [usize; 3], seed: u64) -> Volume {
    let mut s = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let h = ((i as f64 * 12.9898 + j as f64 * 78.233 + k as f64 * 37.719 + seed as f64).sin() * 43758.5453).fract().abs();
                s.push(h as f32);
            }
        }
    }
    Volume::new("test", "hashed", dims, [1.0; 3], [0.0; 3], Samples::F32(s)).unwrap()
}

/// The ray casters' brick flags and the reference's (which flags cells,
/// brick 1, and bricks for its own tests) are booleans: equal, exactly, for
/// every brick size, shape and transfer function tried (with a transparent
/// stretch ending at a step, ramps starting at zero, all-transparent).
#[test]
fn brick_flags_agree() {
    let mut tfs = transfer_functions();
    tfs.push(tf("transparent below 0.8", &[(0.0, [1.0; 3], 0.0), (0.8, [1.0; 3], 0.0), (1.0, [1.0; 3], 1.0)]));
    tfs.push(tf("step at 0.3", &[(0.3, [1.0; 3], 0.0), (0.3, [1.0; 3], 2.0), (0.6, [1.0; 3], 2.0), (0.6, [1.0; 3], 0.0)]));
    tfs.push(tf("transparent", &[(0.0, [1.0; 3], 0.0), (1.0, [1.0; 3], 0.0)]));
    let mut flagged = 0usize;
    for (n, dims) in [[2, 2, 2], [9, 5, 3], [12, 7, 11], [17, 16, 2]].into_iter().enumerate() {
        let vol = hashed_volume(dims, n as u64);
        for brick in 1..=5 {
            assert_eq!(bricks::grid_of(dims, brick), reference::volume::brick_grid(dims, brick), "{dims:?} brick {brick}");
            for tf in &tfs {
                let ours = bricks::attenuating(vol.dims(), vol.samples(), tf, brick);
                assert_eq!(ours, reference::volume::attenuating_bricks(&vol, tf, brick).iter().collect::<Vec<_>>(), "'{}' {dims:?} brick {brick}", tf.name);
                flagged += ours.iter().filter(|&&f| f).count();
            }
        }
    }
    assert!(flagged > 0, "some bricks are flagged (the comparison is not all-false)");
}
