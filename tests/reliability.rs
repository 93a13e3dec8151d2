//! What an outside red team broke, one regression per class (issue 8): no
//! output path replaced or left behind, all-or-nothing outputs, no hang, sizes
//! checked first, no blank picture with exit 0, nothing read back trusted,
//! messages that name the option or file. Every run here is small and
//! bounded; a hang would fail the test through `run_bounded`.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn volbench() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_volbench"));
    c.stdin(Stdio::null());
    c
}

/// Run with a 60 s bound: a hang is a failure, not a stuck test.
fn run_bounded(cmd: &mut Command) -> Output {
    let mut child = cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return child.wait_with_output().unwrap();
        }
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("volbench did not finish within 60 s: {cmd:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Exit 1 (an error, not a panic's 101), with every needle in the message.
fn assert_error(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "missing '{n}' in: {err}");
    }
}

fn small_run(dir: &Path) -> Command {
    let mut c = volbench();
    c.args(["run", "--data", "post-small", "--method", "balanced", "--size", "32x32", "--frames", "1", "--warmup", "0"]);
    c.env("VOLBENCH_CACHE", dir.join("cache"));
    c
}

fn names_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

#[test]
fn outputs_never_replace_special_files_and_leave_nothing_behind() {
    let d = tempfile::tempdir().unwrap();
    // /dev/null is written through, not replaced by a regular file.
    let o = run_bounded(small_run(d.path()).args(["--json", "/dev/null"]));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!std::fs::metadata("/dev/null").unwrap().is_file());
    // A directory or a trailing slash as an output: a clear error, nothing left.
    let out = d.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let o = run_bounded(small_run(d.path()).arg("--png").arg(&out));
    assert_error(&o, &["--png", "directory"]);
    let o = run_bounded(small_run(d.path()).arg("--png").arg(format!("{}/", out.join("x").display())));
    assert_error(&o, &["--png"]);
    assert!(names_in(&out).is_empty(), "{:?}", names_in(&out));
    // Two outputs on one path: refused before anything runs.
    let same = out.join("r.png");
    let o = run_bounded(small_run(d.path()).arg("--png").arg(&same).arg("--diff-png").arg(&same));
    assert_error(&o, &["--diff-png", "same file"]);
    assert!(names_in(&out).is_empty());
    // All or nothing: a JSON that cannot be written means no PNG either.
    let o = run_bounded(small_run(d.path()).arg("--png").arg(out.join("a.png")).arg("--json").arg(out.join("missing/a.json")));
    assert_error(&o, &["a.json"]);
    assert!(names_in(&out).is_empty(), "{:?}", names_in(&out));
}

#[test]
fn json_to_stdout() {
    let d = tempfile::tempdir().unwrap();
    let o = run_bounded(small_run(d.path()).args(["--json", "-"]));
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is the JSON alone");
    assert_eq!(v["method"], "balanced");
}

#[test]
fn sizes_are_checked_before_anything_is_allocated() {
    let d = tempfile::tempdir().unwrap();
    let o = run_bounded(volbench().args(["run", "--data", "post-small", "--method", "vicp", "--frames", "18446744073709551615"]));
    assert_error(&o, &["--frames"]);
    let o = run_bounded(volbench().args(["run", "--data", "post-small", "--method", "vicp", "--frames", "1", "--warmup", "18446744073709551615"]));
    assert_error(&o, &["--warmup"]);
    let o = run_bounded(small_run(d.path()).args(["--integrator", "preint", "--table-size", "2048"]));
    assert_error(&o, &["--table-size", "2048", "bytes"]);
    for size in ["16386", "4294967294"] {
        let o = run_bounded(volbench().args(["stress", "--size", size]));
        assert_error(&o, &["--size"]);
    }
    // Larger than one allocation of the device (16384^2 RGBA32F = 4 GiB):
    // refused before the target or the CPU reference is made.
    let o = run_bounded(volbench().args(["run", "--data", "post-small", "--method", "vicp", "--size", "16384x16384", "--reference"]));
    assert_error(&o, &["--size", "16384x16384"]);
}

#[test]
fn special_input_files_are_refused_before_reading() {
    let d = tempfile::tempdir().unwrap();
    let fifo = d.path().join("mesh.vtk");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let o = run_bounded(volbench().args(["run", "--method", "vicp", "--data"]).arg(&fifo));
    assert_error(&o, &["mesh.vtk", "not a regular file"]);
    let o = run_bounded(small_run(d.path()).args(["--tf", "/dev/zero"]));
    assert_error(&o, &["/dev/zero", "not a regular file"]);
    // A 2 GiB sparse file is refused from its size, not read.
    let big = d.path().join("big.vtk");
    std::fs::File::create(&big).unwrap().set_len(2 << 30).unwrap();
    let o = run_bounded(volbench().args(["run", "--method", "vicp", "--data"]).arg(&big));
    assert_error(&o, &["big.vtk", "larger than"]);
}

