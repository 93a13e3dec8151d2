//! The stress cases of `volbench stress` (issue 4): the generators build what
//! they claim, and a reduced sweep at 64x64 (both methods, every integrator,
//! the exact and the papers' interpolation, both sorts on the cases where the
//! order matters) writes no NaN or Inf pixel and meets every case's
//! documented bound. The full sweep is `volbench stress` (or the ignored
//! `full_stress_table` below, STRESS_SIZE / STRESS_ONLY=case,case).

mod common;

use std::sync::{Arc, Mutex, OnceLock};

use volbench::algo::registry;
use volbench::harness::stress::{self, CaseData, Extra, StressCase, StressConfig, StressReport, StressRow};
use volbench::mesh::TetGeometry;
use volbench::vk::{Context, ContextDesc};

const SIZE: u32 = 64;
/// The second size CI runs: the cases whose max error depends on how finely
/// the pixels sample the image (bounds were once fitted at 64x64 and failed
/// at 128x128 and 256x256).
const SECOND_SIZE: u32 = 256;

/// One validated context for the whole binary; runs are serialised because
/// lavapipe already uses every core.
fn context() -> std::sync::MutexGuard<'static, Arc<Context>> {
    static CTX: OnceLock<Mutex<Arc<Context>>> = OnceLock::new();
    CTX.get_or_init(|| {
        let ctx = Context::new(&ContextDesc { device: None, validation: true })
            .expect("a Vulkan device (run scripts/setup.sh)");
        Mutex::new(ctx)
    })
    .lock()
    .unwrap_or_else(|p| p.into_inner())
}

fn cases() -> Vec<StressCase> {
    stress::stress_cases(SIZE)
}

fn case(name: &str) -> StressCase {
    cases().into_iter().find(|c| c.name == name).unwrap_or_else(|| panic!("no stress case '{name}'"))
}

fn run(cases: &[StressCase], cfg: &StressConfig) -> Vec<StressRow> {
    let ctx = context();
    let rows = stress::run_cases(&ctx, cases, cfg).expect("stress run");
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
    rows
}

/// Every row finite and within its bound; the table of the offenders otherwise.
fn assert_all_pass(rows: &[StressRow]) {
    assert!(!rows.is_empty());
    let bad: Vec<StressRow> =
        rows.iter().filter(|r| r.status == "fail" || r.nan_pixels + r.inf_pixels > 0).cloned().collect();
    assert!(bad.is_empty(), "{} of {} stress rows fail:\n{}", bad.len(), rows.len(), stress::stress_table(&bad));
}

/// Every combination of the given methods and option values.
fn config(methods: &[&str], integrators: &[&str], interpolations: &[&str], sorts: &[&str]) -> StressConfig {
    config_at(SIZE, methods, integrators, interpolations, sorts)
}

fn config_at(size: u32, methods: &[&str], integrators: &[&str], interpolations: &[&str], sorts: &[&str]) -> StressConfig {
    let r = registry::builtin();
    let mut specs = Vec::new();
    for m in methods {
        for i in integrators {
            for p in interpolations {
                for s in sorts {
                    specs.push(r.parse_spec(&format!("{m}:integrator={i},interpolation={p},sort={s}"), &[]).unwrap());
                }
            }
        }
    }
    StressConfig { size, specs, images: None }
}

const INTEGRATORS: [&str; 4] = ["average", "preint", "ppi", "linear-exact"];

// ---------------------------------------------------------------------------
// The generators (no GPU)

