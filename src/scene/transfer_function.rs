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
        let inside = self.points.iter().filter(|p| p.scalar >= lo && p.scalar <= hi).map(|p| p.attenuation);
        let max = [self.eval(lo).1, self.eval(hi).1].into_iter().chain(inside).fold(0.0, f64::max);
        max * length > 1e-4
    }

    /// Colour and attenuation at scalar `s`.
    pub fn eval(&self, s: f64) -> ([f64; 3], f64) {
        let pts = &self.points;
        let Some(first) = pts.first() else { return ([0.0; 3], 0.0) };
        if s <= first.scalar || pts.len() == 1 {
            return (first.color, first.attenuation);
        }
        let last = pts[pts.len() - 1];
        if s >= last.scalar {
            return (last.color, last.attenuation);
        }
        // First point strictly above s; its predecessor is at or below s.
        let i = pts.partition_point(|p| p.scalar <= s);
        let (a, b) = (pts[i - 1], pts[i]);
        let t = (s - a.scalar) / (b.scalar - a.scalar);
        let lerp = |x: f64, y: f64| x + (y - x) * t;
        (
            [lerp(a.color[0], b.color[0]), lerp(a.color[1], b.color[1]), lerp(a.color[2], b.color[2])],
            lerp(a.attenuation, b.attenuation),
        )
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
