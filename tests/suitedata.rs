//! `volbench suite --data FILE`: the suite on a user's own files. Small
//! files generated here (a `.vtu` of hexahedra with a scalar and a vector
//! point array, a `.vti` volume) run every method of their kind with the
//! same report; `--filter`, repeated `--data`, `--tf`, and bad input before
//! anything runs. Without peers (CI has no VTK); the peers' side of a
//! user's file is `harness::peers::original_dataset` (tests/peers.rs).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

mod common;
use common::user_files::{write_vti, write_vtu};

fn volbench() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_volbench"));
    c.env("VOLBENCH_VALIDATION", "1");
    c
}

fn fixtures(dir: &Path) -> (PathBuf, PathBuf) {
    let (vtu, vti) = (dir.join("my mesh.vtu"), dir.join("blob.vti"));
    write_vtu(&vtu);
    write_vti(&vti);
    (vtu, vti)
}

fn text(out: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr))
}

fn summary(dir: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap()
}

/// The method names of the runs on `dataset`.
fn methods_on(s: &Value, dataset: &str) -> Vec<String> {
    let mut m: Vec<String> =
        s["runs"].as_array().unwrap().iter().filter(|r| r["dataset"] == dataset).map(|r| r["method"].as_str().unwrap().to_string()).collect();
    m.dedup();
    m
}

#[test]
fn a_users_mesh_and_volume_run_every_method_of_their_kind_with_the_report() {
    let tmp = tempfile::tempdir().unwrap();
    let (vtu, vti) = fixtures(tmp.path());
    let out_dir = tmp.path().join("out");
    let out = volbench().args(["suite", "--quick", "--data"]).arg(&vtu).arg("--data").arg(&vti).arg("--out").arg(&out_dir).output().unwrap();
    assert!(out.status.success(), "{}", text(&out));
    let s = summary(&out_dir);
    let registry = volbench::algo::registry::builtin();
    use volbench::algo::method::DataKind;
    let names = |k: DataKind| registry.for_kind(k).map(|m| m.name.to_string()).collect::<Vec<_>>();
    // Only the files: no shipped dataset ran.
    let datasets: Vec<&str> = s["datasets"].as_array().unwrap().iter().map(|d| d["name"].as_str().unwrap()).collect();
    assert_eq!(datasets, ["my_mesh", "blob"]);
    assert!(s["runs"].as_array().unwrap().iter().all(|r| datasets.contains(&r["dataset"].as_str().unwrap())));
    for (d, kind) in [("my_mesh", DataKind::TetMesh), ("blob", DataKind::Volume)] {
        assert_eq!(methods_on(&s, d), names(kind), "{d}: every method of its kind");
        for r in s["runs"].as_array().unwrap().iter().filter(|r| r["dataset"] == d) {
            assert!(r["status"] == "ok" || r["status"] == "skipped", "{d} {}: {}", r["label"], r["message"]);
            if r["status"] == "ok" {
                let e = r["result"]["error"]["rmse"].as_f64().unwrap();
                assert!(e < 2e-2, "{d} {}: RMSE {e} against the f64 reference", r["label"]);
            }
        }
        assert!(out_dir.join(format!("montage-{d}.png")).is_file(), "{d}");
        assert!(out_dir.join(format!("plots/time_error-{d}.png")).is_file(), "{d}");
    }
    for d in s["datasets"].as_array().unwrap() {
        assert_eq!((d["user"].as_bool(), d["transfer_function"].as_str()), (Some(true), Some("generic-ramp")), "{d}");
    }
    assert_eq!(s["settings"]["data"].as_array().unwrap().len(), 2);
    let report = std::fs::read_to_string(out_dir.join("report.md")).unwrap();
    assert!(report.contains("## Datasets"), "{report}");
    assert!(report.contains(&format!("| my_mesh | {} (your file) | tet-mesh | temp | generic-ramp |", vtu.display())), "{report}");
    assert!(report.contains(&format!("| blob | {} (your file) | volume |", vti.display())), "{report}");
    // The runs table gives each row's rate in its kind's own unit: a volume
    // has samples, not cells (it used to read "0.000" M cells/s).
    let rows = |d: &str| report.lines().filter(|l| l.starts_with(&format!("| {d} | ")) && l.contains(" | ok | ")).collect::<Vec<_>>();
    assert!(!rows("blob").is_empty() && !rows("my_mesh").is_empty(), "{report}");
    for l in rows("blob") {
        assert!(l.contains(" M samples/s |") && !l.contains("cells/s"), "{l}");
    }
    for l in rows("my_mesh") {
        assert!(l.contains(" M cells/s |"), "{l}");
    }
    let csv = std::fs::read_to_string(out_dir.join("summary.csv")).unwrap();
    assert!(csv.lines().any(|l| l.starts_with("volbench,blob,raycast-compute,")), "{csv}");
    // The user's files are inputs, left as they were.
    assert!(vtu.is_file() && vti.is_file());
}

