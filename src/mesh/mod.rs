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

pub mod datasets;
pub mod geometry;
pub mod plot3d;
pub mod split;
pub mod vtk;

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
