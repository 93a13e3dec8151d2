//! Skipping what a scene does not need, for every tetrahedral cell-projection
//! method: one mechanism, three rules, each exact (the image is bit-for-bit
//! what drawing every cell gives; `tests/cull.rs` holds the methods to that).
//!
//! 1. **Transparent cells** ([`TransparentCells`]): a cell whose every lookup
//!    of the integration tables reads zero attenuation contributes exactly
//!    (0, 0, 0, 0), premultiplied, and "over" blending of (0, 0, 0, 0)
//!    leaves the pixel unchanged. Every integrator in
//!    `shaders/common/integrate.glsl` gives exactly zero there: average
//!    multiplies the colour by alpha = 1 − exp(−0) = 0; ppi and linear-exact
//!    get ζ = 1 and Ψ clamped to [ζ, 1] = 1, so both colour weights
//!    (Ψ − ζ, 1 − Ψ) are 0; preint's table entries over zero attenuation are
//!    `integrate_piece`'s exact zero segments. The test is made against what
//!    the device reads, not only the transfer function: scalars look up a
//!    table of samples with linear interpolation, so a cell whose vertex
//!    scalars lie in [min, max] reads the samples from the one at or below
//!    min to the one above max; one more sample on each side covers exit
//!    scalars that f32 rounding puts just outside the vertex range. The cell
//!    is culled only if the transfer function's attenuation is ≤ 0 (the
//!    shaders clamp it at 0) over that whole closed scalar span
//!    (`TransferFunction::piece_at` at both ends, every control point
//!    inside). Classified once per transfer function
//!    ([`TransparentCells::classify`]); a new transfer function re-classifies.
//! 2. **Off-screen cells** ([`Frustum`]): a cell whose four vertices are all
//!    outside one clip plane of Vulkan's view volume (−w ≤ x, y ≤ w,
//!    0 ≤ z ≤ w, in homogeneous clip coordinates, which are linear in the
//!    position: the whole cell is then outside that half-space) is clipped
//!    away whole by the rasterizer anyway. A cell cut by the near plane or
//!    straddling any plane is kept. "Outside" needs a margin of 1e-6
//!    relative (f64 here, f32 on the device: a vertex within rounding of a
//!    plane counts as inside).
//! 3. **Unchanged frames** ([`Culler::unchanged`]): the same camera, image
//!    size and transfer function as the frame whose data is on the device
//!    re-use it: no cull, no sort, no pack, no upload. The draw is recorded
//!    again (the device's work is re-done and timed), so frame times stay
//!    the cost of a frame whose CPU half is skipped, not of an image copy.
//!
//! Visibility order: the cells that survive keep their order. A centroid sort
//! sorts only the survivors (its LSD radix sort is stable from ascending
//! cell ids, so that is exactly the full order filtered). MPVO sorts the
//! whole mesh and the order is then filtered ([`Culler::filter_order`]):
//! sorting the survivors with only the adjacency among survivors would drop
//! the ordering constraints that run through culled cells (a → culled → b
//! orders a before b; without the culled cell a and b are unconstrained),
//! whereas any subsequence of a valid visibility order is valid.
//!
//! Counts per frame ([`FrameCull`]) go to the run's `frame_counts`.

use std::sync::Arc;

use rayon::prelude::*;

use super::RelativeMesh;

use crate::algo::integrate::{IntegrationTables, Integrator};
use crate::mesh::TetMesh;
use crate::scene::{Camera, TransferFunction};

/// The scalar samples the fragment stage interpolates linearly: `samples`
/// evenly spaced over `[lo, hi]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LookupGrid {
    pub lo: f64,
    pub hi: f64,
    pub samples: usize,
}

impl LookupGrid {
    /// The grid an integrator reads scalars through: the transfer-function
    /// table, or for classic pre-integration its (s_f, s_b) table (the only
    /// table it reads).
    pub fn of(tables: &IntegrationTables) -> Self {
        let (lo, hi) = tables.tf_range;
        let samples = match tables.integrator {
            Integrator::Preint => tables.table_size,
            Integrator::Average | Integrator::Ppi | Integrator::LinearExact => tables.tf_size,
        };
        LookupGrid { lo, hi, samples: samples.max(2) }
    }