#[test]
fn a_file_named_like_a_shipped_mesh_is_not_shown_with_its_preset() {
    let d = tempfile::tempdir().unwrap();
    let copy = d.path().join("bluntfin.vtk");
    std::fs::copy(concat!(env!("CARGO_MANIFEST_DIR"), "/data/unstructured/post_tets_vtkdata.vtk"), &copy).unwrap();
    let o = run_bounded(
        volbench().args(["run", "--method", "balanced", "--size", "32x32", "--frames", "1", "--json", "-", "--data"]).arg(&copy),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_ne!(v["transfer_function"], "bluntfin-default");
}

#[test]
fn a_corrupted_reference_cache_entry_is_recomputed_and_reported() {
    let d = tempfile::tempdir().unwrap();
    let json = |o: &Output| -> serde_json::Value { serde_json::from_slice(&o.stdout).unwrap() };
    let first = run_bounded(small_run(d.path()).args(["--reference", "--json", "-"]));
    assert!(first.status.success(), "{}", stderr(&first));
    let cache = d.path().join("cache");
    let entry = std::fs::read_dir(&cache).unwrap().next().unwrap().unwrap().path();
    // Flip bits in the pixels without changing the length.
    let mut bytes = std::fs::read(&entry).unwrap();
    let n = bytes.len();
    for b in &mut bytes[n - 4096..] {
        *b ^= 0x5a;
    }
    std::fs::write(&entry, &bytes).unwrap();
    let second = run_bounded(small_run(d.path()).args(["--reference", "--json", "-"]));
    assert!(second.status.success(), "{}", stderr(&second));
    let (a, b) = (json(&first), json(&second));
    assert!(b["error"]["reference_recomputed"].as_str().unwrap().contains("checksum"), "{}", b["error"]);
    assert_eq!(a["error"]["rmse"], b["error"]["rmse"]);
    // And the rewritten entry is trusted again.
    let third = run_bounded(small_run(d.path()).args(["--reference", "--json", "-"]));
    assert_eq!(json(&third)["error"]["reference_cached"], true);
}

#[test]
fn a_sweep_with_a_failing_row_completes_reports_it_and_exits_non_zero() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("cmp");
    let o = run_bounded(
        volbench()
            .args(["compare", "--data", "post-small", "--size", "32x32", "--frames", "1", "--warmup", "0"])
            .args(["--method", "balanced:integrator=preint,table_size=4096", "--method", "vicp"])
            .arg("--out")
            .arg(&out)
            .env("VOLBENCH_CACHE", d.path().join("cache")),
    );
    assert_error(&o, &["1 of 2 runs failed"]);
    let table = std::fs::read_to_string(out.join("comparison.md")).unwrap();
    assert!(table.contains("FAILED") && table.contains("table-size"), "{table}");
    assert!(out.join("post-small-vicp.json").is_file(), "{:?}", names_in(&out));
}

#[test]
fn options_a_method_does_not_have_are_errors() {
    let o = run_bounded(volbench().args(["run", "--data", "post-small", "--method", "balanced:integrater=ppi"]));
    assert_error(&o, &["balanced", "integrater"]);
    let o = run_bounded(volbench().args(["pareto", "--data", "post-small", "--integrator", "bogus"]));
    assert_error(&o, &["integrator", "bogus"]);
}

#[test]
fn second_red_team_pass() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("o");
    std::fs::create_dir(&out).unwrap();
    // A FIFO output is refused up front (it would block without a reader).
    let fifo = out.join("f.json");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let o = run_bounded(small_run(d.path()).arg("--png").arg(out.join("a.png")).arg("--json").arg(&fifo));
    assert_error(&o, &["f.json", "FIFO"]);
    // `name/.` names a directory.
    let o = run_bounded(small_run(d.path()).arg("--json").arg(out.join("x.json/.")));
    assert_error(&o, &["x.json/.", "directory"]);
    // A device that fails is written before anything is renamed: no PNG.
    let o = run_bounded(small_run(d.path()).arg("--png").arg(out.join("b.png")).args(["--json", "/dev/full"]));
    assert_error(&o, &["/dev/full"]);
    let names = names_in(&out);
    assert_eq!(names, ["f.json"], "nothing written, no temporary file: {names:?}");
    // A key given twice in one spec.
    let o = run_bounded(volbench().args(["run", "--data", "post-small", "--method", "balanced:integrator=ppi,integrator=preint"]));
    assert_error(&o, &["integrator", "twice"]);
    // An attenuation that underflows what f32 opacity resolves.
    let tf = d.path().join("faint.json");
    std::fs::write(&tf, r#"{"points": [{"scalar": 0, "color": [1, 1, 1], "attenuation": 1e-300}]}"#).unwrap();
    let o = run_bounded(small_run(d.path()).arg("--tf").arg(&tf));
    assert_error(&o, &["faint.json", "visible"]);
    // --out that is a regular file: named, before anything runs.
    let file = d.path().join("afile");
    std::fs::write(&file, b"x").unwrap();
    let o = run_bounded(volbench().args(["compare", "--data", "post-small", "--method", "vicp", "--out"]).arg(&file));
    assert_error(&o, &["afile", "not a directory"]);
    // A huge bad token is quoted short.
    let mut bytes = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/data/unstructured/post_tets_vtkdata.vtk")).unwrap();
    bytes.extend(std::iter::repeat_n(b'X', 200_000));
    let big = d.path().join("trail.vtk");
    std::fs::write(&big, &bytes).unwrap();
    let o = run_bounded(volbench().args(["run", "--method", "vicp", "--data"]).arg(&big));
    assert_error(&o, &["trail.vtk"]);
    assert!(stderr(&o).len() < 2000, "{} bytes of message", stderr(&o).len());
}
