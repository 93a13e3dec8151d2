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

/// A method spec with options, as the suite names its adaptive-refinement
/// runs (`tet-raycast:adaptive=0.008`, issue 37), is a benchmark of its own:
/// both ray casters with the option, each under its label.
#[test]
fn adaptive_refinement_specs_are_benchmarks() {
    let exe = env!("CARGO_BIN_EXE_volbench");
    let dir = tempfile::tempdir().unwrap();
    let out = volbench()
        .args(["ab", exe, exe, "--spec", "tet-raycast:adaptive=0.008", "--spec", "raycast-compute:adaptive=0.016"])
        .args(["--filter", "post-small", "--filter", "hydrogen", "--pairs", "2", "--processes", "2", "--size", "32x32", "--frames", "1", "--warmup", "0"])
        .arg("--out")
        .arg(dir.path())
        .env("VOLBENCH_VALIDATION", "1")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("ab.json")).unwrap()).unwrap();
    let rows: Vec<(&str, &str)> = v["rows"].as_array().unwrap().iter().map(|r| (r["dataset"].as_str().unwrap(), r["label"].as_str().unwrap())).collect();
    assert_eq!(rows, [("post-small", "tet-raycast:adaptive=0.008"), ("hydrogen", "raycast-compute:adaptive=0.016")], "{v}");
    for r in v["rows"].as_array().unwrap() {
        assert!(r["error"].is_null(), "{r}");
        assert_eq!(r["samples"].as_array().unwrap().len(), 2, "{r}");
    }
}

/// A fake volbench in sh, fast and GPU-free: `--version`; `run … --serve`
/// speaks the serve protocol (every frame 1 ms; with `AB_TEST_PIDS` set it
/// first starts a `sleep` that outlives it and appends its pid there);
/// `run … --json F` writes a run JSON of two 1 ms frames to F.
const FAKE: &str = r#"case "$1" in --version) echo 'volbench 0.1.0'; exit 0;; esac
case "$*" in *--serve*)
  if [ -n "$AB_TEST_PIDS" ]; then sleep 300 >/dev/null 2>&1 </dev/null & echo $! >> "$AB_TEST_PIDS"; fi
  echo '{"protocol":"volbench-serve/1","version":"volbench 0.1.0","git_sha":"x","spec":"balanced","dataset":"post-small"}'
  while read cmd n; do case "$cmd" in frame) echo '{"frame_ms":[1.0],"gpu_ms":[1.0]}';; quit) exit 0;; esac; done
  exit 0;;
esac
json=
while [ $# -gt 0 ]; do [ "$1" = --json ] && json=$2; shift; done
echo '{"time_ms":{"samples":{"frame":[1.0,1.0]}}}' > "$json""#;

/// `volbench ab BASE NEW` with 2 pairs over 2 rounds at 32x32 and `extra`,
/// in `cwd` with `env` added, its address space limited to 256 MiB (it
/// needs far less; a child's output held whole would exhaust it): exit code, stdout,
/// stderr, wall time.
fn small_ab(base: &str, new: &str, extra: &[&str], cwd: &Path, env: &[(&str, &str)]) -> (Option<i32>, String, String, std::time::Duration) {
    let start = std::time::Instant::now();
    let out = Command::new("sh")
        .args(["-c", "ulimit -v 262144 && exec \"$0\" \"$@\"", env!("CARGO_BIN_EXE_volbench"), "ab", base, new])
        .args(["--filter", "balanced", "--pairs", "2", "--processes", "2", "--size", "32x32", "--warmup", "0", "--seed", "3"])
        .args(extra)
        .current_dir(cwd)
        .envs(env.iter().copied())
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned());
    assert!(!stderr.contains("panicked") && !stderr.contains("memory allocation"), "{stderr}");
    (out.status.code(), stdout, stderr, start.elapsed())
}

