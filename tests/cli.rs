//! The command line end to end: clear errors and exit codes, and a small run
//! whose JSON carries the documented fields.

mod common;

use std::process::Command;

fn volbench() -> Command {
    Command::new(env!("CARGO_BIN_EXE_volbench"))
}

#[test]
fn no_driver_is_a_clear_error() {
    let out = volbench().arg("info").env("VK_DRIVER_FILES", "/nonexistent").env("VK_ICD_FILENAMES", "/nonexistent").output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no Vulkan driver"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn unknown_device_lists_the_available_ones() {
    let out = volbench().args(["--device", "no-such-gpu", "info"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no Vulkan device matches 'no-such-gpu'") && err.contains("llvmpipe"), "{err}");
}

#[test]
fn environment_switches_are_checked_before_any_work() {
    for (var, value, needle) in [
        ("VOLBENCH_PEER_TIMEOUT_S", "garbage", "VOLBENCH_PEER_TIMEOUT_S=garbage: expected a whole number of at least 1"),
        ("VOLBENCH_PEER_TIMEOUT_S", "0", "VOLBENCH_PEER_TIMEOUT_S=0"),
        ("VOLBENCH_TEST_RENUMBER", "hilbert", "expected one of: morton"),
        ("VOLBENCH_TEST_BRICK_MAP_HOST", "sometimes", "VOLBENCH_TEST_BRICK_MAP_HOST=sometimes"),
        ("VOLBENCH_TEST_STAGING_CHUNK_BYTES", "4k", "VOLBENCH_TEST_STAGING_CHUNK_BYTES=4k"),
        ("VOLBENCH_TEST_RESIDENT_BATHC", "8", "VOLBENCH_TEST_RESIDENT_BATHC=8"),
    ] {
        // `list` needs no device: the check comes first, for every command.
        let out = volbench().arg("list").env(var, value).output().unwrap();
        assert_eq!(out.status.code(), Some(1), "{var}={value}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{var}={value}: {err}");
    }
}

#[test]
fn a_missing_volume_preset_is_an_error_naming_it() {
    // A data folder with the volumes but without tf/.
    let dir = tempfile::tempdir().unwrap();
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data");
    std::os::unix::fs::symlink(data.join("volumes"), dir.path().join("volumes")).unwrap();
    let out = volbench()
        .args(["run", "--data", "headsq", "--method", "raycast-compute", "--size", "16x16", "--frames", "1"])
        .env("VOLBENCH_DATA", dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("the preset transfer function of 'headsq'") && err.contains("headsq.json") && err.contains("is missing"), "{err}");
}

#[test]
fn an_output_directory_in_use_is_refused() {
    // This process holds the directory, as a running suite would.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("res");
    let held = volbench::fsio::lock_out_dir("--out", &out).unwrap();
    let run = |out: &std::path::Path| {
        volbench()
            .args(["pareto", "--data", "hydrogen", "--method", "raycast-compute", "--size", "16x16", "--frames", "1", "--warmup", "0"])
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let o = run(&out);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    let me = format!("pid {}", std::process::id());
    assert!(err.contains("another volbench is writing its results there") && err.contains(&me), "{err}");
    assert!(!out.join("pareto.json").exists());
    drop(held);
}

#[test]
fn an_unknown_file_lists_every_format_read() {
    let dir = tempfile::tempdir().unwrap();
    let junk = dir.path().join("scan.xyz9");
    std::fs::write(&junk, b"not a dataset\n").unwrap();
    let out = volbench().args(["run", "--method", "raycast-compute", "--data"]).arg(&junk).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("neither its content nor its extension is a format volbench reads"), "{err}");
    for format in [".vtu and .pvtu", "PLOT3D", "NRRD", ".vti", "STRUCTURED_POINTS", "NIfTI-1", "MetaImage (.mha, .mhd", ".npz", "GeoTIFF"] {
        assert!(err.contains(format), "{format} missing: {err}");
    }
}

#[test]
fn invalid_arguments_name_the_argument() {
    for (args, needle) in [
        (vec!["run", "--mesh", "post-small", "--method", "balanced", "--size", "0x5"], "--size"),
        (vec!["run", "--mesh", "post-small", "--method", "nope"], "--method"),
        (vec!["run", "--mesh", "post-small", "--method", "vicp", "--frames", "0"], "--frames"),
        (vec!["run", "--mesh", "no/such/file.vtk", "--method", "vicp"], "no/such/file.vtk"),
    ] {
        let out = volbench().args(&args).output().unwrap();
        assert_ne!(out.status.code(), Some(0), "{args:?}");
        assert_ne!(out.status.code(), Some(101), "{args:?} panicked");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

#[test]
fn run_writes_the_documented_json() {
    let dir = tempfile::tempdir().unwrap();
    let (json, png) = (dir.path().join("r.json"), dir.path().join("r.png"));
    let out = volbench()
        .args(["run", "--mesh", "post-small", "--method", "balanced", "--size", "64x48", "--frames", "2", "--warmup", "1"])
        .arg("--json")
        .arg(&json)
        .arg("--png")
        .arg(&png)
        .arg("--reference")
        .env("VOLBENCH_VALIDATION", "1")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for path in [
        "/method", "/mesh", "/cells", "/width", "/height", "/frames",
        "/upload/bytes_per_frame", "/upload/bytes_per_cell", "/upload/floats_per_cell", "/upload/static_bytes",
        "/time_ms/frame/median", "/time_ms/frame/min", "/time_ms/frame/max", "/time_ms/gpu/median",
        "/time_ms/sort/median", "/time_ms/pack/median", "/cells_per_second",
        "/stats/vertex_invocations", "/stats/fragment_invocations", "/device/name", "/device/driver_info",
        "/error/rmse", "/error/max_abs", "/error/psnr_db", "/error/reference", "/git_sha",
    ] {
        assert!(v.pointer(path).is_some(), "missing {path}");
    }
    common::assert_matches_schema("run.schema.json", &v, "volbench run --json");
    assert_eq!(v["method"], "balanced");
    assert_eq!(v["mesh"], "post-small");
    // The validation layer changes what is measured: recorded.
    assert_eq!(v["env_switches"], serde_json::json!({ "VOLBENCH_VALIDATION": "1" }));
    assert_eq!(v["upload"]["floats_per_cell"], 28.0);
    assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(64), Some(48)));
    assert!(png.exists());
    // The fixed cost: 5 frames with the camera turned away, in which
    // culling leaves every cell out (nothing is in view).
    assert_eq!(v["time_ms"]["samples"]["fixed"].as_array().map(Vec::len), Some(5));
    assert!(v["time_ms"]["fixed_gpu"]["median"].as_f64().is_some_and(|t| t >= 0.0));
    assert_eq!(v["frame_counts"]["fixed.cells_drawn"]["total"], 0);
    assert_eq!(v["frame_counts"]["fixed.cull.frustum"]["per_frame"][0], 8750);
    // The reference view's statistics are still collected.
    assert!(v["stats"]["fragment_invocations"].as_u64().is_some_and(|n| n > 0));
}

#[test]
fn sort_and_transfer_function_options() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("r.json");
    let tf = concat!(env!("CARGO_MANIFEST_DIR"), "/data/tf/post-small.json");
    let out = volbench()
        .args(["run", "--mesh", "post-small", "--method", "vicp", "--size", "48x48", "--frames", "1", "--warmup", "0"])
        .args(["--sort", "mpvo", "--integrator", "linear-exact", "--interpolation", "exact", "--tf", tf, "--reference"])
        .arg("--json")
        .arg(&json)
        .env("VOLBENCH_VALIDATION", "1")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["options"]["sort"], "mpvo");
    assert_eq!(v["options"]["integrator"], "linear-exact");
    assert_eq!(v["options"]["interpolation"], "exact");
    assert_eq!(v["upload"]["floats_per_cell"], 132.0);
    // The preset file is the built-in preset: same name.
    assert_eq!(v["transfer_function"], "post-small-default");
    assert!(v["diagnostics"]["centroid_order"]["constraints"].as_u64().unwrap() > 0);

    // A bad transfer-function file: a clear error naming it, no output.
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, r#"{"points": [{"scalar": 1, "color": [2, 0, 0], "attenuation": 1}]}"#).unwrap();
    let json2 = dir.path().join("r2.json");
    let out = volbench()
        .args(["run", "--mesh", "post-small", "--method", "vicp", "--size", "8x8", "--frames", "1"])
        .arg("--tf")
        .arg(&bad)
        .arg("--json")
        .arg(&json2)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.json"), "{err}");
    assert!(!json2.exists());
}
