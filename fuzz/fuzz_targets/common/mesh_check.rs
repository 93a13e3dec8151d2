//! What every mesh-reader target checks: a mesh that loads is non-empty,
//! has a scalar per point and finite per-tet precomputation; an error starts
//! with the file label.

use volbench::mesh::{TetGeometry, TetMesh};

pub fn check(label: &str, result: anyhow::Result<TetMesh>) {
    match result {
        Ok(mesh) => {
            assert!(!mesh.tets.is_empty() && mesh.points.len() == mesh.scalars.len());
            let g = TetGeometry::compute(&mesh);
            for c in &g.cells {
                assert!(c.gradient.iter().chain(c.planes.iter().flatten()).all(|v| v.is_finite()), "{c:?}");
                assert!(c.volume.is_finite() && c.volume >= 0.0);
            }
        }
        Err(e) => assert!(format!("{e:#}").starts_with(label), "{e:#}"),
    }
}
