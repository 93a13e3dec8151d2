//! Empty-space skipping's bricks (see the module note of `super`): the
//! volume is cut into bricks of `brick`³ voxels, each flagged when the
//! transfer function may give attenuation somewhere in it ([`attenuating`];
//! the CPU reference flags its cells with its own code,
//! `reference::volume::attenuating_bricks`, and `tests/reference_agrees.rs`
//! compares the two), and every unflagged brick
//! holds its Chebyshev (L∞) distance, in bricks, to the nearest flagged
//! one. A ray in an unflagged brick at distance d lies in an empty cube of
//! 2d − 1 bricks a side centred on it and leaps to the cube's exit in one
//! iteration. On llvmpipe a skipped brick costs a loop iteration as dear as
//! a sample (both sides of every branch run), so without the distances small
//! bricks would cost more iterations than the samples they save.

use crate::scene::TransferFunction;
use crate::volume::Samples;

use super::super::segment::transfer_at;

/// Bricks along x, y, z for `dims` samples. Brick b along an axis holds the
/// samples b·brick ..= (b + 1)·brick (its own and the next brick's first
/// layer: every sample a trilinear lookup inside it may read).
pub fn grid_of(dims: [usize; 3], brick: usize) -> [usize; 3] {
    dims.map(|n| n.saturating_sub(1).div_ceil(brick).max(1))
}

/// Per brick (x fastest): whether the transfer function has attenuation
/// anywhere over the range of the brick's samples (a trilinear value stays
/// within its corners' range), one layer of bricks at a time
/// ([`LayerFlags`]). `samples` are a volume's of `dims` (also when taken
/// from it, `Volume::take_samples`).
pub fn attenuating(dims: [usize; 3], samples: &Samples, tf: &TransferFunction, brick: usize) -> Vec<bool> {
    assert_eq!(samples.len(), dims[0] * dims[1] * dims[2], "one sample per grid point");
    let mut layers = LayerFlags::new(dims, tf, brick);
    let grid = grid_of(dims, brick);
    let mut flags = Vec::with_capacity(grid[0] * grid[1] * grid[2]);
    for bz in 0..grid[2] {
        flags.extend(layers.flags(bz, samples));
    }
    flags
}

/// [`attenuating`] one layer of bricks at a time, in any order: a layer
/// reads only its own sample layers ([`LayerFlags::sample_layers`]), so a
/// caller that frees the samples from the end as it goes can flag the
/// layers as it frees them. The working ranges are one layer's, never one
/// per brick of the volume (16 bytes a brick were twice an 8-bit volume's
/// bytes at `brick=2`).
pub struct LayerFlags<'t> {
    dims: [usize; 3],
    grid: [usize; 3],
    brick: usize,
    tf: &'t TransferFunction,
    range: Vec<(f64, f64)>,
}

impl<'t> LayerFlags<'t> {
    pub fn new(dims: [usize; 3], tf: &'t TransferFunction, brick: usize) -> Self {
        let grid = grid_of(dims, brick);
        LayerFlags { dims, grid, brick, tf, range: vec![(f64::INFINITY, f64::NEG_INFINITY); grid[0] * grid[1]] }
    }

    /// The sample layers (z) brick layer `bz` holds: its own and the next's
    /// first (the last brick layer: up to the volume's last).
    pub fn sample_layers(&self, bz: usize) -> std::ops::RangeInclusive<usize> {
        let last = if bz + 1 == self.grid[2] { self.dims[2] - 1 } else { (bz + 1) * self.brick };
        bz * self.brick..=last.min(self.dims[2] - 1)
    }

