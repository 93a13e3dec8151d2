//! The meshes volbench knows by name, where their files live, and the
//! transfer function each one is shown with.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};

use crate::mesh::{self, TetMesh};
use crate::scene::{ControlPoint, TransferFunction};

/// The named real meshes (files under `data/`, see data/README.md).
pub const NAMED_MESHES: [&str; 3] = ["bluntfin", "oxygenpost", "post-small"];

/// `data/` of this checkout, or `VOLBENCH_DATA` when set.
pub fn data_dir() -> PathBuf {
    match std::env::var_os("VOLBENCH_DATA") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("data"),
    }
}

/// Load a mesh by name (`bluntfin`, `oxygenpost`, `post-small`) or path.
pub fn load_mesh(spec: &str) -> Result<TetMesh> {
    let dir = data_dir();
    let mesh = match spec {
        "bluntfin" => mesh::datasets::load_bluntfin(&dir),
        "oxygenpost" => mesh::datasets::load_oxygenpost(&dir),
        "post-small" => mesh::datasets::load_post_small(&dir),
        path => {
            let p = Path::new(path);
            if !p.exists() {
                anyhow::bail!(
                    "mesh '{path}': no such file, and not one of the named meshes ({})",
                    NAMED_MESHES.join(", ")
                );
            }
            mesh::datasets::load_path(p)
        }
    };
    let mut mesh = mesh.with_context(|| format!("loading mesh '{spec}'"))?;
    if NAMED_MESHES.contains(&spec) {
        // Results name a shipped mesh the way the command line does.
        mesh.name = spec.to_string();
    }
    Ok(mesh)
}

/// The transfer function a mesh is shown with. Attenuation is given per mesh
/// diagonal, so a preset reads the same whatever the mesh's units.
pub fn default_transfer_function(mesh: &TetMesh) -> TransferFunction {
    let (lo, hi) = mesh.scalar_range();
    let diag = mesh.bounds().diagonal().max(f64::MIN_POSITIVE);
    // (relative scalar in [0,1], colour, optical depth across one diagonal)
    let stops: &[(f64, [f64; 3], f64)] = match mesh.name.as_str() {
        // Density: freestream (~1) almost clear; the bow shock and the
        // compression in front of the fin show as warm shells.
        "bluntfin" => &[
            (0.00, [0.10, 0.20, 0.90], 4.0),
            (0.12, [0.10, 0.50, 1.00], 1.0),
            (0.18, [0.20, 0.80, 0.60], 0.5),
            (0.30, [0.90, 0.90, 0.20], 8.0),
            (0.55, [1.00, 0.50, 0.10], 20.0),
            (1.00, [1.00, 0.10, 0.05], 40.0),
        ],
        // Velocity magnitude: the slow wake behind the post stands out blue,
        // the fast stream around it is faint.
        // Velocity magnitude (flow along +x, freestream ~1.1 = 0.8 of the
        // range): the no-slip walls (post and floor, ~0) stay clear, the slow
        // wake behind the post shows blue, the freestream is a faint haze and
        // the fast flow past the post's flanks (up to 1.39) glows orange.
        "oxygenpost" => &[
            (0.00, [0.10, 0.20, 0.60], 0.0),
            (0.04, [0.10, 0.30, 1.00], 0.0),
            (0.08, [0.10, 0.40, 1.00], 2.0),
            (0.30, [0.20, 0.90, 1.00], 8.0),
            (0.45, [0.30, 1.00, 0.60], 4.0),
            (0.55, [0.40, 0.80, 0.40], 0.2),
            (0.91, [0.90, 0.80, 0.30], 0.2),
            (0.95, [1.00, 0.50, 0.10], 6.0),
            (1.00, [1.00, 0.20, 0.05], 20.0),
        ],
        // Pressure on VTK's small tetrahedral post.
        "post-small" | "post_small" => &[
            (0.00, [0.10, 0.30, 1.00], 30.0),
            (0.25, [0.20, 0.70, 1.00], 12.0),
            (0.50, [0.30, 0.90, 0.40], 3.0),
            (0.75, [1.00, 0.80, 0.20], 1.5),
            (1.00, [1.00, 0.30, 0.10], 6.0),
        ],
        _ => &[
            (0.0, [0.2, 0.3, 1.0], 1.0),
            (0.5, [0.3, 1.0, 0.3], 4.0),
            (1.0, [1.0, 0.3, 0.1], 8.0),
        ],
    };
    TransferFunction {
        name: format!("{}-default", mesh.name),
        points: stops
            .iter()
            .map(|&(t, color, depth)| ControlPoint { scalar: lo + t * (hi - lo), color, attenuation: depth / diag })
            .collect(),
    }
}
