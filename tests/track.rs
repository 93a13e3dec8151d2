//! `volbench compare BASELINE NEW`: benchmark tracking between two suite
//! summaries. A real quick suite on the small post is the baseline; the
//! "new" summaries are that one with one figure deliberately changed, and
//! each change must fail with a clear line naming the run and the figure.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use serde_json::Value;

fn volbench() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_volbench"));
    c.env("VOLBENCH_VALIDATION", "1");
    c
}

/// One quick suite run on `post-small` (vicp and balanced), shared by the tests.
fn baseline() -> &'static (tempfile::TempDir, Value) {
    static B: OnceLock<(tempfile::TempDir, Value)> = OnceLock::new();
    B.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let out = volbench().args(["suite", "--quick", "--filter", "post-small", "--out"]).arg(dir.path().join("run")).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let v: Value = serde_json::from_slice(&std::fs::read(dir.path().join("run/summary.json")).unwrap()).unwrap();
        (dir, v)
    })
}

fn write(dir: &Path, name: &str, v: &Value) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, serde_json::to_vec_pretty(v).unwrap()).unwrap();
    p
}

fn track(new: &Value, extra: &[&str]) -> (Output, String) {
    track_pair(&baseline().1, new, extra)
}

fn track_pair(base: &Value, new: &Value, extra: &[&str]) -> (Output, String) {
    let (dir, _) = baseline();
    let tmp = tempfile::tempdir_in(dir.path()).unwrap();
    let (b, n) = (write(tmp.path(), "base.json", base), write(tmp.path(), "new.json", new));
    let out = volbench().arg("compare").arg(&b).arg(&n).args(extra).output().unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    (out, text)
}

fn row<'a>(v: &'a mut Value, method: &str) -> &'a mut Value {
    v["runs"].as_array_mut().unwrap().iter_mut().find(|r| r["method"] == method).unwrap()
}

#[test]
fn an_unchanged_summary_passes() {
    let (out, text) = track(&baseline().1, &["--no-times"]);
    assert!(out.status.success(), "{text}");
    assert!(text.contains(" 0 regressions"), "{text}");
}

#[test]
fn a_changed_byte_count_fails_with_a_line_naming_it() {
    let mut v = baseline().1.clone();
    let r = &mut row(&mut v, "balanced")["result"]["upload"];
    let bpc = r["bytes_per_cell"].as_f64().unwrap();
    r["bytes_per_cell"] = (bpc + 4.0).into();
    let (out, text) = track(&v, &["--no-times"]);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains(&format!("| REGRESSION | post-small/balanced | upload.bytes_per_cell | {bpc} | {} |", bpc + 4.0)), "{text}");
    assert!(text.contains("1 regression against"), "{text}");
}

#[test]
fn a_changed_integrator_or_a_grown_error_fails() {
    let mut v = baseline().1.clone();
    let r = &mut row(&mut v, "vicp")["result"];
    let spec = r["spec"].as_str().unwrap().replace("integrator=ppi", "integrator=average");
    r["spec"] = spec.clone().into();
    let rmse = r["error"]["rmse"].as_f64().unwrap();
    r["error"]["rmse"] = (rmse * 3.0 + 1e-3).into();
    let (out, text) = track(&v, &["--no-times"]);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("| REGRESSION | post-small/vicp | spec |") && text.contains(&spec), "{text}");
    assert!(text.contains("| REGRESSION | post-small/vicp | error.rmse |"), "{text}");
    // A smaller error is an improvement, not a failure.
    let mut v = baseline().1.clone();
    row(&mut v, "vicp")["result"]["error"]["rmse"] = (rmse * 0.5).into();
    let (out, text) = track(&v, &["--no-times"]);
    assert!(out.status.success() && text.contains("| improved | post-small/vicp | error.rmse |"), "{text}");
}

