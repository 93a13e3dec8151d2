//! Exact emission–absorption integration of one ray segment through a cell
//! (SPEC §2, "reference" row), and front-to-back compositing of segments.
//!
//! Along a segment the scalar is linear (it is linear inside a tet), so it is
//! split at every transfer-function control point it crosses; on each piece
//! colour L and attenuation τ are linear in depth and the piece integrates
//! exactly to `C = L_b·(Ψ − ζ) + L_f·(1 − Ψ)`, `α = 1 − ζ` (see [`mod@super::psi`]).
//!
//! Transfer-function conventions (matching `TransferFunction::eval`): linear
//! between control points, clamped outside them; at a step (two points with
//! the same scalar) each piece uses the one-sided values of the interval it
//! lies in, so a step is honoured exactly. A constant-scalar segment sitting
//! exactly on a step takes the right-hand value, as `eval` does. Negative
//! attenuations are treated as 0.
//!
//! Opacity is carried as optical depth (`∫τ`), not as α, so that
//! `α = −expm1(−depth)` keeps full relative precision for thin media and the
//! composited transmittance is `exp(−Σ depth)` exactly.

use crate::scene::TransferFunction;

use super::psi::psi_terms;

/// The integral over one segment: premultiplied colour and optical depth.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Segment {
    /// Premultiplied emitted colour seen at the segment's front end.
    pub color: [f64; 3],
    /// ∫τ over the segment; transmittance is `exp(−optical_depth)`.
    pub optical_depth: f64,
}

impl Segment {
    /// Opacity `1 − exp(−optical_depth)`.
    pub fn alpha(&self) -> f64 {
        -(-self.optical_depth).exp_m1()
    }

    /// Premultiplied RGBA.
    pub fn rgba(&self) -> [f64; 4] {
        [self.color[0], self.color[1], self.color[2], self.alpha()]
    }

    /// `self` over `behind` (front-to-back composition of two segments).
    pub fn over(&self, behind: &Segment) -> Segment {
        let t = (-self.optical_depth).exp();
        Segment {
            color: [
                self.color[0] + t * behind.color[0],
                self.color[1] + t * behind.color[1],
                self.color[2] + t * behind.color[2],
            ],
            optical_depth: self.optical_depth + behind.optical_depth,
        }
    }
}

/// One piece of the emission–absorption integral with colour and attenuation
/// linear in depth: front values (`l_f`, `tau_f`), back values (`l_b`,
/// `tau_b`), length `d`.
pub fn integrate_piece(l_f: [f64; 3], tau_f: f64, l_b: [f64; 3], tau_b: f64, d: f64) -> Segment {
    let a = tau_f.max(0.0) * d;
    let b = tau_b.max(0.0) * d;
    if !(a > 0.0 || b > 0.0) {
        return Segment::default();
    }
    let t = psi_terms(a, b);
    let col = |i: usize| l_b[i] * t.psi_minus_zeta + l_f[i] * t.one_minus_psi;
    Segment {
        color: [col(0), col(1), col(2)],
        optical_depth: 0.5 * (a + b),
    }
}