    /// The closed scalar span whose samples a lookup of any scalar in
    /// `[a, b]` reads, widened by one sample on each side (see the module
    /// note).
    pub fn span(&self, a: f64, b: f64) -> (f64, f64) {
        let last = (self.samples - 1) as f64;
        let step = (self.hi - self.lo) / last;
        let index = |s: f64| (((s - self.lo) / (self.hi - self.lo)).clamp(0.0, 1.0) * last).floor();
        // Below: the sample at or below a, one more. Above: the sample above
        // b (the lookup's k + 1), one more.
        let i0 = (index(a) - 1.0).max(0.0);
        let i1 = (index(b) + 2.0).min(last);
        let (mut lo, mut hi) = (self.lo + step * i0, self.lo + step * i1);
        // Scalars outside the grid clamp to its ends: the span reaches them.
        if i0 == 0.0 {
            lo = lo.min(a);
        }
        if i1 == last {
            hi = hi.max(b);
        }
        (lo, hi)
    }
}

/// Whether the attenuation of `tf` is ≤ 0 everywhere on the closed interval
/// `[lo, hi]`: at both ends (right-continuous, `piece_at`), at every control
/// point inside, and so (piecewise linear) everywhere between.
pub fn transparent_over(tf: &TransferFunction, lo: f64, hi: f64) -> bool {
    if !(lo <= hi) {
        return false;
    }
    let ends = [tf.piece_at(lo).eval(lo).1, tf.piece_at(hi).eval(hi).1];
    let inside = tf.points.iter().filter(|p| p.scalar >= lo && p.scalar <= hi).map(|p| p.attenuation);
    ends.into_iter().chain(inside).all(|tau| tau <= 0.0)
}

/// Which cells the transfer function makes fully transparent (rule 1).
#[derive(Debug, Clone)]
pub struct TransparentCells {
    /// Cells that are not transparent, ascending.
    pub visible: Vec<u32>,
    /// How many are transparent.
    pub culled: usize,
    /// What they were classified against.
    tf: TransferFunction,
    grid: LookupGrid,
}

impl TransparentCells {
    pub fn classify(mesh: &TetMesh, tf: &TransferFunction, grid: LookupGrid) -> Self {
        let keep: Vec<bool> = mesh
            .tets
            .par_iter()
            .map(|t| {
                let s = t.map(|i| mesh.scalars[i as usize]);
                let (a, b) = (s.iter().copied().fold(f64::INFINITY, f64::min), s.iter().copied().fold(f64::NEG_INFINITY, f64::max));
                let (lo, hi) = grid.span(a, b);
                !transparent_over(tf, lo, hi)
            })
            .collect();
        let mut visible: Vec<u32> = keep.iter().enumerate().filter(|(_, &k)| k).map(|(i, _)| i as u32).collect();
        visible.shrink_to_fit();
        TransparentCells { culled: mesh.tets.len() - visible.len(), visible, tf: tf.clone(), grid }
    }

    /// Whether this classification holds for `tf` read through `grid`.
    pub fn is_for(&self, tf: &TransferFunction, grid: LookupGrid) -> bool {
        self.tf == *tf && self.grid == grid
    }
}

/// Outcode bits: outside x < −w, x > w, y < −w, y > w, z < 0, z > w.
fn outcode(m: &[[f64; 4]; 4], p: [f64; 3]) -> u8 {
    // Column-major: clip = M · (p, 1).
    let c: [f64; 4] = std::array::from_fn(|r| m[0][r] * p[0] + m[1][r] * p[1] + m[2][r] * p[2] + m[3][r]);
    let (x, y, z, w) = (c[0], c[1], c[2], c[3]);
    // Outside by more than rounding: f32 on the device may put the vertex
    // on the other side of a plane it is within 1e-6 (relative) of.
    let eps = 1e-6 * (x.abs() + y.abs() + z.abs() + w.abs());
    let mut code = 0u8;
    code |= u8::from(x < -w - eps);
    code |= u8::from(x > w + eps) << 1;
    code |= u8::from(y < -w - eps) << 2;
    code |= u8::from(y > w + eps) << 3;
    code |= u8::from(z < -eps) << 4;
    code |= u8::from(z > w + eps) << 5;
    code
}

/// The off-screen test (rule 2) for one view.
pub struct Frustum {
    /// `Camera::view_proj_relative(origin, ..)`, column-major.
    matrix: [[f64; 4]; 4],
}

impl Frustum {
    /// `origin`: what `points` passed to [`Frustum::outcodes`] are relative to.
    pub fn new(camera: &Camera, origin: [f64; 3], width: u32, height: u32) -> Self {
        Frustum { matrix: camera.view_proj_relative(origin, width, height).to_cols_array_2d() }
    }

