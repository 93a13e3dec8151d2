//! `pt-compute` on lavapipe with the validation layer on (synchronisation
//! validation too, in scripts/test.sh): the image is balanced's (RMSE <=
//! 1e-4) with every integrator and both interpolations, on shipped meshes
//! and on a generated one, with the same error against the f64 reference;
//! its work counts are consistent. Correctness and deterministic counts
//! only, no timings.

mod common;
use common::run_mesh as run;

use volbench::algo::cell_projection::pt_compute::{BIN_PHASE, COMPOSITE_PHASE};
use volbench::harness::datasets;
use volbench::harness::image::RgbaImage;
use volbench::harness::run::RunConfig;
use volbench::mesh::split::hex_grid_to_tets;
use volbench::mesh::TetMesh;
use volbench::scene::{Camera, ControlPoint, Projection, TransferFunction};

fn config(size: u32, projection: Projection) -> RunConfig {
    RunConfig { width: size, height: size, frames: 2, warmup: 1, projection, ..RunConfig::default() }
}

/// A 7x6x5-point grid jittered by a fixed pseudo-random offset (up to 0.3
/// of a spacing: non-uniform, skewed cells) with a non-linear scalar field:
/// a mesh no method was tuned on.
fn jittered_mesh() -> TetMesh {
    let dims = [7usize, 6, 5];
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 33) as f64 / (1u64 << 31) as f64) - 0.5
    };
    let mut points = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let interior = |v: usize, n: usize| v > 0 && v + 1 < n;
                let jitter = if interior(i, dims[0]) && interior(j, dims[1]) && interior(k, dims[2]) { 0.6 } else { 0.0 };
                points.push([
                    i as f64 + jitter * next(),
                    j as f64 + jitter * next(),
                    k as f64 + jitter * next(),
                ]);
            }
        }
    }
    let scalars = points.iter().map(|p| (0.7 * p[0]).sin() + 0.3 * p[1] - 0.2 * p[2]).collect();
    hex_grid_to_tets("jittered", dims, points, scalars).unwrap()
}

fn ramp_tf() -> TransferFunction {
    TransferFunction {
        name: "ramp".into(),
        points: vec![
            ControlPoint { scalar: -1.5, color: [0.1, 0.3, 1.0], attenuation: 0.1 },
            ControlPoint { scalar: 0.5, color: [1.0, 0.9, 0.2], attenuation: 0.8 },
            ControlPoint { scalar: 2.5, color: [1.0, 0.2, 0.0], attenuation: 2.0 },
        ],
    }
}

fn reference(mesh: &TetMesh, tf: &TransferFunction, camera: &Camera, size: u32) -> RgbaImage {
    let r = volbench::reference::render_reference(mesh, camera, tf, size, size).unwrap();
    RgbaImage { width: size, height: size, pixels: r.pixels.iter().map(|p| p.map(|c| c as f32)).collect() }
}

/// pt-compute against balanced with `options` on `mesh` seen by `camera`:
/// RMSE <= 1e-4 between them, and against the f64 reference no more error
/// than balanced plus what early termination may leave out (1e-5).
fn assert_matches_balanced(name: &str, mesh: &TetMesh, tf: &TransferFunction, camera: Camera, size: u32, options: &str) {
    let cfg = RunConfig { fixed_camera: Some(camera), ..config(size, camera.projection) };
    let sep = if options.is_empty() { "" } else { ":" };
    let b = run(mesh, tf, &format!("balanced{sep}{options}"), &cfg);
    let p = run(mesh, tf, &format!("pt-compute{sep}{options}"), &cfg);
    assert!(p.image.covered_pixels() > size as usize * size as usize / 10, "{name} {options}: {} pixels", p.image.covered_pixels());
    assert_eq!(p.image.non_finite_pixels(), 0, "{name} {options}");
    let e = p.image.compare(&b.image).unwrap();
    assert!(e.rmse <= 1e-4, "{name} {options}: RMSE {} between balanced and pt-compute (max {})", e.rmse, e.max_abs);
    let r = reference(mesh, tf, &camera, size);
    let (eb, ep) = (b.image.compare(&r).unwrap(), p.image.compare(&r).unwrap());
    eprintln!("{name} {options}: vs balanced {:.2e}/{:.2e}; vs reference balanced {:.2e}/{:.2e}, pt-compute {:.2e}/{:.2e}",
        e.rmse, e.max_abs, eb.rmse, eb.max_abs, ep.rmse, ep.max_abs);
    assert!(ep.rmse <= eb.rmse * 1.05 + 1e-5, "{name} {options}: RMSE vs reference {} (balanced {})", ep.rmse, eb.rmse);
    assert!(ep.max_abs <= eb.max_abs * 1.05 + 1e-5, "{name} {options}: max error vs reference {} (balanced {})", ep.max_abs, eb.max_abs);
}