#[test]
fn children_that_hang_are_killed_at_the_deadline() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fake = script(d, "fake", FAKE);
    // `--version` never returns (nor does the child it waits for).
    let hang = script(d, "hang", "sleep 300 & wait");
    let (code, _, stderr, took) = small_ab(&hang, &fake, &["--timeout", "1"], d, &[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("BASE") && stderr.contains("`--version`: still running after 1 s (--timeout); killed its process group"), "{stderr}");
    assert!(took.as_secs() < 30, "{took:?}");
    // A per-run run that never ends: the benchmark fails, ab goes on.
    let hang_run = script(d, "hang-run", "[ \"$1\" = --version ] && { echo 'volbench 0.1.0'; exit 0; }\nsleep 300 & wait");
    let (code, stdout, stderr, took) = small_ab(&fake, &hang_run, &["--per-run", "--timeout", "1"], d, &[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stdout.contains("hang-run run: still running after 1 s (--timeout); killed its process group"), "{stdout}");
    assert!(stderr.contains("1 of 1 benchmarks failed"), "{stderr}");
    assert!(took.as_secs() < 30, "{took:?}");
}

#[test]
fn children_that_print_without_end_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fake = script(d, "fake", FAKE);
    // A `--version` that prints forever: killed past 64 KiB.
    let spew = script(d, "spew", "exec yes 'volbench 0.1.0'");
    let (code, _, stderr, _) = small_ab(&fake, &spew, &[], d, &[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("NEW") && stderr.contains("`--version`: printed more than 65536 bytes; killed its process group"), "{stderr}");
    // A per-run run that prints forever: stopped at the deadline, in
    // bounded memory.
    let spew_run = script(d, "spew-run", "[ \"$1\" = --version ] && { echo 'volbench 0.1.0'; exit 0; }\nexec yes");
    let (code, stdout, stderr, _) = small_ab(&fake, &spew_run, &["--per-run", "--timeout", "2"], d, &[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stdout.contains("spew-run run: still running after 2 s (--timeout)"), "{stdout}");
    // 300 MB of output from a run that succeeds: kept head and tail only.
    let chatty = script(d, "chatty", &format!("[ \"$1\" = run ] && head -c 300000000 /dev/zero\n{FAKE}"));
    let (code, stdout, stderr, _) = small_ab(&fake, &chatty, &["--per-run"], d, &[]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stdout.contains("| post-small | balanced | per run | 2 |"), "{stdout}");
    // A server whose handshake is one endless line: refused past 1 MiB.
    let endless = script(d, "endless", &format!("case \"$*\" in *--serve*) exec cat /dev/zero;; esac\n{FAKE}"));
    let (code, stdout, stderr, _) = small_ab(&fake, &endless, &[], d, &[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stdout.contains("a line longer than 1048576 bytes"), "{stdout}");
}

/// Whether process `pid` is gone (a zombie nobody reaped counts as gone).
fn gone(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).map_or(true, |s| s.rsplit(')').next().is_some_and(|r| r.trim_start().starts_with('Z')))
}

#[test]
fn serve_grandchildren_do_not_outlive_quit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fake = script(d, "fake", FAKE);
    let pids = d.join("pids");
    let (code, stdout, stderr, _) = small_ab(&fake, &fake, &[], d, &[("AB_TEST_PIDS", pids.to_str().unwrap())]);
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    assert!(stdout.contains("| post-small | balanced | per frame | 2 |"), "{stdout}");
    let pids: Vec<u32> = std::fs::read_to_string(&pids).unwrap().lines().map(|l| l.trim().parse().unwrap()).collect();
    // Two rounds of a server per binary, each leaving a sleep behind.
    assert_eq!(pids.len(), 4, "{pids:?}");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
    while !pids.iter().all(|&p| gone(p)) && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let left: Vec<u32> = pids.iter().copied().filter(|&p| !gone(p)).collect();
    for &p in &left {
        let _ = Command::new("kill").arg(p.to_string()).status();
    }
    assert!(left.is_empty(), "serve grandchildren still running after ab: {left:?}");
}

#[test]
fn an_existing_relative_path_is_that_file_and_must_be_executable() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    script(d, "vb", FAKE);
    // Another `vb` first in PATH: `ab vb vb` must not run it.
    let bin = d.join("bin");
    std::fs::create_dir(&bin).unwrap();
    script(&bin, "vb", "echo 'volbench 9.9.9 from PATH'");
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let (code, stdout, stderr, _) = small_ab("vb", "vb", &["--out", "out"], d, &[("PATH", &path)]);
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("out/ab.json")).unwrap()).unwrap();
    assert_eq!(v["base"]["version"], "volbench 0.1.0", "{v}");
    assert_eq!(v["base"]["path"].as_str().unwrap(), d.canonicalize().unwrap().join("vb").to_str().unwrap());
    // A file without execute permission says so.
    std::fs::write(d.join("nx"), FAKE).unwrap();
    std::fs::set_permissions(d.join("nx"), std::fs::Permissions::from_mode(0o644)).unwrap();
    let (code, _, stderr, _) = small_ab("nx", "vb", &[], d, &[("PATH", &path)]);
    assert_eq!(code, Some(1));
    assert!(stderr.contains("BASE nx: not executable"), "{stderr}");
}

