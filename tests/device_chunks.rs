//! Per-cell device data split at the device's limits (`algo::chunks`,
//! issue 22 item 3): with the limits lowered by the test knob
//! `VOLBENCH_TEST_DEVICE_LIMIT_BYTES`, post-small's arrays are split over
//! several buffers, bindings and draws, as a 33 M-tet mesh's are on
//! lavapipe, and the image must be the one drawn unsplit, bit for bit.
//! Validation layer on. One test function: the knob is process-wide.

mod common;

use volbench::algo::chunks::{DEVICE_LIMIT_VAR, MAX_CHUNKS};
use volbench::harness::datasets;
use volbench::harness::run::RunConfig;

/// A method, the lowered limit in bytes, and the split expected in its
/// `details.device_chunks`.
type Case = (&'static str, u64, &'static [(&'static str, u64)]);

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
    let cases: [Case; 3] = [
        ("resident", 200 << 10, &[("cell_buffers", 7), ("cells_per_buffer", 1422), ("draws", 5), ("cells_per_draw", 1828)]),
        ("balanced", 200 << 10, &[("draws", 5), ("cells_per_draw", 1828)]),
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

    // A knob that is not a byte count is refused naming it.
    std::env::set_var(DEVICE_LIMIT_VAR, "lots");
    let e = volbench::harness::run::run(&ctx, &spec, &dataset, &tf, &cfg).err().expect("a bad knob must be refused");
    std::env::remove_var(DEVICE_LIMIT_VAR);
    assert!(format!("{e:#}").contains(DEVICE_LIMIT_VAR), "{e:#}");
}
