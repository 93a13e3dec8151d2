//! The f64 CPU reference for regular-grid volumes (SPEC §3, §5): every GPU
//! ray-casting image is compared with this.
//!
//! **Field.** Node-centred: sample (i, j, k) sits at `Volume::position(i, j, k)`
//! and the scalar between samples is the trilinear interpolation of the eight
//! samples of the cell around the point. The field is defined on the box of
//! the sample positions (`Volume::bounds`, first to last sample) and is zero
//! density outside it. The GPU methods use the same convention: texel centres
//! at sample positions, i.e. texture coordinate `(u + 0.5) / dims` for voxel
//! coordinate `u = (p − origin) / spacing`.
//!
//! **Integral.** Each pixel's ray (`Camera::ray`, f64) is clipped to the box
//! and to the camera's depth range [near, far] (view-space depth, as for the
//! tet reference), then walked cell by cell (3D DDA in voxel coordinates).
//! Inside a cell the scalar along the ray is cubic; the cell's piece is cut
//! into `ceil(64 · length in voxels)` equal sub-segments (each at most 1/64
//! of a voxel long, Euclidean length in voxel units), the scalar taken linear
//! on each, and each sub-segment integrated exactly with the tet reference's
//! segment integral (`integrate_segment`: split at transfer-function control
//! points, emission–absorption closed form in Ψ and ζ). Sub-segments are
//! composited front to back; the result is premultiplied RGBA on a
//! transparent black background, row 0 at the top.
//!
//! Cells whose eight samples span a scalar range over which the transfer
//! function's attenuation is zero everywhere are stepped over exactly: a
//! trilinear value never leaves the range of its corners, and a zero-τ
//! stretch contributes nothing. Compositing stops once the optical depth
//! exceeds 60 (what remains is < 1e-26), as in the tet reference.
//!
//! **Accuracy.** The only approximation is the linear scalar on each
//! sub-segment: the cubic's deviation from its chord over h = 1/64 voxel is
//! at most h²/8 times its second derivative (≤ 2·max corner difference per
//! voxel²), i.e. < 3.1e-5 of the cell's scalar range. Tested against closed
//! forms (constant field, linear ramp) to 1e-9 in `tests` below and
//! `tests/raycast.rs`.

use anyhow::{ensure, Result};
use bit_vec::BitVec;
use glam::DVec3;
use rayon::prelude::*;

use crate::scene::{Camera, Projection, TransferFunction};
use crate::volume::Volume;

use super::integrate::{integrate_segment, Segment};
use super::ReferenceImage;

/// Sub-segments per voxel of ray length (the step is ≤ 1/64 voxel).
pub const SUBSTEPS_PER_VOXEL: f64 = 64.0;

/// Optical depth beyond which a ray is finished (transmittance < 1e-26).
const OPAQUE_DEPTH: f64 = 60.0;

/// Largest attenuation `tf` takes over scalars [lo, hi] (piecewise linear:
/// at the ends or at a control point inside), negative values as 0.
pub fn max_attenuation(tf: &TransferFunction, lo: f64, hi: f64) -> f64 {
    let inside = tf.points.iter().filter(|p| p.scalar >= lo && p.scalar <= hi).map(|p| p.attenuation);
    [tf.eval(lo).1, tf.eval(hi).1].into_iter().chain(inside).fold(0.0, f64::max)
}

/// Bricks along x, y, z for `dims` samples: brick b covers voxel
/// coordinates [b·brick, (b + 1)·brick] (its samples and the next brick's
/// first layer: the trilinear neighbourhood of every point in it).
pub fn brick_grid(dims: [usize; 3], brick: usize) -> [usize; 3] {
    dims.map(|d| d.saturating_sub(1).div_ceil(brick).max(1))
}

