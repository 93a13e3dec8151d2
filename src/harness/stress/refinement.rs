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

/// A rod 0.003 x 0.003 across (x and z in [0.5, 0.503]) of high scalars
/// along y through the unit cube of low ones, seen from the side: a bright
/// line a fifth of a pixel wide at 64x64 (under two pixels at 512x512, under
/// the test rays' 4-pixel spacing at every size up to it) through a faint
/// block, slanted (the image rolled) so that it crosses pixel-centre columns
/// at every size. Well-posed at every size: the eye is in none of the
/// mesh's face planes (rays cross every face at 20 degrees or more), and the
/// transfer function is one linear piece over the scalars, so every
/// integrator is exact but for its arithmetic and the reference and every
/// method see the same point-sampled line; what refinement loses is the
/// only error.
pub(super) fn sliver() -> StressCase {
    // 0.5 is a level of 8 already; the rod's other face and the 0.001-wide
    // cells either side of it, where the scalar falls to the cube's.
    let mut around = levels(8);
    around.extend([0.499, 0.503, 0.504]);
    around.sort_by(f64::total_cmp);
    around.dedup();
    let l = levels(8);
    let mut points = Vec::new();
    for &z in &around {
        for &y in &l {
            for &x in &around {
                points.push([x, y, z]);
            }
        }
    }
    let rod = |v: f64| (0.5..=0.503).contains(&v);
    let scalars = points.iter().map(|&p: &[f64; 3]| if rod(p[0]) && rod(p[2]) { 1.0 } else { SLIVER_FAINT * field(p) }).collect();
    let dims = [around.len(), l.len(), around.len()];
    let mesh = validated(hex_grid_to_tets("adaptive-sliver", dims, points, scalars).expect("stress grid"));
    let c = 0.5015;
    // From the side, 21 degrees off the z axis; the image rolled by 0.06 rad
    // so that the line is not a pixel column.
    let roll: f64 = 0.06;
    let camera = look([c + 0.9, 0.45, c + 2.3], [c, 0.5, c], [roll.sin(), roll.cos(), 0.0], Projection::Perspective { fovy_deg: 30.0 }, 0.9);
    StressCase {
        name: "adaptive-sliver".into(),
        description: "a rod 0.003 x 0.003 across of scalar 1 (bright, attenuation 30) along y through the unit cube \
                      of scalars 0..0.03 (faint), seen from the side: a slanted line 0.2 pixel wide at 64x64, \
                      1.5 at 512x512, between coarse rays; interior (no boundary silhouette, no change in boundary \
                      entries), so adaptive refinement does not catch it structurally: a row that loses it fails \
                      (docs/stress.md)"
            .into(),
        data: CaseData::TetMesh(mesh),
        camera,
        tf: TransferFunction {
            name: "sliver".into(),
            points: vec![
                ControlPoint { scalar: 0.0, color: [0.1, 0.3, 1.0], attenuation: 0.3 },
                ControlPoint { scalar: 1.0, color: [1.0, 0.8, 0.1], attenuation: 30.0 },
            ],
        },
        allowances: Vec::new(),
    }
}

/// The cube's scalars around the rod: `field` scaled so that the one
/// linear transfer-function piece keeps them faint (attenuation <= 1.2).
const SLIVER_FAINT: f64 = 0.03;

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
    speck_in(
        "adaptive-speck",
        15,
        [7, 6, 8],
        12.0,
        "15^3 samples of 0 (transparent) and one of 1 (attenuation 12): a single bright voxel in empty space",
        "Measured without adaptive refinement 7.7e-3 (64x64) and 2.3e-2 (128x128) with point samples, 1.6e-2 and \
         3.2e-2 pre-integrated",
    )
}

/// The same speck, denser, in a 65^3 volume, off-centre: about one pixel wide at
/// 64x64 (four at 256x256), under the 4-pixel spacing of the coarsest
/// test rays, far from the box's faces and alone: the volume key's case
/// (its dilated bricks are 17 bricks across; the speck's own brick, 2
/// voxels, falls between the test rays of the blocks around it).
pub(super) fn far_speck() -> StressCase {
    speck_in(
        "adaptive-speck-far",
        65,
        [41, 25, 37],
        400.0,
        "65^3 samples of 0 (transparent) and one of 1 (attenuation 400) off-centre: a single bright voxel about a pixel \
         wide at 64x64, under the coarse rays' spacing",
        "Measured without adaptive refinement 7.4e-3 (64x64) to 3.4e-2 (512x512) with point samples, 1.8e-2 to 4.1e-2 \
         pre-integrated",
    )
}

/// `measured`: the case's own error without refinement, the allowance's evidence.
fn speck_in(name: &str, n: usize, at: [usize; 3], attenuation: f64, description: &str, measured: &str) -> StressCase {
    let mut samples = vec![0.0f32; n * n * n];
    samples[at[0] + n * (at[1] + n * at[2])] = 1.0;
    let spacing = [1.0 / (n - 1) as f64; 3];
    let volume = Volume::new("stress volume", name, [n; 3], spacing, [0.0; 3], Samples::F32(samples)).expect("stress volume");
    let tf = TransferFunction {
        name: "speck".into(),
        points: vec![
            ControlPoint { scalar: 0.0, color: [0.1, 0.3, 1.0], attenuation: 0.0 },
            ControlPoint { scalar: 1.0, color: [1.0, 0.9, 0.3], attenuation },
        ],
    };
    StressCase {
        name: name.into(),
        description: description.into(),
        data: CaseData::Volume(volume),
        camera: oblique_camera(),
        tf,
        allowances: vec![Allowance::all(
            5e-2,
            format!(
                "model error, not the refinement: a one-voxel spike of attenuation {attenuation} under a trilinear \
                 field is a tent two voxels wide that half-voxel point samples (and segments taken linear between \
                 samples) resolve coarsely. {measured}; allowance rounded up"
            ),
        )],
    }
}
