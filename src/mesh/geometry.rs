//! Validation and view-independent per-tet precomputation.
//!
//! [`TetMesh::validate`] is the single gate every loader goes through: it
//! rejects meshes no renderer could use (non-finite values, bad indices,
//! repeated vertices, duplicate cells, coordinates or extents outside the
//! supported range, no cell with volume), reorients inverted cells so that
//! the module-wide convention (positive signed volume) holds, and counts
//! degenerate cells, which are kept because real data has them (the blunt
//! fin's collapsed points) and the renderers must survive them.
//!
//! # Supported ranges
//!
//! Checked by `validate`; each error names the source, the value and the
//! supported range.
//!
//! - Coordinates: `|x| <= MAX_COORDINATE` (1e15) on every axis.
//! - Extent, the bounding-box diagonal `D`: `MIN_EXTENT <= D <= MAX_EXTENT`
//!   (1e-15 to 1e15). The device computes in f32 relative to the mesh (see
//!   `algo::tet_mesh::render_origin`), where squared lengths overflow
//!   near 1.8e19 and leave the normal range below 1.1e-19. Measured on
//!   lavapipe with a 6^3 grid (1,296 tets) scaled by 10^k: every method and
//!   integrator matches the reference from 1e-19 to 1e18; scaled by 1e19
//!   the error jumps to RMSE 0.35, by 1e-20 VICP's doubles (0.021 against
//!   0.009) and by 1e-24 balanced's. The bounds keep three to four orders
//!   of magnitude of headroom on either side, for meshes and views other
//!   than the ones measured; the stress suite's meshes (scaled by 1e-12 and
//!   1e12, moved 1e7 from the origin) and the measured grid at diagonals
//!   1.0e-15 and 9.9e14 render correctly. Within the coordinate bound the
//!   distance from the origin does not matter: positions are sent relative
//!   to the mesh's centre, the subtraction done in f64, and the view matrix
//!   is built for those relative positions (`Camera::view_proj_relative`;
//!   the reference bins and walks relative to the eye), so nothing large
//!   cancels: a grid moved by 1e14 renders with the error it has at the
//!   origin (`tests/reliability.rs`).
//! - Scalars: `|s| <= MAX_ABS_VALUE` (f32's largest finite value); they are
//!   sent relative to their range, so any range within f32 works.
//! - Cells: every tet has four distinct vertex indices; no two tets have the
//!   same four vertex positions (the same vertices in any order, or points
//!   at identical positions): a cell listed twice is integrated twice and
//!   renders wrong; at least one tet has non-zero volume (a mesh of only flat
//!   cells renders nothing). Zero-volume cells among others are kept and
//!   counted (`MeshStats::zero_volume`).
//! - Overlaps: cells with volume must not overlap through a shared face
//!   (points at identical positions count as one): no face is held by three
//!   or more of them, and two that share a face lie on opposite sides of it.
//!   This catches a cell repeated with one vertex moved, folds and
//!   inside-out neighbours at the cost of one sort of the faces; overlapping
//!   cells that share no face at all (a copy made of new, displaced points)
//!   are not detected, since that needs a spatial search.
//!
//! [`TetGeometry::compute`] does once, at load time and in f64, what SPEC §1
//! calls view-independent: the constant scalar gradient of each tet and its
//! four outward face planes. Degenerate cells get zeros and a flag, never
//! NaN/Inf, so they can be packed and drawn as empty.
//!
//! [`tet_det`] is volbench's one zero-volume (flatness) test: validation's
//! `zero_volume` count, `TetPrecomputed::degenerate` (GPU paths, MPVO) and
//! the CPU reference's solid/flat cells all come from it, so they agree on
//! which cells are flat.

use super::{Bounds, TetMesh};
use anyhow::{bail, Result};
use rayon::prelude::*;
use std::collections::HashMap;

/// Relative threshold for a zero-volume cell (see [`tet_det`]): the cell is
/// flat when, at each of its four vertices, `|det|` is at most
/// `ZERO_VOLUME_REL` times the product of the three edge lengths meeting
/// there, i.e. every vertex's three edges are coplanar to within 1e-10 (the
/// sine of the angle between one edge and the plane of the other two). The
/// test depends only on the cell's shape, not on its size or elongation: a
/// needle of aspect ratio 1e6 (edges at its base at right angles) is solid,
/// while a cap or sliver whose height is 1e-10 of its width is flat. 1e-10 is
/// far above f64 rounding of `det` (~1e-16 of that product), so a cell whose
/// vertices are coplanar up to rounding is flat, and far below real thin
/// cells: the stress suite's thinnest slivers stay solid, the blunt fin's
/// collapsed cells (det exactly 0) are its 77 zero-volume cells.
pub const ZERO_VOLUME_REL: f64 = 1e-10;

/// Largest magnitude accepted for a scalar: `f32::MAX`. Every GPU path packs
/// f32, where larger values become infinite.
pub const MAX_ABS_VALUE: f64 = f32::MAX as f64;

/// Largest magnitude accepted for a coordinate (module docs, "Supported
/// ranges"). Within it the f64 geometry (determinants ~ L^3, gradients)
/// cannot overflow either.
pub const MAX_COORDINATE: f64 = 1e15;

/// Smallest accepted bounding-box diagonal (module docs, "Supported ranges").
pub const MIN_EXTENT: f64 = 1e-15;

