//! `volbench ab` end to end: bad input is a clear error before anything
//! runs, and a binary against itself on a tiny case writes the documented
//! table and JSON. Nothing here depends on timing: the verdict may be any
//! of the four, and the exit code must agree with it.

use std::process::Command;

fn volbench() -> Command {
    Command::new(env!("CARGO_BIN_EXE_volbench"))
}

#[test]
fn bad_binaries_and_revisions_are_clear_errors() {
    let exe = env!("CARGO_BIN_EXE_volbench");
    for (base, needle) in [
        ("/no/such/volbench", "neither an existing file nor a git revision"),
        ("no-such-revision-xyz", "neither an existing file nor a git revision"),
        ("/bin/true", "is not a volbench binary"),
        ("/", "is not a file"),
    ] {
        let out = volbench().args(["ab", base, exe, "--filter", "balanced"]).output().unwrap();
        assert_eq!(out.status.code(), Some(1), "{base}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("BASE") && err.contains(needle), "{base}: {err}");
    }
    for (args, needle) in [
        (vec!["--pairs", "1"], "--pairs"),
        (vec!["--threshold", "0"], "--threshold"),
        (vec!["--filter", "nope"], "--filter nope"),
        (vec!["--spec", "balanced:nope=1"], "--spec"),
    ] {
        let out = volbench().args(["ab", exe, exe]).args(&args).output().unwrap();
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

#[test]
fn a_binary_against_itself_writes_the_table_and_json() {
    let exe = env!("CARGO_BIN_EXE_volbench");
    let dir = tempfile::tempdir().unwrap();
    let out = volbench()
        .args(["ab", exe, exe, "--filter", "balanced", "--pairs", "3", "--size", "32x32", "--frames", "2", "--warmup", "0", "--seed", "5"])
        .arg("--out")
        .arg(dir.path())
        .env("VOLBENCH_VALIDATION", "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("ab.json")).unwrap()).unwrap();
    assert_eq!(v["schema"], "volbench-ab/1");
    assert_eq!(v["settings"]["pairs"], 3);
    assert_eq!(v["settings"]["seed"], 5);
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 1);
    let row = &rows[0];
    assert_eq!((row["dataset"].as_str(), row["label"].as_str()), (Some("post-small"), Some("balanced")));
    assert!(row["error"].is_null(), "{row}");
    let samples = row["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 3);
    assert!(samples.iter().all(|s| s["base_ms"].as_f64().unwrap() > 0.0 && s["new_ms"].as_f64().unwrap() > 0.0));
    let e = &row["estimate"];
    let (lo, ratio, hi) = (e["ci_low"].as_f64().unwrap(), e["ratio"].as_f64().unwrap(), e["ci_high"].as_f64().unwrap());
    assert!(lo <= ratio && ratio <= hi, "{e}");
    let verdict = row["verdict"].as_str().unwrap();
    assert!(["slower", "faster", "same", "undecided"].contains(&verdict), "{verdict}");
    // The exit code follows the verdict (a self-comparison can, rarely, read slower).
    assert_eq!(out.status.success(), verdict != "slower", "{verdict}: {stderr}");
    assert!(stdout.contains("| post-small | balanced | 3 |") && stdout.contains("95 % interval"), "{stdout}");
    assert_eq!(std::fs::read_to_string(dir.path().join("ab.md")).unwrap(), stdout);
}