#[test]
fn data_with_scalar_filter_and_tf_runs_only_the_named_method_on_that_array_with_that_transfer_function() {
    let tmp = tempfile::tempdir().unwrap();
    let (vtu, _) = fixtures(tmp.path());
    let vector = format!("{}#velocity", vtu.display());
    let tf = tmp.path().join("glow.json");
    std::fs::write(
        &tf,
        r#"{"name": "glow", "scalar_units": "relative", "attenuation_units": "per_diagonal",
            "points": [{"scalar": 0, "color": [0, 0, 1], "attenuation": 1}, {"scalar": 1, "color": [1, 1, 0], "attenuation": 6}]}"#,
    )
    .unwrap();
    let out_dir = tmp.path().join("out");
    let out = volbench()
        .args(["suite", "--quick", "--filter", "tet-raycast", "--tf"])
        .arg(&tf)
        .arg("--data")
        .arg(&vector)
        .arg("--data")
        .arg("post-small")
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    let s = summary(&out_dir);
    // A shipped dataset named by --data goes with the file; the filter keeps one method on both.
    assert_eq!(methods_on(&s, "my_mesh-velocity"), ["tet-raycast"]);
    assert_eq!(methods_on(&s, "post-small"), ["tet-raycast"]);
    assert!(s["runs"].as_array().unwrap().iter().all(|r| r["result"]["transfer_function"] == "glow"), "--tf on every dataset");
    let d = &s["datasets"][0];
    assert_eq!((d["user"].as_bool(), d["source"].as_str(), d["scalar_array"].as_str()), (Some(true), Some(vector.as_str()), Some("velocity")));
    assert_eq!(s["datasets"][1]["user"], false);
    assert_eq!(d["transfer_function"], "glow");
    let report = std::fs::read_to_string(out_dir.join("report.md")).unwrap();
    assert!(report.contains(&format!("| my_mesh-velocity | {vector} (your file) | tet-mesh | velocity | glow | --tf {} |", tf.display())), "{report}");
    assert!(report.contains(&format!("| post-small | post-small | tet-mesh | Pressure | glow | --tf {} |", tf.display())), "{report}");
}

#[test]
fn bad_data_is_a_clear_error_before_the_suite_starts() {
    let tmp = tempfile::tempdir().unwrap();
    let (vtu, _) = fixtures(tmp.path());
    let bad = tmp.path().join("broken.vtu");
    std::fs::write(&bad, b"<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece NumberOfPoints=\"4\"").unwrap();
    let missing = tmp.path().join("missing.vtu");
    let no_array = format!("{}#pressure", vtu.display());
    let bad_tf = tmp.path().join("tf.json");
    std::fs::write(&bad_tf, b"{\"points\": []}").unwrap();
    let cases: Vec<(Vec<String>, Vec<String>)> = vec![
        (vec!["--data".into(), bad.display().to_string()], vec![bad.display().to_string(), "--data".into()]),
        (vec!["--data".into(), missing.display().to_string()], vec![missing.display().to_string(), "no such file".into()]),
        (vec!["--data".into(), no_array.clone()], vec!["pressure".into(), "temp".into()]),
        (vec!["--data".into(), vtu.display().to_string(), "--data".into(), vtu.display().to_string()], vec!["twice".into()]),
        (vec!["--data".into(), vtu.display().to_string(), "--filter".into(), "post-small".into()], vec!["--filter post-small".into(), "my_mesh".into()]),
        (vec!["--data".into(), vtu.display().to_string(), "--tf".into(), bad_tf.display().to_string()], vec!["--tf".into(), bad_tf.display().to_string()]),
    ];
    for (args, needles) in cases {
        let out = volbench().args(["suite", "--quick"]).args(&args).arg("--out").arg(tmp.path().join("out")).output().unwrap();
        let t = text(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {t}");
        for n in &needles {
            assert!(t.contains(n.as_str()), "{args:?}: '{n}' not in: {t}");
        }
        assert!(!t.contains("suite: ["), "{args:?}: nothing ran: {t}");
        assert!(!tmp.path().join("out").exists(), "{args:?}: no output written");
    }
}