/// Per brick (x fastest): whether the transfer function has attenuation
/// somewhere over the brick's sample range (a trilinear value never leaves
/// the range of its corners). With `brick` 1 the bricks are the cells.
/// One layer of bricks at a time: each layer's sample range per (x brick,
/// y row), then per (x brick, y brick); memory is two such rows of ranges,
/// never a multiple of the volume (each sample is read about once).
/// One bit a brick: the reference flags cells (`brick` 1), and a byte a
/// cell was as large as an 8-bit volume beside it (issue 21's bound,
/// docs/bad-input.md "Memory").
pub fn attenuating_bricks(vol: &Volume, tf: &TransferFunction, brick: usize) -> BitVec {
    let dims = vol.dims();
    let grid = brick_grid(dims, brick);
    // The samples of brick b along one axis of n samples.
    let span = |b: usize, n: usize| (b * brick).min(n - 1)..=((b + 1) * brick).min(n - 1);
    let mut flags = BitVec::with_capacity(grid[0] * grid[1] * grid[2]);
    let rows = grid[0] * dims[1];
    let (mut lo, mut hi) = (vec![f64::INFINITY; rows], vec![f64::NEG_INFINITY; rows]);
    for bz in 0..grid[2] {
        lo.fill(f64::INFINITY);
        hi.fill(f64::NEG_INFINITY);
        for k in span(bz, dims[2]) {
            for j in 0..dims[1] {
                for bx in 0..grid[0] {
                    let n = bx + grid[0] * j;
                    for i in span(bx, dims[0]) {
                        let v = vol.value(i, j, k);
                        lo[n] = lo[n].min(v);
                        hi[n] = hi[n].max(v);
                    }
                }
            }
        }
        for by in 0..grid[1] {
            for bx in 0..grid[0] {
                let (mut mn, mut mx) = (f64::INFINITY, f64::NEG_INFINITY);
                for j in span(by, dims[1]) {
                    mn = mn.min(lo[bx + grid[0] * j]);
                    mx = mx.max(hi[bx + grid[0] * j]);
                }
                flags.push(max_attenuation(tf, mn, mx) > 0.0);
            }
        }
    }
    flags
}