    /// One outcode per point.
    pub fn outcodes(&self, points: &[[f64; 3]], out: &mut Vec<u8>) {
        out.resize(points.len(), 0);
        out.par_iter_mut().zip(points.par_iter()).with_min_len(4096).for_each(|(o, &p)| *o = outcode(&self.matrix, p));
    }

    /// Whether a cell with these vertex outcodes is outside one plane.
    #[inline]
    pub fn outside(codes: [u8; 4]) -> bool {
        codes[0] & codes[1] & codes[2] & codes[3] != 0
    }
}

/// What the rules skipped in one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameCull {
    /// Cells skipped as fully transparent (rule 1).
    pub transparent: u64,
    /// Cells skipped as off-screen, of those not transparent (rule 2).
    pub frustum: u64,
    /// Cells drawn.
    pub drawn: u64,
    /// The previous frame's data was re-used (rule 3): nothing was culled,
    /// sorted, packed or uploaded.
    pub reused: bool,
}

/// The key of a frame's data: what it depends on.
#[derive(Debug, Clone, Copy, PartialEq)]
struct FrameKey {
    camera: Camera,
    width: u32,
    height: u32,
    /// Bumped on each re-classification (a new transfer function).
    tf_generation: u64,
}

/// The three rules for one mesh (the API every tetrahedral method calls).
/// Off (`cull=off`): every cell, every frame prepared anew.
pub struct Culler {
    enabled: bool,
    transparent: TransparentCells,
    /// Mesh points relative to the render origin, and the cells (shared
    /// with the near caps).
    mesh: Arc<RelativeMesh>,
    outcodes: Vec<u8>,
    survivors: Vec<u32>,
    /// Per cell: drawn this frame (for `filter_order`).
    drawn_mask: Vec<bool>,
    tf_generation: u64,
    /// The frame whose data is on the device.
    last: Option<FrameKey>,
}

impl Culler {
    /// `origin`: the mesh's render origin (`render_origin`).
    pub fn new(mesh: &TetMesh, tf: &TransferFunction, grid: LookupGrid, origin: [f64; 3], enabled: bool) -> Self {
        Self::shared(mesh, RelativeMesh::new(mesh, origin), tf, grid, enabled)
    }

    /// With the relative mesh the method's other passes read too.
    pub fn shared(mesh: &TetMesh, relative: Arc<RelativeMesh>, tf: &TransferFunction, grid: LookupGrid, enabled: bool) -> Self {
        let transparent = if enabled {
            TransparentCells::classify(mesh, tf, grid)
        } else {
            TransparentCells { visible: (0..mesh.tets.len() as u32).collect(), culled: 0, tf: tf.clone(), grid }
        };
        Culler {
            enabled,
            transparent,
            mesh: relative,
            outcodes: Vec::new(),
            survivors: Vec::new(),
            drawn_mask: Vec::new(),
            tf_generation: 0,
            last: None,
        }
    }

    pub fn enabled(&self) -> bool {
        self.enabled
    }

    pub fn host_bytes(&self, memory: &mut crate::algo::host_memory::HostMemory) {
        memory.vec("cull: visible (non-transparent) cells", &self.transparent.visible);
        memory.vec("cull: per-frame outcodes, survivors, mask", &self.outcodes);
        memory.vec("cull: per-frame outcodes, survivors, mask", &self.survivors);
        memory.vec("cull: per-frame outcodes, survivors, mask", &self.drawn_mask);
    }

    /// Cells the transfer function makes transparent.
    pub fn transparent_cells(&self) -> usize {
        self.transparent.culled
    }

    /// Re-classify for a new transfer function (read through `grid`); a
    /// no-op when it is the one already classified. Returns whether it
    /// re-classified.
    pub fn set_transfer_function(&mut self, mesh: &TetMesh, tf: &TransferFunction, grid: LookupGrid) -> bool {
        if !self.enabled || self.transparent.is_for(tf, grid) {
            return false;
        }
        self.transparent = TransparentCells::classify(mesh, tf, grid);
        self.tf_generation += 1;
        self.last = None;
        true
    }

    fn key(&self, camera: &Camera, width: u32, height: u32) -> FrameKey {
        FrameKey { camera: *camera, width, height, tf_generation: self.tf_generation }
    }

    /// Whether the data on the device was prepared for this very view
    /// (rule 3; never when culling is off).
    pub fn unchanged(&self, camera: &Camera, width: u32, height: u32) -> bool {
        self.enabled && self.last == Some(self.key(camera, width, height))
    }

