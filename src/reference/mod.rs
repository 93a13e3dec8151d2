//! The CPU reference renderer: every GPU image is compared with this (SPEC §5).
//!
//! **What.** For each pixel, the exact ray of [`Camera::ray`] (f64, perspective
//! rays are really perspective) is followed through the tetrahedral mesh; every
//! cell it crosses contributes the exact emission–absorption integral of its
//! segment (scalar linear along the segment, split at the transfer function's
//! control points, each piece closed-form in Ψ and ζ: [`integrate`], [`mod@psi`]),
//! composited front to back ("over") on a transparent black background. The
//! output is premultiplied RGBA, row 0 at the top. Nothing is sampled, so the
//! only error is f64 rounding (≲1e-13 on a pixel).
//!
//! **Method: ray walking, not per-pixel cell sorting.** Face adjacency is built
//! once (`topology.rs`, on the shared builder `mesh::adjacency`, matching
//! vertex indices, no welding); the boundary faces are binned into 8×8-pixel screen
//! tiles by their projected bounding boxes; each ray tests the boundary faces
//! of its tile for *entry*, sorts the entries by depth and walks from each one,
//! cell to cell through the exit face, until it leaves through a boundary face;
//! the next entry after that exit restarts the walk, which is how non-convex
//! meshes (holes, separate parts) are handled. Walking costs O(cells on the
//! ray) per pixel, against O(cells whose screen box covers the pixel) for the
//! bin-and-clip alternative, and it needs no per-pixel sort of intervals.
//!
//! **Robustness, tie-breaking.** All crossing decisions use Plücker edge values
//! `w(e) = d·((p_i − o) × (p_j − o))` of the ray against mesh edges: a face is
//! crossed iff its three oriented edge values have one sign (the sign says
//! entering or leaving), and the crossing point's barycentric weights are those
//! values. Each edge's value is computed from its *canonical* orientation
//! (lower vertex index first) with the same operations whichever cell asks, so
//! the two cells sharing a face, and the faces sharing an edge, see the very
//! same numbers: a ray can never slip between two faces or cross both.
//! A value that is exactly 0 (the ray meets the edge's line: rays through
//! edges and vertices, rays lying in a face, axis-aligned views of grid
//! meshes) is replaced by the sign it takes when the ray origin is moved by
//! `ε·n1 + ε²·n2` (n1, n2 ⊥ d, fixed per ray): simulation of simplicity. So a
//! ray through an edge is assigned to exactly one of the cells around it, a
//! ray lying in a shared face to exactly one side, and a ray along an edge
//! parallel to it never crosses the faces seen edge-on (they are never
//! entered, the cells on either side are). The exit point of one cell *is*
//! the entry point of the next (carried over, not recomputed), so depths
//! telescope: no gaps, no overlaps.
//!
//! **Degenerate cells.** The line crosses exactly two faces of any cell it
//! meets, flat or not: the walk leaves through "the other crossed face",
//! i.e. the face whose signs are opposite to those of the face it came in
//! by. For a solid, positively oriented cell that is the usual exit; a flat
//! cell (zero-volume by `mesh::geometry::tet_det`: coplanar to 1e-10, the
//! test that also makes the GPU paths' cells `degenerate`; or inverted) has
//! no orientation to trust, so it is crossed whichever way its vertices are
//! ordered, with a zero-length segment (exit depth is clamped to be ≥ entry
//! depth). For the same reason a boundary face of a flat cell counts as an
//! entry whichever way it is crossed; if it was really an exit, the walk
//! meets a solid cell from its exit side at once and stops there
//! (`reversed_walks`, harmless).
//!
//! **Safety nets** (all counted in [`ReferenceStats`], all 0 in the tests on
//! exact data and on the blunt fin and oxygen post meshes): sign patterns
//! that rounding has made inconsistent (a ray within an ulp of a vertex, or
//! along an edge that is parallel to it only up to rounding) fall back to the
//! least-violated exit face; a walk that makes no depth progress for 1024
//! cells, or a ray that visits more than 4·(number of cells) + 1024 cells, is
//! stopped; a boundary entry lying more than 1e-9 × (mesh diagonal) before
//! the previous walk's exit is skipped (only possible for overlapping
//! meshes). Cells with a repeated vertex index are ignored; faces shared by
//! three or more cells are treated as boundary. The edge-sharing argument
//! holds where cells share vertex *indices*: across an unmerged seam (the
//! oxygen post's O-grid seam is two coincident boundaries) a ray hitting a
//! seam edge exactly is decided separately on each side.
//!
//! **Validation** (see `tests/reference_analytic.rs`): slabs seen along the
//! grid with rays exactly along edges, in faces and through vertices, oblique
//! and perspective views, linear ramps, non-convex and touching parts and a
//! flat cell all match closed forms to 1e-9; on the blunt fin and the oxygen
//! post, walking agrees with clipping each ray against every tet to ~3e-12.
//! A 512×512 image of the oxygen post (513,375 tets) takes about 1 s in
//! release on 2 cores.
//!
//! **Conventions.** Segments are clipped to the camera's depth range [near,
//! far] (view-space depth, as the GPU's clipper does). Compositing stops once
//! the optical depth exceeds 60 (what remains is < 1e-26). The library prints
//! nothing.