#[test]
fn every_case_is_small_and_valid() {
    let all = cases();
    assert!(all.len() >= 20);
    let mut names: Vec<&str> = all.iter().map(|c| c.name.as_str()).collect();
    names.sort();
    names.dedup();
    assert_eq!(names.len(), all.len(), "case names must be unique");
    for c in &all {
        match &c.data {
            CaseData::TetMesh(m) => assert!((300..=5000).contains(&m.tets.len()), "{}: {} tets", c.name, m.tets.len()),
            CaseData::Volume(v) => {
                let n: usize = v.dims().iter().product();
                // The far speck needs a volume many bricks across (its point is
                // a voxel alone far from the box's faces; docs/stress.md).
                let most = if c.name == "adaptive-speck-far" { 300_000 } else { 5000 };
                assert!((500..=most).contains(&n), "{}: {n} samples", c.name);
            }
        }
        assert!(c.tf.points.windows(2).all(|w| w[0].scalar <= w[1].scalar), "{}", c.name);
        assert!(c.camera.near > 0.0 && c.camera.near < c.camera.far, "{}", c.name);
        for a in &c.allowances {
            assert!(a.extra == Extra::PapersModel || a.extra.amount(0.0) > 0.0, "{}", c.name);
            assert!(!a.reason.is_empty(), "{}", c.name);
        }
    }
}

#[test]
fn slivers_reach_1e_12_of_the_bounding_box_and_stay_solid() {
    let c = case("slivers");
    let g = TetGeometry::compute(c.mesh().unwrap());
    let b = c.mesh().unwrap().bounds();
    let bbox: f64 = (0..3).map(|k| b.max[k] - b.min[k]).product();
    let min = g.cells.iter().map(|x| x.volume).fold(f64::INFINITY, f64::min);
    assert!(min / bbox < 1.1e-12 && min / bbox > 0.9e-12, "smallest volume {:e} of the box", min / bbox);
    assert_eq!(g.degenerate_count(), 0, "slivers are thin, not zero-volume");
    // In f32 the two thinnest layers have no thickness at all.
    let zs: Vec<f32> = c.mesh().unwrap().points.iter().map(|p| p[2] as f32).collect();
    assert!(zs.contains(&0.5) && c.mesh().unwrap().points.iter().any(|p| p[2] > 0.5 && (p[2] as f32) == 0.5));
}

#[test]
fn degenerate_cases_are_degenerate() {
    let z = case("zero-volume");
    assert!(z.mesh().unwrap().stats.zero_volume >= 64, "{}", z.mesh().unwrap().stats.zero_volume);
    assert_eq!(TetGeometry::compute(z.mesh().unwrap()).degenerate_count(), z.mesh().unwrap().stats.zero_volume);
    let n = case("needles-caps");
    let g = TetGeometry::compute(n.mesh().unwrap());
    let max = g.cells.iter().map(|x| x.volume).fold(0.0, f64::max);
    let min = g.cells.iter().map(|x| x.volume).fold(f64::INFINITY, f64::min);
    assert!(min < 1e-5 * max, "caps and needles down to 1e-6 of a cell: {min:e} vs {max:e}");

    // The eye in two face planes, on a vertex.
    let e = case("eye-on-plane");
    assert_eq!((e.camera.eye[1], e.camera.eye[2]), (0.5, 0.5));
    let v = case("eye-on-vertex");
    assert!(v.mesh().unwrap().points.contains(&v.camera.eye));

    // Pixel centres exactly on grid lines: the ray origins' coordinates are
    // multiples of 1/8 for some pixels, along the view axis for all.
    let a = case("axis-ortho");
    let mut on_lines = 0;
    for x in 0..SIZE {
        let (o, d) = a.camera.ray(x as f64, (SIZE / 2) as f64, SIZE, SIZE);
        assert_eq!((d.x, d.y, d.z), (0.0, 0.0, -1.0));
        if (o.x * 8.0).fract() == 0.0 && (0.0..=1.0).contains(&o.x) {
            on_lines += 1;
        }
    }
    assert_eq!(on_lines, 9, "a pixel centre on each of the 9 grid lines x = k/8");
}

#[test]
fn translated_cases_move_mesh_and_camera_together() {
    let base = case("baseline");
    for (name, offset) in [("translate-1e3", 1e3), ("translate-1e5", 1e5), ("translate-1e7", 1e7)] {
        let c = case(name);
        assert_eq!(c.mesh().unwrap().tets, base.mesh().unwrap().tets);
        let by = [offset, -0.75 * offset, 0.5 * offset];
        // Equal up to the f64 rounding of the translated coordinates.
        let tol = 4.0 * f64::EPSILON * offset;
        let moved = |a: [f64; 3], b: [f64; 3]| (0..3).all(|k| (a[k] - by[k] - b[k]).abs() <= tol);
        assert!(moved(c.camera.eye, base.camera.eye), "{name}");
        assert!(moved(c.camera.target, base.camera.target), "{name}");
        assert!(moved(c.mesh().unwrap().points[7], base.mesh().unwrap().points[7]), "{name}");
    }
}

