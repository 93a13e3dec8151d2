//! Volume cases (regular grids: the ray casters).

use super::blocks::{field, grid_aligned_orthographic, inside_camera, oblique_camera, ramp_tf, scaled_camera};
use super::{Allowance, CaseData, StressCase};
use crate::scene::Camera;
use crate::volume::{Samples, Volume};

/// The stress field sampled on `dims` samples spanning the unit cube
/// (anisotropic spacing unless the dims are equal), times `world` (spacing
/// and origin scaled alike), scalars `shift + scale * field`, f32.
fn grid_volume(name: &str, dims: [usize; 3], world: f64, scale: f64, shift: f64) -> Volume {
    let rel = |n: usize, a: usize| if dims[a] > 1 { n as f64 / (dims[a] - 1) as f64 } else { 0.0 };
    let mut samples = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                samples.push((shift + scale * field([rel(i, 0), rel(j, 1), rel(k, 2)])) as f32);
            }
        }
    }
    let spacing = std::array::from_fn(|a| world / (dims[a] - 1).max(1) as f64);
    Volume::new("stress volume", name, dims, spacing, [0.0; 3], Samples::F32(samples)).expect("stress volume")
}

/// The control volume: 17x13x9 samples over the unit cube (spacing 1/16,
/// 1/12, 1/8: anisotropic).
const VOLUME_DIMS: [usize; 3] = [17, 13, 9];

fn volume_case(name: &str, description: &str, volume: Volume, camera: Camera) -> StressCase {
    let (lo, hi) = volume.range();
    let tf = ramp_tf(&format!("{name}-ramp"), lo, if hi > lo { hi } else { lo + 1.0 });
    StressCase { name: name.into(), description: description.into(), data: CaseData::Volume(volume), camera, tf, allowances: Vec::new() }
}

pub(super) fn volume_cases(size: u32) -> Vec<StressCase> {
    let v = |name: &str| grid_volume(name, VOLUME_DIMS, 1.0, 1.0, 0.0);
    let inside = inside_camera();
    let on_face = Camera { eye: [0.0, 0.45, 0.55], target: [1.0, 0.6, 0.4], ..inside };
    let huge = 1e6;
    let huge_camera = scaled_camera(oblique_camera(), huge);
    let mut huge_case = volume_case(
        "vol-huge-spacing",
        "the control volume with spacing 1e6 times larger (and camera and attenuation scaled alike: the same image)",
        grid_volume("vol-huge-spacing", VOLUME_DIMS, huge, 1.0, 0.0),
        huge_camera,
    );
    for p in &mut huge_case.tf.points {
        p.attenuation /= huge;
    }
    let mut thin = volume_case(
        "vol-thin",
        "17x17x2 samples over the unit square: one voxel (1/16) thick, attenuation x10, oblique perspective",
        grid_volume("vol-thin", [17, 17, 2], 1.0, 1.0, 0.0),
        oblique_camera(),
    );
    for p in &mut thin.tf.points {
        p.attenuation *= 10.0;
    }
    thin.allowances.push(Allowance::all(
        1e-2,
        "model error, not the thinness: attenuation x10 makes a half-voxel step's optical depth up to ~1, where \
         point samples at step middles (and segments taken linear between samples) are off by more than on the \
         control volume. Measured 5.2e-3 (point), 2.4e-3 (preint) at 64x64, allowance rounded up",
    ));
    vec![
        volume_case("vol-baseline", "control: 17x13x9 samples over the unit cube (anisotropic spacing), oblique perspective, linear transfer function", v("vol-baseline"), oblique_camera()),
        // No allowance: the pixels whose rays lie in the box's faces are
        // the box's silhouette, set aside and counted like a mesh's (the
        // rasterizer's top-left rule leaves the centres on the right and
        // bottom edges uncovered in raycast-fragment; docs/stress.md).
        volume_case(
            "vol-grazing",
            "the control volume, orthographic view along -x with pixel rows and columns exactly in the box's \
             faces (y, z = 0 and 1): rays grazing the box",
            v("vol-grazing"),
            grid_aligned_orthographic(size, 0),
        ),
        volume_case("vol-eye-on-face", "the eye exactly on the box's face x = 0, looking in (60 degrees, near plane 1e-3)", v("vol-eye-on-face"), on_face),
        volume_case("vol-camera-inside", "the eye inside the control volume, near plane 1e-3, 60 degree field of view", v("vol-camera-inside"), inside),
        thin,
        huge_case,
        volume_case(
            "vol-constant",
            "every sample 0.6 (no scalar range: the transfer function's table spans [0.6, 1.6])",
            grid_volume("vol-constant", VOLUME_DIMS, 1.0, 0.0, 0.6),
            oblique_camera(),
        ),
        volume_case(
            "vol-values-1e30",
            "the control volume's values times 1e30 (f32), the transfer function scaled alike",
            grid_volume("vol-values-1e30", VOLUME_DIMS, 1.0, 1e30, 0.0),
            oblique_camera(),
        ),
        volume_case(
            "vol-range-1e-6",
            "the control volume's values times 1e-6 (a tiny range), the transfer function scaled alike",
            grid_volume("vol-range-1e-6", VOLUME_DIMS, 1.0, 1e-6, 0.0),
            oblique_camera(),
        ),
        volume_case(
            "vol-offset-1e6",
            "values 1e6 + [0, 1] in f32 (spacing 0.0625 there: 16 levels), the transfer function over that range",
            grid_volume("vol-offset-1e6", VOLUME_DIMS, 1.0, 1.0, 1e6),
            oblique_camera(),
        ),
    ]
}