    /// Brick layer `bz`'s flags (x fastest) from `samples`, which must
    /// hold at least the volume's samples up to the end of
    /// [`LayerFlags::sample_layers`]`(bz)` (a missing one reads as NaN, which
    /// flags nothing: a caller's bug).
    pub fn flags(&mut self, bz: usize, samples: &Samples) -> Vec<bool> {
        let (dims, grid, brick) = (self.dims, self.grid, self.brick);
        // The bricks holding sample i along an axis: its own, and the one
        // before when it is that brick's last layer.
        let owners = |i: usize, g: usize| {
            let own = (i / brick).min(g - 1);
            let before = (i > 0 && i.is_multiple_of(brick)).then(|| i / brick - 1);
            [Some(own), before.filter(|&b| b != own)]
        };
        self.range.fill((f64::INFINITY, f64::NEG_INFINITY));
        for k in self.sample_layers(bz) {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let v = samples.get(i + dims[0] * (j + dims[1] * k)).unwrap_or(f64::NAN);
                    for by in owners(j, grid[1]).into_iter().flatten() {
                        for bx in owners(i, grid[0]).into_iter().flatten() {
                            let r = &mut self.range[bx + grid[0] * by];
                            *r = (r.0.min(v), r.1.max(v));
                        }
                    }
                }
            }
        }
        self.range.iter().map(|&(lo, hi)| attenuates_over(self.tf, lo, hi)).collect()
    }

    /// After [`LayerFlags::flags`]: which bricks of that layer are dense,
    /// the transfer function's attenuation over their range above
    /// `tau_limit` somewhere (`coarse`, module note of `super`).
    pub fn dense(&self, tau_limit: f64) -> Vec<bool> {
        self.range.iter().map(|&(lo, hi)| max_attenuation_over(self.tf, lo, hi) > tau_limit).collect()
    }
}

/// Whether τ > 0 somewhere on scalars [lo, hi]: τ is piecewise linear, so
/// at an end or at a control point between them.
fn attenuates_over(tf: &TransferFunction, lo: f64, hi: f64) -> bool {
    max_attenuation_over(tf, lo, hi) > 0.0
}

/// The largest τ on scalars [lo, hi]: τ is piecewise linear, so at an end
/// or at a control point between them.
fn max_attenuation_over(tf: &TransferFunction, lo: f64, hi: f64) -> f64 {
    let inner = tf.points.iter().filter(|p| p.scalar >= lo && p.scalar <= hi).map(|p| p.attenuation);
    inner.fold(transfer_at(tf, lo).1.max(transfer_at(tf, hi).1), f64::max)
}

/// Largest distance stored (one byte per brick); farther bricks store this
/// (a smaller cube than possible: still empty).
pub const MAX_DISTANCE: u8 = 255;

/// Writes flags as a brick map's start: 0 on a set brick, [`MAX_DISTANCE`]
/// elsewhere (one layer of bricks at a time, as [`LayerFlags`] gives them).
pub fn mark(flags: impl IntoIterator<Item = bool>, map: &mut [u8]) {
    for (m, f) in map.iter_mut().zip(flags) {
        *m = if f { 0 } else { MAX_DISTANCE };
    }
}

/// Turns `map`'s first n bytes (a brick's distance, n = `second.len()`)
/// into n pairs in place, brick b's bytes at 2b and 2b + 1, the second
/// from `second` (`coarse`: the distance to a dense brick). From the last
/// brick back, each first byte is read before anything overwrites it.
pub fn interleave_pairs(map: &mut [u8], second: &[u8]) {
    assert!(map.len() >= 2 * second.len(), "room for the pairs");
    for (b, &s) in second.iter().enumerate().rev() {
        map[2 * b] = map[b];
        map[2 * b + 1] = s;
    }
}