/// Largest accepted bounding-box diagonal (module docs, "Supported ranges").
pub const MAX_EXTENT: f64 = 1e15;

/// The supported ranges for any dataset's box (meshes, volumes, terrain):
/// every corner within ±[`MAX_COORDINATE`] and the diagonal within
/// [`MIN_EXTENT`, `MAX_EXTENT`], checked when the data is loaded so that a
/// box the renderers cannot resolve in f32 is an error naming it, not an
/// empty image later. `what` names the data ("volume", "terrain").
pub fn check_box(source: &str, what: &str, min: [f64; 3], max: [f64; 3]) -> Result<()> {
    if let Some(c) = min.iter().chain(&max).find(|c| !c.is_finite() || c.abs() > MAX_COORDINATE) {
        bail!(
            "{source}: the {what} reaches coordinate {c:e}, outside the supported [-{MAX_COORDINATE:e}, {MAX_COORDINATE:e}] \
             (box {min:?} to {max:?}; the renderers compute in f32): check its origin and spacing"
        );
    }
    let d = sub(max, min).iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(MIN_EXTENT..=MAX_EXTENT).contains(&d) {
        bail!(
            "{source}: the {what}'s extent (box diagonal) {d:e} is outside the supported {MIN_EXTENT:e} to {MAX_EXTENT:e} \
             (box {min:?} to {max:?}; the renderers compute in f32): check its spacing"
        );
    }
    Ok(())
}

/// Small f64 vector helpers shared by the geometry and the CPU reference.
#[inline]
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The section of a tet (vertices `v` at view depths `z`) by the plane at
/// depth `cap`: 3 or 4 points, in order around the polygon (the near caps,
/// `near.rs`, and the papers' model of them, `reference::papers`).
pub fn plane_section(v: &[[f64; 3]; 4], z: &[f64; 4], cap: f64) -> Vec<[f64; 3]> {
    let below: Vec<usize> = (0..4).filter(|&i| z[i] < cap).collect();
    let above: Vec<usize> = (0..4).filter(|&i| z[i] >= cap).collect();
    let cut = |i: usize, j: usize| {
        let t = (cap - z[i]) / (z[j] - z[i]);
        std::array::from_fn(|k| v[i][k] + (v[j][k] - v[i][k]) * t)
    };
    match (below.len(), above.len()) {
        (1, 3) => above.iter().map(|&j| cut(below[0], j)).collect(),
        (3, 1) => below.iter().map(|&i| cut(i, above[0])).collect(),
        // Around the quad: (b0,a0), (b0,a1), (b1,a1), (b1,a0).
        (2, 2) => vec![cut(below[0], above[0]), cut(below[0], above[1]), cut(below[1], above[1]), cut(below[1], above[0])],
        _ => Vec::new(),
    }
}

#[inline]
fn len2(a: [f64; 3]) -> f64 {
    dot(a, a)
}

/// `det[p1-p0, p2-p0, p3-p0]` (six times the signed volume) and whether the
/// cell counts as zero-volume under [`ZERO_VOLUME_REL`]: the one flatness
/// test (module docs). The flag ignores orientation; callers that also need
/// a positive orientation (the reference's "solid") check the sign of `det`.
///
/// The determinant is computed from the vertex whose three edges have the
/// smallest length product (the others follow in an even permutation, so
/// the sign is that of `det[p1-p0, p2-p0, p3-p0]`): its rounding error is
/// about 1e-16 of that product, so at the tip of a needle, where the three
/// long edges are nearly parallel, precision is not lost to cancellation.
pub fn tet_det(p: [[f64; 3]; 4]) -> (f64, bool) {
    let (det, zero, _) = tet_det_from(p);
    (det, zero)
}

/// [`tet_det`] and the vertex order it was computed in (an even permutation
/// of 0..4, starting at the best-conditioned vertex), for computations that
/// should use the same edges.
fn tet_det_from(p: [[f64; 3]; 4]) -> (f64, bool, [usize; 4]) {
    // Edge lengths l[a][b]; the vertex with the smallest product of its
    // three edges is the best-conditioned base (and gives the loosest, i.e.
    // shape-only, threshold).
    let l = |a: usize, b: usize| len2(sub(p[a], p[b])).sqrt();
    let (l01, l02, l03, l12, l13, l23) = (l(0, 1), l(0, 2), l(0, 3), l(1, 2), l(1, 3), l(2, 3));
    let products = [l01 * l02 * l03, l01 * l12 * l13, l02 * l12 * l23, l03 * l13 * l23];
    // Even permutations of (0, 1, 2, 3) starting at each vertex.
    const FROM: [[usize; 4]; 4] = [[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]];
    let base = (1..4).fold(0, |b, v| if products[v] < products[b] { v } else { b });
    let [o, a, b, c] = FROM[base];
    let det = dot(sub(p[a], p[o]), cross(sub(p[b], p[o]), sub(p[c], p[o])));
    let zero = det == 0.0 || det.abs() <= ZERO_VOLUME_REL * products[base];
    (det, zero, FROM[base])
}

/// `a` of the plane `n·(x - origin) + a = 0` through the face opposite
/// vertex `i` of `p`, from the face's centroid (symmetric in its three
/// vertices).
fn face_offset(n: [f64; 3], p: [[f64; 3]; 4], i: usize, origin: [f64; 3]) -> f64 {
    let f = [(i + 1) % 4, (i + 2) % 4, (i + 3) % 4];
    let rel = |v: usize, k: usize| p[f[v]][k] - origin[k];
    let fc: [f64; 3] = std::array::from_fn(|k| (rel(0, k) + rel(1, k) + rel(2, k)) / 3.0);
    -dot(n, fc)
}