/// The exact integral over a segment of length `length` whose scalar goes
/// linearly from `s_front` (the end nearer the eye) to `s_back`.
pub fn integrate_segment(tf: &TransferFunction, s_front: f64, s_back: f64, length: f64) -> Segment {
    if length.is_nan() || length <= 0.0 {
        return Segment::default();
    }
    let pts = &tf.points[..];
    let ds = s_back - s_front;
    // Control points strictly inside the scalar range, in the order the ray meets them.
    let (lo, hi) = if ds >= 0.0 {
        (s_front, s_back)
    } else {
        (s_back, s_front)
    };
    let first = pts.partition_point(|p| p.scalar <= lo);
    let last = pts.partition_point(|p| p.scalar < hi);
    let inner = if first < last {
        &pts[first..last]
    } else {
        &pts[0..0]
    };
    let piece = |sa: f64, sb: f64, ua: f64, ub: f64| -> Segment {
        let tfp = tf.piece_at(0.5 * (sa + sb));
        let (lf, tf_) = tfp.eval(sa);
        let (lb, tb) = tfp.eval(sb);
        integrate_piece(lf, tf_, lb, tb, length * (ub - ua))
    };
    let mut acc = Segment::default();
    let (mut sa, mut ua) = (s_front, 0.0);
    let mut cut = |sb: f64, acc: &mut Segment| {
        let ub = ((sb - s_front) / ds).clamp(0.0, 1.0);
        if ub > ua {
            *acc = acc.over(&piece(sa, sb, ua, ub));
        }
        sa = sb;
        ua = ub;
    };
    if ds >= 0.0 {
        inner.iter().for_each(|p| cut(p.scalar, &mut acc));
    } else {
        inner.iter().rev().for_each(|p| cut(p.scalar, &mut acc));
    }
    if ua < 1.0 {
        // The last piece (the only one if no control point is crossed).
        acc = acc.over(&piece(sa, s_back, ua, 1.0));
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::ControlPoint;

    fn tf(points: &[(f64, [f64; 3], f64)]) -> TransferFunction {
        TransferFunction {
            name: "t".into(),
            points: points
                .iter()
                .map(|&(scalar, color, attenuation)| ControlPoint {
                    scalar,
                    color,
                    attenuation,
                })
                .collect(),
        }
    }

    /// Brute force on the original integral ∫ L(s(x)) τ(s(x)) exp(−∫₀ˣ τ) dx
    /// with `TransferFunction::eval`: composite Simpson on each stretch between
    /// the control points the scalar crosses (end samples nudged 1e-12 inside
    /// the stretch so steps take the right side), the inner integral by the
    /// same Simpson sums (exact for τ linear on a cell).
    fn brute(tf: &TransferFunction, s0: f64, s1: f64, d: f64, n: usize) -> [f64; 4] {
        let mut cuts = vec![0.0];
        for p in &tf.points {
            let u = (p.scalar - s0) / (s1 - s0);
            if u > 0.0 && u < 1.0 {
                cuts.push(u);
            }
        }
        cuts.push(1.0);
        cuts.sort_by(f64::total_cmp);
        let (mut depth, mut col) = (0.0, [0.0; 3]);
        for w in cuts.windows(2) {
            let (ua, ub) = (w[0], w[1]);
            if ub <= ua {
                continue;
            }
            let at = |u: f64| {
                let u = u.clamp(ua + 1e-12 * (ub - ua), ub - 1e-12 * (ub - ua));
                tf.eval(s0 + (s1 - s0) * u)
            };
            let h = (ub - ua) / n as f64;
            for k in 0..n {
                let u0 = ua + k as f64 * h;
                let (um, u1) = (u0 + 0.5 * h, u0 + h);
                let ((c0, t0), (cm, tm), (c1, t1)) = (at(u0), at(um), at(u1));
                let dm = depth + 0.25 * h * d * (t0 + tm);
                let d1 = depth + h * d / 6.0 * (t0 + 4.0 * tm + t1);
                let (w0, wm, w1) = (t0 * (-depth).exp(), tm * (-dm).exp(), t1 * (-d1).exp());
                for i in 0..3 {
                    col[i] += h * d / 6.0 * (c0[i] * w0 + 4.0 * cm[i] * wm + c1[i] * w1);
                }
                depth = d1;
            }
        }
        [col[0], col[1], col[2], 1.0 - (-depth).exp()]
    }

    #[test]
    fn constant_medium() {
        let tf = TransferFunction::constant([0.2, 0.5, 1.0], 3.0);
        let s = integrate_segment(&tf, 0.3, 0.7, 0.5);
        let alpha = 1.0 - (-1.5f64).exp();
        assert!((s.alpha() - alpha).abs() < 1e-15);
        for i in 0..3 {
            assert!((s.color[i] - tf.points[0].color[i] * alpha).abs() < 1e-15);
        }
    }

    #[test]
    fn matches_brute_force_with_steps_and_both_directions() {
        let tf = tf(&[
            (0.1, [0.0, 0.0, 1.0], 0.0),
            (0.3, [0.0, 1.0, 0.0], 2.0),
            (0.5, [1.0, 0.0, 0.0], 6.0),
            (0.5, [0.2, 0.2, 0.2], 0.5), // step
            (0.9, [1.0, 1.0, 0.0], 9.0),
        ]);
        for &(s0, s1, d) in &[
            (0.0, 1.0, 0.7),
            (1.0, 0.0, 0.7),
            (0.2, 0.45, 1.3),
            (0.6, 0.35, 0.2),
            (0.5, 0.8, 1.0),
            (0.95, 2.0, 1.0),
        ] {
            let seg = integrate_segment(&tf, s0, s1, d).rgba();
            let acc = brute(&tf, s0, s1, d, 4000);
            for i in 0..4 {
                assert!(
                    (seg[i] - acc[i]).abs() < 1e-9,
                    "{s0}->{s1} d={d} ch{i}: {} vs {}",
                    seg[i],
                    acc[i]
                );
            }
        }
    }
}
