//! Cases built to defeat adaptive image-space refinement (`adaptive=TOL`,
//! issue 37, `algo::adaptive`): features narrower than the coarse rays'
//! spacing, a shell seen edge-on, a single bright voxel (a transfer
//! function of narrow bands is tests/adaptive.rs's, held against the image
//! of every pixel cast: its integration error alone exceeds every
//! integrator's stress bound). Every method renders them (they are ordinary
//! scenes); the rows with `adaptive` set show whether the structural and
//! colour tests caught the feature (error as without it) or not (the row
//! fails its bound and is reported). Which is which: docs/stress.md.

use super::blocks::{field, grid_mesh, levels, look, oblique_camera, validated};
use super::{Allowance, CaseData, Extra, StressCase};
use crate::mesh::split::hex_grid_to_tets;
use crate::scene::{ControlPoint, Projection, TransferFunction};
use crate::volume::{Samples, Volume};

/// Faint blue at the low end, bright opaque orange at the top.
fn spike_tf(name: &str, lo: f64, hi: f64, top_attenuation: f64) -> TransferFunction {
    TransferFunction {
        name: name.into(),
        points: vec![
            ControlPoint { scalar: lo, color: [0.1, 0.3, 1.0], attenuation: 0.3 },
            ControlPoint { scalar: lo + 0.5 * (hi - lo), color: [0.1, 0.3, 1.0], attenuation: 0.3 },
            ControlPoint { scalar: hi, color: [1.0, 0.8, 0.1], attenuation: top_attenuation },
        ],
    }
}

/// A slab 0.003 thick of high scalars (x in [0.5, 0.503]) inside the unit
/// cube of low ones, seen edge-on from in its plane: a bright line about a
/// quarter of a pixel wide at 64x64 through a faint block, met only by the
/// rays of one column of pixels.
pub(super) fn sliver() -> StressCase {
    let mut xs = levels(8);
    xs.extend([0.499, 0.5, 0.503, 0.504]);
    xs.sort_by(f64::total_cmp);
    let l = levels(8);
    let mut points = Vec::new();
    for &z in &l {
        for &y in &l {
            for &x in &xs {
                points.push([x, y, z]);
            }
        }
    }
    let scalars = points.iter().map(|&p: &[f64; 3]| if (0.5..=0.503).contains(&p[0]) { 1.0 } else { 0.3 * field(p) }).collect();
    let mesh = validated(hex_grid_to_tets("adaptive-sliver", [xs.len(), l.len(), l.len()], points, scalars).expect("stress grid"));
    let c = 0.5015;
    let camera = look([c, 0.45, 3.0], [c, 0.5, 0.5], [0.0, 1.0, 0.0], Projection::Perspective { fovy_deg: 30.0 }, 0.9);
    StressCase {
        name: "adaptive-sliver".into(),
        description: "a slab 0.003 thick of scalar 1 (bright, attenuation 40) in the unit cube of scalars 0..0.3 \
                      (faint), seen edge-on from in its plane: a line under a pixel wide between coarse rays"
            .into(),
        data: CaseData::TetMesh(mesh),
        camera,
        tf: spike_tf("sliver", 0.0, 1.0, 40.0),
        allowances: Vec::new(),
    }
}

/// A plate 1 x 1 x 0.04 seen edge-on from in its mid-plane: its top and
/// bottom faces' rims are silhouettes, projected along the line it makes.
pub(super) fn shell_edge_on() -> StressCase {
    let l = levels(8);
    let mesh = validated(grid_mesh("adaptive-shell", &l, &l, &[0.0, 0.04]));
    let (lo, hi) = mesh.scalar_range();
    let camera = look([0.55, -2.0, 0.02], [0.5, 0.5, 0.02], [0.0, 0.0, 1.0], Projection::Perspective { fovy_deg: 30.0 }, 0.75);
    let mut tf = super::blocks::ramp_tf("adaptive-shell-ramp", lo, hi);
    for p in &mut tf.points {
        p.attenuation *= 8.0;
    }
    StressCase {
        name: "adaptive-shell".into(),
        description: "a plate 1 x 1 x 0.04 (320 tets) seen edge-on from its mid-plane, attenuation x8: a line \
                      about a pixel thick at 64x64 whose silhouette edges lie along it"
            .into(),
        data: CaseData::TetMesh(mesh),
        camera,
        tf,
        allowances: vec![Allowance {
            when: &[("integrator", &["average", "preint"])],
            extra: Extra::Fixed(1e-2),
            reason: "the integrators' model error, not the refinement: rays at a grazing angle through the plate \
                     cross long cells at attenuation x8, where the average and the pre-integration table's \
                     linear model are furthest off. Measured 7.5e-3 (average) and 3.3e-3 (preint) at 128x128 \
                     with every method, with or without adaptive refinement; allowance rounded up"
                .into(),
        }],
    }
}

/// A 15^3 volume of zeros (transparent) with one sample at 1 (bright,
/// dense): a speck a few pixels wide, alone in empty bricks.
pub(super) fn speck() -> StressCase {
    let n = 15usize;
    let mut samples = vec![0.0f32; n * n * n];
    samples[7 + n * (6 + n * 8)] = 1.0;
    let spacing = [1.0 / (n - 1) as f64; 3];
    let volume = Volume::new("stress volume", "adaptive-speck", [n; 3], spacing, [0.0; 3], Samples::F32(samples)).expect("stress volume");
    let tf = TransferFunction {
        name: "speck".into(),
        points: vec![
            ControlPoint { scalar: 0.0, color: [0.1, 0.3, 1.0], attenuation: 0.0 },
            ControlPoint { scalar: 1.0, color: [1.0, 0.9, 0.3], attenuation: 12.0 },
        ],
    };
    StressCase {
        name: "adaptive-speck".into(),
        description: "15^3 samples of 0 (transparent) and one of 1 (attenuation 12): a single bright voxel in empty \
                      space"
            .into(),
        data: CaseData::Volume(volume),
        camera: oblique_camera(),
        tf,
        allowances: vec![Allowance::all(
            5e-2,
            "model error, not the refinement: a one-voxel spike of attenuation 12 under a trilinear field is a tent \
             two voxels wide that half-voxel point samples (and segments taken linear between samples) resolve \
             coarsely. Measured without adaptive refinement 7.7e-3 (64x64) and 2.3e-2 (128x128) with point \
             samples, 1.6e-2 and 3.2e-2 pre-integrated; allowance rounded up",
        )],
    }
}