/// What [`TetMesh::validate`] reports about duplicate cells.
struct DuplicateTets {
    /// Cells that repeat an earlier one.
    count: usize,
    /// The first cell (by index) that repeats an earlier one, and that one.
    second: usize,
    first: usize,
}

impl TetMesh {
    /// Checks the mesh, reorients inverted cells and counts zero-volume ones
    /// (see module docs). `source` (a file path or dataset name) is quoted in
    /// every error. `stats.reoriented` is incremented by the number of cells
    /// swapped now; `stats.zero_volume` is set to the current count, so calling
    /// this twice is harmless.
    pub fn validate(&mut self, source: &str) -> Result<()> {
        if self.points.is_empty() || self.tets.is_empty() {
            bail!(
                "{source}: empty mesh ({} points, {} tets)",
                self.points.len(),
                self.tets.len()
            );
        }
        if self.points.len() != self.scalars.len() {
            bail!(
                "{source}: {} points but {} scalars (one scalar per point is required)",
                self.points.len(),
                self.scalars.len()
            );
        }
        if self.points.len() > u32::MAX as usize {
            bail!("{source}: {} points do not fit 32-bit indices", self.points.len());
        }
        if let Some(i) = self.points.par_iter().position_first(|p| !p.iter().all(|c| c.is_finite())) {
            bail!("{source}: point {i} has a non-finite coordinate {:?}", self.points[i]);
        }
        if let Some(i) = self.scalars.par_iter().position_first(|s| !s.is_finite()) {
            bail!("{source}: point {i} has a non-finite scalar {}", self.scalars[i]);
        }
        let far = |p: &[f64; 3]| p.iter().any(|c| c.abs() > MAX_COORDINATE);
        if let Some(i) = self.points.par_iter().position_first(far) {
            let p = self.points[i];
            bail!(
                "{source}: point {i} at ({:e}, {:e}, {:e}) is outside the supported coordinate range \
                 [-{MAX_COORDINATE:e}, {MAX_COORDINATE:e}] (the renderers compute in f32; see mesh::geometry)",
                p[0],
                p[1],
                p[2]
            );
        }
        if let Some(i) = self.scalars.par_iter().position_first(|v| v.abs() > MAX_ABS_VALUE) {
            bail!(
                "{source}: point {i} has a scalar beyond the f32 range (|s| > {MAX_ABS_VALUE:e}): {}; \
                 the renderers compute in f32",
                self.scalars[i]
            );
        }
        self.check_extent(source)?;
        let np = self.points.len();
        if let Some(c) = self.tets.par_iter().position_first(|t| t.iter().any(|&v| v as usize >= np)) {
            bail!(
                "{source}: tet {c} has vertex index out of range {:?} (mesh has {np} points)",
                self.tets[c]
            );
        }
        let repeats = |t: &[u32; 4]| (0..4).any(|a| (a + 1..4).any(|b| t[a] == t[b]));
        if let Some(c) = self.tets.par_iter().position_first(repeats) {
            bail!("{source}: tet {c} repeats a vertex index {:?}", self.tets[c]);
        }
        if let Some(d) = self.find_duplicate_tets() {
            bail!(
                "{source}: {} duplicate tet(s): tet {} has the same four vertex positions as tet {} \
                 ({:?} and {:?}, vertex order aside); a cell listed twice is integrated twice and renders wrong",
                d.count,
                d.second,
                d.first,
                self.tets[d.second],
                self.tets[d.first]
            );
        }
        let points = &self.points;
        let (reoriented, zero) = self
            .tets
            .par_iter_mut()
            .map(|t| {
                let (det, zero) = tet_det(t.map(|v| points[v as usize]));
                let flip = det < 0.0;
                if flip {
                    t.swap(2, 3);
                }
                (flip as usize, zero as usize)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        self.stats.reoriented += reoriented;
        self.stats.zero_volume = zero;
        self.check_overlaps(source)?;
        if zero == self.tets.len() {
            bail!(
                "{source}: all {zero} tets have zero volume (at every vertex, the three edges are coplanar \
                 to within {ZERO_VOLUME_REL:e}): the mesh is flat and would render nothing"
            );
        }
        Ok(())
    }

    /// Refuses cells with volume that overlap through a shared face (module
    /// docs): a face held by three or more solid cells, or two solid cells
    /// on the same side of their common face (a fold). Faces are matched by
    /// position (points at identical coordinates are one), as the renderers'
    /// adjacency does. Flat cells take no part: they hold no volume, and real
    /// data welds them onto solid neighbours (the blunt fin's collapsed
    /// points). One sort of the 4n faces, no pairwise search; overlapping
    /// cells that share no face are not found here. Expects oriented cells
    /// with indices in range.
    fn check_overlaps(&self, source: &str) -> Result<()> {
        use super::adjacency::{weld_coincident, FaceAdjacency, FACE_VERTS, NONE};
        let solid: Vec<bool> = self.tets.par_iter().map(|t| !tet_det(t.map(|v| self.points[v as usize])).1).collect();
        let weld = weld_coincident(&self.points);
        let adj = FaceAdjacency::build(&self.tets, Some(&weld), |_| true);
        let face_of = |slot: u32| -> [u32; 3] {
            let (c, f) = (slot as usize / 4, slot as usize % 4);
            FACE_VERTS[f].map(|l| self.tets[c][l])
        };
        // A face with three or more solid holders.
        let crowded = adj.shared.iter().filter_map(|holders| {
            let solid_holders: Vec<usize> =
                holders.iter().map(|&s| s as usize / 4).filter(|&c| solid[c]).collect();
            (solid_holders.len() >= 3).then(|| (holders[0], solid_holders))
        });
        let crowded: Vec<(u32, Vec<usize>)> = crowded.collect();
        if let Some((slot, cells)) = crowded.first() {
            bail!(
                "{source}: {} face(s) are shared by three or more cells with volume, which therefore overlap: \
                 face {:?} is a face of tets {:?}; a conforming mesh shares a face between at most two cells",
                crowded.len(),
                face_of(*slot),
                cells
            );
        }
        // Two solid cells on the same side of their common face: cell c's
        // vertex f replaced by the partner's opposite vertex keeps c's
        // (positive) orientation.
        let folded = |slot: usize| -> bool {
            let p = adj.partner[slot];
            if p == NONE || (p as usize) < slot {
                return false;
            }
            let (c, f) = (slot / 4, slot % 4);
            let (d, g) = (p as usize / 4, p as usize % 4);
            if !solid[c] || !solid[d] {
                return false;
            }
            let mut q = self.tet_points(c);
            q[f] = self.points[self.tets[d][g] as usize];
            let (det, flat) = tet_det(q);
            det > 0.0 && !flat
        };
        let folds: Vec<usize> = (0..adj.partner.len()).into_par_iter().filter(|&s| folded(s)).collect();
        if let Some(&slot) = folds.first() {
            let p = adj.partner[slot] as usize;
            bail!(
                "{source}: {} pair(s) of cells overlap: tets {} and {} share the face {:?} but lie on the same \
                 side of it (a folded or repeated cell)",
                folds.len(),
                slot / 4,
                p / 4,
                face_of(slot as u32)
            );
        }
        Ok(())
    }

    /// The bounding-box diagonal within [`MIN_EXTENT`, `MAX_EXTENT`] (module
    /// docs). Expects finite coordinates.
    fn check_extent(&self, source: &str) -> Result<()> {
        let b = self.bounds();
        let d = b.diagonal();
        if d == 0.0 {
            let p = self.points[0];
            bail!(
                "{source}: the mesh has zero extent: all {} points are at ({:e}, {:e}, {:e}); \
                 the supported extent (bounding-box diagonal) is {MIN_EXTENT:e} to {MAX_EXTENT:e}",
                self.points.len(),
                p[0],
                p[1],
                p[2]
            );
        }
        if !(MIN_EXTENT..=MAX_EXTENT).contains(&d) {
            bail!(
                "{source}: the mesh's extent (bounding-box diagonal) {d:e} is outside the supported range \
                 {MIN_EXTENT:e} to {MAX_EXTENT:e} (bounds {:?} to {:?}; the renderers compute in f32, see \
                 mesh::geometry)",
                b.min,
                b.max
            );
        }
        Ok(())
    }

    /// The tets that repeat an earlier tet's four vertex positions (in any
    /// order; points at bitwise-equal positions count as one, so a cell
    /// repeated through duplicated points is found too). `None` if there
    /// are none. Expects vertex indices in range.
    fn find_duplicate_tets(&self) -> Option<DuplicateTets> {
        // Each point's representative: the first point at the same position
        // (+0.0 and -0.0 are one position).
        let mut first_at: HashMap<[u64; 3], u32> = HashMap::with_capacity(self.points.len());
        let rep: Vec<u32> = (0..self.points.len() as u32)
            .map(|i| *first_at.entry(self.points[i as usize].map(|c| (c + 0.0).to_bits())).or_insert(i))
            .collect();
        drop(first_at);
        let mut keys: Vec<([u32; 4], u32)> = self
            .tets
            .par_iter()
            .enumerate()
            .map(|(c, t)| {
                let mut k = t.map(|v| rep[v as usize]);
                k.sort_unstable();
                (k, c as u32)
            })
            .collect();
        keys.par_sort_unstable();
        let mut found: Option<DuplicateTets> = None;
        let mut group_start = 0;
        for i in 1..keys.len() {
            if keys[i].0 != keys[i - 1].0 {
                group_start = i;
                continue;
            }
            // Indices ascend within a group: cell keys[i] repeats the
            // group's first. Report the earliest cell that repeats another.
            let d = found.get_or_insert(DuplicateTets { count: 0, second: usize::MAX, first: 0 });
            d.count += 1;
            let later = keys[i].1 as usize;
            if later < d.second {
                d.second = later;
                d.first = keys[group_start].1 as usize;
            }
        }
        found
    }

    /// Axis-aligned bounds of the points (all zeros for an empty mesh).
    /// Vertices and scalars of cell `t`.
    #[inline]
    pub fn cell(&self, t: [u32; 4]) -> ([[f64; 3]; 4], [f64; 4]) {
        (t.map(|v| self.points[v as usize]), t.map(|v| self.scalars[v as usize]))
    }

    /// Centroid (mean of the 4 vertices) of cell `t`: the one definition
    /// (`TetGeometry::centroids`, the sorts' f32 centroids).
    #[inline]
    pub fn centroid(&self, t: [u32; 4]) -> [f64; 3] {
        let p = t.map(|v| self.points[v as usize]);
        std::array::from_fn(|k| 0.25 * (p[0][k] + p[1][k] + p[2][k] + p[3][k]))
    }

    pub fn bounds(&self) -> Bounds {
        if self.points.is_empty() {
            return Bounds { min: [0.0; 3], max: [0.0; 3] };
        }
        let mut min = [f64::INFINITY; 3];
        let mut max = [f64::NEG_INFINITY; 3];
        for p in &self.points {
            for c in 0..3 {
                min[c] = min[c].min(p[c]);
                max[c] = max[c].max(p[c]);
            }
        }
        Bounds { min, max }
    }

    /// The four vertex positions of tet `c`.
    pub fn tet_points(&self, c: usize) -> [[f64; 3]; 4] {
        self.tets[c].map(|v| self.points[v as usize])
    }

    /// The four vertex scalars of tet `c`.
    pub fn tet_scalars(&self, c: usize) -> [f64; 4] {
        self.tets[c].map(|v| self.scalars[v as usize])
    }

    /// Scalar range `(min, max)` ((0, 0) for an empty mesh).
    pub fn scalar_range(&self) -> (f64, f64) {
        if self.scalars.is_empty() {
            return (0.0, 0.0);
        }
        self.scalars
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &s| (lo.min(s), hi.max(s)))
    }
}

/// View-independent data of one tet (SPEC §1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetPrecomputed {
    /// Constant scalar gradient `g` (0 for degenerate cells).
    pub gradient: [f64; 3],
    /// Plane of the face opposite vertex `i`: `[n.x, n.y, n.z, a]` with `n` a
    /// unit outward normal and `n·x + a = 0` on the face (0 for degenerate cells).
    pub planes: [[f64; 4]; 4],
    /// Volume (>= 0; the signed volume of the stored, oriented cell).
    pub volume: f64,
    /// Zero-volume cell by [`tet_det`] (or, only beyond validated input, a
    /// determinant, plane or gradient that is not finite): gradient and
    /// planes are 0.
    pub degenerate: bool,
}