/// Turns a marked map ([`mark`]) into each brick's Chebyshev distance to
/// the nearest set brick, capped at [`MAX_DISTANCE`] (also when none is
/// set; the flags dilated by a cube of radius r have distances
/// `d.saturating_sub(r)`), in place: the
/// two-pass chamfer transform with the 26 neighbours at distance 1 (exact
/// for the chessboard metric, Rosenfeld & Pfaltz 1966), so no memory but
/// the map's own, one byte a brick (the prefix counts it replaced took four
/// more: at `brick=1` four times an 8-bit volume).
pub fn chebyshev_in_place(map: &mut [u8], grid: [usize; 3]) {
    assert_eq!(map.len(), grid[0] * grid[1] * grid[2], "one byte per brick");
    // The 13 neighbours before a brick in x-fastest order; the backward
    // pass reads their mirror images.
    const BEFORE: [[isize; 3]; 13] = [
        [-1, -1, -1], [0, -1, -1], [1, -1, -1],
        [-1, 0, -1], [0, 0, -1], [1, 0, -1],
        [-1, 1, -1], [0, 1, -1], [1, 1, -1],
        [-1, -1, 0], [0, -1, 0], [1, -1, 0],
        [-1, 0, 0],
    ];
    let g = grid.map(|n| n as isize);
    let pass = |map: &mut [u8], p: [isize; 3], sign: isize| {
        let at = |q: [isize; 3]| (q[0] + g[0] * (q[1] + g[1] * q[2])) as usize;
        let here = at(p);
        let mut d = map[here];
        if d == 0 {
            return;
        }
        for o in BEFORE {
            let q = [p[0] + sign * o[0], p[1] + sign * o[1], p[2] + sign * o[2]];
            if (0..3).all(|a| (0..g[a]).contains(&q[a])) {
                d = d.min(map[at(q)].saturating_add(1));
            }
        }
        map[here] = d;
    };
    for z in 0..g[2] {
        for y in 0..g[1] {
            for x in 0..g[0] {
                pass(map, [x, y, z], 1);
            }
        }
    }
    for z in (0..g[2]).rev() {
        for y in (0..g[1]).rev() {
            for x in (0..g[0]).rev() {
                pass(map, [x, y, z], -1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The map of `flags` (x fastest): [`mark`] then [`chebyshev_in_place`].
    fn distances(flags: &[bool], grid: [usize; 3]) -> Vec<u8> {
        let mut map = vec![0u8; flags.len()];
        mark(flags.iter().copied(), &mut map);
        chebyshev_in_place(&mut map, grid);
        map
    }

    fn brute_force(flags: &[bool], grid: [usize; 3]) -> Vec<u8> {
        let pos = |n: usize| [n % grid[0], n / grid[0] % grid[1], n / (grid[0] * grid[1])];
        (0..flags.len())
            .map(|n| {
                let p = pos(n);
                let d = (0..flags.len())
                    .filter(|&m| flags[m])
                    .map(|m| {
                        let q = pos(m);
                        (0..3).map(|a| p[a].abs_diff(q[a])).max().unwrap()
                    })
                    .min()
                    .unwrap_or(usize::MAX);
                d.min(MAX_DISTANCE as usize) as u8
            })
            .collect()
    }

    proptest! {
        #[test]
        fn distances_are_chebyshev_to_the_nearest_flag(
            gx in 1usize..9, gy in 1usize..9, gz in 1usize..9, density in 0.0f64..0.3, seed in any::<u64>()
        ) {
            let grid = [gx, gy, gz];
            let n = gx * gy * gz;
            // A cheap deterministic pattern from the seed.
            let mut state = seed | 1;
            let flags: Vec<bool> = (0..n).map(|_| {
                state ^= state << 13; state ^= state >> 7; state ^= state << 17;
                (state % 1000) as f64 / 1000.0 < density
            }).collect();
            prop_assert_eq!(distances(&flags, grid), brute_force(&flags, grid));
        }
    }

    #[test]
    fn the_largest_attenuation_over_a_range_finds_inner_control_points() {
        use crate::scene::{ControlPoint, TransferFunction};
        let pt = |scalar: f64, attenuation: f64| ControlPoint { scalar, color: [1.0; 3], attenuation };
        let tf = TransferFunction { name: "t".into(), points: vec![pt(0.0, 0.0), pt(0.5, 8.0), pt(1.0, 2.0)] };
        assert_eq!(max_attenuation_over(&tf, 0.1, 0.2), 3.2);
        assert_eq!(max_attenuation_over(&tf, 0.4, 0.9), 8.0);
        assert_eq!(max_attenuation_over(&tf, 0.75, 1.5), 5.0);
        assert_eq!(max_attenuation_over(&tf, -1.0, 0.0), 0.0);
    }

    #[test]
    fn pairs_interleave_two_planes_in_place() {
        let mut map = vec![1, 2, 3, 4, 0, 0, 0, 0, 9];
        interleave_pairs(&mut map, &[10, 20, 30, 40]);
        assert_eq!(map, vec![1, 10, 2, 20, 3, 30, 4, 40, 9]);
    }

    #[test]
    fn far_bricks_store_the_cap_and_an_empty_grid_is_all_cap() {
        let grid = [300, 1, 1];
        let mut flags = vec![false; 300];
        flags[0] = true;
        let d = distances(&flags, grid);
        assert_eq!(&d[..3], &[0, 1, 2]);
        assert_eq!(d[254], 254);
        assert!(d[255..].iter().all(|&x| x == MAX_DISTANCE));
        assert!(distances(&[false; 8], [2, 2, 2]).iter().all(|&x| x == MAX_DISTANCE));
    }

}