pub mod gauss_legendre;
pub mod integrate;
pub mod papers;
pub mod psi;
pub mod silhouette;
mod raycast;
pub mod volume;

use anyhow::{bail, ensure, Result};
use rayon::prelude::*;
use serde::Serialize;

use crate::mesh::TetMesh;
use crate::scene::{Camera, Projection, TransferFunction};

pub use integrate::{integrate_piece, integrate_segment, Segment};
pub use psi::{psi, psi_terms, PsiTerms};
pub use volume::render_volume_reference;

/// A reference image: premultiplied RGBA in f64, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f64; 4]>,
}

impl ReferenceImage {
    /// Pixel (x, y), row 0 at the top.
    pub fn get(&self, x: u32, y: u32) -> [f64; 4] {
        self.pixels[(y * self.width + x) as usize]
    }
}

/// What the traversal did; anomalies are expected to be 0 on valid meshes.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct ReferenceStats {
    /// Rays cast (one per pixel).
    pub rays: u64,
    /// Rays that entered the mesh at least once.
    pub rays_hit: u64,
    /// Walks started from boundary entries.
    pub walks: u64,
    /// Cells visited in total.
    pub steps: u64,
    /// Boundary faces of the mesh.
    pub boundary_faces: u64,
    /// Anomaly: exit faces chosen by the fallback rule (inconsistent signs
    /// from rounding, near-degenerate cells).
    pub fallback_exits: u64,
    /// Anomaly: walks stopped for lack of progress or by the step budget.
    pub aborted_walks: u64,
    /// Anomaly: boundary entries found before the previous walk's exit.
    pub skipped_entries: u64,
    /// Walks stopped on finding themselves going backwards (after entering
    /// through a flat boundary cell that was really an exit; harmless).
    pub reversed_walks: u64,
    /// Invalid input: faces shared by 3+ cells (treated as boundary).
    pub non_manifold_faces: u64,
    /// Cells ignored because a vertex index repeats.
    pub collapsed_tets: u64,
}

impl ReferenceStats {
    fn merge(mut self, o: ReferenceStats) -> ReferenceStats {
        self.rays += o.rays;
        self.rays_hit += o.rays_hit;
        self.walks += o.walks;
        self.steps += o.steps;
        self.fallback_exits += o.fallback_exits;
        self.aborted_walks += o.aborted_walks;
        self.skipped_entries += o.skipped_entries;
        self.reversed_walks += o.reversed_walks;
        self
    }
}

/// Render the f64 reference image of `mesh` seen by `camera` with `tf`.
pub fn render_reference(
    mesh: &TetMesh,
    camera: &Camera,
    tf: &TransferFunction,
    width: u32,
    height: u32,
) -> Result<ReferenceImage> {
    render_reference_with_stats(mesh, camera, tf, width, height).map(|(img, _)| img)
}

/// The f64 model of the papers' interpolation of exit data ([`papers`]):
/// the same walk and integration as the reference, each cell's segment
/// as those methods compute it (the one holding the eye by its near cap), with exit
/// distances clamped at `distance_clamp_diagonals` mesh diagonals as they
/// clamp them.
pub fn render_papers_model(
    mesh: &TetMesh,
    camera: &Camera,
    tf: &TransferFunction,
    width: u32,
    height: u32,
    distance_clamp_diagonals: f64,
) -> Result<ReferenceImage> {
    let f = camera.forward();
    let model = papers::PapersModel {
        view_dir: [f.x, f.y, f.z],
        perspective: camera.is_perspective(),
        max_distance: (distance_clamp_diagonals * mesh_diagonal(mesh)).max(1e-30),
        max_length: 1.01 * longest_edge(mesh),
        near: camera.near,
        cap_depth: camera.near_cap_depth(),
    };
    render(mesh, camera, tf, width, height, Some(model)).map(|(img, _)| img)
}

/// [`render_reference`], also returning what the traversal did.
pub fn render_reference_with_stats(
    mesh: &TetMesh,
    camera: &Camera,
    tf: &TransferFunction,
    width: u32,
    height: u32,
) -> Result<(ReferenceImage, ReferenceStats)> {
    render(mesh, camera, tf, width, height, None)
}

