//! Rays aligned with the mesh: along edges, in face planes, through
//! vertices, slivers seen edge-on.

use super::blocks::{grid_aligned_orthographic, look, mesh_ramp_tf, unit_grid};
use super::cells::sliver_mesh;
use super::{CaseData, StressCase};
use crate::scene::Projection;

/// The unit grid seen orthographically straight down the z axis with pixel
/// centres on the grid lines: rays exactly along edges, exactly in faces
/// (n.d = 0 for every vertical face plane), through vertices.
pub(super) fn axis_orthographic(size: u32) -> StressCase {
    let mesh = unit_grid("axis-ortho");
    let camera = grid_aligned_orthographic(size, 2);
    StressCase {
        name: "axis-ortho".into(),
        description: "8^3 grid, orthographic view along -z with pixel centres exactly on grid lines: rays along \
                      edges, in face planes (n.d = 0) and through vertices"
            .into(),
        tf: mesh_ramp_tf(&mesh),
        data: CaseData::TetMesh(mesh),
        camera,
        allowances: Vec::new(),
    }
}

/// The sliver mesh seen orthographically along -x with pixel rows exactly in
/// the planes z = 1/4, 1/2, 3/4 where the thin layers start: rays inside the
/// slivers' faces, the layers seen exactly edge-on (and 1e-8 and 3.84e-10
/// thick layers have no thickness at all in f32).
pub(super) fn slivers_edge_on(size: u32) -> StressCase {
    let mesh = sliver_mesh();
    StressCase {
        name: "slivers-edge-on".into(),
        description: "the sliver mesh, orthographic view along -x, pixel rows exactly in the thin layers' planes: \
                      slivers seen edge-on, rays in their faces"
            .into(),
        tf: mesh_ramp_tf(&mesh),
        data: CaseData::TetMesh(mesh),
        camera: grid_aligned_orthographic(size, 0),
        allowances: Vec::new(),
    }
}

/// Perspective with the eye in two of the grid's face planes (y = 0.5 and
/// z = 0.5): the faces in those planes are seen exactly edge-on (e = 0 in the
/// exact interpolation's u = h/e, n.d = 0 in IntersectBackFace).
pub(super) fn eye_on_face_plane() -> StressCase {
    let mesh = unit_grid("eye-on-plane");
    let camera =
        look([2.25, 0.5, 0.5], [0.5, 0.4375, 0.5625], [0.0, 1.0, 0.0], Projection::Perspective { fovy_deg: 40.0 }, 0.9);
    StressCase {
        name: "eye-on-plane".into(),
        description: "8^3 grid in perspective with the eye exactly in the face planes y = 0.5 and z = 0.5 (rays \
                      in those faces, faces seen edge-on)"
            .into(),
        tf: mesh_ramp_tf(&mesh),
        data: CaseData::TetMesh(mesh),
        camera,
        allowances: Vec::new(),
    }
}