#[test]
fn report_is_json_with_a_cases_array() {
    let row = StressRow {
        case: "baseline".into(),
        method: "vicp",
        options: "integrator=ppi,interpolation=exact,sort=centroid".into(),
        integrator: "ppi".into(),
        interpolation: "exact".into(),
        sort: "centroid".into(),
        adaptive: "-".into(),
        error: None,
        nan_pixels: 0,
        inf_pixels: 0,
        max_abs_error: 3e-5,
        silhouette_pixels: 2,
        silhouette_max_error: 0.5,
        papers_model_gap: Some(2e-4),
        rmse: 3e-7,
        status: "ok",
        bound: 1e-3,
    };
    let failed = StressRow { error: Some("boom".into()), status: "fail", max_abs_error: f64::NAN, rmse: f64::NAN, ..row.clone() };
    let v = serde_json::to_value(StressReport { cases: vec![row.clone(), failed] }).unwrap();
    common::assert_matches_schema("stress.schema.json", &v, "a stress report");
    let r = &v["cases"][0];
    for key in [
        "case",
        "method",
        "integrator",
        "interpolation",
        "sort",
        "adaptive",
        "nan_pixels",
        "inf_pixels",
        "max_abs_error",
        "silhouette_pixels",
        "silhouette_max_error",
        "rmse",
        "status",
        "bound",
    ] {
        assert!(!r[key].is_null(), "missing {key}");
    }
    let table = stress::stress_table(&[row]);
    assert!(stress::describe_cases(SIZE).contains("- **camera-inside**"));
    assert!(
        table.lines().nth(2).unwrap().starts_with("| baseline | vicp | ppi | exact | centroid | - | 0 | 0 | 3.00e-5 | 2 (5.00e-1) |"),
        "{table}"
    );
}

// ---------------------------------------------------------------------------
// On the device (64x64; ~25 s in the dev profile on 2 cores)

/// Every case with the balanced method, every integrator, exact
/// interpolation, centroid order: the widest sweep of the integrators'
/// arithmetic (the NaN of 0 * Inf in tau * D showed here).
#[test]
fn every_case_every_integrator_is_finite_and_within_bounds() {
    let rows = run(
        &cases(),
        &config(&["balanced"], &INTEGRATORS, &["exact"], &["centroid"]),
    );
    assert_all_pass(&rows);
}

/// VICP (its IntersectBackFace runs in the vertex stage) and the papers'
/// interpolation, with the default integrator.
#[test]
fn every_case_vicp_and_paper_interpolation() {
    let rows = run(
        &cases(),
        &config(&["vicp"], &["ppi"], &["paper", "exact"], &["centroid"]),
    );
    assert_all_pass(&rows);
    // Both methods compute the same thing: VICP's rows meet the same bounds,
    // and on the translated mesh the same error as on the original.
    let err = |name: &str| rows.iter().find(|r| r.case == name && r.interpolation == "exact").unwrap().max_abs_error;
    assert!((err("translate-1e7") - err("baseline")).abs() < 1e-5, "{} vs {}", err("translate-1e7"), err("baseline"));
}

/// MPVO's order where the centroid order is documented as wrong, and on
/// the meshes far from the origin.
#[test]
fn mpvo_order_meets_the_accuracy_bound_where_centroid_does_not() {
    let names = ["needles-caps", "zero-volume", "translate-1e7"];
    let selected: Vec<StressCase> = cases().into_iter().filter(|c| names.contains(&c.name.as_str())).collect();
    let rows = run(
        &selected,
        &config(&["balanced"], &["linear-exact"], &["exact"], &["mpvo"]),
    );
    assert_all_pass(&rows);
    for r in &rows {
        assert_eq!(r.status, "ok", "{}: no allowance applies to MPVO rows", r.case);
    }
}