impl TetPrecomputed {
    pub const DEGENERATE: TetPrecomputed = TetPrecomputed {
        gradient: [0.0; 3],
        planes: [[0.0; 4]; 4],
        volume: 0.0,
        degenerate: true,
    };

    /// Computes gradient, outward planes and volume of a tet from its vertex
    /// positions and scalars. Works for either orientation; never yields
    /// NaN/Inf for finite input. (Validated meshes keep every coordinate
    /// within [`MAX_COORDINATE`], where nothing overflows; beyond, up to
    /// f64::MAX, a cell whose determinant overflows is reported degenerate
    /// with volume `f64::MAX`.)
    pub fn from_vertices(p: [[f64; 3]; 4], s: [f64; 4]) -> TetPrecomputed {
        let (det, zero, order) = tet_det_from(p);
        if !det.is_finite() {
            return TetPrecomputed { volume: f64::MAX, ..Self::DEGENERATE };
        }
        if zero {
            return TetPrecomputed { volume: (det / 6.0).abs(), ..Self::DEGENERATE };
        }
        // From the vertex `det` was computed from (same sign, same edges).
        let [o, v1, v2, v3] = order;
        let e1 = sub(p[v1], p[o]);
        let e2 = sub(p[v2], p[o]);
        let e3 = sub(p[v3], p[o]);
        // Cramer via cross products: g = (ds1 (e2×e3) + ds2 (e3×e1) + ds3 (e1×e2)) / det.
        let c23 = cross(e2, e3);
        let c31 = cross(e3, e1);
        let c12 = cross(e1, e2);
        let (d1, d2, d3) = (s[v1] - s[o], s[v2] - s[o], s[v3] - s[o]);
        let inv = 1.0 / det;
        let gradient: [f64; 3] =
            std::array::from_fn(|k| (d1 * c23[k] + d2 * c31[k] + d3 * c12[k]) * inv);
        let mut planes = [[0.0; 4]; 4];
        for (i, plane) in planes.iter_mut().enumerate() {
            let f = [(i + 1) % 4, (i + 2) % 4, (i + 3) % 4];
            let mut n = cross(sub(p[f[1]], p[f[0]]), sub(p[f[2]], p[f[0]]));
            let len = len2(n).sqrt();
            if len.is_nan() || len <= 0.0 || len.is_infinite() {
                return TetPrecomputed { volume: (det / 6.0).abs(), ..Self::DEGENERATE };
            }
            n = n.map(|c| c / len);
            let mut a = face_offset(n, p, i, [0.0; 3]);
            if dot(n, p[i]) + a > 0.0 {
                n = n.map(|c| -c);
                a = -a;
            }
            *plane = [n[0], n[1], n[2], a];
        }
        let out = TetPrecomputed { gradient, planes, volume: (det / 6.0).abs(), degenerate: false };
        if out.gradient.iter().chain(out.planes.iter().flatten()).all(|v| v.is_finite()) {
            out
        } else {
            TetPrecomputed { volume: out.volume, ..Self::DEGENERATE }
        }
    }

