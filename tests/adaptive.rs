//! Adaptive image-space refinement (`adaptive=TOL`, issue 37) on lavapipe
//! with the validation layer on: the refined image against the f64
//! reference and against the same method casting every pixel, at two image
//! sizes; the work counts (rays cast against pixels) deterministic; an
//! adversarial view that must refine nearly everything it covers. No
//! timings.

mod common;

use common::context;
use volbench::algo::registry;
use volbench::harness::datasets::{self, Dataset};
use volbench::harness::image::RgbaImage;
use volbench::harness::run::{run as run_method, RunConfig, RunOutput};
use volbench::mesh::TetMesh;
use volbench::reference::render_reference_with_stats;
use volbench::scene::{Camera, ControlPoint, Projection, TransferFunction};

fn run(mesh: &TetMesh, tf: &TransferFunction, spec: &str, camera: Camera, size: u32) -> RunOutput {
    let dataset = Dataset::from_mesh(mesh.clone(), false, "test".into());
    let spec = registry::builtin().parse_spec(spec, &[]).expect("spec");
    let cfg = RunConfig { width: size, height: size, frames: 1, warmup: 1, fixed_camera: Some(camera), ..RunConfig::default() };
    let ctx = context();
    let out = run_method(&ctx, &spec, &dataset, tf, &cfg).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
    out
}

fn reference(mesh: &TetMesh, tf: &TransferFunction, camera: &Camera, size: u32) -> RgbaImage {
    let (r, _) = render_reference_with_stats(mesh, camera, tf, size, size).unwrap();
    RgbaImage { width: size, height: size, pixels: r.pixels.iter().map(|p| p.map(|c| c as f32)).collect() }
}

fn count(o: &RunOutput, name: &str) -> u64 {
    *o.result.work.counts.get(name).unwrap_or_else(|| panic!("work count '{name}' missing: {:?}", o.result.work.counts))
}

fn orbit(mesh: &TetMesh, angle_deg: f64) -> Camera {
    Camera::orbit(&mesh.bounds(), angle_deg.to_radians(), Projection::Perspective { fovy_deg: 30.0 })
}

/// The documented bound (docs/methods.md, adaptive refinement): on a view
/// whose features are wider than the blocks, the refined image's RMSE
/// against the image of every pixel cast is at most TOL, and against the
/// reference at most the full image's plus TOL.
#[test]
fn post_small_refined_within_tol_at_two_sizes_with_fewer_rays() {
    let mesh = datasets::load_mesh("post-small").unwrap();
    let tf = datasets::mesh_transfer_function(&mesh, Some("post-small"));
    let camera = orbit(&mesh, 40.0);
    for size in [160u32, 320] {
        let want = reference(&mesh, &tf, &camera, size);
        let full = run(&mesh, &tf, "tet-raycast", camera, size);
        let ef = full.image.compare(&want).unwrap();
        for tol in [0.008, 0.016] {
            let spec = format!("tet-raycast:adaptive={tol}");
            let a = run(&mesh, &tf, &spec, camera, size);
            let ea = a.image.compare(&want).unwrap();
            let eaf = a.image.compare(&full.image).unwrap();
            let rays = count(&a, "adaptive_rays_cast");
            let rect = count(&a, "pixels_in_rect");
            let covered = count(&a, "adaptive_covered_pixels");
            eprintln!(
                "post-small {size}x{size} tol {tol}: RMSE vs reference {:.3e} (full {:.3e}), vs full {:.3e} (max {:.3e}); rays {rays} of {rect} rect pixels, {covered} covered; {:?}",
                ea.rmse, ef.rmse, eaf.rmse, eaf.max_abs, a.result.work.counts
            );
            assert_eq!(a.image.non_finite_pixels(), 0);
            assert!(eaf.rmse <= tol, "{size} {tol}: RMSE against the full image {:.3e}", eaf.rmse);
            assert!(ea.rmse <= ef.rmse + tol, "{size} {tol}: RMSE {:.3e} against the reference, full {:.3e}", ea.rmse, ef.rmse);
            // Fewer rays than pixels on this smooth view.
            assert!(rays * 10 < rect * 8, "{size} {tol}: {rays} rays for {rect} pixels");
            assert!(rays >= (rect / 64), "{size} {tol}: at least the lattice of 8");
            // Every covered pixel counted once: the same coverage as the full image (within what interpolation blurs at the edge).
            let full_cov = full.image.covered_pixels() as u64;
            assert!(covered.abs_diff(full_cov) * 20 <= full_cov, "{covered} covered, full image {full_cov}");
            // The rays the walk counted are the ones cast.
            assert!(count(&a, "rays_hit") <= rays);
            // Deterministic: the same counts again.
            let b = run(&mesh, &tf, &spec, camera, size);
            for (k, v) in &a.result.work.counts {
                assert_eq!(b.result.work.counts.get(k), Some(v), "{k}");
            }
            assert_eq!(a.image.compare(&b.image).unwrap().max_abs, 0.0);
        }
    }
}

