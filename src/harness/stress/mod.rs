//! `volbench stress`: adversarial meshes, volumes, views and transfer
//! functions, rendered with every registered method and each of its stress
//! option sets and compared with the f64 CPU reference (issues 4 and 9).
//! Every mesh and volume is built in code and small (a few hundred to a few
//! thousand tets or samples), so the whole sweep runs in minutes on lavapipe.
//!
//! Each case is a scene (mesh or volume, camera, transfer function) plus its
//! documented limitations ([`Allowance`]); a method renders the cases of its
//! data kind. A row (case x method with an option set) is held to the
//! method's accuracy bound (`Family::accuracy_bound`, measured by its
//! family on a benign "baseline" case, with margin) plus the allowances that
//! apply to it: nothing here names a method or its options. Its `status` is
//! `ok` when the image has no NaN or Inf pixel and its max |error| against
//! the reference is within the bound, `documented` for the same with an
//! allowance applied, `fail` otherwise. The max error of a mesh case leaves
//! out the pixels on the mesh's (or the volume's box's) silhouette up to the
//! rasterizer's rounding (`reference::silhouette`), counted in the row.
//! [`describe_cases`] lists every case and allowance.
//!
//! The cases are built by family, one module each: `cells` (the control
//! grid and badly shaped cells), `alignment` (rays along edges and in face
//! planes), `views` (the eye in the mesh, near and far planes through it),
//! `scale` (extreme coordinates and scalars), `optics` (transfer-function
//! steps, opaque media), `volumes` (the ray casters' cases) and
//! `refinement` (cases built to defeat adaptive refinement), from the
//! `blocks` they share; `run` renders them and compares.

use serde::Serialize;

use super::datasets::Dataset;
use crate::algo::method::{DataKind, Options};
use crate::algo::registry::MethodSpec;
use crate::mesh::TetMesh;
use crate::scene::{Camera, TransferFunction};
use crate::volume::Volume;

mod alignment;
mod blocks;
mod cells;
mod optics;
mod refinement;
mod run;
mod scale;
mod views;
mod volumes;

pub use run::{
    failures, non_finite_pixels, run_cases, run_cases_with_progress, run_stress, run_stress_with_progress, stress_table,
    StressConfig,
};

/// A documented limitation: rows it applies to may exceed the accuracy
/// bound by `extra` (why, and how `extra` was obtained, in `reason`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Allowance {
    /// The option values it applies to: every listed option must have one
    /// of its listed values (empty: every row of the case).
    pub when: &'static [(&'static str, &'static [&'static str])],
    pub extra: Extra,
    pub reason: String,
}

/// What an allowance adds to the bound.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Extra {
    /// A constant (how it was obtained: the allowance's reason).
    Fixed(f64),
    /// Derived per image from the case's data: the max |error| of the f64
    /// model of the papers' interpolation (`reference::render_papers_model`)
    /// against the reference, over the pixels the row is compared on. A
    /// method within its integrator's bound of the model is then within
    /// this plus that bound of the reference (triangle inequality), at any
    /// image size.
    PapersModel,
}

impl Extra {
    /// The amount, given the case's papers' model error at this size.
    pub fn amount(&self, papers_model_error: f64) -> f64 {
        match *self {
            Extra::Fixed(x) => x,
            Extra::PapersModel => papers_model_error,
        }
    }
}

impl Allowance {
    fn all(extra: f64, reason: impl Into<String>) -> Self {
        Allowance { when: &[], extra: Extra::Fixed(extra), reason: reason.into() }
    }

    /// The papers' interpolation of exit data under perspective (every
    /// perspective mesh case carries it): derived, see [`Extra::PapersModel`].
    fn papers_interpolation() -> Self {
        Allowance {
            when: &[("interpolation", &["paper"])],
            extra: Extra::PapersModel,
            reason: "the papers' interpolation of exit data is not exact under perspective (README: \"Perspective\"): \
                     each vertex's ray-plane distance is interpolated across the face, off by the ratio of the \
                     vertex's and the ray's directions to the plane. Derived per image: the max |error| of the f64 \
                     model of that interpolation (reference::papers) against the reference, over the compared \
                     pixels (docs/stress.md)"
                .into(),
        }
    }