/// The volume cases (rays grazing the box, the eye on a face and inside,
/// a one-voxel-thick volume, huge spacing, a constant volume, values near
/// 1e30, a 1e-6 range, 1e6 + [0, 1] in f32) with both ray casters and every
/// stress option set of theirs: finite, within the methods' bounds, and
/// documented only where the case says so.
#[test]
fn volume_cases_with_both_ray_casters() {
    // The adaptive-refinement cases and option sets: adaptive_refinement_cases.
    let selected: Vec<StressCase> =
        cases().into_iter().filter(|c| matches!(c.data, CaseData::Volume(_)) && !c.name.starts_with("adaptive-")).collect();
    let names: Vec<&str> = selected.iter().map(|c| c.name.as_str()).collect();
    for want in ["vol-grazing", "vol-eye-on-face", "vol-camera-inside", "vol-thin", "vol-huge-spacing", "vol-constant", "vol-values-1e30", "vol-range-1e-6", "vol-offset-1e6"] {
        assert!(names.contains(&want), "{want} missing: {names:?}");
    }
    let mut cfg = StressConfig::full(&registry::builtin(), SIZE).unwrap();
    cfg.specs.retain(|s| s.info.name.starts_with("raycast") && !s.label().contains("adaptive"));
    assert_eq!(cfg.specs.len(), 6, "two ray casters x three stress option sets");
    let rows = run(&selected, &cfg);
    assert_eq!(rows.len(), selected.len() * 6, "every volume case with every ray-cast spec, no mesh method");
    assert_all_pass(&rows);
    for r in &rows {
        let documented = r.case == "vol-thin";
        assert_eq!(r.status == "documented", documented, "{}: {} ({})", r.case, r.status, r.options);
        // Without an allowance the ray casters are held to 1e-3.
        if !documented {
            assert!(r.max_abs_error <= 1e-3, "{} {} {}: {}", r.case, r.method, r.options, r.max_abs_error);
        }
    }
    let v = serde_json::to_value(StressReport { cases: rows.clone() }).unwrap();
    common::assert_matches_schema("stress.schema.json", &v, "the volume stress rows");
    check_grazing(&rows, SIZE);
}

/// The cases built against adaptive refinement (issue 37) with both
/// adaptive ray casters and every stress option set of theirs, at 64x64 and
/// 256x256 (~8 s each): every row without refinement within its bound; the
/// single bright voxel caught, in a small volume and alone in a large one
/// where it is a pixel or so wide (its error with refinement that of the
/// same method without); the shell seen edge-on within its bound, and caught at
/// 64x64 where it is a band under a block tall (at 256x256 it is 9 pixels
/// tall and its inside is an ordinary smooth region); the rod between
/// coarse rays not caught and reported: its refined row fails, with an
/// error over 100 times that without refinement (docs/stress.md, "Adaptive
/// refinement").
#[test]
fn adaptive_refinement_cases_at_two_sizes() {
    for size in [SIZE, SECOND_SIZE] {
        let selected: Vec<StressCase> = stress::stress_cases(size).into_iter().filter(|c| c.name.starts_with("adaptive-")).collect();
        assert_eq!(selected.len(), 4);
        let mut cfg = StressConfig::full(&registry::builtin(), size).unwrap();
        cfg.specs.retain(|s| s.info.name == "tet-raycast" || s.info.name == "raycast-compute");
        let rows = run(&selected, &cfg);
        // Every row says whether it was refined.
        for r in &rows {
            assert_eq!(r.adaptive, if r.options.contains("adaptive=0.008") { "0.008" } else { "0" }, "{} {}", r.method, r.options);
        }
        let lost = |r: &&StressRow| r.case == "adaptive-sliver" && r.adaptive != "0";
        let rest: Vec<StressRow> = rows.iter().filter(|r| !lost(r)).cloned().collect();
        assert_all_pass(&rest);
        let row = |case: &str, adaptive: bool| -> &StressRow {
            rows.iter()
                .find(|r| r.case == case && (r.adaptive != "0") == adaptive && (r.options.contains("integrator=ppi") || r.options.contains("integrator=point")))
                .unwrap_or_else(|| panic!("{case}: no row with adaptive {adaptive}"))
        };
        for speck in ["adaptive-speck", "adaptive-speck-far"] {
            let (with, without) = (row(speck, true), row(speck, false));
            assert!((with.max_abs_error - without.max_abs_error).abs() <= 1e-4, "{size} {speck}: {} with, {} without", with.max_abs_error, without.max_abs_error);
        }
        let (with, without) = (row("adaptive-shell", true), row("adaptive-shell", false));
        if size == SIZE {
            assert!((with.max_abs_error - without.max_abs_error).abs() <= 1e-4, "{size} shell: {} with, {} without", with.max_abs_error, without.max_abs_error);
        }
        let (with, without) = (row("adaptive-sliver", true), row("adaptive-sliver", false));
        assert_eq!(with.status, "fail", "{size}: the rod is no longer lost ({:.2e}): docs/stress.md says it is", with.max_abs_error);
        assert!(with.error.is_none() && with.nan_pixels + with.inf_pixels == 0, "{size}: {with:?}");
        assert!(with.max_abs_error > with.bound && with.max_abs_error > 100.0 * without.max_abs_error, "{size}: {} with, {} without", with.max_abs_error, without.max_abs_error);
        assert!(without.max_abs_error <= 1e-4, "{size}: the rod without refinement {}", without.max_abs_error);
    }
}