    /// Record that the frame for this view is the one on the device.
    pub fn remember(&mut self, camera: &Camera, width: u32, height: u32) {
        self.last = Some(self.key(camera, width, height));
    }

    /// Cull for this view (rules 1 and 2): the cells to draw are then
    /// [`Culler::survivors`], and the result says what was skipped. Off:
    /// `None` (draw every cell).
    pub fn cull(&mut self, camera: &Camera, width: u32, height: u32) -> Option<FrameCull> {
        if !self.enabled {
            return None;
        }
        let frustum = Frustum::new(camera, self.mesh.origin, width, height);
        frustum.outcodes(&self.mesh.points, &mut self.outcodes);
        let (codes, tets) = (&self.outcodes, &self.mesh.tets);
        self.survivors.clear();
        self.survivors.par_extend(self.transparent.visible.par_iter().copied().filter(|&c| {
            let t = tets[c as usize];
            !Frustum::outside(t.map(|i| codes[i as usize]))
        }));
        let drawn = self.survivors.len() as u64;
        Some(FrameCull {
            transparent: self.transparent.culled as u64,
            frustum: self.transparent.visible.len() as u64 - drawn,
            drawn,
            reused: false,
        })
    }

    /// The cells the last [`Culler::cull`] kept, ascending.
    pub fn survivors(&self) -> &[u32] {
        &self.survivors
    }

    /// `order` (a visibility order of every cell) restricted to the cells
    /// of the last [`Culler::cull`], order kept (see the module note).
    pub fn filter_order(&mut self, order: &[u32], out: &mut Vec<u32>) {
        self.drawn_mask.clear();
        self.drawn_mask.resize(self.mesh.tets.len(), false);
        for &c in &self.survivors {
            self.drawn_mask[c as usize] = true;
        }
        out.clear();
        out.extend(order.iter().copied().filter(|&c| self.drawn_mask[c as usize]));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{ControlPoint, Projection};

    fn pt(scalar: f64, attenuation: f64) -> ControlPoint {
        ControlPoint { scalar, color: [1.0; 3], attenuation }
    }

    /// Opaque only on [0.4, 0.6] of [0, 1].
    fn band() -> TransferFunction {
        TransferFunction { name: "band".into(), points: vec![pt(0.0, 0.0), pt(0.4, 0.0), pt(0.5, 5.0), pt(0.6, 0.0), pt(1.0, 0.0)] }
    }

    #[test]
    fn transparency_is_judged_over_the_closed_interval() {
        let tf = band();
        assert!(transparent_over(&tf, 0.0, 0.4));
        assert!(transparent_over(&tf, 0.6, 1.0));
        assert!(!transparent_over(&tf, 0.0, 0.41));
        assert!(!transparent_over(&tf, 0.45, 0.46), "no control point inside, but the ends are opaque");
        assert!(!transparent_over(&tf, 0.3, 0.7), "a control point inside is opaque");
        // A step up at 0.4: the value at 0.4 is the one after the step.
        let step = TransferFunction { name: "s".into(), points: vec![pt(0.0, 0.0), pt(0.4, 0.0), pt(0.4, 1.0)] };
        assert!(!transparent_over(&step, 0.0, 0.4));
        assert!(transparent_over(&step, 0.0, 0.39));
        assert!(!transparent_over(&tf, 0.5, 0.4), "an empty interval is never culled");
    }

    #[test]
    fn the_span_covers_every_sample_a_lookup_reads_plus_one() {
        let g = LookupGrid { lo: 0.0, hi: 1.0, samples: 11 };
        // [0.31, 0.33] reads samples 3 and 4 (0.3, 0.4): span [0.2, 0.5].
        let (a, b) = g.span(0.31, 0.33);
        assert!((a - 0.2).abs() < 1e-12 && (b - 0.5).abs() < 1e-12, "{a} {b}");
        // Clamped at the ends, and reaching scalars beyond them.
        let close = |(a, b): (f64, f64), (x, y): (f64, f64)| (a - x).abs() < 1e-12 && (b - y).abs() < 1e-12;
        assert!(close(g.span(-1.0, 0.05), (-1.0, 0.2)), "{:?}", g.span(-1.0, 0.05));
        assert!(close(g.span(0.95, 2.0), (0.8, 2.0)), "{:?}", g.span(0.95, 2.0));
        // With this grid a cell in [0.2, 0.33] of the band TF reads the
        // sample at 0.4's neighbour 0.5 (opaque): kept, although the TF
        // itself is zero on [0.2, 0.33].
        let tf = band();
        assert!(transparent_over(&tf, 0.2, 0.33));
        let (lo, hi) = g.span(0.2, 0.33);
        assert!(!transparent_over(&tf, lo, hi));
        let (lo, hi) = g.span(0.7, 0.9);
        assert!(transparent_over(&tf, lo, hi));
    }

    fn two_cells() -> TetMesh {
        // Two unit tets apart along x, scalars 0.1 (left) and 0.5 (right).
        let points = vec![
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0],
            [10.0, 0.0, 0.0], [11.0, 0.0, 0.0], [10.0, 1.0, 0.0], [10.0, 0.0, 1.0],
        ];
        let scalars = vec![0.1, 0.1, 0.1, 0.1, 0.5, 0.5, 0.5, 0.5];
        TetMesh { name: "two".into(), points, scalars, tets: vec![[0, 1, 2, 3], [4, 5, 6, 7]], stats: Default::default() }
    }