/// Symlinks at every name a scratch directory of the next `n` processes
/// could have had when it was named `prefix<pid>`, all to `victim`.
fn plant_links(tmp: &Path, prefix: &str, victim: &Path, n: u32) {
    let last: u32 = std::fs::read_to_string("/proc/sys/kernel/ns_last_pid").ok().and_then(|s| s.trim().parse().ok()).unwrap_or(1);
    for pid in last + 1..=last + n {
        std::os::unix::fs::symlink(victim, tmp.join(format!("{prefix}{pid}"))).unwrap();
    }
}

#[test]
fn scratch_directories_ignore_links_planted_in_tmpdir() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fake = script(d, "fake", FAKE);
    let (tmp, victim) = (d.join("tmp"), d.join("victim"));
    std::fs::create_dir(&tmp).unwrap();
    std::fs::create_dir(&victim).unwrap();
    plant_links(&tmp, "volbench-ab-", &victim, 400);
    let before = std::fs::read_dir(&tmp).unwrap().count();
    let (code, stdout, stderr, _) = small_ab(&fake, &fake, &["--per-run"], d, &[("TMPDIR", tmp.to_str().unwrap())]);
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    assert_eq!(std::fs::read_dir(&victim).unwrap().count(), 0, "written through a planted link");
    // Nothing left behind either: only the planted links.
    assert_eq!(std::fs::read_dir(&tmp).unwrap().count(), before);
}

#[test]
fn a_build_that_hangs_is_killed_with_its_jobs_at_the_build_deadline() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fake = script(d, "fake", FAKE);
    let pids = d.join("pids");
    // A `cargo` that starts a job (as cargo starts rustc) and never ends.
    let cargo = script(d, "cargo", &format!("sleep 300 & echo $! >> {0}\necho $$ >> {0}\nwait", pids.display()));
    let target = d.join("target");
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (code, _, stderr, took) = small_ab(
        "HEAD",
        &fake,
        &["--build-timeout", "2", "--target-dir", target.to_str().unwrap()],
        repo,
        &[("CARGO", cargo.as_str())],
    );
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("BASE HEAD: building revision")
            && stderr.contains("cargo build --release: still running after 2 s (--build-timeout); killed it and the processes it started"),
        "{stderr}"
    );
    assert!(took.as_secs() < 60, "{took:?}");
    let pids = std::fs::read_to_string(&pids).unwrap();
    assert_eq!(pids.split_whitespace().count(), 2, "{pids}");
    for pid in pids.split_whitespace() {
        assert!(gone(pid.parse().unwrap()), "process {pid} outlived the build deadline");
    }
    // The temporary worktree went with the build.
    let left: Vec<_> = std::fs::read_dir(target.join("ab")).unwrap().flatten().map(|e| e.file_name()).collect();
    assert!(left.is_empty(), "{left:?}");
}