/// vol-grazing at `size`: the rays in the box's faces are its silhouette
/// (the outline's pixel rows and columns: the box spans 8k pixels, k the
/// largest power of two with 16k <= 3/4 of the image, as the camera places
/// it; 8k + 1 centres a side, corners shared), set aside and counted;
/// raycast-compute clips analytically and integrates them, raycast-fragment
/// misses those on its right and bottom edges (top-left rule; 0.95 at
/// 64x64, then an allowance of 1.0 for the whole case), and every other
/// pixel is within the ray casters' 1e-3 with no allowance.
fn check_grazing(rows: &[StressRow], size: u32) {
    let mut k = 1;
    while 16 * k <= 3 * size as usize / 4 {
        k *= 2;
    }
    let grazing: Vec<&StressRow> = rows.iter().filter(|r| r.case == "vol-grazing").collect();
    assert_eq!(grazing.len(), 6);
    for r in grazing {
        assert_eq!((r.status, r.silhouette_pixels), ("ok", 4 * 8 * k), "{} {}", r.method, r.options);
        assert!(r.max_abs_error <= 1e-3, "{} {}: {}", r.method, r.options, r.max_abs_error);
        if r.method == "raycast-compute" {
            assert!(r.silhouette_max_error <= 1e-3, "{}", r.silhouette_max_error);
        }
    }
}

/// vol-grazing at the second size: the rule scales with the image (a row
/// and column of pixels, not a fitted count) and the rest stays within 1e-3.
#[test]
fn grazing_rays_hold_at_a_second_size() {
    let selected: Vec<StressCase> =
        stress::stress_cases(SECOND_SIZE).into_iter().filter(|c| c.name == "vol-grazing").collect();
    let mut cfg = StressConfig::full(&registry::builtin(), SECOND_SIZE).unwrap();
    cfg.specs.retain(|s| s.info.name.starts_with("raycast") && !s.label().contains("adaptive"));
    check_grazing(&run(&selected, &cfg), SECOND_SIZE);
}

