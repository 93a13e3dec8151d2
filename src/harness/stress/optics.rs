//! Transfer functions that break the integrators' model: steps and spikes,
//! opaque media.

use super::blocks::{oblique_camera, unit_grid};
use super::{Allowance, CaseData, Extra, StressCase};
use crate::scene::{ControlPoint, TransferFunction};

/// Steps: coincident control points (a jump in colour and attenuation at one
/// scalar), twice, plus a narrow spike.
pub(super) fn tf_steps() -> StressCase {
    let mesh = unit_grid("tf-steps");
    let (lo, hi) = mesh.scalar_range();
    let at = |t: f64| lo + t * (hi - lo);
    let cp = |t: f64, color: [f64; 3], attenuation: f64| ControlPoint { scalar: at(t), color, attenuation };
    let tf = TransferFunction {
        name: "steps".into(),
        points: vec![
            cp(0.0, [0.1, 0.2, 0.8], 0.3),
            cp(0.35, [0.1, 0.2, 0.8], 0.3),
            cp(0.35, [1.0, 0.9, 0.2], 5.0),
            cp(0.6, [1.0, 0.9, 0.2], 5.0),
            cp(0.6, [0.2, 0.9, 0.3], 0.5),
            cp(0.8, [0.2, 0.9, 0.3], 0.5),
            cp(0.8, [1.0, 0.1, 0.1], 8.0),
            cp(0.82, [1.0, 0.1, 0.1], 8.0),
            cp(0.82, [0.2, 0.9, 0.3], 0.5),
            cp(1.0, [0.2, 0.9, 0.3], 0.5),
        ],
    };
    StressCase {
        name: "tf-steps".into(),
        description: "8^3 grid, transfer function with three steps (coincident control points) and a spike 0.02 \
                      of the range wide, attenuation 0.3 to 8"
            .into(),
        data: CaseData::TetMesh(mesh),
        camera: oblique_camera(),
        tf,
        allowances: vec![
            Allowance {
                when: &[("integrator", &["average", "ppi", "linear-exact"])],
                extra: Extra::Fixed(0.5),
                reason: "model error, not numerics: these integrators take colour and attenuation at a segment's \
                         two ends and linear in between, so a step inside a segment is smeared over it (the f64 \
                         reference splits segments at control points). Measured <= 0.39 at 128x128; the \
                         allowance is that rounded up, not derived (a ray may cross several steps)"
                    .into(),
            },
            Allowance {
                when: &[("integrator", &["preint"])],
                extra: Extra::Fixed(5e-2),
                reason: "pre-integration integrates steps, but its table samples the scalar range 128 times: a \
                         step moves by up to 1/127 of the range. Measured <= 2.2e-2 (exact interpolation) at \
                         128x128, allowance rounded up"
                    .into(),
            },
        ],
    }
}

/// Attenuation rising linearly from 0 to `tau` per unit length over the
/// scalar range (no control point inside it, so the linear integrators'
/// model holds): optical depths up to tau per unit, beyond f32's range in
/// tau * D when tau is near f32::MAX.
pub(super) fn opaque(tau: f64) -> StressCase {
    let name = format!("opaque-{tau:e}");
    let mesh = unit_grid(&name);
    let (lo, hi) = mesh.scalar_range();
    let tf = TransferFunction {
        name: name.clone(),
        points: vec![
            ControlPoint { scalar: lo, color: [0.1, 0.3, 1.0], attenuation: 0.0 },
            ControlPoint { scalar: hi, color: [1.0, 0.6, 0.1], attenuation: tau },
        ],
    };
    StressCase {
        name,
        description: format!(
            "8^3 grid, attenuation rising linearly from 0 to {tau:e} per unit length over the scalar range: \
             optical depths far beyond exp's range"
        ),
        data: CaseData::TetMesh(mesh),
        camera: oblique_camera(),
        tf,
        allowances: vec![
            Allowance {
                when: &[("integrator", &["preint"])],
                extra: Extra::Fixed(1.0),
                reason: "no useful bound: the pre-integration table (128 x 128 scalars x 32 lengths) cannot \
                         resolve such a medium: one scalar step is an attenuation step of tau/127 and the first \
                         length sample is already opaque, so short segments get alpha interpolated between 0 and 1 \
                         (measured 0.92). Only finiteness is asserted"
                    .into(),
            },
            Allowance {
                when: &[("integrator", &["average"])],
                extra: Extra::Fixed(0.1),
                reason: "model error: averaging the two ends' attenuation (0 at one end, huge at the other) \
                         misplaces where along the segment the medium turns opaque. Measured 3.7e-2 at 128x128, \
                         allowance rounded up"
                    .into(),
            },
        ],
    }
}