    fn applies(&self, options: &Options) -> bool {
        self.when.iter().all(|(k, values)| options.text(k).is_ok_and(|v| values.contains(&v.as_str())))
    }

    /// Which rows it applies to, as text ("all rows" when any).
    fn which(&self) -> String {
        if self.when.is_empty() {
            return "all rows".into();
        }
        self.when.iter().map(|(k, v)| format!("{k}={}", v.join("|"))).collect::<Vec<_>>().join(", ")
    }
}

/// What a case renders: a tetrahedral mesh or a regular volume (each
/// rendered by the registered methods of its kind).
#[derive(Debug, Clone)]
pub enum CaseData {
    TetMesh(TetMesh),
    Volume(Volume),
}

impl CaseData {
    pub fn kind(&self) -> DataKind {
        match self {
            CaseData::TetMesh(_) => DataKind::TetMesh,
            CaseData::Volume(_) => DataKind::Volume,
        }
    }

    fn dataset(&self, case: &str) -> Dataset {
        let source = format!("stress case {case}");
        match self {
            CaseData::TetMesh(m) => Dataset::from_mesh(m.clone(), false, source),
            CaseData::Volume(v) => Dataset::from_volume(v.clone(), false, source),
        }
    }

    /// "2,560 tets" or "17x15x13 samples".
    pub fn size_text(&self) -> String {
        match self {
            CaseData::TetMesh(m) => format!("{} tets", m.tets.len()),
            CaseData::Volume(v) => {
                let d = v.dims();
                format!("{}x{}x{} samples", d[0], d[1], d[2])
            }
        }
    }
}

/// One adversarial scene.
#[derive(Debug, Clone)]
pub struct StressCase {
    pub name: String,
    pub description: String,
    pub data: CaseData,
    pub camera: Camera,
    pub tf: TransferFunction,
    /// Known limitations (none: held to the accuracy bound alone).
    pub allowances: Vec<Allowance>,
}

impl StressCase {
    /// The mesh of a mesh case.
    pub fn mesh(&self) -> Option<&TetMesh> {
        match &self.data {
            CaseData::TetMesh(m) => Some(m),
            CaseData::Volume(_) => None,
        }
    }
}

/// One (case, method with an option set) render against the reference: a
/// view of the run's result record, or of its failure (`error`).
#[derive(Debug, Clone, Serialize)]
pub struct StressRow {
    pub case: String,
    pub method: &'static str,
    /// The full option set (`key=value,...`).
    pub options: String,
    /// These three options where the method has them ("-" otherwise).
    pub integrator: String,
    pub interpolation: String,
    pub sort: String,
    /// Adaptive image-space refinement's tolerance (`adaptive=TOL`: "0" off;
    /// "-" for a method without the option): whether the row's image was
    /// refined or had a ray per pixel.
    pub adaptive: String,
    /// Why the run failed (status `fail`).
    pub error: Option<String>,
    pub nan_pixels: usize,
    pub inf_pixels: usize,
    /// Max |error| over the pixels not set aside as on the silhouette.
    pub max_abs_error: f64,
    /// Pixels within `SILHOUETTE_TOLERANCE_PX` of the mesh's silhouette,
    /// left out of `max_abs_error` (see `reference::silhouette`), and the
    /// max |error| over them (0 when none).
    pub silhouette_pixels: usize,
    pub silhouette_max_error: f64,
    /// Rows held against the papers' model (`Extra::PapersModel`): max
    /// |image − model| over the compared pixels, what the integrator's
    /// bound must cover for the derived bound to hold (None otherwise).
    pub papers_model_gap: Option<f64>,
    pub rmse: f64,
    pub status: &'static str,
    pub bound: f64,
}

/// What `volbench stress --json` writes.
#[derive(Debug, Clone, Serialize)]
pub struct StressReport {
    pub cases: Vec<StressRow>,
}

