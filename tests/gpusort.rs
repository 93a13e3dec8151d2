//! `resident-gpusort` on lavapipe with the validation layer on (synchronisation
//! validation too, in scripts/test.sh): the device radix sort's order equals
//! the CPU's centroid sort exactly, the image is `resident`'s and
//! `balanced`'s, and per frame only the camera crosses. Correctness and
//! deterministic counts only, no timings.

mod common;
use common::{context, run_mesh as run};

use volbench::algo::cell_projection::device_sort::{DeviceCentroidSort, SortCamera, CAMERA_BYTES, TILE};
use volbench::algo::cell_projection::resident::FLOATS_PER_STORED_CELL;
use volbench::algo::cell_projection::resident_gpusort::SORT_PHASE;
use volbench::algo::cell_projection::sort::CentroidSort;
use volbench::algo::cell_projection::centroids_relative_f32;
use volbench::algo::tet_mesh::{render_origin, FrameConstants};
use volbench::algo::integrate::{PSI_TABLE_SIZE, TF_TABLE_SIZE};
use volbench::algo::registry;
use volbench::harness::datasets;
use volbench::harness::run::RunConfig;
use volbench::mesh::Bounds;
use volbench::scene::{Camera, Projection};
use volbench::vk::{CommandRecorder, UploadCounter};

/// The device order for `centroids` (relative to `origin`) seen by `camera`,
/// and the bytes the sort pushed.
fn device_order(centroids: &[[f32; 3]], origin: [f64; 3], camera: &Camera) -> (Vec<u32>, UploadCounter) {
    let ctx = context();
    let mut setup = UploadCounter::default();
    let sort = DeviceCentroidSort::new(&ctx, "test sort", centroids, &mut setup).expect("device sort");
    let rec = CommandRecorder::new(&ctx, "test sort").expect("recorder");
    let mut frame = UploadCounter::default();
    rec.begin().expect("begin");
    sort.record(&rec, &SortCamera::new(camera, origin), &mut frame).expect("record");
    rec.submit_and_wait().expect("submit");
    let order = sort.read_order(&ctx).expect("read back");
    assert!(sort.gpu_ms().expect("timestamps").is_finite());
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
    (order, frame)
}

fn cpu_order(centroids: &[[f32; 3]], origin: [f64; 3], camera: &Camera) -> Vec<u32> {
    CentroidSort::with_origin(centroids.to_vec(), origin).sort(camera).to_vec()
}

/// Deterministic pseudo-random centroids in the unit cube, quantised to
/// `levels` steps per axis (few levels: many equal depths).
fn centroids(n: usize, levels: u32, seed: u64) -> Vec<[f32; 3]> {
    let mut state = seed;
    let mut next = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 33) as u32 % levels) as f32 / levels as f32
    };
    (0..n).map(|_| [next(), next(), next()]).collect()
}

fn cameras() -> Vec<Camera> {
    let b = Bounds { min: [0.0; 3], max: [1.0; 3] };
    vec![
        Camera::orbit(&b, 0.3, Projection::Perspective { fovy_deg: 30.0 }),
        Camera::orbit(&b, 2.1, Projection::Orthographic { height: 1.5 }),
    ]
}

/// Exact equality of the permutation with the CPU's stable radix sort of the
/// same f32 keys: sizes below, at and above one workgroup's tile, not powers
/// of two, and ties (equal keys keep cell-index order).
#[test]
fn the_device_order_is_the_cpu_centroid_order() {
    assert_eq!(TILE, 2048, "the sizes below straddle one tile");
    for (n, levels) in [(1usize, 1000u32), (7, 1000), (1000, 1 << 20), (2048, 1 << 20), (5003, 1 << 20), (20_000, 4), (70_001, 64)] {
        let c = centroids(n, levels, n as u64);
        for camera in cameras() {
            let (gpu, pushed) = device_order(&c, [0.0; 3], &camera);
            let cpu = cpu_order(&c, [0.0; 3], &camera);
            assert_eq!(gpu.len(), n);
            if let Some(i) = (0..n).find(|&i| gpu[i] != cpu[i]) {
                panic!("n = {n}, levels {levels}, {:?}: first difference at {i}: device {} cpu {}", camera.projection, gpu[i], cpu[i]);
            }
            // Per sort only the camera is pushed.
            assert_eq!(pushed.frame_constant_bytes(), CAMERA_BYTES as u64);
            assert_eq!(pushed.frame_cell_bytes() + pushed.static_bytes(), 0);
        }
    }
    // The tie cases have ties: far fewer distinct centroids than cells.
    let c = centroids(20_000, 4, 20_000);
    let mut distinct: Vec<[u32; 3]> = c.iter().map(|p| p.map(f32::to_bits)).collect();
    distinct.sort();
    distinct.dedup();
    assert!(distinct.len() <= 64, "{}", distinct.len());
}

