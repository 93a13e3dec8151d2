//! Tetrahedral meshes: the cell data every cell-projection method and the CPU
//! reference read. Loading (PLOT3D, VTK legacy), validation and the per-tet
//! view-independent precomputation (gradient, face planes) live here; nothing in
//! this module knows about Vulkan.
//!
//! Conventions used everywhere in volbench:
//! - Every tet is stored with positive signed volume,
//!   `det[p1-p0, p2-p0, p3-p0] > 0` (inverted input cells are reoriented by
//!   swapping two vertices, and counted).
//! - Face `i` is the face opposite vertex `i`. Its plane `n_i·x + a_i = 0` has a
//!   unit normal `n_i` pointing *out* of the tet.
//! - Positions and scalars are kept in f64; GPU paths convert to f32 when packing.
//! - Every loaded mesh has passed [`TetMesh::validate`], which also enforces
//!   the supported coordinate and extent ranges (see `geometry`'s module
//!   docs, "Supported ranges").

pub mod adjacency;
pub mod cell_data;
pub mod cells;
pub mod datasets;
pub mod geometry;
pub mod higher_order;
pub mod plot3d;
pub mod polyhedron;
pub mod refine;
pub mod reorder;
pub mod repair;
pub mod split;
pub mod tet_builder;
pub mod tetrahedralize;
pub mod topology;
pub mod vtk;
pub mod vtu;

pub use geometry::{TetGeometry, TetPrecomputed};

/// Counts gathered while loading and validating a mesh; reported with results.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct MeshStats {
    /// Cells that arrived with negative volume and were reoriented.
    pub reoriented: usize,
    /// Cells whose volume is zero (or negligible relative to the mesh scale);
    /// they are kept (so per-cell byte counts stay exact) but contribute nothing.
    pub zero_volume: usize,
    /// PLOT3D grids with IBLANK: hexahedra with IBLANK = 0 at any corner.
    /// They are still split and kept (0 for other sources).
    pub blanked_cells: usize,
    /// 0-, 1- and 2-D cells (vertices, lines, triangles, quads ...) in an
    /// unstructured file: no volume, skipped (see `cells`).
    pub skipped_lower_dim: usize,
    /// Cells marked `DUPLICATECELL` in a `vtkGhostType` cell array (a
    /// neighbouring piece owns them): skipped, as VTK does.
    pub ghost_cells: usize,
    /// Cells skipped as VTK does not draw them: marked `HIDDENCELL` or
    /// `REFINEDCELL` (not `DUPLICATECELL`), or using a point marked
    /// `HIDDENPOINT` in a `vtkGhostType` point array.
    pub hidden_cells: usize,
    /// Points marked `DUPLICATEPOINT` or `HIDDENPOINT` in a `vtkGhostType`
    /// point array (kept; a `.pvtu`'s seam weld merges duplicates).
    pub ghost_points: usize,
    /// `.pvtu`: points repeated on the pieces' seams (equal coordinates)
    /// merged into one.
    pub seam_points_merged: usize,
    /// Of those, points whose copies carried different scalars (the first
    /// copy's value is kept, and a note printed).
    pub seam_scalar_mismatches: usize,
    /// Which array is the scalar, point or cell data, and how cell data is
    /// shown (`scalar_array`, `scalar_association`, `scalar_components`,
    /// `cell_data` in the JSON; see `cell_data`). `None` where the source
    /// has no named arrays (PLOT3D) or the mesh was made in memory.
    #[serde(flatten)]
    pub scalar: Option<cell_data::ScalarInfo>,
    /// A mesh whose cells carry constant values (`cell_data`): for each
    /// vertex, the vertex it copies (every tet has its own four), by which
    /// the walks' face adjacency matches faces. Empty otherwise.
    #[serde(skip)]
    pub vertex_origin: Vec<u32>,
    /// File cells split other than by the plain rule, per reason (`repair`).
    pub repairs: Repairs,
    /// Higher-order cells (quadratic, Lagrange) in an unstructured file, and
    /// how they were read (`higher_order`); 0 / `None` when there are none.
    pub higher_order_cells: usize,
    pub higher_order: Option<HigherOrder>,
    /// Polyhedron cells (and pentagonal / hexagonal prisms) split around
    /// face and cell centroids (`polyhedron`).
    pub polyhedra: usize,
    /// Points added by splitting (face, body and cell centroids, mid-face
    /// nodes of serendipity cells), each with its interpolated scalar.
    pub added_points: usize,
}

