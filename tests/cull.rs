//! Culling in every tetrahedral cell-projection method (`cell_projection::cull`)
//! on lavapipe with the validation layer on: the image with culling is the
//! image without (RMSE ≤ 1e-6) on a transfer function that makes most cells
//! transparent and on a zoomed camera that puts many cells off-screen; the
//! counts are deterministic (cells each rule skipped, cells drawn, the
//! rasterizer's primitives = 4 per drawn cell); an unchanged view re-uses
//! the previous frame (nothing uploaded). No timings.

mod common;
use common::context;


use volbench::algo::registry;
use volbench::harness::datasets::{self, Dataset};
use volbench::harness::run::{run as run_method, RasterizerReport, RunConfig, RunOutput};
use volbench::mesh::TetMesh;
use volbench::scene::{ControlPoint, TransferFunction};


fn run(dataset: &Dataset, tf: &TransferFunction, spec: &str, cfg: &RunConfig) -> RunOutput {
    let spec = registry::builtin().parse_spec(spec, &[]).expect("spec");
    let ctx = context();
    let out = run_method(&ctx, &spec, dataset, tf, cfg).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
    out
}

/// Opaque only in [0.45, 0.55] of the mesh's scalar range (zero
/// attenuation elsewhere): most cells are transparent.
fn band_tf(mesh: &TetMesh) -> TransferFunction {
    let (lo, hi) = mesh.scalar_range();
    let diag = mesh.bounds().diagonal();
    let p = |t: f64, tau: f64| ControlPoint { scalar: lo + t * (hi - lo), color: [1.0, 0.6, 0.2], attenuation: tau / diag };
    TransferFunction { name: "band".into(), points: vec![p(0.0, 0.0), p(0.45, 0.0), p(0.5, 30.0), p(0.55, 0.0), p(1.0, 0.0)] }
}

fn count(out: &RunOutput, name: &str) -> Vec<u64> {
    out.result.frame_counts.get(name).unwrap_or_else(|| panic!("frame_counts.{name}")).per_frame.clone()
}

/// `spec` with culling on and off: same image, and the counts add up.
/// Returns (transparent, frustum) cells skipped in the reference frame's
/// view (the first timed frame: the orbit's angle 0).
fn culled_equals_unculled(dataset: &Dataset, tf: &TransferFunction, spec: &str, cfg: &RunConfig) -> (u64, u64) {
    let sep = if spec.contains(':') { ',' } else { ':' };
    let on = run(dataset, tf, &format!("{spec}{sep}cull=on"), cfg);
    let off = run(dataset, tf, &format!("{spec}{sep}cull=off"), cfg);
    let e = on.image.compare(&off.image).unwrap();
    // Culling leaves out only cells that contribute exactly (0,0,0,0):
    // the images are bit-identical; 1e-6 allows for nothing but that.
    assert!(e.rmse <= 1e-6, "{spec}: RMSE {} between culled and unculled", e.rmse);
    assert!(on.image.covered_pixels() > 100, "{spec}: the view should show something");
    let n = on.result.work.counts["cells"];
    // Triangles come 4 per drawn cell, or per drawn piece (atfs).
    let drawn_of = |o: &RunOutput| o.result.work.counts.get("pieces_drawn").copied().unwrap_or(o.result.work.counts["cells_drawn"]);
    let (drawn, drawn_off) = (drawn_of(&on), drawn_of(&off));
    assert_eq!(off.result.work.counts["cells_drawn"], n, "{spec}: cull=off draws every cell");
    let (t, f) = (count(&on, "cull.transparent"), count(&on, "cull.frustum"));
    let d = count(&on, "cells_drawn");
    assert_eq!(d.len(), cfg.frames);
    for i in 0..cfg.frames {
        assert_eq!(t[i] + f[i] + d[i], n, "{spec}: frame {i}: every cell is drawn or skipped by one rule");
    }
    assert!(count(&off, "cull.transparent").iter().chain(&count(&off, "cull.frustum")).all(|&c| c == 0));
    // The rasterizer's counts (reference frame): 4 triangles per drawn
    // cell in, nothing clipped away by lavapipe's count, and the same
    // fragments where the skipped cells had none to give.
    let (Some(s_on), Some(s_off)) = (on.result.stats, off.result.stats) else { panic!("pipeline statistics on lavapipe") };
    assert_eq!(s_on.input_primitives, 4 * drawn, "{spec}");
    assert_eq!(s_off.input_primitives, 4 * drawn_off, "{spec}");
    assert!(s_on.fragment_invocations <= s_off.fragment_invocations, "{spec}");
    match on.result.rasterizer {
        RasterizerReport::Counts { primitives_in, fragment_invocations, .. } => {
            assert_eq!(primitives_in, 4 * drawn);
            assert_eq!(fragment_invocations, s_on.fragment_invocations);
        }
        RasterizerReport::Unavailable(_) => panic!("lavapipe has pipeline statistics"),
    }
    // Fewer bytes cross: only the drawn cells' records. Per drawn cell the
    // record is the method's (culled or not); per mesh cell it shrinks.
    let (u_on, u_off) = (&on.result.upload, &off.result.upload);
    assert!(u_on.cell_bytes_per_frame < u_off.cell_bytes_per_frame, "{spec}");
    // (atfs: its cells' piece counts differ, so the bytes per drawn cell do too.)
    if !on.result.work.counts.contains_key("pieces_drawn") {
        assert_eq!(u_on.bytes_per_cell, u_off.bytes_per_cell, "{spec}: the record per drawn cell");
    }
    assert_eq!(u_off.bytes_per_mesh_cell, u_off.bytes_per_cell, "{spec}");
    assert!(u_on.bytes_per_mesh_cell.unwrap() < u_on.bytes_per_cell.unwrap(), "{spec}");
    (t[0], f[0])
}

