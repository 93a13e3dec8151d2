//! Transfer functions: scalar -> (emitted colour L, attenuation tau per unit
//! length), piecewise linear between control points and clamped outside them.
//! The CPU reference evaluates the control points exactly; the GPU samples a
//! table of them (see `table`).

use serde::{Deserialize, Serialize};

/// Largest magnitude a table entry takes (see `TransferFunction::table`).
pub const TABLE_MAX: f64 = 1e30;

/// Half-width of the range a constant field's transfer function is spread
/// over, relative to the field's magnitude (at least 1): see
/// [`effective_scalar_range`].
pub const DEGENERATE_RANGE_HALF_WIDTH: f64 = 0.5;

/// The scalar range a range-relative transfer function is built over (the
/// one rule for it: `scene::tf_file`'s relative units, and the built-in
/// presets). A field's range `[lo, hi]` with `hi > lo` is used as is. A
/// constant field (`lo == hi == v`) would put every control point at `v`,
/// a step exactly at the only value the field takes, whose side the GPU
/// table and the CPU reference may then take differently; instead the range
/// is widened symmetrically to `[v - w, v + w]` with
/// `w = DEGENERATE_RANGE_HALF_WIDTH * max(|v|, 1)`, so the field's value
/// sits at relative 0.5, between control points (wide enough to stay
/// distinct from `v` in f64 and f32 whatever `v` is). Anything else
/// (`hi < lo`, non-finite) is returned unchanged for the caller to reject.
pub fn effective_scalar_range(lo: f64, hi: f64) -> (f64, f64) {
    if lo == hi && lo.is_finite() {
        let w = DEGENERATE_RANGE_HALF_WIDTH * lo.abs().max(1.0);
        (lo - w, lo + w)
    } else {
        (lo, hi)
    }
}

/// One linear interval of a transfer function (see
/// [`TransferFunction::piece_at`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TfPiece {
    /// Below the first point or from the last on (or no points at all).
    Const([f64; 3], f64),
    /// Between two consecutive points at different scalars.
    Linear(ControlPoint, ControlPoint),
}