/// What was repaired while splitting a file's cells (counts of file cells;
/// see `repair`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Repairs {
    /// Cells given inside out (every sub-tet of negative volume): kept,
    /// their tets reoriented.
    pub reoriented_cells: usize,
    /// Non-convex or twisted cells whose first triangulation folded over,
    /// split by another one with the same face diagonals.
    pub resplit_cells: usize,
    /// Cells no triangulation on their own vertices unfolds, split around an
    /// added centroid point (face diagonals kept).
    pub centroid_split_cells: usize,
    /// Collapsed cells (repeated point ids): read as their degenerate form
    /// (a hexahedron with a collapsed edge or face as a wedge or pyramid...);
    /// those collapsed to no volume at all add no tets.
    pub degenerate_cells: usize,
}

/// How higher-order cells are read (`--higher-order`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum HigherOrder {
    /// Subdivided into linear tets through every node (default).
    #[default]
    Subdivide,
    /// Only the corner nodes, as the linear cell of the same shape.
    Corners,
}

impl HigherOrder {
    pub fn parse(s: &str) -> anyhow::Result<HigherOrder> {
        match s {
            "subdivide" => Ok(HigherOrder::Subdivide),
            "corners" => Ok(HigherOrder::Corners),
            _ => anyhow::bail!("--higher-order '{s}': expected 'subdivide' (every node kept) or 'corners' (corner nodes only)"),
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            HigherOrder::Subdivide => "subdivide",
            HigherOrder::Corners => "corners",
        }
    }
}

impl MeshStats {
    /// Adds the counts a reader gathers before the cells are split
    /// (ghosts and seams) to these.
    pub fn add_read_counts(&mut self, read: &MeshStats) {
        self.ghost_cells += read.ghost_cells;
        self.hidden_cells += read.hidden_cells;
        self.ghost_points += read.ghost_points;
        self.seam_points_merged += read.seam_points_merged;
        self.seam_scalar_mismatches += read.seam_scalar_mismatches;
    }
}

/// A tetrahedral mesh with one scalar per vertex.
#[derive(Debug, Clone)]
pub struct TetMesh {
    /// Short name (dataset name or file stem) used in results.
    pub name: String,
    pub points: Vec<[f64; 3]>,
    pub scalars: Vec<f64>,
    /// Vertex indices, positively oriented (see module docs).
    pub tets: Vec<[u32; 4]>,
    pub stats: MeshStats,
}

/// Axis-aligned bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl Bounds {
    pub fn center(&self) -> [f64; 3] {
        [
            0.5 * (self.min[0] + self.max[0]),
            0.5 * (self.min[1] + self.max[1]),
            0.5 * (self.min[2] + self.max[2]),
        ]
    }
    pub fn diagonal(&self) -> f64 {
        let d = [
            self.max[0] - self.min[0],
            self.max[1] - self.min[1],
            self.max[2] - self.min[2],
        ];
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    }
}

/// Mesh-size guard, to be called before any per-cell allocation on the
/// device: errors unless `cells * bytes_per_cell` bytes fit in `limit_bytes`
/// (e.g. the device's largest buffer or heap). The product is computed in
/// u128, so absurd counts give an error, never an overflow.
pub fn check_fits(cells: usize, bytes_per_cell: usize, limit_bytes: u64) -> anyhow::Result<()> {
    let need = cells as u128 * bytes_per_cell as u128;
    if need > limit_bytes as u128 {
        anyhow::bail!(
            "mesh too large for the device: {cells} cells x {bytes_per_cell} bytes per cell = {need} bytes \
             ({:.1} MiB), more than the limit of {limit_bytes} bytes ({:.1} MiB)",
            need as f64 / (1u64 << 20) as f64,
            limit_bytes as f64 / (1u64 << 20) as f64
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::check_fits;

    #[test]
    fn check_fits_limits_and_overflow() {
        check_fits(0, 528, 0).unwrap();
        check_fits(1000, 112, 112_000).unwrap();
        let e = check_fits(1001, 112, 112_000).unwrap_err().to_string();
        assert!(e.contains("1001 cells") && e.contains("112112 bytes") && e.contains("112000"), "{e}");
        assert!(check_fits(usize::MAX, usize::MAX, u64::MAX).is_err());
    }
}