const METHODS: &[&str] = &["vicp", "balanced", "resident", "balanced:sort=mpvo", "atfs"];

#[test]
fn a_transparent_transfer_function_culls_most_cells_and_changes_no_pixel() {
    let dataset = datasets::load("post-small").unwrap();
    let datasets::DatasetData::TetMesh { mesh, .. } = &dataset.data else { unreachable!() };
    let tf = band_tf(mesh);
    let n = mesh.tets.len() as u64;
    let cfg = RunConfig { width: 96, height: 96, frames: 2, warmup: 0, ..RunConfig::default() };
    for spec in METHODS {
        let (transparent, _) = culled_equals_unculled(&dataset, &tf, spec, &cfg);
        assert!(transparent > n / 2, "{spec}: {transparent} of {n} cells transparent");
    }
}

#[test]
fn a_zoomed_camera_culls_off_screen_cells_and_changes_no_pixel() {
    let dataset = datasets::load("post-small").unwrap();
    let tf = dataset.default_transfer_function().unwrap();
    let n = dataset.summary().counts["cells"];
    let cfg = RunConfig { width: 96, height: 96, frames: 2, warmup: 0, zoom: 4.0, ..RunConfig::default() };
    for spec in METHODS {
        let (transparent, frustum) = culled_equals_unculled(&dataset, &tf, spec, &cfg);
        assert_eq!(transparent, 0, "{spec}: the preset is nowhere transparent");
        assert!(frustum > n / 4, "{spec}: {frustum} of {n} cells off-screen");
    }
}

/// A still camera: the first frame prepares and uploads, every later one
/// re-uses it (no sort, pack or upload: only the push constants cross),
/// and the image is the unculled one.
#[test]
fn a_still_camera_reuses_the_previous_frame() {
    let dataset = datasets::load("post-small").unwrap();
    let tf = dataset.default_transfer_function().unwrap();
    let cfg = RunConfig { width: 64, height: 64, frames: 3, warmup: 1, orbit_step: 0.0, ..RunConfig::default() };
    for spec in ["vicp", "balanced", "resident", "pt-compute"] {
        let on = run(&dataset, &tf, spec, &cfg);
        let off = run(&dataset, &tf, &format!("{spec}:cull=off"), &cfg);
        assert_eq!(count(&on, "cull.reused"), vec![1, 1, 1], "{spec}: the warm-up frame prepared, the timed ones re-use it");
        assert_eq!(count(&off, "cull.reused"), vec![0, 0, 0]);
        assert_eq!(on.result.upload.cell_bytes_per_frame, 0, "{spec}: nothing re-uploaded");
        assert_eq!(on.result.upload.bytes_per_frame, on.result.upload.constant_bytes_per_frame);
        assert!(off.result.upload.cell_bytes_per_frame > 0);
        let e = on.image.compare(&off.image).unwrap();
        assert!(e.rmse <= 1e-6, "{spec}: RMSE {}", e.rmse);
        // Re-used frames are drawn again: the device did the same work.
        assert_eq!(on.result.stats.unwrap().fragment_invocations, off.result.stats.unwrap().fragment_invocations);
    }
}

/// The suite's culling scenes on the oxygen post: every scene runs with
/// culling on and off, the report has the culling table with the
/// unchanged-image check, and the transparent preset culls most cells.
#[test]
fn the_suite_reports_the_culling_scenes_with_the_unchanged_image_check() {
    use volbench::harness::suite::{plan, run_suite, Scene, SuiteSettings};
    let registry = registry::builtin();
    let settings = SuiteSettings { width: 32, height: 32, frames: 2, warmup: 0, ..SuiteSettings::standard(true, vec!["oxygenpost".into()]) };
    let planned = plan(&registry, &settings).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let ctx = context();
    let summary = run_suite(&ctx, &registry, &planned, &settings, dir.path(), |_, _| {}).unwrap();
    assert!(summary.runs.iter().all(|r| r.status == "ok"), "{:?}", summary.runs.iter().map(|r| &r.message).collect::<Vec<_>>());
    let scenes: Vec<Scene> = summary.cull_checks.iter().map(|c| c.scene).collect();
    assert_eq!(scenes, [Scene::Transparent, Scene::Still], "--quick: no zoomed scene");
    for c in &summary.cull_checks {
        assert!(c.rmse <= 1e-6, "{:?}: RMSE {}", c.scene, c.rmse);
    }
    let row = |label: &str| summary.runs.iter().find(|r| r.label == label).and_then(|r| r.result.as_ref()).unwrap_or_else(|| panic!("{label}"));
    let t = row("vicp @transparent");
    let n = t.work.counts["cells"];
    assert!(t.frame_counts["cull.transparent"].per_frame.iter().all(|&c| c > n / 2), "most cells transparent");
    // No warm-up here: the first timed frame prepares, the second re-uses it.
    assert_eq!(row("vicp @still").frame_counts["cull.reused"].per_frame, vec![0, 1]);
    let report = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(report.contains("## Culling") && report.contains("| oxygenpost | still | vicp |"), "{report}");
    assert!(report.matches("| unchanged |").count() == 2, "{report}");
}