/// Every stress case, for images of `size` x `size` pixels (the axis-aligned
/// view places pixel centres on grid lines for that size).
pub fn stress_cases(size: u32) -> Vec<StressCase> {
    let mut cases = vec![
        cells::baseline(),
        cells::slivers(),
        cells::needles_and_caps(),
        cells::zero_volume(),
        alignment::axis_orthographic(size),
        alignment::slivers_edge_on(size),
        alignment::eye_on_face_plane(),
        views::camera_inside(),
        views::near_plane_cut(),
        views::far_plane_cut(),
        scale::far_from_origin(1e3),
        scale::far_from_origin(1e5),
        scale::far_from_origin(1e7),
        scale::scalar_range("scalars-1e-6", 1e-6, 0.0, "in [0, 1e-6]"),
        scale::scalar_range("scalars-1e6", 1e6, 0.0, "in [0, 1e6]"),
        scale::scalar_range("scalars-offset-1e6", 1.0, 1e6, "in 1e6 + [0, 1] (f32 spacing 0.0625 at 1e6)"),
        optics::tf_steps(),
        views::eye_on_vertex(),
        scale::mesh_scale(1e-12),
        scale::mesh_scale(1e12),
        // The ends of the supported extent (diagonal 1e-15 to 1e15, see
        // `mesh::geometry`): 1.7e-15 and 8.7e14.
        scale::mesh_scale(1e-15),
        scale::mesh_scale(5e14),
        scale::scalar_range("scalars-1e37", 1e37, 0.0, "in [0, 1e37]"),
        optics::opaque(1e6),
        optics::opaque(3e38),
        refinement::sliver(),
        refinement::shell_edge_on(),
    ];
    for c in cases.iter_mut().filter(|c| c.camera.is_perspective()) {
        c.allowances.push(Allowance::papers_interpolation());
    }
    cases.extend(volumes::volume_cases(size));
    cases.push(refinement::speck());
    cases.push(refinement::far_speck());
    cases
}

/// The distance clamp the papers' model uses, in mesh diagonals: the
/// cell-projection methods' default (`distance_clamp`), which no stress
/// option set changes.
pub const PAPERS_DISTANCE_CLAMP_DIAGONALS: f64 = 1e3;

/// Whether a row of `case` with `spec` is held against the papers' model
/// (then the case's model error at this size is needed for its bound).
pub fn uses_papers_model(case: &StressCase, spec: &MethodSpec) -> bool {
    case.allowances.iter().any(|a| a.extra == Extra::PapersModel && a.applies(&spec.options))
}

// ---------------------------------------------------------------------------
// Bounds

/// The bound a row is held to (the method's accuracy bound, see
/// `Family::accuracy_bound`, plus the allowances that apply), and whether
/// a documented limitation applies; `None` when the method renders this
/// option set's computation for the case's view under another set.
/// `papers_model_error`: the case's [`Extra::PapersModel`] at this size
/// (used only where that allowance applies).
pub fn bound(case: &StressCase, spec: &MethodSpec, papers_model_error: f64) -> Option<(f64, bool)> {
    let base = (spec.info.family.accuracy_bound)(&spec.options, case.camera.is_perspective())?;
    let applicable: Vec<&Allowance> = case.allowances.iter().filter(|a| a.applies(&spec.options)).collect();
    Some((base + applicable.iter().map(|a| a.extra.amount(papers_model_error)).sum::<f64>(), !applicable.is_empty()))
}


/// Every case with its description and documented allowances, as Markdown
/// (for `volbench stress` to print before its table, and for the README).
pub fn describe_cases(size: u32) -> String {
    let mut s = String::new();
    for c in stress_cases(size) {
        s.push_str(&format!("- **{}** ({}): {}.\n", c.name, c.data.size_text(), c.description));
        for a in &c.allowances {
            let amount = match a.extra {
                Extra::Fixed(x) => format!("+{x:.2e}"),
                Extra::PapersModel => "+(papers' model error)".into(),
            };
            s.push_str(&format!("  - allowance {amount} ({}): {}.\n", a.which(), a.reason));
        }
    }
    s
}