    /// Plane `i` for points given relative to `origin`: the same normal, the
    /// offset recomputed from the face's vertices minus `origin` (`p` are
    /// the cell's vertices, as given to `from_vertices`), so it stays exact
    /// far from the world origin, where `planes[i][3]` is as large as the
    /// coordinates and has lost their low digits. Equal to `planes[i]` for
    /// origin 0.
    pub fn plane_relative(&self, i: usize, p: [[f64; 3]; 4], origin: [f64; 3]) -> [f64; 4] {
        let [nx, ny, nz, _] = self.planes[i];
        if self.degenerate {
            return [0.0; 4];
        }
        [nx, ny, nz, face_offset([nx, ny, nz], p, i, origin)]
    }

    /// SPEC's 3-float plane for vertex `i` at `cell_vertex_pos`: the plane of
    /// the opposite face encoded as `n' = n_i / (n_i·v_i + a_i)`, so that a ray
    /// from the vertex along a unit direction `d` exits through that face at
    /// `t = -1 / (n'·d)`. Zero for degenerate cells (or a vertex on its
    /// opposite plane).
    pub fn opposite_plane_3(&self, cell_vertex_pos: [f64; 3], i: usize) -> [f64; 3] {
        if self.degenerate {
            return [0.0; 3];
        }
        let [nx, ny, nz, a] = self.planes[i];
        let dist = nx * cell_vertex_pos[0] + ny * cell_vertex_pos[1] + nz * cell_vertex_pos[2] + a;
        if dist == 0.0 || !dist.is_finite() {
            return [0.0; 3];
        }
        let r = [nx / dist, ny / dist, nz / dist];
        if r.iter().all(|v| v.is_finite()) {
            r
        } else {
            [0.0; 3]
        }
    }
}