#[test]
fn renders_what_balanced_renders_on_shipped_meshes() {
    for (name, projection, options) in [
        ("post-small", Projection::Perspective { fovy_deg: 30.0 }, ""),
        ("post-small", Projection::Perspective { fovy_deg: 30.0 }, "interpolation=paper"),
        ("post-small", Projection::Orthographic { height: 1.0 }, "sort=mpvo"),
    ] {
        let mesh = datasets::load_mesh(name).unwrap();
        let tf = datasets::mesh_transfer_function(&mesh, Some(name));
        let camera = Camera::orbit(&mesh.bounds(), 0.0, projection);
        assert_matches_balanced(name, &mesh, &tf, camera, 96, options);
    }
}

/// The blunt fin: thin cells whose faces rays run nearly along (stress case
/// "slivers-edge-on" alike); coverage decided per face from the snapped
/// projected vertices, as the rasterizer does, so the two cells around such
/// a face agree on every pixel.
#[test]
fn renders_what_balanced_renders_on_the_blunt_fin() {
    let mesh = datasets::load_mesh("bluntfin").unwrap();
    let tf = datasets::mesh_transfer_function(&mesh, Some("bluntfin"));
    let camera = Camera::orbit(&mesh.bounds(), 0.0, Projection::Perspective { fovy_deg: 30.0 });
    assert_matches_balanced("bluntfin", &mesh, &tf, camera, 96, "");
}

/// Every integrator, both interpolations, at two image sizes (a tile grid
/// that does and does not divide the image), on a generated mesh.
#[test]
fn renders_what_balanced_renders_on_a_generated_mesh() {
    let mesh = jittered_mesh();
    let tf = ramp_tf();
    for (size, angle, projection) in [
        (64, 0.7, Projection::Perspective { fovy_deg: 35.0 }),
        (75, 2.3, Projection::Orthographic { height: 9.0 }),
    ] {
        let camera = Camera::orbit(&mesh.bounds(), angle, projection);
        for integrator in ["average", "preint", "ppi", "linear-exact"] {
            for interpolation in ["exact", "paper"] {
                let options = format!("integrator={integrator},interpolation={interpolation}");
                assert_matches_balanced("jittered", &mesh, &tf, camera, size, &options);
            }
        }
    }
}

/// The eye inside the mesh: cells behind the eye are left out, the cells
/// around it come from the near caps drawn over the compositing pass.
#[test]
fn the_eye_inside_the_mesh_renders_what_balanced_renders() {
    let mesh = jittered_mesh();
    let tf = ramp_tf();
    let camera = Camera {
        eye: [3.1, 2.4, 2.2],
        target: [6.0, 5.0, 3.0],
        up: [0.0, 0.0, 1.0],
        projection: Projection::Perspective { fovy_deg: 60.0 },
        near: 0.05,
        far: 50.0,
    };
    assert_matches_balanced("jittered, eye inside", &mesh, &tf, camera, 64, "");
}

/// The counts: every drawn cell binned (the camera frames the mesh), a
/// listed pair per segment integrated (or more: early termination), none
/// tested by planes (the eye is outside), segments integrated at least one
/// per covered pixel; the phases are reported; an opaque medium stops
/// pixels early and changes nothing visible.
#[test]
fn work_counts_and_phases() {
    let mesh = datasets::load_mesh("post-small").unwrap();
    let tf = datasets::mesh_transfer_function(&mesh, Some("post-small"));
    let out = run(&mesh, &tf, "pt-compute", &config(64, Projection::Perspective { fovy_deg: 30.0 }));
    let w = &out.result.work;
    let get = |k: &str| *w.counts.get(k).unwrap_or_else(|| panic!("work count {k}: {:?}", w.counts));
    assert!(get("cells_binned") > 0 && get("cells_binned") <= get("cells_drawn"));
    assert!(get("pixel_cell_pairs") >= get("pixels_integrated"));
    assert_eq!(get("cells_plane_tested"), 0, "the eye is outside the mesh");
    assert!(get("pixels_covered") > 0);
    assert!(get("pixels_integrated") >= get("pixels_covered"));
    assert!(get("pixels_terminated_early") <= get("pixels_covered"));
    let phases = &out.result.time_ms;
    for phase in [BIN_PHASE, COMPOSITE_PHASE] {
        assert!(phases.phases.contains_key(phase), "{phase}: {:?}", phases.phases.keys().collect::<Vec<_>>());
    }

    let opaque = TransferFunction::constant([1.0, 0.5, 0.25], 1e4);
    let cube = jittered_mesh();
    let camera = Camera::orbit(&cube.bounds(), 0.4, Projection::Perspective { fovy_deg: 35.0 });
    let cfg = RunConfig { fixed_camera: Some(camera), ..config(48, camera.projection) };
    let p = run(&cube, &opaque, "pt-compute", &cfg);
    let b = run(&cube, &opaque, "balanced", &cfg);
    assert!(p.result.work.counts["pixels_terminated_early"] > 0);
    let e = p.image.compare(&b.image).unwrap();
    assert!(e.rmse <= 1e-4 && e.max_abs <= 1e-4, "{e:?}");
}