/// The ray's parameter interval inside the axis-aligned box [min, max]
/// (slab test), or `None` when it misses. Rays parallel to a slab are inside
/// it iff their origin is.
pub fn box_interval(o: DVec3, d: DVec3, min: [f64; 3], max: [f64; 3]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < min[a] || o[a] > max[a] {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[a];
        let (mut ta, mut tb) = ((min[a] - o[a]) * inv, (max[a] - o[a]) * inv);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Render the f64 reference image of `vol` seen by `camera` with `tf`.
pub fn render_volume_reference(
    vol: &Volume,
    camera: &Camera,
    tf: &TransferFunction,
    width: u32,
    height: u32,
) -> Result<ReferenceImage> {
    ensure!(width > 0 && height > 0, "reference: empty image {width}x{height}");
    ensure!(
        tf.points.windows(2).all(|w| w[0].scalar <= w[1].scalar),
        "reference: transfer function '{}' control points are not sorted by scalar",
        tf.name
    );
    ensure!(
        tf.points.iter().all(|p| p.scalar.is_finite() && p.attenuation.is_finite() && p.color.iter().all(|c| c.is_finite())),
        "reference: transfer function '{}' has a non-finite control point",
        tf.name
    );
    let fwd = camera.forward();
    ensure!(
        fwd.is_finite() && fwd.cross(DVec3::from(camera.up)).length() > 0.0,
        "reference: degenerate camera (eye = target, or up parallel to the view direction)"
    );
    ensure!(camera.near < camera.far, "reference: camera near {} >= far {}", camera.near, camera.far);
    let pixel_count = (width as usize)
        .checked_mul(height as usize)
        .ok_or_else(|| anyhow::anyhow!("reference: image {width}x{height} is too large"))?;
    let mut pixels = vec![[0.0f64; 4]; pixel_count];
    let dims = vol.dims();
    if dims.iter().any(|&d| d < 2) {
        // A flat box: every chord has length 0.
        return Ok(ReferenceImage { width, height, pixels });
    }
    let walker = Walker::new(vol, tf);
    let (near, far) = (camera.near, camera.far);
    pixels.par_chunks_mut(width as usize).enumerate().for_each(|(y, row)| {
        for (x, px) in row.iter_mut().enumerate() {
            let (o, d) = camera.ray(x as f64, y as f64, width, height);
            let cos = match camera.projection {
                Projection::Perspective { .. } => d.dot(fwd),
                Projection::Orthographic { .. } => 1.0,
            };
            *px = walker.trace(o, d, near / cos, far / cos).rgba();
        }
    });
    Ok(ReferenceImage { width, height, pixels })
}

/// The ray walk over one volume and transfer function.
struct Walker<'a> {
    vol: &'a Volume,
    tf: &'a TransferFunction,
    dims: [usize; 3],
    spacing: DVec3,
    origin: DVec3,
    /// Per cell (x fastest, dims − 1 per axis): some attenuation is possible.
    visible: BitVec,
}

impl<'a> Walker<'a> {
    fn new(vol: &'a Volume, tf: &'a TransferFunction) -> Walker<'a> {
        let dims = vol.dims();
        let visible = attenuating_bricks(vol, tf, 1);
        Walker { vol, tf, dims, spacing: vol.spacing().into(), origin: vol.origin().into(), visible }
    }

    /// Trilinear value in cell `c` at local coordinates `f` (clamped to the cell).
    fn sample(&self, c: [usize; 3], f: DVec3) -> f64 {
        let f = f.clamp(DVec3::ZERO, DVec3::ONE);
        let v = |di: usize, dj: usize, dk: usize| self.vol.value(c[0] + di, c[1] + dj, c[2] + dk);
        let lx = |dj, dk| v(0, dj, dk) + (v(1, dj, dk) - v(0, dj, dk)) * f.x;
        let ly = |dk| lx(0, dk) + (lx(1, dk) - lx(0, dk)) * f.y;
        ly(0) + (ly(1) - ly(0)) * f.z
    }

    /// The integral along `o + t·d` for t in [t_min, t_max] ∩ the box.
    fn trace(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Segment {
        let b = self.vol.bounds();
        let Some((tb0, tb1)) = box_interval(o, d, b.min, b.max) else { return Segment::default() };
        let (t0, t1) = (tb0.max(t_min), tb1.min(t_max));
        if !(t0 < t1) {
            return Segment::default();
        }
        // Voxel coordinates: u(t) = uo + t·ud; cell c covers [c, c + 1].
        let uo = (o - self.origin) / self.spacing;
        let ud = d / self.spacing;
        let vox_per_t = ud.length();
        let cells = [self.dims[0] - 1, self.dims[1] - 1, self.dims[2] - 1];
        let cell_of = |t: f64| -> [usize; 3] {
            let u = uo + ud * t;
            std::array::from_fn(|a| (u[a].floor().max(0.0) as usize).min(cells[a] - 1))
        };
        let mut acc = Segment::default();
        let mut t = t0;
        // The cell holding the start: a point just inside the segment.
        let mut c = cell_of(t0 + (t1 - t0) * 1e-9);
        loop {
            // Exit of cell c along the ray.
            let mut t_exit = t1;
            for a in 0..3 {
                if ud[a] > 0.0 {
                    t_exit = t_exit.min((c[a] as f64 + 1.0 - uo[a]) / ud[a]);
                } else if ud[a] < 0.0 {
                    t_exit = t_exit.min((c[a] as f64 - uo[a]) / ud[a]);
                }
            }
            let t_exit = t_exit.max(t);
            if t_exit > t && self.visible.get(c[0] + cells[0] * (c[1] + cells[1] * c[2])).unwrap_or(false) {
                let n = ((t_exit - t) * vox_per_t * SUBSTEPS_PER_VOXEL).ceil().max(1.0);
                let cell_origin = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
                let local = |tt: f64| uo + ud * tt - cell_origin;
                let h = (t_exit - t) / n;
                let mut s_a = self.sample(c, local(t));
                for k in 1..=(n as u64) {
                    let tb = if k as f64 == n { t_exit } else { t + h * k as f64 };
                    let s_b = self.sample(c, local(tb));
                    acc = acc.over(&integrate_segment(self.tf, s_a, s_b, h));
                    s_a = s_b;
                }
                if acc.optical_depth > OPAQUE_DEPTH {
                    break;
                }
            }
            if t_exit >= t1 {
                break;
            }
            // Step into the neighbour across the face(s) reached at t_exit.
            let mut moved = false;
            for a in 0..3 {
                let boundary = if ud[a] > 0.0 {
                    (c[a] as f64 + 1.0 - uo[a]) / ud[a]
                } else if ud[a] < 0.0 {
                    (c[a] as f64 - uo[a]) / ud[a]
                } else {
                    f64::INFINITY
                };
                if boundary <= t_exit {
                    if ud[a] > 0.0 {
                        if c[a] + 1 >= cells[a] {
                            return acc;
                        }
                        c[a] += 1;
                    } else {
                        if c[a] == 0 {
                            return acc;
                        }
                        c[a] -= 1;
                    }
                    moved = true;
                }
            }
            if !moved {
                break;
            }
            t = t_exit;
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::ControlPoint;
    use crate::volume::Samples;

    fn ramp_volume(dims: [usize; 3], spacing: [f64; 3], f: impl Fn([f64; 3]) -> f64) -> Volume {
        let origin = [-1.0, 0.5, 2.0];
        let mut s = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = [origin[0] + i as f64 * spacing[0], origin[1] + j as f64 * spacing[1], origin[2] + k as f64 * spacing[2]];
                    s.push(f(p) as f32);
                }
            }
        }
        Volume::new("test", "ramp", dims, spacing, origin, Samples::F32(s)).unwrap()
    }

    #[test]
    fn brick_grid_covers_every_cell() {
        assert_eq!(brick_grid([9, 17, 2], 8), [1, 2, 1]);
        assert_eq!(brick_grid([10, 3, 2], 2), [5, 1, 1]);
        assert_eq!(brick_grid([256, 256, 133], 2), [128, 128, 66]);
    }

    /// A linear field is reproduced exactly by trilinear interpolation, so the
    /// whole chord is one linear segment: the closed form is
    /// `integrate_segment` over the chord.
    #[test]
    fn linear_ramp_matches_one_segment_over_the_chord() {
        // Dyadic gradient, spacing and origin: the samples are exact in f32.
        let g = DVec3::new(0.25, -0.125, 0.5);
        let vol = ramp_volume([5, 4, 6], [0.5, 0.75, 0.25], |p| 2.0 + g.dot(DVec3::from(p)));
        let tf = TransferFunction {
            name: "t".into(),
            points: vec![
                ControlPoint { scalar: 1.5, color: [0.1, 0.2, 0.9], attenuation: 0.2 },
                ControlPoint { scalar: 2.6, color: [0.9, 0.8, 0.1], attenuation: 3.0 },
                ControlPoint { scalar: 3.5, color: [1.0, 0.1, 0.1], attenuation: 0.5 },
            ],
        };
        let w = Walker::new(&vol, &tf);
        let b = vol.bounds();
        let c = DVec3::from(b.center());
        for (o, d) in [
            (c + DVec3::new(-5.0, 0.3, 0.1), DVec3::new(1.0, 0.1, -0.05)),
            (c + DVec3::new(1.0, 4.0, -2.0), DVec3::new(-0.2, -1.0, 0.45)),
            (c, DVec3::new(0.0, 0.0, 1.0)), // starts inside
        ] {
            let d = d.normalize();
            let got = w.trace(o, d, 0.0, 100.0).rgba();
            let (t0, t1) = box_interval(o, d, b.min, b.max).unwrap();
            let t0 = t0.max(0.0);
            let s = |t: f64| 2.0 + g.dot(o + d * t);
            let want = integrate_segment(&tf, s(t0), s(t1), t1 - t0).rgba();
            for i in 0..4 {
                assert!((got[i] - want[i]).abs() < 1e-9, "{o} {d} ch{i}: {} vs {}", got[i], want[i]);
            }
            assert!(want[3] > 0.05, "the test ray must see something");
        }
    }

    #[test]
    fn constant_field_is_one_minus_exp_of_the_chord() {
        let vol = ramp_volume([3, 3, 3], [1.0, 1.0, 2.0], |_| 1.0);
        let tf = TransferFunction::constant([0.5, 0.25, 1.0], 0.7);
        let w = Walker::new(&vol, &tf);
        // Along x through the middle: chord 2.
        let o = DVec3::new(-3.0, 1.5, 4.0);
        let got = w.trace(o, DVec3::X, 0.0, 100.0).rgba();
        let a = 1.0 - (-0.7f64 * 2.0).exp();
        assert!((got[3] - a).abs() < 1e-12 && (got[0] - 0.5 * a).abs() < 1e-12, "{got:?}");
        // Clipped by near/far to [3.5, 4.5]: chord 1.
        let got = w.trace(o, DVec3::X, 2.5, 3.5).rgba();
        let a = 1.0 - (-0.7f64).exp();
        assert!((got[3] - a).abs() < 1e-12, "{got:?}");
    }

    /// White, transparent up to `edge`, attenuation rising to `top` at 1.
    fn transparent_below(edge: f64, top: f64) -> TransferFunction {
        TransferFunction {
            name: "t".into(),
            points: vec![
                ControlPoint { scalar: 0.0, color: [1.0; 3], attenuation: 0.0 },
                ControlPoint { scalar: edge, color: [1.0; 3], attenuation: 0.0 },
                ControlPoint { scalar: 1.0, color: [1.0; 3], attenuation: top },
            ],
        }
    }

    #[test]
    fn transparent_cells_are_skipped_exactly() {
        let tf = transparent_below(0.5, 4.0);
        let vol = ramp_volume([8, 3, 3], [1.0; 3], |p| if p[0] > 3.0 { 1.0 } else { 0.0 });
        let w = Walker::new(&vol, &tf);
        let cells = w.visible.iter().filter(|&v| v).count();
        // Samples at x = -1..6: x > 3 from i = 5 on, so cells 4, 5, 6 along x.
        assert_eq!(cells, 3 * 2 * 2);
        assert_eq!(max_attenuation(&tf, 0.1, 0.4), 0.0);
        assert!(max_attenuation(&tf, 0.1, 0.6) > 0.0);
    }

    proptest::proptest! {
        /// The axis-by-axis reduction flags exactly the bricks whose own
        /// sample range (read directly) has attenuation.
        #[test]
        fn attenuating_bricks_match_each_bricks_own_range(
            nx in 2usize..12, ny in 2usize..12, nz in 2usize..12, brick in 1usize..6, seed in 0u64..1000
        ) {
            let tf = transparent_below(0.8, 1.0);
            let hash = |p: [f64; 3]| ((p[0] * 12.9898 + p[1] * 78.233 + p[2] * 37.719 + seed as f64).sin() * 43758.5453).fract().abs();
            let vol = ramp_volume([nx, ny, nz], [1.0; 3], hash);
            let grid = brick_grid([nx, ny, nz], brick);
            let flags = attenuating_bricks(&vol, &tf, brick);
            proptest::prop_assert_eq!(flags.len(), grid[0] * grid[1] * grid[2]);
            for (n, flag) in flags.iter().enumerate() {
                let b = [n % grid[0], n / grid[0] % grid[1], n / (grid[0] * grid[1])];
                let span = |a: usize, d: usize| (b[a] * brick).min(d - 1)..=((b[a] + 1) * brick).min(d - 1);
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for k in span(2, nz) {
                    for j in span(1, ny) {
                        for i in span(0, nx) {
                            lo = lo.min(vol.value(i, j, k));
                            hi = hi.max(vol.value(i, j, k));
                        }
                    }
                }
                proptest::prop_assert_eq!(flag, max_attenuation(&tf, lo, hi) > 0.0, "brick {:?}", b);
            }
        }
    }
}