/// Per-cell precomputation for a whole mesh, indexed like `TetMesh::tets`.
#[derive(Debug, Clone)]
pub struct TetGeometry {
    pub cells: Vec<TetPrecomputed>,
    /// Cell centroids (mean of the 4 vertices), e.g. for the depth sort.
    pub centroids: Vec<[f64; 3]>,
}

impl TetGeometry {
    /// Computes gradients, planes, volumes and centroids in parallel.
    /// Expects a validated mesh (indices in range).
    pub fn compute(mesh: &TetMesh) -> TetGeometry {
        let (cells, centroids) = mesh
            .tets
            .par_iter()
            .map(|&t| {
                let (p, s) = mesh.cell(t);
                (TetPrecomputed::from_vertices(p, s), mesh.centroid(t))
            })
            .unzip();
        TetGeometry { cells, centroids }
    }

    /// Number of degenerate cells.
    pub fn degenerate_count(&self) -> usize {
        self.cells.iter().filter(|c| c.degenerate).count()
    }

    /// Sum of cell volumes.
    pub fn total_volume(&self) -> f64 {
        self.cells.iter().map(|c| c.volume).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::super::MeshStats;
    use super::*;

    /// Small deterministic PRNG (xorshift64*), values in [-1, 1).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let v = self.0.wrapping_mul(0x2545F4914F6CDD1D);
            (v >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        }
        fn vec3(&mut self) -> [f64; 3] {
            [self.next(), self.next(), self.next()]
        }
    }

    fn random_tet(rng: &mut Rng) -> [[f64; 3]; 4] {
        loop {
            let p = [rng.vec3(), rng.vec3(), rng.vec3(), rng.vec3()];
            let (det, zero) = tet_det(p);
            if !zero && det.abs() > 1e-3 {
                return p;
            }
        }
    }

    fn mesh_of(p: [[f64; 3]; 4], s: [f64; 4]) -> TetMesh {
        TetMesh {
            name: "t".into(),
            points: p.to_vec(),
            scalars: s.to_vec(),
            tets: vec![[0, 1, 2, 3]],
            stats: MeshStats::default(),
        }
    }

    #[test]
    fn gradient_exact_for_linear_field() {
        let mut rng = Rng(0x9E3779B97F4A7C15);
        for _ in 0..200 {
            let p = random_tet(&mut rng);
            let g = rng.vec3().map(|v| v * 10.0);
            let c = rng.next();
            let s = p.map(|q| dot(g, q) + c);
            let t = TetPrecomputed::from_vertices(p, s);
            assert!(!t.degenerate);
            for k in 0..3 {
                assert!((t.gradient[k] - g[k]).abs() < 1e-9 * (1.0 + g[k].abs()), "{t:?} vs {g:?}");
            }
            let (det, _) = tet_det(p);
            assert!((t.volume - det.abs() / 6.0).abs() < 1e-15);
        }
    }

    #[test]
    fn planes_are_unit_and_outward() {
        let mut rng = Rng(12345);
        for _ in 0..200 {
            let p = random_tet(&mut rng);
            let t = TetPrecomputed::from_vertices(p, [0.0; 4]);
            for i in 0..4 {
                let [nx, ny, nz, a] = t.planes[i];
                assert!(((nx * nx + ny * ny + nz * nz).sqrt() - 1.0).abs() < 1e-12);
                let eval = |q: [f64; 3]| nx * q[0] + ny * q[1] + nz * q[2] + a;
                assert!(eval(p[i]) < 0.0, "opposite vertex must be inside");
                for (j, &q) in p.iter().enumerate() {
                    if j != i {
                        assert!(eval(q).abs() < 1e-12, "face vertex on plane");
                    }
                }
                // Outward: a point just beyond the face centroid is outside.
                let centroid: [f64; 3] = std::array::from_fn(|k| {
                    (0..4).filter(|&j| j != i).map(|j| p[j][k]).sum::<f64>() / 3.0
                });
                assert!(eval([centroid[0] + 1e-3 * nx, centroid[1] + 1e-3 * ny, centroid[2] + 1e-3 * nz]) > 0.0);
            }
        }
    }

