//! The real meshes the benchmarks run on, loaded from the project's `data/`
//! folder (public NASA/VTK data; see the datasets README for provenance), plus a loader for user files.
//!
//! - `bluntfin`: NASA blunt fin PLOT3D grid (40×32×32), density, 5-tet split
//!   → 40,960 points / 187,395 tets (Moreland's thesis Table 6.1).
//! - `oxygenpost`: NASA liquid-oxygen post (38×76×38), velocity magnitude
//!   (|momentum|/density), 5-tet split → 109,744 points / 513,375 tets. Its
//!   grid file carries IBLANK; every hex is split regardless (the published
//!   tet count uses them all) and the number of cells touching a blanked
//!   (IBLANK = 0) point is recorded in `stats.blanked_cells`. For the shipped
//!   file that is 0: IBLANK is 1 everywhere except -1 (overset fringe, not
//!   blanked) on the 4,332 points of the O-grid seam rows j = 0, 74, 75.
//! - `post_small`: VTK's `post.vtk`, a 8,750-tet unstructured subset of the post.
//!
//! Nothing here prints; all counts are returned in the mesh.

use super::plot3d::{read_q, read_xyz};
use super::split::hex_grid_to_tets;
use super::vtk::read_vtk_legacy;
use super::TetMesh;
use anyhow::{bail, Result};
use std::path::Path;

/// Names accepted by [`load_builtin`].
pub const BUILTIN: [&str; 3] = ["bluntfin", "oxygenpost", "post_small"];

pub const BLUNTFIN_XYZ: &str = "plot3d/bluntfinxyz.bin";
pub const BLUNTFIN_Q: &str = "plot3d/bluntfinq.bin";
pub const POST_XYZ: &str = "plot3d/postxyz.bin";
pub const POST_Q: &str = "plot3d/postq.bin";
pub const POST_SMALL_VTK: &str = "unstructured/post_tets_vtkdata.vtk";

/// Which point field of a PLOT3D solution becomes the mesh scalar.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plot3dScalar {
    Density,
    VelocityMagnitude,
}

/// Loads a PLOT3D grid + solution pair and splits it into tets (5 per hex).
/// `stats.blanked_cells` counts hexes with IBLANK = 0 at a corner (they are
/// split and kept all the same).
pub fn load_plot3d(name: &str, xyz: &Path, q: &Path, scalar: Plot3dScalar) -> Result<TetMesh> {
    let grid = read_xyz(xyz)?;
    let sol = read_q(q)?;
    sol.check_matches(&grid, q, xyz)?;
    let blanked_cells = grid.blanked_cells();
    let scalars = match scalar {
        Plot3dScalar::Density => sol.density().to_vec(),
        Plot3dScalar::VelocityMagnitude => sol.velocity_magnitude(),
    };
    let source = format!("{} + {}", xyz.display(), q.display());
    let mut mesh = hex_grid_to_tets(&source, grid.dims, grid.points, scalars)?;
    mesh.name = name.to_string();
    mesh.stats.blanked_cells = blanked_cells;
    Ok(mesh)
}

/// Blunt fin, density scalar.
pub fn load_bluntfin(data_dir: &Path) -> Result<TetMesh> {
    load_plot3d(
        "bluntfin",
        &data_dir.join(BLUNTFIN_XYZ),
        &data_dir.join(BLUNTFIN_Q),
        Plot3dScalar::Density,
    )
}

/// Liquid-oxygen post, velocity-magnitude scalar (its density is constant 1).
pub fn load_oxygenpost(data_dir: &Path) -> Result<TetMesh> {
    load_plot3d(
        "oxygenpost",
        &data_dir.join(POST_XYZ),
        &data_dir.join(POST_Q),
        Plot3dScalar::VelocityMagnitude,
    )
}

/// VTK's small tetrahedral post (`post.vtk`), pressure scalar.
pub fn load_post_small(data_dir: &Path) -> Result<TetMesh> {
    let mut m = read_vtk_legacy(data_dir.join(POST_SMALL_VTK))?;
    m.name = "post_small".to_string();
    Ok(m)
}

/// One of [`BUILTIN`] by name.
pub fn load_builtin(name: &str, data_dir: &Path) -> Result<TetMesh> {
    match name {
        "bluntfin" => load_bluntfin(data_dir),
        "oxygenpost" => load_oxygenpost(data_dir),
        "post_small" => load_post_small(data_dir),
        _ => bail!("unknown built-in mesh '{name}'; known: {}", BUILTIN.join(", ")),
    }
}

/// A mesh file chosen by its extension. Supported: `.vtk` (VTK legacy
/// UNSTRUCTURED_GRID of tetrahedra with point scalars, ASCII or BINARY).
pub fn load_path(path: impl AsRef<Path>) -> Result<TetMesh> {
    let path = path.as_ref();
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("vtk") => read_vtk_legacy(path),
        _ => bail!(
            "{}: unsupported mesh format (extension {}); supported: .vtk (VTK legacy \
             UNSTRUCTURED_GRID of tetrahedra with point scalars, ASCII or BINARY). \
             PLOT3D grids need a grid and a solution file: use the built-in meshes ({}) \
             or datasets::load_plot3d",
            path.display(),
            ext.map_or("none".to_string(), |e| format!(".{e}")),
            BUILTIN.join(", ")
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unsupported_extension_lists_formats() {
        let e = load_path("/x/mesh.off").unwrap_err().to_string();
        assert!(e.contains("/x/mesh.off") && e.contains(".vtk") && e.contains(".off"), "{e}");
        let e = load_path("/x/noext").unwrap_err().to_string();
        assert!(e.contains("none"), "{e}");
        assert!(load_builtin("nope", Path::new("/")).unwrap_err().to_string().contains("bluntfin"));
    }
}
