//! `volbench scale` keeps what it measured: a later level that fails (its
//! mesh does not fit the file-size limit, as on a full disk) or a stop
//! signal leaves the complete results of the levels before it and none of
//! the interrupted level's files; a study that would not fit is refused
//! with the figures before anything is made.

use std::io::BufRead as _;
use std::path::Path;
use std::process::{Command, Stdio};

use serde_json::Value;

const EXE: &str = env!("CARGO_BIN_EXE_volbench");

/// The cheapest study: post-small (8,750 tets; 70,000 at level 1),
/// tet-raycast at 32x32, one frame, no reference.
fn scale_args(out: &Path, levels: usize) -> Vec<String> {
    let mut a: Vec<String> = ["scale", "--data", "post-small", "--method", "tet-raycast", "--size", "32x32", "--frames", "1", "--warmup", "0", "--reference-max-cells", "0", "--levels"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    a.push(levels.to_string());
    a.push("--out".into());
    a.push(out.to_string_lossy().into_owned());
    a
}

/// Every file under `dir`, relative, sorted.
fn files(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else {
                out.push(p.strip_prefix(dir).unwrap().to_string_lossy().into_owned());
            }
        }
    }
    out.sort();
    out
}

/// The results of the finished levels are complete and nothing else of
/// the run is left: one mesh per finished level, no run JSON, no temporary.
fn assert_only_finished_levels(out: &Path) -> usize {
    let report: Value = serde_json::from_slice(&std::fs::read(out.join("scale.json")).unwrap()).unwrap();
    let levels = report["levels"].as_array().unwrap().len();
    assert!(levels >= 1);
    assert_eq!(report["rows"].as_array().unwrap().len(), levels, "one method, one row per level");
    assert!(report["rows"].as_array().unwrap().iter().all(|r| r["status"] == "ok"), "{report}");
    let csv = std::fs::read_to_string(out.join("scale.csv")).unwrap();
    assert_eq!(csv.lines().count(), levels + 1, "{csv}");
    let md = std::fs::read_to_string(out.join("scale.md")).unwrap();
    assert_eq!(md.lines().filter(|l| l.starts_with("| tet-raycast |")).count(), levels, "{md}");
    let mut expected: Vec<String> = (0..levels).map(|l| format!("meshes/post-small-L{l}.vtk")).collect();
    // `.volbench-lock`: the --out lock (fsio::lock_out_dir) stays, naming its last holder.
    expected.extend([".volbench-lock", "scale.csv", "scale.json", "scale.md", "scale_memory.png", "scale_memory.svg", "scale_time.png", "scale_time.svg"].map(String::from));
    expected.sort();
    assert_eq!(files(out), expected);
    levels
}

#[test]
fn a_later_level_that_cannot_be_written_keeps_the_finished_levels() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    // A file-size limit of 1 MB (SIGXFSZ ignored, so a write past it fails
    // with EFBIG as on a full disk): level 0's mesh (283 KB) fits, level
    // 1's (2.1 MB) does not.
    let script = "trap '' XFSZ; ulimit -f 1000; exec \"$0\" \"$@\"";
    let o = Command::new("bash").arg("-c").arg(script).arg(EXE).args(scale_args(&out, 1)).env("VOLBENCH_VALIDATION", "1").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("level 1 (scale.json, .csv and .md in") && err.contains("hold levels 0 to 0; its own files removed)"), "{err}");
    assert!(err.contains("post-small-L1.vtk"), "{err}");
    assert_eq!(assert_only_finished_levels(&out), 1);
}

#[test]
fn a_stop_signal_removes_the_interrupted_level_and_keeps_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    let mut child = Command::new(EXE).args(scale_args(&out, 2)).env("VOLBENCH_VALIDATION", "1").stderr(Stdio::piped()).stdout(Stdio::null()).spawn().unwrap();
    let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
    // Level 1's run has started: its mesh is written, its child runs.
    let mut seen = Vec::new();
    for line in lines.by_ref() {
        let line = line.unwrap();
        seen.push(line.clone());
        if line.contains("level 1 (70000 tets): tet-raycast") {
            break;
        }
    }
    assert!(seen.last().is_some_and(|l| l.contains("level 1 (")), "{seen:?}");
    assert!(Command::new("kill").arg("-TERM").arg(child.id().to_string()).status().unwrap().success());
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(128 + 15), "{rest:?}");
    assert!(rest.iter().any(|l| l.contains("stopped by signal 15")), "{rest:?}");
    // Level 0 at least; level 1 only if it finished before the signal came.
    let levels = assert_only_finished_levels(&out);
    assert!(levels <= 2, "{levels}");
}

#[test]
fn a_study_that_would_not_fit_is_refused_before_anything_is_made() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    // The oxygen post (513,375 tets) refined 4 times: 2.1 G tets.
    let mut args = scale_args(&out, 4);
    args[2] = "oxygenpost".into();
    let o = Command::new(EXE).args(&args).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("--levels 4: the study would not fit") && err.contains("at level 4 (2102784000 tets)"), "{err}");
    assert!(err.contains("GiB available (MemAvailable)") && err.contains("use fewer --levels"), "{err}");
    assert!(!out.exists(), "nothing made");
}
