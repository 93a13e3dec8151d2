//! Per-cell device data split at the device's limits (`algo::chunks`,
//! issue 22 item 3): with the limits lowered by the test knob
//! `VOLBENCH_TEST_DEVICE_LIMIT_BYTES`, post-small's arrays are split over
//! several buffers, bindings and draws, as a 33 M-tet mesh's are on
//! lavapipe, and the image must be the one drawn unsplit, bit for bit.
//! balanced's records packed in place at upload (past its pack-ahead budget,
//! lowered by `VOLBENCH_TEST_PACK_AHEAD_BYTES`) draw the same image too.
//! Validation layer on. One test function: the knobs are process-wide.

mod common;

use volbench::algo::cell_projection::balanced::PACK_AHEAD_VAR;
use volbench::algo::cell_projection::resident::RESIDENT_BATCH_VAR;
use volbench::algo::chunks::{DEVICE_LIMIT_VAR, MAX_CHUNKS};
use volbench::harness::datasets;
use volbench::harness::run::RunConfig;

/// A method, the lowered limit in bytes, and the split expected in its
/// `details.device_chunks`.
type Case = (&'static str, u64, &'static [(&'static str, u64)]);

/// `spec` run with the test knob `knob` set, and the device limit knob too
/// when `limit` is given; both removed after.
fn run_with_knobs(
    mesh: &volbench::mesh::TetMesh,
    tf: &volbench::scene::TransferFunction,
    spec: &str,
    cfg: &RunConfig,
    knob: (&str, u64),
    limit: Option<u64>,
) -> volbench::harness::run::RunOutput {
    std::env::set_var(knob.0, knob.1.to_string());
    if let Some(l) = limit {
        std::env::set_var(DEVICE_LIMIT_VAR, l.to_string());
    }
    let run = common::run_mesh(mesh, tf, spec, cfg);
    std::env::remove_var(knob.0);
    std::env::remove_var(DEVICE_LIMIT_VAR);
    run
}

#[test]
fn data_split_at_lowered_limits_draws_the_same_image() {
    let mesh = datasets::load_mesh("post-small").unwrap();
    let tf = datasets::mesh_transfer_function(&mesh, Some("post-small"));
    let cfg = RunConfig { width: 96, height: 96, frames: 2, warmup: 1, ..RunConfig::default() };
    // 200 KiB: resident's 144-byte cells in 7 texel buffers of 1422, its
    // order in 5 draws of 1828 (the 112-byte records its expansion writes
    // per storage binding);
    // balanced's 112-byte records in 5 draws of 1828. 32 KiB: tet-raycast's
    // points (2,288) in 2 buffers of 2048 texels, each per-cell array in 5.
    // 1 MiB: VICP's 528-byte records in 5 draws of 1985. 200 KiB: ATFS's
    // 112-byte pieces (11,193 with post-small's transfer function) in 7
    // draws of 1828; pt-compute's 144-byte stored cells as resident's, in 7
    // texel buffers of 1422.
    let cases: [Case; 6] = [
        ("resident", 200 << 10, &[("cell_buffers", 7), ("cells_per_buffer", 1422), ("draws", 5), ("cells_per_draw", 1828)]),
        ("balanced", 200 << 10, &[("draws", 5), ("cells_per_draw", 1828)]),
        ("vicp", 1 << 20, &[("draws", 5), ("cells_per_draw", 1985)]),
        ("atfs", 200 << 10, &[("draws", 7), ("pieces_per_draw", 1828)]),
        ("pt-compute", 200 << 10, &[("cell_buffers", 7), ("cells_per_buffer", 1422)]),
        ("tet-raycast", 32 << 10, &[("point_buffers", 2), ("points_per_buffer", 2048), ("buffers_per_cell_array", 5)]),
    ];
    for (spec, limit, expected) in cases {
        std::env::remove_var(DEVICE_LIMIT_VAR);
        let whole = common::run_mesh(&mesh, &tf, spec, &cfg);
        std::env::set_var(DEVICE_LIMIT_VAR, limit.to_string());
        let split = common::run_mesh(&mesh, &tf, spec, &cfg);
        std::env::remove_var(DEVICE_LIMIT_VAR);
        let chunks = &split.result.details["device_chunks"];
        for &(key, value) in expected {
            assert_eq!(chunks[key].as_u64(), Some(value), "{spec}: device_chunks.{key} in {chunks}");
        }
        let unsplit = &whole.result.details["device_chunks"];
        for key in ["cell_buffers", "draws", "point_buffers", "buffers_per_cell_array"] {
            assert!(unsplit[key].is_null() || unsplit[key] == 1, "{spec}: unsplit run has {key} = {}", unsplit[key]);
        }
        assert!(whole.image.covered_pixels() > 1000, "{spec}: the mesh should fill part of the image");
        assert_eq!(whole.result.work.counts["cells"], split.result.work.counts["cells"], "{spec}");
        assert_eq!(whole.image.compare(&split.image).unwrap().max_abs, 0.0, "{spec}: splitting the data changed the image");
    }

    // balanced packs the records past its pack-ahead budget straight into
    // the vertex buffers at upload (`balanced::PACK_AHEAD_VAR` lowers the
    // budget): none ahead, 1000 cells ahead (inside the first of 5 draws at
    // 200 KiB, so one draw is part copied, part packed in place), and 4000
    // (across two draws); the image and the bytes per frame are those of
    // packing everything ahead.
    let whole = common::run_mesh(&mesh, &tf, "balanced", &cfg);
    assert!(whole.result.details["host_memory"]["by_structure"]["projector: order packed in upload"] == 0);
    for (ahead_cells, limit) in [(0u64, None), (1000, None), (1000, Some(200u64 << 10)), (4000, Some(200 << 10)), (0, Some(200 << 10))] {
        let run = run_with_knobs(&mesh, &tf, "balanced", &cfg, (PACK_AHEAD_VAR, ahead_cells * 112), limit);
        let what = format!("balanced, {ahead_cells} cells packed ahead, limit {limit:?}");
        let memory = &run.result.details["host_memory"]["by_structure"];
        assert_eq!(memory["projector: records packed ahead (at most PACK_AHEAD_BYTES)"].as_u64(), Some(ahead_cells * 112), "{what}");
        let rest = memory["projector: order packed in upload"].as_u64().unwrap();
        let drawn = run.result.work.counts["cells_drawn"];
        assert!(rest >= (drawn - ahead_cells.min(drawn)) * 4 && rest <= (mesh.tets.len() as u64 - ahead_cells) * 4, "{what}: {rest} bytes of order kept");
        assert_eq!(whole.result.upload.bytes_per_frame, run.result.upload.bytes_per_frame, "{what}: the same bytes cross");
        assert_eq!(whole.image.compare(&run.image).unwrap().max_abs, 0.0, "{what}: packing in place changed the image");
    }

    // resident-gpusort's device sort with its centroids in 5 storage
    // buffers of 2048 (32 KiB; its cells would need more than 8 texel
    // buffers there, so the sort is run on its own): the order read back is
    // the one sorted from one buffer.
    {
        use volbench::algo::cell_projection::device_sort::{DeviceCentroidSort, SortCamera};
        use volbench::algo::cell_projection::centroids_relative_f32;
        use volbench::algo::tet_mesh::render_origin;
        let origin = render_origin(&mesh);
        let centroids = centroids_relative_f32(&mesh, origin);
        let camera = volbench::scene::Camera::orbit(&mesh.bounds(), 1.0, volbench::scene::Projection::Perspective { fovy_deg: 30.0 });
        let ctx = common::context();
        let order = |limit: Option<u64>| {
            match limit {
                Some(l) => std::env::set_var(DEVICE_LIMIT_VAR, l.to_string()),
                None => std::env::remove_var(DEVICE_LIMIT_VAR),
            }
            let mut setup = volbench::vk::UploadCounter::default();
            let sort = DeviceCentroidSort::new(&ctx, "test sort", &centroids, &mut setup).expect("device sort");
            std::env::remove_var(DEVICE_LIMIT_VAR);
            let rec = volbench::vk::CommandRecorder::new(&ctx, "test sort").expect("recorder");
            rec.begin().expect("begin");
            sort.record(&rec, &SortCamera::new(&camera, origin), &mut volbench::vk::UploadCounter::default()).expect("record");
            rec.submit_and_wait().expect("submit");
            (sort.centroid_buffers(), sort.read_order(&ctx).expect("read back"))
        };
        let (whole_split, whole) = order(None);
        let (split_split, split) = order(Some(32 << 10));
        assert_eq!((whole_split.0, split_split), (1, (5, 2048)));
        assert_eq!(whole.len(), mesh.tets.len());
        assert_eq!(whole, split, "splitting the centroids changed the order");
        assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
    }

    // resident expands and draws its order batch by batch into one
    // records buffer (`resident::RESIDENT_BATCH_VAR` lowers the batch): 9
    // batches of 1000, 137 of 64, and 1000 under the 200 KiB limit (the
    // cells in 7 texel buffers) draw the image of one batch, bit for bit,
    // and per frame only each batch's length is added to the order.
    let whole = common::run_mesh(&mesh, &tf, "resident", &cfg);
    let n = mesh.tets.len() as u64;
    for (batch, limit) in [(1000u64, None), (64, None), (1000, Some(200u64 << 10))] {
        let run = run_with_knobs(&mesh, &tf, "resident", &cfg, (RESIDENT_BATCH_VAR, batch), limit);
        let what = format!("resident, batches of {batch}, limit {limit:?}");
        let chunks = &run.result.details["device_chunks"];
        assert_eq!(chunks["draws"].as_u64(), Some(n.div_ceil(batch)), "{what}: {chunks}");
        assert_eq!(chunks["cells_per_draw"].as_u64(), Some(batch), "{what}: {chunks}");
        let lengths = 4 * (n.div_ceil(batch) - 1);
        assert_eq!(run.result.upload.bytes_per_frame, whole.result.upload.bytes_per_frame + lengths, "{what}");
        assert_eq!(run.result.stats.unwrap().fragment_invocations, whole.result.stats.unwrap().fragment_invocations, "{what}");
        assert_eq!(whole.image.compare(&run.image).unwrap().max_abs, 0.0, "{what}: batching changed the image");
    }

    // More pieces than the shader has bindings: a clear error, no picture.
    std::env::set_var(DEVICE_LIMIT_VAR, (16u64 << 10).to_string());
    let dataset = datasets::Dataset::from_mesh(mesh.clone(), false, "test".into());
    let spec = volbench::algo::registry::builtin().parse_spec("resident", &[]).unwrap();
    let ctx = common::context();
    let e = volbench::harness::run::run(&ctx, &spec, &dataset, &tf, &cfg).err().expect("too many pieces must be refused");
    std::env::remove_var(DEVICE_LIMIT_VAR);
    let msg = format!("{e:#}");
    assert!(msg.contains("resident cells") && msg.contains(&format!("more than the {MAX_CHUNKS} bindings")), "{msg}");
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());

    // Memory is checked before allocating, host bytes with device bytes: a
    // trillion cells are refused naming the memory (on a CPU device both
    // together), a thousand pass.
    let e = volbench::algo::chunks::check_memory(&ctx.info, 1 << 40, 528, 1120).expect_err("a trillion cells cannot fit");
    let msg = format!("{e:#}");
    let names = if ctx.info.is_cpu() { "device and host memory together" } else { "memory" };
    assert!(msg.contains(names) && msg.contains("1099511627776 cells"), "{msg}");
    volbench::algo::chunks::check_memory(&ctx.info, 1000, 528, 1120).unwrap();

    // A knob that is not a byte count is refused naming it.
    std::env::set_var(DEVICE_LIMIT_VAR, "lots");
    let e = volbench::harness::run::run(&ctx, &spec, &dataset, &tf, &cfg).err().expect("a bad knob must be refused");
    std::env::remove_var(DEVICE_LIMIT_VAR);
    assert!(format!("{e:#}").contains(DEVICE_LIMIT_VAR), "{e:#}");
    std::env::set_var(RESIDENT_BATCH_VAR, "0");
    let e = volbench::harness::run::run(&ctx, &spec, &dataset, &tf, &cfg).err().expect("a zero batch must be refused");
    std::env::remove_var(RESIDENT_BATCH_VAR);
    assert!(format!("{e:#}").contains(RESIDENT_BATCH_VAR), "{e:#}");
}