#[test]
fn a_missing_or_failed_run_fails() {
    let mut v = baseline().1.clone();
    let r = row(&mut v, "balanced");
    r["status"] = "failed".into();
    r["message"] = "out of memory".into();
    r["result"] = Value::Null;
    v["runs"].as_array_mut().unwrap().retain(|r| r["method"] != "vicp");
    let (out, text) = track(&v, &["--no-times"]);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("| REGRESSION | post-small/vicp | row | ok | missing |"), "{text}");
    assert!(text.contains("| REGRESSION | post-small/balanced | status | ok | failed | out of memory |"), "{text}");
}

#[test]
fn a_moved_time_ratio_fails_only_in_one_sitting_or_when_asked() {
    let mut v = baseline().1.clone();
    assert!(v["environment"]["machine_boot_id"].as_str().is_some_and(|m| m.len() == 32), "the suite records its machine and boot");
    let samples = &mut row(&mut v, "balanced")["result"]["time_ms"]["samples"]["frame"];
    *samples = samples.as_array().unwrap().iter().map(|t| Value::from(t.as_f64().unwrap() * 5.0)).collect();
    // Another machine (or the same one another day): a note, exit 0;
    // `--times` makes it a failure.
    for (field, other) in [("machine_boot_id", "0123456789abcdef0123456789abcdef"), ("started_utc", "20200101T000000Z")] {
        let mut elsewhere = v.clone();
        elsewhere["environment"][field] = other.into();
        let (out, text) = track(&elsewhere, &[]);
        assert!(out.status.success(), "{text}");
        assert!(text.lines().any(|l| l.starts_with("| note | post-small/balanced ÷ post-small/") && l.contains("a note: not the same machine and sitting")), "{text}");
        assert!(text.contains("| note | environment | times |") && text.contains(" 0 regressions"), "{text}");
        let (out, text) = track(&elsewhere, &["--times"]);
        assert_eq!(out.status.code(), Some(1), "{text}");
    }
    // The same machine and sitting (the same suite's environment): a failure.
    let (out, text) = track(&v, &[]);
    assert_eq!(out.status.code(), Some(1), "{text}");
    // Each run's ratio is to the dataset's first run by name.
    assert!(text.lines().any(|l| l.starts_with("| REGRESSION | post-small/balanced ÷ post-small/") && l.contains("| frame-time ratio |")), "{text}");
    // Absolute times only when asked for.
    assert!(!text.contains("time_ms.frame (same device)"), "{text}");
    let (_, text) = track(&v, &["--absolute-times"]);
    assert!(text.contains("| REGRESSION | post-small/balanced | time_ms.frame (same device) |"), "{text}");
    let (out, text) = track(&v, &["--no-times"]);
    assert!(out.status.success(), "{text}");
}

#[test]
fn another_device_tolerates_arithmetic_counts_but_not_bytes() {
    let mut v = baseline().1.clone();
    v["environment"]["cpu_model"] = "another CPU".into();
    let stats = &mut row(&mut v, "vicp")["result"]["stats"];
    let f = stats["fragment_invocations"].as_u64().unwrap();
    stats["fragment_invocations"] = (f + f / 5000).into();
    let (out, text) = track(&v, &[]);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("| note | environment | device |"), "{text}");
    row(&mut v, "vicp")["result"]["upload"]["static_bytes"] = 1.into();
    let (out, text) = track(&v, &[]);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("| REGRESSION | post-small/vicp | upload.static_bytes |"), "{text}");
}

#[test]
fn different_settings_or_bad_files_are_clear_errors() {
    let mut v = baseline().1.clone();
    v["settings"]["width"] = 512.into();
    let (out, text) = track(&v, &[]);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("different settings"), "{text}");
    let (out, text) = track(&serde_json::json!([1, 2]), &[]);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("new.json: not a volbench suite summary.json"), "{text}");
}