/// A real mesh far from the world origin (the centroids relative to its
/// render origin, as the method sends them).
#[test]
fn the_device_order_is_the_cpu_order_on_a_real_mesh() {
    let mut mesh = datasets::load_mesh("post-small").unwrap();
    for p in &mut mesh.points {
        p[0] += 1e5;
    }
    let origin = render_origin(&mesh);
    assert_ne!(origin, [0.0; 3]);
    let c = centroids_relative_f32(&mesh, origin);
    for angle in [0.0, 1.0, 4.0] {
        let camera = Camera::orbit(&mesh.bounds(), angle, Projection::Perspective { fovy_deg: 30.0 });
        assert_eq!(device_order(&c, origin, &camera).0, cpu_order(&c, origin, &camera), "angle {angle}");
    }
}

fn small_config(size: u32) -> RunConfig {
    RunConfig { width: size, height: size, frames: 2, warmup: 1, ..RunConfig::default() }
}

/// The same image as `resident` and `balanced` with the centroid sort.
#[test]
fn renders_what_resident_and_balanced_render() {
    for (name, projection) in [
        ("post-small", Projection::Perspective { fovy_deg: 30.0 }),
        ("post-small", Projection::Orthographic { height: 1.0 }),
        ("bluntfin", Projection::Perspective { fovy_deg: 30.0 }),
    ] {
        let mesh = datasets::load_mesh(name).unwrap();
        let tf = datasets::mesh_transfer_function(&mesh, Some(name));
        let cfg = RunConfig { projection, ..small_config(96) };
        let g = run(&mesh, &tf, "resident-gpusort:sort=centroid", &cfg);
        assert!(g.image.covered_pixels() > 1000, "{name}");
        assert_eq!(g.image.non_finite_pixels(), 0);
        for other in ["resident:sort=centroid", "balanced:sort=centroid"] {
            let o = run(&mesh, &tf, other, &cfg);
            let e = o.image.compare(&g.image).unwrap();
            assert!(e.rmse <= 1e-4, "{name} {projection:?}: RMSE {} between {other} and resident-gpusort", e.rmse);
            assert_eq!(
                o.result.stats.unwrap().fragment_invocations,
                g.result.stats.unwrap().fragment_invocations,
                "{name}: {other}"
            );
        }
    }
}

/// Per frame only the camera crosses: the draw's frame constants and the
/// sort's camera, both push constants; no cell bytes. The sort's GPU time
/// is its own phase, and there is no CPU sort.
#[test]
fn only_the_camera_crosses_per_frame() {
    let mesh = datasets::load_mesh("post-small").unwrap();
    let n = mesh.tets.len() as u64;
    let tf = datasets::mesh_transfer_function(&mesh, Some("post-small"));
    let r = run(&mesh, &tf, "resident-gpusort", &small_config(64)).result;
    let camera_bytes = (std::mem::size_of::<FrameConstants>() + CAMERA_BYTES) as u64;
    assert_eq!(camera_bytes, 128 + 28, "the frame constants and the sort camera (eye, perspective, direction)");
    assert_eq!(r.upload.bytes_per_frame, camera_bytes);
    assert_eq!(r.upload.constant_bytes_per_frame, camera_bytes);
    assert_eq!(r.upload.cell_bytes_per_frame, 0);
    assert_eq!(r.upload.bytes_per_cell, Some(0.0));
    assert_eq!(r.upload.floats_per_cell, Some(0.0));
    assert_eq!(r.upload.frame_counters.static_bytes(), 0);
    // Static: tables, cells, strips, centroids (vec4) and 8 passes' params.
    const TABLE_BYTES: u64 = (TF_TABLE_SIZE * 16 + (PSI_TABLE_SIZE - 1) * (PSI_TABLE_SIZE - 1) * 16) as u64;
    let per_cell = FLOATS_PER_STORED_CELL as u64 * 4 + 12 * 4 + 16;
    let pass_params = std::mem::size_of::<volbench::algo::cell_projection::device_sort::PassParams>() as u64;
    assert_eq!(r.upload.static_bytes, TABLE_BYTES + per_cell * n + 8 * pass_params);
    let samples = &r.time_ms.samples;
    assert_eq!(samples[SORT_PHASE].len(), r.frames, "{:?}", samples.keys());
    assert!(!samples.contains_key("sort"), "no CPU sort: {:?}", samples.keys());
    assert_eq!(r.stats.expect("statistics").input_vertices, 12 * n);
    assert_eq!(r.options.text("sort").unwrap(), "centroid");
    common::assert_matches_schema("run.schema.json", &serde_json::to_value(&r).unwrap(), "a resident-gpusort run");
}

#[test]
fn mpvo_is_an_error_naming_the_option() {
    let e = registry::builtin().parse_spec("resident-gpusort:sort=mpvo", &[]).unwrap_err().to_string();
    assert!(e.contains("'resident-gpusort'") && e.contains("option 'sort'") && e.contains("centroid"), "{e}");
    let e = registry::builtin().parse_spec("resident-gpusort", &[("sort", "mpvo".into())]).unwrap_err().to_string();
    assert!(e.contains("option 'sort'"), "{e}");
}