    #[test]
    fn transparent_cells_are_reclassified_when_the_transfer_function_changes() {
        let mesh = two_cells();
        let grid = LookupGrid { lo: 0.0, hi: 1.0, samples: 1024 };
        let mut c = Culler::new(&mesh, &band(), grid, [0.0; 3], true);
        assert_eq!(c.transparent_cells(), 1);
        assert!(!c.set_transfer_function(&mesh, &band(), grid), "same TF: nothing to do");
        let all = TransferFunction::constant([1.0; 3], 1.0);
        assert!(c.set_transfer_function(&mesh, &all, grid));
        assert_eq!(c.transparent_cells(), 0);
        let off = Culler::new(&mesh, &band(), grid, [0.0; 3], false);
        assert_eq!(off.transparent_cells(), 0);
    }

    #[test]
    fn cells_outside_one_plane_are_culled_and_cut_cells_kept() {
        let mesh = two_cells();
        let grid = LookupGrid { lo: 0.0, hi: 1.0, samples: 1024 };
        let all = TransferFunction::constant([1.0; 3], 1.0);
        let mut c = Culler::new(&mesh, &all, grid, [0.0; 3], true);
        let look = |eye: [f64; 3], target: [f64; 3], near: f64| Camera {
            eye,
            target,
            up: [0.0, 1.0, 0.0],
            projection: Projection::Perspective { fovy_deg: 30.0 },
            near,
            far: 100.0,
        };
        // Looking at the left cell from +z: the right one (x = 10..11) is
        // off to the side.
        let cam = look([0.3, 0.3, 5.0], [0.3, 0.3, 0.0], 0.1);
        let n = c.cull(&cam, 64, 64).unwrap();
        assert_eq!(c.survivors(), &[0]);
        assert_eq!(n, FrameCull { transparent: 0, frustum: 1, drawn: 1, reused: false });
        // Behind the eye: culled by the near plane.
        let cam = look([5.0, 0.3, 0.3], [20.0, 0.3, 0.3], 0.1);
        c.cull(&cam, 64, 64).unwrap();
        assert_eq!(c.survivors(), &[1]);
        // The near plane cuts the left cell (eye inside its bounding box
        // region, near plane through it): kept.
        let cam = look([0.2, 0.2, 0.45], [0.2, 0.2, -10.0], 0.3);
        c.cull(&cam, 64, 64).unwrap();
        assert_eq!(c.survivors(), &[0]);
        // Frame re-use follows the key.
        assert!(!c.unchanged(&cam, 64, 64));
        c.remember(&cam, 64, 64);
        assert!(c.unchanged(&cam, 64, 64));
        assert!(!c.unchanged(&cam, 64, 32));
        c.set_transfer_function(&mesh, &band(), grid);
        assert!(!c.unchanged(&cam, 64, 64), "a new transfer function is a new frame");
    }

    #[test]
    fn filtering_keeps_the_order() {
        let mesh = two_cells();
        let grid = LookupGrid { lo: 0.0, hi: 1.0, samples: 1024 };
        let mut c = Culler::new(&mesh, &band(), grid, [0.0; 3], true);
        let cam = Camera::orbit(&mesh.bounds(), 0.0, Projection::Perspective { fovy_deg: 30.0 });
        c.cull(&cam, 64, 64).unwrap();
        assert_eq!(c.survivors(), &[1]);
        let mut out = Vec::new();
        c.filter_order(&[1, 0], &mut out);
        assert_eq!(out, vec![1]);
    }
}
