//! Building blocks every case family uses: the smooth field, grids of it,
//! the transfer functions and cameras.

use super::{Allowance, Extra};
use crate::mesh::split::hex_grid_to_tets;
use crate::mesh::TetMesh;
use crate::scene::{Camera, ControlPoint, Projection, TransferFunction};

/// The smooth field every grid case carries (range about [0, 1]); linear
/// inside each cell once sampled at the vertices, like any mesh field.
pub(super) fn field(p: [f64; 3]) -> f64 {
    0.55 * p[2] + 0.3 * p[0] + 0.15 * (0.5 + 0.5 * (3.0 * p[1] + 1.0).sin())
}

/// A structured grid over the given coordinate levels, split into 5 tets
/// per hex (conforming), scalars from `field`.
pub(super) fn grid_mesh(name: &str, xs: &[f64], ys: &[f64], zs: &[f64]) -> TetMesh {
    let mut points = Vec::with_capacity(xs.len() * ys.len() * zs.len());
    for &z in zs {
        for &y in ys {
            for &x in xs {
                points.push([x, y, z]);
            }
        }
    }
    let scalars = points.iter().map(|&p| field(p)).collect();
    hex_grid_to_tets(name, [xs.len(), ys.len(), zs.len()], points, scalars).expect("stress grid")
}

pub(super) fn levels(n: usize) -> Vec<f64> {
    (0..=n).map(|i| i as f64 / n as f64).collect()
}

/// The unit cube, 8 hexes a side: 2,560 tets.
pub(super) fn unit_grid(name: &str) -> TetMesh {
    let l = levels(8);
    grid_mesh(name, &l, &l, &l)
}

/// The transfer function of every case but the step case: one linear piece
/// over the mesh's scalar range (no control point inside it), so that the
/// integrators that assume colour and attenuation linear along a segment
/// are exact but for their own arithmetic and the stress shows alone.
/// Attenuation 0.5..4 per unit length (optical depth ~2 across the cube).
pub(super) fn ramp_tf(name: &str, lo: f64, hi: f64) -> TransferFunction {
    TransferFunction {
        name: name.into(),
        points: vec![
            ControlPoint { scalar: lo, color: [0.1, 0.3, 1.0], attenuation: 0.5 },
            ControlPoint { scalar: hi, color: [1.0, 0.6, 0.1], attenuation: 4.0 },
        ],
    }
}

pub(super) fn mesh_ramp_tf(mesh: &TetMesh) -> TransferFunction {
    let (lo, hi) = mesh.scalar_range();
    ramp_tf(&format!("{}-ramp", mesh.name), lo, hi)
}

/// A camera at `eye` looking at `target`, near/far bracketing the sphere of
/// radius `r` around `target` (as `Camera::orbit` does).
pub(super) fn look(eye: [f64; 3], target: [f64; 3], up: [f64; 3], projection: Projection, r: f64) -> Camera {
    let d = ((0..3).map(|k| (eye[k] - target[k]).powi(2)).sum::<f64>()).sqrt();
    Camera { eye, target, up, projection, near: (d - 1.01 * r).max(1e-3 * d), far: d + 1.01 * r }
}

/// The oblique perspective view of the unit cube used by most cases.
pub(super) fn oblique_camera() -> Camera {
    look([2.3, 1.7, 2.9], [0.5, 0.5, 0.5], [0.0, 1.0, 0.0], Projection::Perspective { fovy_deg: 30.0 }, 0.9)
}

/// The centroid order is not a visibility order for badly shaped cells:
/// colour (not alpha, which does not depend on order) is off where two
/// cells are drawn in the wrong order. MPVO rows are held to accuracy.
pub(super) fn centroid_order_allowance(measured: f64) -> Allowance {
    Allowance {
        when: &[("sort", &["centroid"])],
        extra: Extra::Fixed(1e-2),
        reason: format!(
            "the centroid sort is not a visibility order for these cells (colour only: alpha, which does not \
             depend on the order, stays within the accuracy bound; with --sort mpvo the error is within it). \
             Measured {measured:.1e} at 128x128, allowance rounded up"
        ),
    }
}

pub(super) fn validated(mut mesh: TetMesh) -> TetMesh {
    let name = mesh.name.clone();
    mesh.validate(&name).expect("stress mesh");
    mesh
}

/// An orthographic camera looking down -`axis` at the unit cube whose pixel
/// centres are multiples of a power-of-two pitch p = 1/(8k), so that every
/// k-th pixel centre lies on a grid line and every coordinate is exact in
/// binary (the mesh spans about 3/4 of the image).
pub(super) fn grid_aligned_orthographic(size: u32, axis: usize) -> Camera {
    let mut k = 1u32;
    while 2 * k * 8 <= (3 * size) / 4 {
        k *= 2;
    }
    let p = 1.0 / (8.0 * k as f64);
    let h = size as f64 * p;
    // Centres at left + (i + 1/2) p are multiples of p when the view centre is
    // 0.5 + p/2 (size even).
    let c = 0.5 + 0.5 * p;
    let mut eye = [c; 3];
    let mut target = [c; 3];
    eye[axis] = 3.0;
    target[axis] = 0.0;
    let up = if axis == 2 { [0.0, 1.0, 0.0] } else { [0.0, 0.0, 1.0] };
    Camera { eye, target, up, projection: Projection::Orthographic { height: h }, near: 1.0, far: 5.0 }
}

/// The eye inside the unit cube looking through it: 60 degrees, near plane 1e-3.
pub(super) fn inside_camera() -> Camera {
    Camera {
        eye: [0.53, 0.46, 0.41],
        target: [1.0, 0.7, 0.9],
        up: [0.0, 1.0, 0.0],
        projection: Projection::Perspective { fovy_deg: 60.0 },
        near: 1e-3,
        far: 3.0,
    }
}

/// `c` with every length scaled by `scale`.
pub(super) fn scaled_camera(mut c: Camera, scale: f64) -> Camera {
    for k in 0..3 {
        c.eye[k] *= scale;
        c.target[k] *= scale;
    }
    c.near *= scale;
    c.far *= scale;
    c
}
