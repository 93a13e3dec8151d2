//! Transfer functions: scalar -> (emitted colour L, attenuation tau per unit
//! length), piecewise linear between control points and clamped outside them.
//! The CPU reference evaluates the control points exactly; the GPU samples a
//! table of them (see `table`).

use serde::{Deserialize, Serialize};

/// Largest magnitude a table entry takes (see `TransferFunction::table`).
pub const TABLE_MAX: f64 = 1e30;

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
}