/// Cells cut by the near plane (the eye inside the mesh, on a vertex, the
/// near plane through the mesh) and by the far plane, with every
/// tetrahedral method: faces are not clipped at the near plane and every
/// segment starts at the near plane and stops at the far plane, so the four
/// cases carry no allowance (eye-on-vertex and camera-inside: none but for
/// the papers' interpolation) and meet the methods' bounds like the others (before: the
/// cut cells' segments were lost or integrated past the far plane, errors up
/// to 1 - exp(-tau L); with near caps, single pixels along the near plane's
/// section still differed by up to 7.7e-3).
#[test]
fn near_and_far_plane_cases_meet_the_bounds_with_every_tet_method() {
    let names = ["camera-inside", "eye-on-vertex", "near-cut", "far-cut"];
    let selected: Vec<StressCase> = cases().into_iter().filter(|c| names.contains(&c.name.as_str())).collect();
    assert_eq!(selected.len(), names.len());
    // eye-on-vertex and camera-inside keep one for the papers' (inexact) perspective interpolation only.
    assert!(selected.iter().all(|c| c.allowances.iter().all(|a| a.when == [("interpolation", &["paper"][..])])));
    let rows = run(&selected, &config(&["vicp", "balanced", "resident", "atfs"], &["preint", "ppi"], &["exact"], &["mpvo"]));
    assert_all_pass(&rows);
    for r in &rows {
        assert_eq!(r.status, "ok", "{} {} {}: {}", r.case, r.method, r.options, r.max_abs_error);
    }
}

/// The size-sensitive cases at a second size, 256x256: the eye on a vertex
/// (faces through the eye were slivers covering single pixels, 5.4e-2 at
/// 128x128 before clip positions were taken relative to the eye), the
/// camera inside (the papers' interpolation, 0.262 at 256x256) and the
/// opaque medium (single silhouette pixels, 5.9e-3 at 256x256 before they
/// were left out as ambiguous: `reference::silhouette`). Exact
/// interpolation meets the accuracy bound alone on all three.
#[test]
fn size_sensitive_cases_hold_at_a_second_size() {
    let names = ["eye-on-vertex", "camera-inside", "opaque-1e6"];
    let selected: Vec<StressCase> =
        stress::stress_cases(SECOND_SIZE).into_iter().filter(|c| names.contains(&c.name.as_str())).collect();
    assert_eq!(selected.len(), names.len());
    let rows = run(&selected, &config_at(SECOND_SIZE, &["balanced", "vicp"], &["ppi"], &["exact", "paper"], &["mpvo"]));
    assert_eq!(rows.len(), 12);
    assert_all_pass(&rows);
    for r in rows.iter().filter(|r| r.interpolation == "exact") {
        assert_eq!(r.status, "ok", "{} {} {}: {}", r.case, r.method, r.options, r.max_abs_error);
    }
    // Pixels set aside on the silhouette: a handful, not a band.
    for r in rows.iter().filter(|r| r.case == "opaque-1e6") {
        assert!((1..=16).contains(&r.silhouette_pixels), "{} {}: {}", r.method, r.options, r.silhouette_pixels);
    }
}

/// pt-compute with the eye in two of the grid's face planes (`eye-on-plane`)
/// at two sizes: the faces in those planes project to lines, and snapping
/// can leave such a face a sliver of positive area, through which the cell
/// behind it covered the centres on the line that its neighbour in front
/// covered too, so both integrated the chord along the face (5.9e-2 at
/// pixel (140, 168) of 256x256, every integrator, both sorts; 64x64 and
/// 128x128 passed). Faces seen edge-on now cover no pixel
/// (`pt_compute::edge_on_faces`): 4.7e-5 at 256x256 with ppi.
#[test]
fn pt_compute_with_the_eye_in_face_planes_at_two_sizes() {
    for size in [SIZE, SECOND_SIZE] {
        let selected: Vec<StressCase> =
            stress::stress_cases(size).into_iter().filter(|c| c.name == "eye-on-plane").collect();
        let rows = run(&selected, &config_at(size, &["pt-compute"], &["ppi"], &["exact"], &["mpvo"]));
        assert_eq!(rows.len(), 1);
        let r = &rows[0];
        assert_eq!(r.status, "ok", "at {size}: {} (bound {})", r.max_abs_error, r.bound);
        assert!(r.max_abs_error <= 1e-3, "at {size}: {}", r.max_abs_error);
    }
}