impl TfPiece {
    /// Colour and attenuation at `s`, extending the piece linearly (the
    /// reference evaluates a piece at its ends).
    pub fn eval(&self, s: f64) -> ([f64; 3], f64) {
        match *self {
            TfPiece::Const(c, tau) => (c, tau),
            TfPiece::Linear(p, q) => {
                let t = (s - p.scalar) / (q.scalar - p.scalar);
                let lerp = |x: f64, y: f64| x + (y - x) * t;
                (
                    [lerp(p.color[0], q.color[0]), lerp(p.color[1], q.color[1]), lerp(p.color[2], q.color[2])],
                    lerp(p.attenuation, q.attenuation),
                )
            }
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ControlPoint {
    pub scalar: f64,
    /// Emitted colour (the "L" of the emission-absorption model), linear RGB.
    pub color: [f64; 3],
    /// Attenuation coefficient tau, per world unit of length.
    pub attenuation: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransferFunction {
    pub name: String,
    /// Sorted by scalar; equal scalars make a step.
    pub points: Vec<ControlPoint>,
}

impl TransferFunction {
    /// Constant colour and attenuation everywhere (the homogeneous medium).
    pub fn constant(color: [f64; 3], attenuation: f64) -> Self {
        TransferFunction {
            name: "constant".into(),
            points: vec![ControlPoint { scalar: 0.0, color, attenuation }],
        }
    }

    pub fn scalar_range(&self) -> (f64, f64) {
        let first = self.points.first().map_or(0.0, |p| p.scalar);
        let last = self.points.last().map_or(0.0, |p| p.scalar);
        (first, last)
    }

    /// Whether anything over scalars [lo, hi] is visibly opaque across a
    /// length `length`: the largest attenuation there (piecewise linear, so
    /// at the ends or a control point) times `length` above 1e-4, well above
    /// what f32 alpha resolves. Used to tell an empty image that must be a
    /// failure from one that is right.
    pub fn visible_over(&self, lo: f64, hi: f64, length: f64) -> bool {
        // Right-continuous (see `piece_at`): the side of a step at `lo`
        // below it is never taken, so only points above `lo` count (the
        // value at `lo` itself is `eval(lo)`).
        let inside = self.points.iter().filter(|p| p.scalar > lo && p.scalar <= hi).map(|p| p.attenuation);
        let max = [self.eval(lo).1, self.eval(hi).1].into_iter().chain(inside).fold(0.0, f64::max);
        max * length > 1e-4
    }

    /// The linear piece that holds scalar `s`: the one rule for where a
    /// scalar falls, used by [`Self::eval`] (hence the GPU tables) and by the
    /// CPU reference's exact integration. The function is right-continuous:
    /// at a step (several points at one scalar) a scalar exactly at the step
    /// takes the value after it, the last point at that scalar; below the
    /// first point and from the last point on it is constant.
    pub fn piece_at(&self, s: f64) -> TfPiece {
        let pts = &self.points;
        let n = pts.len();
        // First point strictly above s; its predecessor is at or below s.
        let i = pts.partition_point(|p| p.scalar <= s);
        if n == 0 {
            TfPiece::Const([0.0; 3], 0.0)
        } else if i == 0 {
            TfPiece::Const(pts[0].color, pts[0].attenuation)
        } else if i == n {
            TfPiece::Const(pts[n - 1].color, pts[n - 1].attenuation)
        } else {
            TfPiece::Linear(pts[i - 1], pts[i])
        }
    }

    /// Colour and attenuation at scalar `s` (right-continuous, see
    /// [`Self::piece_at`]).
    pub fn eval(&self, s: f64) -> ([f64; 3], f64) {
        self.piece_at(s).eval(s)
    }

    /// `n` samples (rgb = colour, a = attenuation) evenly spaced over
    /// `[lo, hi]`, for the GPU's linearly interpolated lookup.
    pub fn table(&self, n: usize, lo: f64, hi: f64) -> Vec<[f32; 4]> {
        let n = n.max(2);
        (0..n)
            .map(|k| {
                let s = lo + (hi - lo) * k as f64 / (n - 1) as f64;
                let (c, tau) = self.eval(s);
                // Clamped so that every entry is finite in f32 (the shaders
                // interpolate entries: Inf + t (Inf - Inf) = NaN); 1e30 per
                // unit length is opaque over 1e-28 of a unit anyway.
                let f = |v: f64| v.clamp(-TABLE_MAX, TABLE_MAX) as f32;
                [f(c[0]), f(c[1]), f(c[2]), f(tau)]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eval_interpolates_and_clamps() {
        let tf = TransferFunction {
            name: "t".into(),
            points: vec![
                ControlPoint { scalar: 0.0, color: [0.0, 0.0, 0.0], attenuation: 0.0 },
                ControlPoint { scalar: 2.0, color: [1.0, 0.5, 0.0], attenuation: 4.0 },
            ],
        };
        assert_eq!(tf.eval(-1.0), ([0.0; 3], 0.0));
        assert_eq!(tf.eval(1.0), ([0.5, 0.25, 0.0], 2.0));
        assert_eq!(tf.eval(5.0), ([1.0, 0.5, 0.0], 4.0));
    }

    #[test]
    fn steps_are_right_continuous_wherever_they_are() {
        let pt = |scalar: f64, attenuation: f64| ControlPoint { scalar, color: [1.0; 3], attenuation };
        // A step at the first point, in the middle and at the last point:
        // at the step's scalar the value after it applies.
        let tf = TransferFunction {
            name: "t".into(),
            points: vec![pt(1.0, 0.0), pt(1.0, 5.0), pt(2.0, 5.0), pt(2.0, 1.0), pt(3.0, 7.0), pt(3.0, 0.0)],
        };
        assert_eq!(tf.eval(1.0).1, 5.0);
        assert_eq!(tf.eval(2.0).1, 1.0);
        assert_eq!(tf.eval(3.0).1, 0.0);
        assert_eq!(tf.eval(0.5).1, 0.0);
        assert_eq!(tf.eval(2.5).1, 4.0);
        // What is visible over a constant field follows the same rule.
        assert!(tf.visible_over(1.0, 1.0, 1.0));
        assert!(!tf.visible_over(3.0, 3.0, 1.0));
        assert!(tf.visible_over(2.5, 3.0, 1.0));
    }

    #[test]
    fn effective_range_widens_only_constant_fields() {
        assert_eq!(effective_scalar_range(-1.0, 2.0), (-1.0, 2.0));
        assert_eq!(effective_scalar_range(1.0, 1.0 + f64::EPSILON), (1.0, 1.0 + f64::EPSILON));
        assert_eq!(effective_scalar_range(0.0, 0.0), (-0.5, 0.5));
        assert_eq!(effective_scalar_range(3.0, 3.0), (1.5, 4.5));
        assert_eq!(effective_scalar_range(-1e20, -1e20), (-1.5e20, -0.5e20));
        assert_eq!(effective_scalar_range(2.0, 1.0), (2.0, 1.0));
        assert!(effective_scalar_range(f64::NAN, f64::NAN).0.is_nan());
        for v in [0.0, 1e-30, -7.0, 1e6, 3e38] {
            let (lo, hi) = effective_scalar_range(v, v);
            assert!(lo < v && v < hi && (lo as f32) < (v as f32) && (v as f32) < (hi as f32), "{v}");
        }
    }
}
