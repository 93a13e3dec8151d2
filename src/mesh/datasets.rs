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
use super::cell_data::ScalarChoice;
use super::vtk::{read_vtk_legacy, read_vtk_legacy_with};
use super::vtu::read_vtu_with;
use super::TetMesh;
use anyhow::{bail, Result};
use std::path::{Path, PathBuf};

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

/// Extensions [`load_path`] reads as one file of a PLOT3D grid + solution pair.
pub const PLOT3D_EXTENSIONS: [&str; 4] = ["bin", "xyz", "x", "q"];

/// Extensions [`load_path`] reads as VTK unstructured grids.
pub const VTK_EXTENSIONS: [&str; 3] = ["vtk", "vtu", "pvtu"];

/// The mesh formats [`load_path`] reads, for messages.
pub const SUPPORTED_FORMATS: &str = ".vtk (VTK legacy UNSTRUCTURED_GRID), .vtu and .pvtu (VTK XML unstructured grids), \
     each with linear, quadratic, Lagrange and polyhedral cells (docs/formats.md), and PLOT3D grid/solution pairs (NAMExyz.bin + \
     NAMEq.bin, or NAME.xyz / NAME.x + NAME.q: give either file)";

/// A mesh file chosen by its extension:
/// - `.vtk`: VTK legacy UNSTRUCTURED_GRID, ASCII or BINARY;
/// - `.vtu` / `.pvtu`: VTK XML unstructured grid, or a parallel one's pieces
///   (see `vtu`); in all three every volumetric cell type is split into
///   tets conformingly (`tetrahedralize`);
/// - a PLOT3D grid or solution file (`.bin`, `.xyz`, `.x`, `.q`): the other
///   file of the pair is found next to it by name (see [`plot3d_pair`]); the
///   hexahedra are split into 5 tets each and the scalar is the density, or the
///   velocity magnitude when the density is constant over the grid (as in the
///   oxygen post), so that the mesh shows something.
pub fn load_path(path: impl AsRef<Path>) -> Result<TetMesh> {
    load_path_array(path, None)
}

/// [`load_path`] with the array `array` (a VTK file's point or cell array
/// by name; vectors by magnitude) as the scalar. PLOT3D pairs have no named
/// arrays.
pub fn load_path_array(path: impl AsRef<Path>, array: Option<&str>) -> Result<TetMesh> {
    load_path_with(path, ScalarChoice { array, ..Default::default() })
}

/// [`load_path`] with the scalar chosen, and cell data treated, as `choice`
/// says (`cell_data`).
pub fn load_path_with(path: impl AsRef<Path>, choice: ScalarChoice) -> Result<TetMesh> {
    let path = path.as_ref();
    let array = choice.array;
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("vtk") => read_vtk_legacy_with(path, choice),
        Some("vtu" | "pvtu") => read_vtu_with(path, choice),
        Some(e) if PLOT3D_EXTENSIONS.contains(&e) => match array {
            None => load_plot3d_path(path),
            Some(a) => bail!(
                "{}: a PLOT3D pair has no named arrays (asked for '{a}'); its scalar is the density, or the \
                 velocity magnitude when the density is constant",
                path.display()
            ),
        },
        _ => bail!(
            "{}: unsupported mesh format (extension {}); supported: {SUPPORTED_FORMATS}; built-in meshes: {}",
            path.display(),
            ext.map_or("none".to_string(), |e| format!(".{e}")),
            BUILTIN.join(", ")
        ),
    }
}

