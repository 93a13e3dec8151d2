//! VTK XML UnstructuredGrid reader: any bytes give a mesh or an error naming
//! the file, never a panic; a mesh that loads is validated (split cells
//! included), so its per-tet precomputation must be finite.
#![no_main]

use libfuzzer_sys::fuzz_target;
use volbench::mesh::{vtu::parse_vtu_bytes, TetGeometry};

fuzz_target!(|data: &[u8]| {
    match parse_vtu_bytes("fuzz.vtu", data, None) {
        Ok(mesh) => {
            assert!(!mesh.tets.is_empty() && mesh.points.len() == mesh.scalars.len());
            let g = TetGeometry::compute(&mesh);
            for c in &g.cells {
                assert!(c.gradient.iter().chain(c.planes.iter().flatten()).all(|v| v.is_finite()), "{c:?}");
                assert!(c.volume.is_finite() && c.volume >= 0.0);
            }
        }
        Err(e) => assert!(format!("{e:#}").starts_with("fuzz.vtu"), "{e:#}"),
    }
});