#[test]
fn bmf_and_gha_exports_have_the_documented_shape() {
    let (dir, _) = baseline();
    let tmp = tempfile::tempdir_in(dir.path()).unwrap();
    let (bmf, gha) = (tmp.path().join("bmf.json"), tmp.path().join("gha.json"));
    let (out, text) = track(&baseline().1, &["--no-times", "--bmf", bmf.to_str().unwrap(), "--gha", gha.to_str().unwrap()]);
    assert!(out.status.success(), "{text}");
    let b: Value = serde_json::from_slice(&std::fs::read(&bmf).unwrap()).unwrap();
    common::assert_matches_schema("bmf.schema.json", &b, "the BMF export");
    let lat = &b["post-small/balanced"]["latency"];
    assert!(lat["lower_value"].as_f64().unwrap() <= lat["value"].as_f64().unwrap());
    assert!(lat["value"].as_f64().unwrap() <= lat["upper_value"].as_f64().unwrap());
    assert_eq!(b["post-small/vicp"]["bytes-per-cell"]["value"], 528.0, "132 floats per tet");
    assert_eq!(b["post-small/balanced"]["bytes-per-cell"]["value"], 112.0, "28 floats per tet");
    let g: Value = serde_json::from_slice(&std::fs::read(&gha).unwrap()).unwrap();
    common::assert_matches_schema("gha.schema.json", &g, "the github-action-benchmark export");
    assert!(g.as_array().unwrap().iter().any(|e| e["name"] == "post-small/vicp latency" && e["unit"] == "ms"));
    // The same path twice is an error, and nothing is written.
    let same = tmp.path().join("same.json");
    let (out, text) = track(&baseline().1, &["--bmf", same.to_str().unwrap(), "--gha", same.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(!same.exists());
}

/// The baseline with a counted section in every row: `device` and `sort`
/// instructions over 2 frames.
fn counted(device: u64, sort: u64) -> Value {
    let mut v = baseline().1.clone();
    v["settings"]["counted"] = true.into();
    for r in v["runs"].as_array_mut().unwrap() {
        r["result"]["count"] = serde_json::json!({
            "frames": 2,
            "phases": { "device": { "total": device, "per_frame": [device / 2, device / 2] },
                        "sort": { "total": sort, "per_frame": [sort / 2, sort / 2] } },
            "frame": { "total": device + sort, "per_frame": [(device + sort) / 2, (device + sort) / 2] },
        });
    }
    v
}

#[test]
fn instruction_counts_are_compared_per_phase_within_one_percent() {
    let base = counted(100_000_000, 4_000_000);
    // 0.5 % more in one phase: within the tolerance.
    let (out, text) = track_pair(&base, &counted(100_500_000, 4_000_000), &["--no-times"]);
    assert!(out.status.success(), "{text}");
    // 5 % more device work: a regression naming the run, the phase and the change.
    let (out, text) = track_pair(&base, &counted(105_000_000, 4_000_000), &["--no-times"]);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(
        text.contains("| REGRESSION | post-small/balanced | instructions.device (per frame) | 50000000 | 52500000 | +2500000 instructions (+5.00 %), beyond the tolerance (max(1 %, 10000 instructions)) |"),
        "{text}"
    );
    // A counted baseline against an uncounted summary: different settings.
    let (out, text) = track_pair(&base, &baseline().1, &["--no-times"]);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("different settings"), "{text}");
    // --bmf exports the counts as their own measures.
    let tmp = tempfile::tempdir_in(baseline().0.path()).unwrap();
    let bmf = tmp.path().join("bmf.json");
    let (out, text) = track_pair(&base, &base, &["--no-times", "--bmf", bmf.to_str().unwrap()]);
    assert!(out.status.success(), "{text}");
    let b: Value = serde_json::from_slice(&std::fs::read(&bmf).unwrap()).unwrap();
    common::assert_matches_schema("bmf.schema.json", &b, "the BMF export");
    assert_eq!(b["post-small/balanced"]["instructions-device"]["value"], 50_000_000.0);
    assert_eq!(b["post-small/balanced"]["instructions-frame"]["value"], 52_000_000.0);
}
