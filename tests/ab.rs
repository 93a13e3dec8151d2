//! `volbench ab` end to end: bad input is a clear error before anything
//! runs, a binary against itself on a tiny case writes the documented
//! table and JSON (per frame and per run), the serve protocol answers,
//! refuses and stops, a server that stops answering is killed, and a binary
//! without serve mode falls back to per-run alternation. Nothing here
//! depends on timing: the verdict may be any of the four, and the exit code
//! must agree with it.

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Command, Stdio};

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
        (vec!["--pairs", "4", "--processes", "5"], "--processes"),
        (vec!["--processes", "1"], "--processes"),
        (vec!["--threshold", "0"], "--threshold"),
        (vec!["--filter", "nope"], "--filter nope"),
        (vec!["--spec", "balanced:nope=1"], "--spec"),
        (vec!["--base-env", "NOEQUALS"], "--base-env NOEQUALS: expected VAR=VALUE"),
        (vec!["--new-env", "=1"], "--new-env =1"),
        (vec!["--new-env", "A=1", "--new-env", "A=2"], "--new-env: A given twice"),
    ] {
        let out = volbench().args(["ab", exe, exe]).args(&args).output().unwrap();
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

/// `ab EXE EXE` on balanced/post-small at 32x32, 3 pairs (per frame: over 3
/// rounds of fresh processes), plus `extra`:
/// the report JSON, stdout, stderr and whether it succeeded; checks what
/// every such run must hold.
fn self_ab(base: &str, new: &str, extra: &[&str]) -> (serde_json::Value, String, String, bool) {
    let dir = tempfile::tempdir().unwrap();
    let out = volbench()
        .args(["ab", base, new, "--filter", "balanced", "--pairs", "3", "--processes", "3", "--size", "32x32", "--frames", "2", "--warmup", "0", "--seed", "5"])
        .args(extra)
        .arg("--out")
        .arg(dir.path())
        .env("VOLBENCH_VALIDATION", "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("ab.json")).unwrap()).unwrap();
    assert_eq!(v["schema"], "volbench-ab/2");
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
    assert!(stdout.contains("| post-small | balanced | ") && stdout.contains("95 % interval"), "{stdout}");
    assert_eq!(std::fs::read_to_string(dir.path().join("ab.md")).unwrap(), stdout);
    (v, stdout.into_owned(), stderr.into_owned(), out.status.success())
}

#[test]
fn a_binary_against_itself_writes_the_table_and_json() {
    let exe = env!("CARGO_BIN_EXE_volbench");
    let (v, stdout, _, _) = self_ab(exe, exe, &[]);
    assert_eq!(v["settings"]["mode"], "per-frame");
    let row = &v["rows"][0];
    assert_eq!(row["mode"], "per-frame");
    assert!(row["fallback"].is_null());
    // 3 pairs over 3 rounds of fresh processes: 3 round means.
    assert_eq!(row["estimate"]["batches"], 3);
    assert!(stdout.contains("| post-small | balanced | per frame | 3 | 3 |"), "{stdout}");
    let (v, stdout, _, _) = self_ab(exe, exe, &["--per-run"]);
    assert_eq!((v["settings"]["mode"].as_str(), v["rows"][0]["mode"].as_str()), (Some("per-run"), Some("per-run")));
    assert_eq!(v["rows"][0]["estimate"]["batches"], 3);
    assert!(stdout.contains("| post-small | balanced | per run | 3 | 3 |"), "{stdout}");
}

/// An executable shell script `name` in `dir` with `body`.
fn script(dir: &Path, name: &str, body: &str) -> String {
    use std::os::unix::fs::PermissionsExt as _;
    let path = dir.join(name);
    std::fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    path.to_string_lossy().into_owned()
}

#[test]
fn an_old_binary_without_serve_mode_falls_back_to_per_run() {
    let exe = env!("CARGO_BIN_EXE_volbench");
    let dir = tempfile::tempdir().unwrap();
    // Refuses --serve as clap does for an unknown flag (the flag named on the
    // first of several lines); anything else is volbench.
    let old = script(
        dir.path(),
        "old",
        &format!(
            "for a in \"$@\"; do [ \"$a\" = --serve ] && {{ printf \"error: unexpected argument '--serve' found\\n\\n  tip: a similar argument exists: '--device'\\n\\nUsage: volbench run --data <NAME|PATH>\\n\\nFor more information, try '--help'.\\n\" >&2; exit 2; }}; done\nexec {exe} \"$@\""
        ),
    );
    let (v, stdout, stderr, _) = self_ab(&old, exe, &[]);
    let row = &v["rows"][0];
    assert_eq!(row["mode"], "per-run", "{row}");
    assert!(row["fallback"].as_str().unwrap().contains("has no serve mode"), "{row}");
    assert!(stderr.contains("falling back to per-run alternation"), "{stderr}");
    assert!(stdout.contains("per run (fallback: no serve mode)"), "{stdout}");
    assert_eq!(row["estimate"]["batches"], 3);
    // One that speaks another protocol version falls back too.
    let other = script(
        dir.path(),
        "other",
        &format!("case \"$*\" in *--serve*) echo '{{\"protocol\":\"volbench-serve/99\",\"version\":\"\",\"git_sha\":\"\",\"spec\":\"\",\"dataset\":\"\"}}'; exit 0;; esac\nexec {exe} \"$@\""),
    );
    let (v, _, stderr, _) = self_ab(exe, &other, &[]);
    assert!(v["rows"][0]["fallback"].as_str().unwrap().contains("volbench-serve/99"), "{stderr}");
}

#[test]
fn a_server_that_stops_answering_is_killed_with_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    // Says it is volbench, then never answers (its child keeps stdout open:
    // only killing the process group ends the wait for it).
    let mute = script(dir.path(), "mute", "[ \"$1\" = --version ] && { echo 'volbench 0.1.0'; exit 0; }\nsleep 300 & wait");
    let exe = env!("CARGO_BIN_EXE_volbench");
    let start = std::time::Instant::now();
    let out = volbench().args(["ab", exe, &mute, "--filter", "balanced", "--pairs", "2", "--processes", "2", "--size", "32x32", "--warmup", "0", "--timeout", "2"]).output().unwrap();
    assert!(start.elapsed().as_secs() < 120, "{:?}", start.elapsed());
    assert_eq!(out.status.code(), Some(1));
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("no answer to its handshake within 2 s (--timeout); killed its process group"), "{stdout}");
    assert!(stderr.contains("1 of 1 benchmarks failed"), "{stderr}");
}

