//! PLOT3D grid reader: any bytes give a grid or an error naming the file,
//! never a panic. A grid that loads is also split into tets (x as the scalar)
//! and its per-tet precomputation must be finite.
#![no_main]

use libfuzzer_sys::fuzz_target;
use volbench::mesh::{plot3d::parse_xyz_bytes, split::hex_grid_to_tets, TetGeometry};

fuzz_target!(|data: &[u8]| {
    match parse_xyz_bytes("fuzz.xyz", data) {
        Ok(grid) => {
            assert_eq!(grid.points.len(), grid.dims.iter().product::<usize>());
            let _ = (grid.blanked_cells(), grid.blanked_points(), grid.fringe_points());
            let scalars = grid.points.iter().map(|p| p[0]).collect();
            match hex_grid_to_tets("fuzz.xyz", grid.dims, grid.points, scalars) {
                Ok(mesh) => {
                    for c in &TetGeometry::compute(&mesh).cells {
                        assert!(c.gradient.iter().chain(c.planes.iter().flatten()).all(|v| v.is_finite()), "{c:?}");
                    }
                }
                Err(e) => assert!(format!("{e:#}").starts_with("fuzz.xyz: "), "{e:#}"),
            }
        }
        Err(e) => assert!(format!("{e:#}").starts_with("fuzz.xyz: "), "{e:#}"),
    }
});