/// The papers' interpolation is held to the integrator's bound plus its f64
/// model's own error against the reference, derived per image
/// (`Extra::PapersModel`), not to a constant fitted at one size: at 64x64
/// and 256x256 the two cases that outgrew the old constant 0.25 at 512x512
/// (needles-caps 0.337, eye-on-plane 0.250011) pass, each row's bound is
/// 1e-3 + the model's max error recomputed here, and the model's error
/// itself is what grows with the size (the sup of its error field).
#[test]
fn papers_interpolation_is_held_to_its_model_at_two_sizes() {
    let names = ["needles-caps", "eye-on-plane"];
    let mut model_error = Vec::new();
    for size in [SIZE, SECOND_SIZE] {
        let selected: Vec<StressCase> =
            stress::stress_cases(size).into_iter().filter(|c| names.contains(&c.name.as_str())).collect();
        assert_eq!(selected.len(), names.len());
        let rows = run(&selected, &config_at(size, &["balanced"], &["ppi"], &["paper"], &["mpvo"]));
        assert_eq!(rows.len(), 2);
        assert_all_pass(&rows);
        for (c, r) in selected.iter().zip(&rows) {
            let CaseData::TetMesh(mesh) = &c.data else { panic!("{} is a mesh case", c.name) };
            let model = volbench::reference::render_papers_model(
                mesh,
                &c.camera,
                &c.tf,
                size,
                size,
                stress::PAPERS_DISTANCE_CLAMP_DIAGONALS,
            )
            .unwrap();
            let reference = volbench::reference::render_reference(mesh, &c.camera, &c.tf, size, size).unwrap();
            let ambiguous = volbench::reference::silhouette::silhouette_pixels(
                mesh,
                &c.camera,
                size,
                size,
                volbench::reference::silhouette::SILHOUETTE_TOLERANCE_PX,
            );
            let e = model
                .pixels
                .iter()
                .zip(&reference.pixels)
                .zip(&ambiguous)
                .filter(|(_, &a)| !a)
                .flat_map(|((m, r), _)| (0..4).map(move |k| (m[k] as f32 - r[k] as f32).abs() as f64))
                .fold(0.0, f64::max);
            // Perspective: the model is off the reference (a whole-face field).
            assert!(e > 0.05, "{} at {size}: model error {e}", c.name);
            assert!((r.bound - (1e-3 + e)).abs() < 1e-6, "{} at {size}: bound {} vs 1e-3 + {e}", c.name, r.bound);
            assert!(r.papers_model_gap.is_some(), "{} at {size}", c.name);
            model_error.push(e);
        }
    }
    // The sup of the model's error field is reached more closely by finer pixels.
    assert!(model_error[2] >= model_error[0] && model_error[3] >= model_error[1], "{model_error:?}");
}

/// The opaque medium carries no allowance for the exact integrators: at
/// 64x64 they are within 1e-3 (the 2 silhouette pixels included).
#[test]
fn opaque_medium_meets_the_accuracy_bound_at_64() {
    let selected: Vec<StressCase> = cases().into_iter().filter(|c| c.name == "opaque-1e6").collect();
    let rows = run(&selected, &config(&["balanced", "vicp"], &["ppi", "linear-exact"], &["exact"], &["mpvo"]));
    assert_eq!(rows.len(), 4);
    for r in &rows {
        assert_eq!(r.status, "ok", "{} {}", r.method, r.options);
        assert!(r.max_abs_error.max(r.silhouette_max_error) <= 1e-3, "{} {}: {}", r.method, r.options, r.max_abs_error);
    }
}

/// The whole sweep with its table (what `volbench stress` prints).
#[test]
#[ignore]
fn full_stress_table() {
    let size: u32 = std::env::var("STRESS_SIZE").ok().and_then(|s| s.parse().ok()).unwrap_or(128);
    let only = std::env::var("STRESS_ONLY").ok();
    let mut cases = stress::stress_cases(size);
    if let Some(o) = &only {
        cases.retain(|c| o.split(',').any(|n| c.name == n));
    }
    println!("{}", stress::describe_cases(size));
    let t = std::time::Instant::now();
    let rows = run(&cases, &StressConfig::full(&registry::builtin(), size).unwrap());
    println!("{}", stress::stress_table(&rows));
    println!("{} renders at {size}x{size} in {:.1} s", rows.len(), t.elapsed().as_secs_f64());
    assert_all_pass(&rows);
}
