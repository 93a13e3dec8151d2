//! `volbench run --count`: the same small run counted several times under
//! callgrind gives every phase's instructions within 0.1 % (docs/tracking.md
//! has the five-run measurement). Needs valgrind (scripts/setup.sh installs
//! it); without it the test says so and passes.

mod common;

use std::process::Command;

use serde_json::Value;

/// Counted runs of the test; each takes some 10 s of CPU under callgrind.
const RUNS: usize = 3;
/// The repeatability every phase must hold.
const REL: f64 = 1e-3;
/// ...or this many instructions.
const FLOOR: f64 = 1000.0;

fn counted(dir: &std::path::Path, i: usize) -> Value {
    let json = dir.join(format!("run{i}.json"));
    let out = Command::new(env!("CARGO_BIN_EXE_volbench"))
        .args(["run", "--data", "post-small", "--method", "balanced", "--size", "32x32", "--frames", "2", "--warmup", "1", "--count", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap()
}

fn valgrind_missing() -> bool {
    if Command::new("valgrind").arg("--version").output().is_err() {
        eprintln!("SKIPPED: valgrind is not installed (scripts/setup.sh installs it); --count cannot be tested");
        return true;
    }
    false
}

#[test]
fn a_counted_run_repeats_within_a_thousandth_in_every_phase() {
    if valgrind_missing() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let runs: Vec<Value> = (0..RUNS).map(|i| counted(dir.path(), i)).collect();
    common::assert_matches_schema("run.schema.json", &runs[0], "a counted run");
    let first = runs[0]["count"].as_object().expect("a counted run has `count`");
    let phases = first["phases"].as_object().unwrap();
    // The runner's phases and balanced's own CPU phases, each with work.
    for p in ["sort", "pack", "upload", "record", "device"] {
        let total = phases.get(p).and_then(|v| v["total"].as_u64()).unwrap_or(0);
        assert!(total > 0, "phase {p} counted no instructions: {first:?}");
    }
    for (name, phase) in phases.iter().chain([(&"frame".to_string(), &first["frame"])]) {
        for (f, _) in phase["per_frame"].as_array().unwrap().iter().enumerate() {
            let v: Vec<f64> = runs
                .iter()
                .map(|r| {
                    let c = &r["count"];
                    let p = if name == "frame" { &c["frame"] } else { &c["phases"][name] };
                    p["per_frame"][f].as_f64().unwrap_or(0.0)
                })
                .collect();
            let (lo, hi) = v.iter().fold((f64::MAX, 0f64), |(a, b), &x| (a.min(x), b.max(x)));
            // Phases of a few thousand instructions (query results) jitter
            // by a few hundred: the floor.
            assert!(hi - lo <= (REL * hi).max(FLOOR), "phase {name}, frame {f}: counts {v:?} differ by more than {REL} relative");
        }
    }
}

#[test]
fn count_needs_a_warm_up_and_refuses_validation() {
    let out = Command::new(env!("CARGO_BIN_EXE_volbench"))
        .args(["run", "--data", "post-small", "--method", "balanced", "--warmup", "0", "--count"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    if !valgrind_missing() {
        assert!(!out.status.success() && err.contains("--warmup 1 or more"), "{err}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_volbench")).args(["--validation", "run", "--data", "post-small", "--method", "balanced", "--count"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--count with --validation"), "{err}");
}
