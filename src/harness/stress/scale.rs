//! Extreme coordinates and scalars: meshes far from the origin, scaled to
//! 1e-15 and 5e14, scalar ranges from 1e-6 to 1e37.

use super::blocks::{mesh_ramp_tf, oblique_camera, ramp_tf, scaled_camera, unit_grid};
use super::{CaseData, StressCase};

/// The unit grid and its camera translated by `offset` (1, -0.75, 0.5).
pub(super) fn far_from_origin(offset: f64) -> StressCase {
    let by = [offset, -0.75 * offset, 0.5 * offset];
    let mut mesh = unit_grid(&format!("translate-{offset:e}"));
    for p in &mut mesh.points {
        for k in 0..3 {
            p[k] += by[k];
        }
    }
    // Same scalars, same transfer function as the untranslated grid.
    let tf = mesh_ramp_tf(&mesh);
    StressCase {
        name: format!("translate-{offset:e}"),
        description: format!(
            "the 8^3 unit grid and the oblique camera translated by ({offset:e}, {:e}, {:e}): in f32 the \
             coordinates keep {} of their 24 bits for the mesh's extent",
            by[1],
            by[2],
            (24.0 - offset.log2()).max(0.0).floor()
        ),
        data: CaseData::TetMesh(mesh),
        camera: oblique_camera().translated(by),
        tf,
        allowances: Vec::new(),
    }
}

/// The unit grid's scalars scaled by `scale` (and shifted by `shift`), the
/// transfer function scaled alike: the same image as the unscaled grid.
pub(super) fn scalar_range(name: &str, scale: f64, shift: f64, what: &str) -> StressCase {
    let mut mesh = unit_grid(name);
    for s in &mut mesh.scalars {
        *s = shift + scale * *s;
    }
    let tf = mesh_ramp_tf(&mesh);
    StressCase {
        name: name.into(),
        description: format!(
            "the 8^3 grid with scalars {what}, the transfer function scaled alike, oblique perspective"
        ),
        data: CaseData::TetMesh(mesh),
        camera: oblique_camera(),
        tf,
        allowances: Vec::new(),
    }
}

/// The unit grid scaled by `scale` (cells 1/8 * scale), the camera and the
/// attenuation scaled alike: the same image as the baseline.
pub(super) fn mesh_scale(scale: f64) -> StressCase {
    let name = format!("mesh-scale-{scale:e}");
    let mut mesh = unit_grid(&name);
    for p in &mut mesh.points {
        for c in p.iter_mut() {
            *c *= scale;
        }
    }
    let (lo, hi) = mesh.scalar_range();
    let mut tf = ramp_tf(&name, lo, hi);
    for p in &mut tf.points {
        p.attenuation /= scale;
    }
    let camera = scaled_camera(oblique_camera(), scale);
    StressCase {
        name,
        description: format!(
            "the 8^3 grid, its camera and attenuation scaled by {scale:e} (same image as the baseline)"
        ),
        data: CaseData::TetMesh(mesh),
        camera,
        tf,
        allowances: Vec::new(),
    }
}
