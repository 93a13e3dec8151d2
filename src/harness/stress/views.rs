//! The eye in or on the mesh and the near and far planes through it.

use super::blocks::{inside_camera, mesh_ramp_tf, oblique_camera, unit_grid};
use super::{Allowance, CaseData, Extra, StressCase};
use crate::scene::{Camera, Projection};

/// The eye inside the mesh, looking through it.
pub(super) fn camera_inside() -> StressCase {
    let mesh = unit_grid("camera-inside");
    let tf = mesh_ramp_tf(&mesh);
    let camera = inside_camera();
    StressCase {
        name: "camera-inside".into(),
        description: "eye inside the 8^3 grid, near plane 1e-3, 60 degree field of view".into(),
        // The papers' allowance (every perspective mesh case) models its near cap.
        allowances: Vec::new(),
        data: CaseData::TetMesh(mesh),
        camera,
        tf,
    }
}

/// The eye outside, the near plane cutting the mesh in the middle.
pub(super) fn near_plane_cut() -> StressCase {
    let mesh = unit_grid("near-cut");
    let tf = mesh_ramp_tf(&mesh);
    let mut camera = oblique_camera();
    let d = ((0..3).map(|k| (camera.eye[k] - camera.target[k]).powi(2)).sum::<f64>()).sqrt();
    camera.near = d - 0.2;
    StressCase {
        name: "near-cut".into(),
        description: "oblique view of the 8^3 grid with the near plane through its middle".into(),
        allowances: Vec::new(),
        data: CaseData::TetMesh(mesh),
        camera,
        tf,
    }
}

/// The far plane cutting the mesh in the middle.
pub(super) fn far_plane_cut() -> StressCase {
    let mesh = unit_grid("far-cut");
    let tf = mesh_ramp_tf(&mesh);
    let mut camera = oblique_camera();
    let d = ((0..3).map(|k| (camera.eye[k] - camera.target[k]).powi(2)).sum::<f64>()).sqrt();
    camera.far = d + 0.1;
    StressCase {
        name: "far-cut".into(),
        description: "oblique view of the 8^3 grid with the far plane through its middle".into(),
        allowances: Vec::new(),
        data: CaseData::TetMesh(mesh),
        camera,
        tf,
    }
}

/// The eye exactly on a mesh vertex inside the mesh: the ray direction
/// through that vertex, normalize(v - eye), is 0/0.
pub(super) fn eye_on_vertex() -> StressCase {
    let mesh = unit_grid("eye-on-vertex");
    let tf = mesh_ramp_tf(&mesh);
    let camera = Camera {
        eye: [0.5, 0.5, 0.375],
        target: [0.9, 0.75, 0.95],
        up: [0.0, 1.0, 0.0],
        projection: Projection::Perspective { fovy_deg: 60.0 },
        near: 1e-3,
        far: 3.0,
    };
    StressCase {
        name: "eye-on-vertex".into(),
        description: "eye exactly on a vertex inside the 8^3 grid (the ray direction through it is 0/0), near \
                      plane 1e-3"
            .into(),
        allowances: vec![Allowance {
            when: &[("interpolation", &["paper"])],
            extra: Extra::Fixed(0.15),
            reason: "the near caps of the cells around the eye on a vertex (near.rs), which the papers' model \
                     (reference::papers, the derived allowance) leaves exact. Not derived: the constant from before \
                     the clip fix (0.371 at 64x64, rounded up), kept; measured max |image - model| 2.5e-2 at \
                     128x128 (balanced, vicp); exact interpolation meets the bound"
                .into(),
        }],
        data: CaseData::TetMesh(mesh),
        camera,
        tf,
    }
}