/// A transfer function with many narrow opaque bands: the image changes
/// colour every few pixels, so nearly every covered block refines down to
/// single pixels, and the image stays within the bound.
#[test]
fn a_high_frequency_transfer_function_refines_nearly_everything() {
    let mesh = datasets::load_mesh("post-small").unwrap();
    let (lo, hi) = mesh.scalar_range();
    let diagonal = mesh.bounds().diagonal();
    let points = (0..=40)
        .map(|i| {
            let s = lo + (hi - lo) * i as f64 / 40.0;
            let on = i % 2 == 0;
            ControlPoint { scalar: s, color: if on { [1.0, 0.9, 0.2] } else { [0.1, 0.2, 1.0] }, attenuation: if on { 60.0 / diagonal } else { 1.0 / diagonal } }
        })
        .collect();
    let tf = TransferFunction { name: "stripes".into(), points };
    let camera = orbit(&mesh, 40.0);
    for size in [96u32, 160] {
        let full = run(&mesh, &tf, "tet-raycast", camera, size);
        let a = run(&mesh, &tf, "tet-raycast:adaptive=0.008", camera, size);
        let e = a.image.compare(&full.image).unwrap();
        let rays = count(&a, "adaptive_rays_cast");
        let covered = full.image.covered_pixels() as u64;
        eprintln!("stripes {size}: RMSE vs full {:.3e} (max {:.3e}); {rays} rays, {covered} covered; {:?}", e.rmse, e.max_abs, a.result.work.counts);
        assert!(e.rmse <= 0.008, "{size}: {:.3e}", e.rmse);
        // Nearly a ray per covered pixel.
        assert!(rays * 10 >= covered * 8, "{size}: {rays} rays for {covered} covered pixels");
        assert!(count(&a, "adaptive_blocks16_refined_colour") + count(&a, "adaptive_blocks16_refined_silhouette") + count(&a, "adaptive_blocks16_refined_structure") > 0);
    }
}

#[test]
fn the_option_is_parsed_and_bounded() {
    let reg = registry::builtin();
    for spec in ["tet-raycast:adaptive=0.008", "tet-raycast:adaptive=0"] {
        reg.parse_spec(spec, &[]).unwrap_or_else(|e| panic!("{spec}: {e:#}"));
    }
    for spec in ["tet-raycast:adaptive=-0.1", "tet-raycast:adaptive=0.5", "tet-raycast:adaptive=x"] {
        let e = reg.parse_spec(spec, &[]).err().unwrap_or_else(|| panic!("{spec} accepted"));
        assert!(format!("{e:#}").contains("adaptive"), "{spec}: {e:#}");
    }
}

/// Two Gaussian blobs on a ramp (tests/raycast.rs's), `dims` samples.
fn blob(dims: [usize; 3]) -> volbench::volume::Volume {
    let mut s = Vec::new();
    let field = |p: [f64; 3]| {
        let g = |c: [f64; 3], r: f64| (-(0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>() / (r * r)).exp();
        g([0.4, 0.5, 0.45], 0.25) + 0.8 * g([0.7, 0.35, 0.6], 0.15) + 0.1 * p[0]
    };
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = [i as f64 / (dims[0] - 1) as f64, j as f64 / (dims[1] - 1) as f64, k as f64 / (dims[2] - 1) as f64];
                s.push(field(p) as f32);
            }
        }
    }
    volbench::volume::Volume::new("test", "blob", dims, [1.0; 3], [0.5, -1.0, 2.0], volbench::volume::Samples::F32(s)).unwrap()
}