#[test]
fn a_serve_process_answers_refuses_bad_commands_and_exits_on_eof() {
    let mut child = volbench()
        .args(["run", "--data", "post-small", "--method", "balanced", "--size", "32x32", "--warmup", "1", "--serve"])
        .env("VOLBENCH_VALIDATION", "1")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut next = || -> serde_json::Value { serde_json::from_str(&lines.next().unwrap().unwrap()).unwrap() };
    let hello = next();
    assert_eq!(hello["protocol"], "volbench-serve/1");
    assert!(hello["version"].as_str().unwrap().starts_with("volbench "));
    assert_eq!(hello["dataset"], "post-small");
    assert!(hello["spec"].as_str().unwrap().starts_with("balanced:"));
    let mut ask = |line: &str| writeln!(stdin, "{line}").and_then(|()| stdin.flush()).unwrap();
    ask("frame 3");
    let frames = next();
    assert_eq!(frames["frame_ms"].as_array().unwrap().len(), 3);
    assert_eq!(frames["gpu_ms"].as_array().unwrap().len(), 3);
    assert!(frames["frame_ms"].as_array().unwrap().iter().all(|t| t.as_f64().unwrap() > 0.0));
    for bad in ["render 2", "frame 0", "frame x"] {
        ask(bad);
        assert!(next()["error"].is_string(), "{bad}");
    }
    ask("frame 1");
    assert_eq!(next()["frame_ms"].as_array().unwrap().len(), 1);
    drop(stdin);
    let status = child.wait().unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert!(status.success(), "{status}: {err}");
    assert!(err.trim().is_empty(), "{err}");
    // Serve mode writes nothing but its answers: no outputs beside it.
    let out = volbench().args(["run", "--data", "post-small", "--method", "balanced", "--serve", "--json", "x.json"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
}

/// `--new-env` reaches NEW's processes and not BASE's: pointing NEW's
/// VOLBENCH_DATA at an empty directory fails NEW alone, in both modes, and
/// the report records each side's environment (BASE's a test switch that
/// balanced does not use: an unknown `VOLBENCH_TEST_*` name is refused).
#[test]
fn a_per_side_environment_reaches_that_side_only() {
    let exe = env!("CARGO_BIN_EXE_volbench");
    let empty = tempfile::tempdir().unwrap();
    let data = format!("VOLBENCH_DATA={}", empty.path().display());
    for mode in [&[][..], &["--per-run"][..]] {
        let dir = tempfile::tempdir().unwrap();
        let out = volbench()
            .args(["ab", exe, exe, "--spec", "balanced", "--filter", "post-small", "--pairs", "2", "--processes", "2", "--size", "32x32", "--warmup", "0"])
            .args(["--base-env", "VOLBENCH_TEST_RESIDENT_BATCH=4096", "--new-env", &data])
            .args(mode)
            .arg("--out")
            .arg(dir.path())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{mode:?}: {stderr}");
        assert!(stderr.contains("benchmarks failed"), "{mode:?}: {stderr}");
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("ab.json")).unwrap()).unwrap();
        assert_eq!(v["base"]["env"]["VOLBENCH_TEST_RESIDENT_BATCH"], "4096", "{v}");
        assert_eq!(v["new"]["env"]["VOLBENCH_DATA"], empty.path().display().to_string(), "{v}");
        let error = v["rows"][0]["error"].as_str().unwrap_or_default();
        // The data directory named in the failure is NEW's alone.
        assert!(error.contains("post-small") && error.contains(&empty.path().display().to_string()), "{mode:?}: {error}");
        let md = std::fs::read_to_string(dir.path().join("ab.md")).unwrap();
        assert!(md.contains("VOLBENCH_TEST_RESIDENT_BATCH=4096") && md.contains(&data), "{md}");
    }
}