/// The `(grid, solution)` pair a single PLOT3D file belongs to, by name:
/// `NAMExyz.bin` <-> `NAMEq.bin` (the NASA files' convention, e.g.
/// `bluntfinxyz.bin` / `bluntfinq.bin`), `NAME.xyz` or `NAME.x` <-> `NAME.q`.
/// Errors (naming the file and what was looked for) when the name follows
/// neither convention or the other file does not exist.
pub fn plot3d_pair(path: &Path) -> Result<(PathBuf, PathBuf)> {
    let file = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    let lower = file.to_ascii_lowercase();
    let with_name = |name: String| path.with_file_name(name);
    // (grid candidates, solution candidates), the given file among them.
    let (grids, sols): (Vec<PathBuf>, Vec<PathBuf>) = if let Some(stem) = lower.strip_suffix(".bin") {
        let stem_orig = &file[..stem.len()];
        if let Some(i) = stem.rfind("xyz") {
            let q = format!("{}q{}.bin", &stem_orig[..i], &stem_orig[i + 3..]);
            (vec![path.to_path_buf()], vec![with_name(q)])
        } else if stem.ends_with('q') {
            let xyz = format!("{}xyz.bin", &stem_orig[..stem.len() - 1]);
            (vec![with_name(xyz)], vec![path.to_path_buf()])
        } else {
            bail!(
                "{}: a .bin mesh is read as a PLOT3D grid/solution pair named NAMExyz.bin and \
                 NAMEq.bin (e.g. bluntfinxyz.bin, bluntfinq.bin), and this name has neither \
                 'xyz' nor a final 'q'",
                path.display()
            );
        }
    } else if lower.ends_with(".q") {
        let stem = &file[..file.len() - 2];
        (vec![with_name(format!("{stem}.xyz")), with_name(format!("{stem}.x"))], vec![path.to_path_buf()])
    } else if lower.ends_with(".xyz") || lower.ends_with(".x") {
        let stem = &file[..file.rfind('.').unwrap_or(file.len())];
        (vec![path.to_path_buf()], vec![with_name(format!("{stem}.q"))])
    } else {
        bail!("{}: not a PLOT3D file name (.bin, .xyz, .x or .q)", path.display());
    };
    let pick = |c: &[PathBuf], what: &str| -> Result<PathBuf> {
        // The file given is read as is (a missing one fails there, with the OS error).
        match c.iter().find(|p| p.as_path() == path || p.is_file()) {
            Some(p) => Ok(p.clone()),
            None => bail!(
                "{}: PLOT3D {what} file not found: looked for {}",
                path.display(),
                c.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(" and ")
            ),
        }
    };
    Ok((pick(&grids, "grid")?, pick(&sols, "solution")?))
}

/// Loads the PLOT3D pair `path` belongs to (see [`load_path`], [`plot3d_pair`]);
/// the mesh is named after the grid file's stem.
pub fn load_plot3d_path(path: &Path) -> Result<TetMesh> {
    let (xyz, q) = plot3d_pair(path)?;
    let grid = read_xyz(&xyz)?;
    let sol = read_q(&q)?;
    sol.check_matches(&grid, &q, &xyz)?;
    let blanked_cells = grid.blanked_cells();
    let rho = sol.density();
    let constant = rho.iter().all(|&r| r == rho[0]);
    let scalars = if constant { sol.velocity_magnitude() } else { rho.to_vec() };
    let source = format!("{} + {}", xyz.display(), q.display());
    let mut mesh = hex_grid_to_tets(&source, grid.dims, grid.points, scalars)?;
    mesh.name = xyz.file_stem().map_or_else(|| "plot3d".into(), |s| s.to_string_lossy().into_owned());
    mesh.stats.blanked_cells = blanked_cells;
    Ok(mesh)
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
        let e = load_path("/x/mesh.bin").unwrap_err().to_string();
        assert!(e.contains("/x/mesh.bin") && e.contains("NAMExyz.bin"), "{e}");
        let e = load_path("/x/gridxyz.bin").unwrap_err().to_string();
        assert!(e.contains("/x/gridq.bin") && e.contains("not found"), "{e}");
        let e = load_path("/x/grid.q").unwrap_err().to_string();
        assert!(e.contains("/x/grid.xyz") && e.contains("/x/grid.x"), "{e}");
        assert!(load_builtin("nope", Path::new("/")).unwrap_err().to_string().contains("bluntfin"));
    }

    #[test]
    fn plot3d_pairs_by_name() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        for f in ["finxyz.bin", "finq.bin", "g.xyz", "g.q", "h.x", "h.q"] {
            std::fs::write(d.join(f), b"").unwrap();
        }
        let pair = |f: &str| plot3d_pair(&d.join(f)).unwrap();
        assert_eq!(pair("finxyz.bin"), (d.join("finxyz.bin"), d.join("finq.bin")));
        assert_eq!(pair("finq.bin"), (d.join("finxyz.bin"), d.join("finq.bin")));
        assert_eq!(pair("g.xyz"), (d.join("g.xyz"), d.join("g.q")));
        assert_eq!(pair("g.q"), (d.join("g.xyz"), d.join("g.q")));
        assert_eq!(pair("h.q"), (d.join("h.x"), d.join("h.q")));
        // Empty files: the error names the grid file and the problem.
        let e = format!("{:#}", load_path(d.join("finq.bin")).unwrap_err());
        assert!(e.contains("finxyz.bin") && e.contains("truncated"), "{e}");
    }
}