fn render(
    mesh: &TetMesh,
    camera: &Camera,
    tf: &TransferFunction,
    width: u32,
    height: u32,
    papers: Option<papers::PapersModel>,
) -> Result<(ReferenceImage, ReferenceStats)> {
    validate(mesh, camera, tf, width, height)?;
    let topo = crate::mesh::topology::Topology::build(mesh);
    let bins = raycast::Bins::build(mesh, &topo, camera, width, height);
    let diag = mesh_diagonal(mesh);
    let tracer = raycast::Tracer {
        mesh,
        topo: &topo,
        bins: &bins,
        tf,
        entry_tolerance: 1e-9 * diag,
        max_steps_per_ray: 4 * mesh.tets.len() as u64 + 1024,
        eye: camera.eye,
        papers,
    };
    // Rays of the camera moved to the origin: relative to the eye.
    let relative = camera.translated(camera.eye.map(|c| -c));
    let fwd = camera.forward();
    let (near, far) = (camera.near, camera.far);
    let mut pixels = vec![[0.0f64; 4]; width as usize * height as usize];
    let stats = pixels
        .par_chunks_mut(width as usize)
        .enumerate()
        .map(|(y, row)| {
            let mut stats = ReferenceStats::default();
            let mut entries = Vec::new();
            for (x, px) in row.iter_mut().enumerate() {
                let (o, d) = relative.ray(x as f64, y as f64, width, height);
                // View depth = t·(d·fwd) (perspective); = t (orthographic).
                let cos = match camera.projection {
                    Projection::Perspective { .. } => d.dot(fwd),
                    Projection::Orthographic { .. } => 1.0,
                };
                let (t_min, t_max) = (near / cos, far / cos);
                *px = tracer.trace(
                    x as u32,
                    y as u32,
                    o.into(),
                    d.into(),
                    t_min,
                    t_max,
                    &mut entries,
                    &mut stats,
                );
            }
            stats
        })
        .reduce(ReferenceStats::default, ReferenceStats::merge);
    let stats = ReferenceStats {
        boundary_faces: topo.boundary.len() as u64,
        non_manifold_faces: topo.non_manifold_faces as u64,
        collapsed_tets: topo.collapsed_tets as u64,
        ..stats
    };
    Ok((
        ReferenceImage {
            width,
            height,
            pixels,
        },
        stats,
    ))
}

fn validate(
    mesh: &TetMesh,
    camera: &Camera,
    tf: &TransferFunction,
    width: u32,
    height: u32,
) -> Result<()> {
    ensure!(
        width > 0 && height > 0,
        "reference: empty image {width}x{height}"
    );
    ensure!(
        mesh.scalars.len() == mesh.points.len(),
        "reference: mesh '{}' has {} points but {} scalars",
        mesh.name,
        mesh.points.len(),
        mesh.scalars.len()
    );
    ensure!(
        (mesh.tets.len() as u64) * 4 < u32::MAX as u64,
        "reference: mesh '{}' has too many cells ({})",
        mesh.name,
        mesh.tets.len()
    );
    let n = mesh.points.len() as u32;
    if let Some((i, t)) = mesh
        .tets
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&v| v >= n))
    {
        bail!(
            "reference: mesh '{}' cell {i} {t:?} indexes past its {n} points",
            mesh.name
        );
    }
    ensure!(
        tf.points.windows(2).all(|w| w[0].scalar <= w[1].scalar),
        "reference: transfer function '{}' control points are not sorted by scalar",
        tf.name
    );
    ensure!(
        tf.points.iter().all(|p| p.scalar.is_finite()
            && p.attenuation.is_finite()
            && p.color.iter().all(|c| c.is_finite())),
        "reference: transfer function '{}' has a non-finite control point",
        tf.name
    );
    let fwd = camera.forward();
    ensure!(
        fwd.is_finite() && fwd.cross(glam::DVec3::from(camera.up)).length() > 0.0,
        "reference: degenerate camera (eye = target, or up parallel to the view direction)"
    );
    ensure!(
        camera.near < camera.far,
        "reference: camera near {} >= far {}",
        camera.near,
        camera.far
    );
    Ok(())
}

/// The longest edge of any cell (no segment through a cell is longer).
fn longest_edge(mesh: &TetMesh) -> f64 {
    let mut m = 0f64;
    for t in &mesh.tets {
        let p = t.map(|i| mesh.points[i as usize]);
        for a in 0..4 {
            for b in a + 1..4 {
                let d = crate::mesh::geometry::sub(p[a], p[b]);
                m = m.max(crate::mesh::geometry::dot(d, d));
            }
        }
    }
    m.sqrt()
}

fn mesh_diagonal(mesh: &TetMesh) -> f64 {
    let d = mesh.bounds().diagonal();
    if d.is_finite() {
        d
    } else {
        0.0
    }
}
