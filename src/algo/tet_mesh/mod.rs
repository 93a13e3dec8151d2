//! The kit every tetrahedral-mesh method shares (cell projection and its
//! compute variant pt-compute, tet-raycast): the frame set up from the camera
//! and the mesh (`frame`: `FrameSetup`, `MeshScale`, `render_origin`,
//! `scalar_map`, the exit data's `Interpolation` and `ExitTolerances`), the
//! help of the integration options they all take, and each integrator's
//! accuracy bound. The methods import it; it imports none of them.

mod frame;

pub use frame::{render_origin, scalar_map, ExitTolerances, FrameConstants, FrameSetup, Interpolation, MeshScale};

use crate::algo::integrate::Integrator;

/// Help of the integration options every tetrahedral method takes.
pub const INTEGRATOR_HELP: &str = "how the fragment stage integrates a cell's segment (see README: integrators)";
pub const TABLE_SIZE_HELP: &str = "side of the integrator's table; 0 = its default (ppi 512, preint 128 with 32 lengths)";

/// The bound of an integrator where interpolation is exact (see
/// `cell_projection::render::accuracy_bound`).
pub fn integrator_bound(integrator: Integrator) -> f64 {
    match integrator {
        Integrator::Average => 5e-3,
        Integrator::Preint => 2e-3,
        Integrator::Ppi | Integrator::LinearExact => 1e-3,
    }
}