    #[test]
    fn three_float_plane_gives_ray_plane_distance() {
        let mut rng = Rng(777);
        let mut checked = 0;
        for _ in 0..200 {
            let p = random_tet(&mut rng);
            let t = TetPrecomputed::from_vertices(p, [0.0; 4]);
            for (i, &pi) in p.iter().enumerate() {
                let d = rng.vec3();
                let l = len2(d).sqrt();
                let d = d.map(|c| c / l);
                let [nx, ny, nz, a] = t.planes[i];
                let n = [nx, ny, nz];
                if dot(n, d).abs() < 1e-3 {
                    continue;
                }
                let t_ref = -(dot(n, pi) + a) / dot(n, d);
                let np = t.opposite_plane_3(pi, i);
                let t3 = -1.0 / dot(np, d);
                assert!((t3 - t_ref).abs() < 1e-9 * (1.0 + t_ref.abs()), "{t3} vs {t_ref}");
                // The point reached lies on the opposite plane.
                let q: [f64; 3] = std::array::from_fn(|k| pi[k] + t3 * d[k]);
                assert!((dot(n, q) + a).abs() < 1e-9 * (1.0 + t3.abs()));
                checked += 1;
            }
        }
        assert!(checked > 500);
    }

    #[test]
    fn degenerate_cells_are_zero_not_nan() {
        // Flat tet (all in z = 0) and a collapsed one (two equal points).
        let flat = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        let collapsed = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        let tiny = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.3, 0.3, 1e-12]];
        for p in [flat, collapsed, tiny] {
            let t = TetPrecomputed::from_vertices(p, [1.0, 2.0, 3.0, 4.0]);
            assert!(t.degenerate);
            assert_eq!(t.gradient, [0.0; 3]);
            assert_eq!(t.planes, [[0.0; 4]; 4]);
            assert_eq!(t.opposite_plane_3(p[0], 0), [0.0; 3]);
        }
        // A flat cell beside a solid one is kept and counted...
        let mut m = mesh_of(flat, [0.0; 4]);
        m.points.push([0.0, 0.0, 1.0]);
        m.scalars.push(0.0);
        m.tets.push([0, 1, 2, 4]);
        m.validate("flat").unwrap();
        assert_eq!(m.stats.zero_volume, 1);
        let g = TetGeometry::compute(&m);
        assert_eq!(g.degenerate_count(), 1);
        // ...a mesh of flat cells only is rejected: it would render nothing.
        let e = mesh_of(flat, [0.0; 4]).validate("flat").unwrap_err().to_string();
        assert!(e.contains("flat: all 1 tets have zero volume"), "{e}");
    }

    #[test]
    fn flatness_depends_on_shape_not_elongation() {
        // A needle of aspect ratio 1e6 (length 1, base edges 1e-6 at right
        // angles) is solid from whichever vertex it is listed; its gradient
        // is exact. A cap 1e-11 high over a unit triangle is flat.
        let w = 1e-6;
        let needle = [[0.0, 0.0, 0.0], [w, 0.0, 0.0], [0.0, w, 0.0], [0.0, 0.0, 1.0]];
        let s = |p: [f64; 3]| 2.0 * p[0] - 3.0 * p[1] + 0.5 * p[2];
        for r in 0..4 {
            let p: [[f64; 3]; 4] = std::array::from_fn(|k| needle[(k + r) % 4]);
            let (det, zero) = tet_det(p);
            assert!(!zero, "rotation {r}");
            assert!((det.abs() - w * w).abs() <= 1e-9 * w * w, "rotation {r}: {det}");
            let t = TetPrecomputed::from_vertices(p, p.map(s));
            assert!(!t.degenerate);
            for (g, want) in t.gradient.iter().zip([2.0, -3.0, 0.5]) {
                assert!((g - want).abs() < 1e-6, "rotation {r}: {:?}", t.gradient);
            }
        }
        let cap = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.3, 0.3, 1e-11]];
        assert!(tet_det(cap).1);
        // The same cap scaled by 1e-9 or 1e9: the test does not see units.
        for k in [1e-9, 1e9] {
            assert!(tet_det(cap.map(|p| p.map(|c| c * k))).1);
            assert!(!tet_det(needle.map(|p| p.map(|c| c * k))).1);
        }
    }

    #[test]
    fn reorientation_is_counted() {
        let mut rng = Rng(4242);
        let mut points = Vec::new();
        let mut tets = Vec::new();
        let mut expected_neg = 0;
        for c in 0..50u32 {
            let p = random_tet(&mut rng);
            if tet_det(p).0 < 0.0 {
                expected_neg += 1;
            }
            points.extend_from_slice(&p);
            tets.push([4 * c, 4 * c + 1, 4 * c + 2, 4 * c + 3]);
        }
        let scalars = points.iter().map(|q| q[0] + 2.0 * q[1]).collect();
        let mut m = TetMesh { name: "r".into(), points, scalars, tets, stats: MeshStats::default() };
        let before = m.tets.clone();
        m.validate("random").unwrap();
        assert!(expected_neg > 0 && expected_neg < 50);
        assert_eq!(m.stats.reoriented, expected_neg);
        assert_eq!(m.stats.zero_volume, 0);
        for (c, t) in m.tets.iter().enumerate() {
            assert!(tet_det(m.tet_points(c)).0 > 0.0);
            let mut a = *t;
            let mut b = before[c];
            a.sort();
            b.sort();
            assert_eq!(a, b, "same vertex set");
        }
        // Idempotent.
        m.validate("random").unwrap();
        assert_eq!(m.stats.reoriented, expected_neg);
        let g = TetGeometry::compute(&m);
        for (c, cell) in g.cells.iter().enumerate() {
            assert!((cell.gradient[0] - 1.0).abs() < 1e-9 && (cell.gradient[1] - 2.0).abs() < 1e-9);
            let p = m.tet_points(c);
            assert!((g.centroids[c][0] - 0.25 * (p[0][0] + p[1][0] + p[2][0] + p[3][0])).abs() < 1e-15);
        }
    }

    #[test]
    fn validate_rejects_bad_meshes() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let check = |mut m: TetMesh, what: &str| {
            let e = m.validate("SRC").unwrap_err().to_string();
            assert!(e.contains("SRC") && e.contains(what), "{e}");
        };
        let mut m = mesh_of(p, [0.0; 4]);
        m.tets.clear();
        check(m, "empty");
        let mut m = mesh_of(p, [0.0; 4]);
        m.scalars.pop();
        check(m, "scalars");
        let mut m = mesh_of(p, [0.0; 4]);
        m.points[2][1] = f64::NAN;
        check(m, "point 2");
        let mut m = mesh_of(p, [0.0; 4]);
        m.scalars[3] = f64::INFINITY;
        check(m, "point 3");
        let mut m = mesh_of(p, [0.0; 4]);
        m.tets[0][1] = 4;
        check(m, "out of range");
        let mut m = mesh_of(p, [0.0; 4]);
        m.tets[0][3] = 1;
        check(m, "repeats");
        let mut m = mesh_of(p, [0.0; 4]);
        m.validate("ok").unwrap();
        assert_eq!(m.bounds(), Bounds { min: [0.0; 3], max: [1.0; 3] });
    }

    #[test]
    fn supported_coordinate_and_extent_ranges() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let scaled = |s: f64, t: f64| mesh_of(p.map(|q| q.map(|c| c * s + t)), [0.0, 1.0, 2.0, 3.0]);
        // The stress suite's scales and offsets stay accepted (diagonal sqrt 3 * s).
        for (s, t) in [(1e-12, 0.0), (1e12, 0.0), (1.0, 1e7), (6e-16, 0.0), (5.7e14, 0.0), (1.0, -1e15 + 2.0)] {
            scaled(s, t).validate("ok").unwrap_or_else(|e| panic!("scale {s:e} offset {t:e}: {e}"));
        }
        for (s, t, what) in [
            (1e19, 0.0, "outside the supported coordinate range [-1e15, 1e15]"),
            (1e-20, 0.0, "extent (bounding-box diagonal) 1.73"),
            (5e-16, 0.0, "is outside the supported range 1e-15 to 1e15"),
            (5.8e14, 0.0, "is outside the supported range 1e-15 to 1e15"),
            (1.0, 2e15, "point 0 at (2e15, 2e15, 2e15) is outside the supported coordinate range"),
            (0.0, 3.0, "zero extent: all 4 points are at (3e0, 3e0, 3e0)"),
        ] {
            let e = scaled(s, t).validate("SRC").unwrap_err().to_string();
            assert!(e.starts_with("SRC: ") && e.contains(what), "scale {s:e} offset {t:e}: {e}");
        }
    }

    #[test]
    fn duplicate_tets_are_rejected() {
        // Two cubes' worth of tets: 0..4 one tet each, then repeats.
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]];
        let mesh = |tets: Vec<[u32; 4]>, extra: Vec<[f64; 3]>| {
            let points: Vec<[f64; 3]> = p.iter().copied().chain(extra).collect();
            TetMesh { name: "d".into(), scalars: vec![0.0; points.len()], points, tets, stats: MeshStats::default() }
        };
        mesh(vec![[0, 1, 2, 3], [1, 2, 3, 4]], vec![]).validate("ok").unwrap();
        // The same vertices in another order (one of them inverted).
        let e = mesh(vec![[0, 1, 2, 3], [1, 2, 3, 4], [3, 2, 1, 0], [4, 3, 2, 1], [2, 0, 3, 1]], vec![])
            .validate("SRC")
            .unwrap_err()
            .to_string();
        assert!(e.contains("SRC: 3 duplicate tet(s): tet 2 has the same four vertex positions as tet 0"), "{e}");
        // The same positions through duplicated points (5 = copy of 0, 6 = -0.0 copy of 2).
        let e = mesh(vec![[1, 2, 3, 4], [0, 1, 2, 3], [5, 1, 6, 3]], vec![[0.0, 0.0, 0.0], [-0.0, 1.0, 0.0]])
            .validate("SRC")
            .unwrap_err()
            .to_string();
        assert!(e.contains("1 duplicate tet(s): tet 2 has the same four vertex positions as tet 1"), "{e}");
    }
}
