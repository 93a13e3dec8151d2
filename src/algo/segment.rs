//! The exact integral of one ray segment through a transfer function, in
//! f64, for the pre-integration tables the GPU reads (`integrate::preint_table`
//! for cell projection, the ray casters' 2D table): SPEC §2's
//! emission–absorption model with the scalar linear along the segment.
//!
//! The segment is cut where its scalar crosses a control point; on each
//! piece colour L and attenuation τ are linear, so the piece contributes
//! `C = L_b·(Ψ − ζ) + L_f·(1 − Ψ)` and transmittance ζ (Ψ in closed form,
//! [`super::psi`]), composited front to back. The transfer function is
//! read straight from its control points (linear between two, constant
//! outside them; inside a step, i.e. two points at one scalar, a piece
//! takes the side it lies on, and a constant scalar on a step the right-hand
//! value), not through `TransferFunction::eval`. The CPU reference
//! (`reference::integrate`) computes the same integral with its own code;
//! `tests/reference_agrees.rs` compares the two.

use crate::scene::{ControlPoint, TransferFunction};

use super::psi::psi;

/// A segment's integral: premultiplied colour and optical depth ∫τ.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SegmentIntegral {
    pub color: [f64; 3],
    pub optical_depth: f64,
}

impl SegmentIntegral {
    /// Premultiplied RGBA, α = 1 − exp(−∫τ).
    pub fn rgba(&self) -> [f64; 4] {
        let [r, g, b] = self.color;
        [r, g, b, -(-self.optical_depth).exp_m1()]
    }
}

/// The transfer function's colour and attenuation at `s` on the stretch
/// that starts at control point `i` (`None`: below the first point).
fn value_on(points: &[ControlPoint], i: Option<usize>, s: f64) -> ([f64; 3], f64) {
    let (p, q) = match i {
        None => (points[0], points[0]),
        Some(i) if i + 1 >= points.len() => (points[i], points[i]),
        Some(i) => (points[i], points[i + 1]),
    };
    let w = if q.scalar > p.scalar { ((s - p.scalar) / (q.scalar - p.scalar)).clamp(0.0, 1.0) } else { 0.0 };
    let mix = |x: f64, y: f64| x * (1.0 - w) + y * w;
    ([mix(p.color[0], q.color[0]), mix(p.color[1], q.color[1]), mix(p.color[2], q.color[2])], mix(p.attenuation, q.attenuation).max(0.0))
}

/// The stretch holding scalar `s`: the last control point at or below it.
fn stretch_of(points: &[ControlPoint], s: f64) -> Option<usize> {
    points.iter().rposition(|p| p.scalar <= s)
}

/// Colour and attenuation (negative taken as 0) at scalar `s`; on a step,
/// the right-hand value. No control points: nothing.
pub(crate) fn transfer_at(tf: &TransferFunction, s: f64) -> ([f64; 3], f64) {
    if tf.points.is_empty() {
        return ([0.0; 3], 0.0);
    }
    value_on(&tf.points, stretch_of(&tf.points, s), s)
}

/// The integral over a segment of `length` whose scalar runs linearly from
/// `s_front` (the end nearer the eye) to `s_back`.
pub fn integrate_segment(tf: &TransferFunction, s_front: f64, s_back: f64, length: f64) -> SegmentIntegral {
    let points = &tf.points[..];
    if points.is_empty() || !(length > 0.0) {
        return SegmentIntegral::default();
    }
    // Cut points as (fraction of the segment, scalar there), in ray order.
    let mut cuts: Vec<(f64, f64)> = vec![(0.0, s_front)];
    let ds = s_back - s_front;
    if ds != 0.0 {
        let (lo, hi) = (s_front.min(s_back), s_front.max(s_back));
        cuts.extend(points.iter().filter(|p| p.scalar > lo && p.scalar < hi).map(|p| ((p.scalar - s_front) / ds, p.scalar)));
    }
    cuts.push((1.0, s_back));
    cuts.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut out = SegmentIntegral::default();
    let mut transmittance = 1.0;
    for w in cuts.windows(2) {
        let ((u0, s0), (u1, s1)) = (w[0], w[1]);
        if !(u1 > u0) {
            continue;
        }
        let stretch = stretch_of(points, 0.5 * (s0 + s1));
        let ((l_f, tau_f), (l_b, tau_b)) = (value_on(points, stretch, s0), value_on(points, stretch, s1));
        let d = length * (u1 - u0);
        let (a, b) = (tau_f * d, tau_b * d);
        if a + b == 0.0 {
            continue;
        }
        let p = psi(a, b);
        let zeta = (-0.5 * (a + b)).exp();
        for ((c, lb), lf) in out.color.iter_mut().zip(l_b).zip(l_f) {
            *c += transmittance * (lb * (p - zeta) + lf * (1.0 - p));
        }
        out.optical_depth += 0.5 * (a + b);
        transmittance *= zeta;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_medium_is_one_minus_exp() {
        let tf = TransferFunction::constant([0.2, 0.5, 1.0], 3.0);
        let s = integrate_segment(&tf, 0.3, 0.7, 0.5).rgba();
        let alpha = -(-1.5f64).exp_m1();
        assert!((s[3] - alpha).abs() < 1e-15);
        for (k, c) in [0.2, 0.5, 1.0].into_iter().enumerate() {
            assert!((s[k] - c * alpha).abs() < 1e-14, "{s:?}");
        }
    }

    #[test]
    fn empty_and_zero_length_segments_are_transparent() {
        let tf = TransferFunction::constant([1.0; 3], 2.0);
        assert_eq!(integrate_segment(&tf, 0.0, 1.0, 0.0), SegmentIntegral::default());
        assert_eq!(integrate_segment(&tf, 0.0, 1.0, f64::NAN), SegmentIntegral::default());
        let none = TransferFunction { name: "none".into(), points: vec![] };
        assert_eq!(integrate_segment(&none, 0.0, 1.0, 1.0), SegmentIntegral::default());
    }
}