fn run_volume(d: &Dataset, tf: &TransferFunction, spec: &str, camera: Camera, size: u32) -> RunOutput {
    let spec = registry::builtin().parse_spec(spec, &[]).expect("spec");
    let cfg = RunConfig { width: size, height: size, frames: 1, warmup: 1, fixed_camera: Some(camera), ..RunConfig::default() };
    let ctx = context();
    let out = run_method(&ctx, &spec, d, tf, &cfg).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
    out
}

/// raycast-compute refined: within TOL (RMSE) of the image of every pixel
/// marched and of the reference plus TOL, with fewer rays, at two sizes;
/// raycast-fragment refuses the option with a message naming it.
#[test]
fn raycast_compute_refined_within_tol_at_two_sizes() {
    let d = Dataset::from_volume(blob([24, 20, 16]), false, "synthetic".into());
    let diag = d.bounds().diagonal();
    let pt = |scalar: f64, color: [f64; 3], depth: f64| ControlPoint { scalar, color, attenuation: depth / diag };
    let tf = TransferFunction {
        name: "test".into(),
        points: vec![
            pt(0.0, [0.1, 0.2, 0.9], 0.0),
            pt(0.25, [0.1, 0.2, 0.9], 0.0),
            pt(0.4, [0.2, 0.9, 0.4], 3.0),
            pt(0.7, [1.0, 0.8, 0.2], 6.0),
            pt(1.0, [1.0, 0.2, 0.1], 20.0),
        ],
    };
    let camera = Camera::orbit(&d.bounds(), 0.6, Projection::Perspective { fovy_deg: 30.0 });
    let volbench::harness::datasets::DatasetData::Volume(v) = &d.data else { unreachable!() };
    for size in [96u32, 200] {
        let r = volbench::reference::render_volume_reference(v, &camera, &tf, size, size).unwrap();
        let want = RgbaImage { width: size, height: size, pixels: r.pixels.iter().map(|p| p.map(|c| c as f32)).collect() };
        let full = run_volume(&d, &tf, "raycast-compute", camera, size);
        let ef = full.image.compare(&want).unwrap();
        for tol in [0.008, 0.016] {
            let spec = format!("raycast-compute:adaptive={tol}");
            let a = run_volume(&d, &tf, &spec, camera, size);
            let ea = a.image.compare(&want).unwrap();
            let eaf = a.image.compare(&full.image).unwrap();
            let rays = count(&a, "adaptive_rays_cast");
            let rect = count(&a, "pixels_in_rect");
            eprintln!(
                "blob {size}x{size} tol {tol}: RMSE vs reference {:.3e} (full {:.3e}), vs full {:.3e} (max {:.3e}); rays {rays} of {rect}; {:?}",
                ea.rmse, ef.rmse, eaf.rmse, eaf.max_abs, a.result.work.counts
            );
            assert!(eaf.rmse <= tol, "{size} {tol}: {:.3e}", eaf.rmse);
            assert!(ea.rmse <= ef.rmse + tol);
            assert!(rays * 10 < rect * 8, "{size} {tol}: {rays} rays for {rect} pixels");
            assert!(count(&a, "rays") <= rays);
            // The leaps before a ray's first visible brick run in a loop of
            // their own with the key's bookkeeping (raycast/common.glsl,
            // trim_empty_ends); the rays start in air.
            let ends = count(&a, "leaps_at_ends");
            assert!(ends > 0 && ends <= count(&a, "leaps"), "{ends}");
            let b = run_volume(&d, &tf, &spec, camera, size);
            for (k, v) in &a.result.work.counts {
                assert_eq!(b.result.work.counts.get(k), Some(v), "{k}");
            }
        }
    }
    let spec = registry::builtin().parse_spec("raycast-fragment:adaptive=0.008", &[]).unwrap();
    let cfg = RunConfig { width: 32, height: 32, frames: 1, warmup: 0, fixed_camera: Some(camera), ..RunConfig::default() };
    let ctx = context();
    let e = run_method(&ctx, &spec, &d, &tf, &cfg).err().expect("raycast-fragment refuses adaptive");
    assert!(format!("{e:#}").contains("adaptive"), "{e:#}");
}
