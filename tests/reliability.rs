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

// A sweep whose row fails mid-way completes, reports it and fails: see
// tests/registry.rs (`test-fails`); a table too large, which used to be
// such a row, is now refused up front
// (`sizes_and_output_paths_of_sweeps_are_checked_before_any_work`).

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

/// An n^3 grid of cubes (side `h`, from `origin`), five tets each (the
/// library's conforming split), as an ASCII legacy VTK file; `scalar` gives
/// each point's value from its position relative to `origin`.
fn write_grid_vtk(path: &Path, n: usize, h: f64, origin: [f64; 3], scalar: impl Fn([f64; 3]) -> f64) {
    // Point (i, j, k) is number i + (n+1) (j + (n+1) k), as the split expects.
    let mut points = Vec::new();
    let mut scalars = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let rel = [i as f64 * h, j as f64 * h, k as f64 * h];
                points.push([origin[0] + rel[0], origin[1] + rel[1], origin[2] + rel[2]]);
                scalars.push(scalar(rel));
            }
        }
    }
    let tets: Vec<[usize; 4]> = volbench::mesh::split::hex_grid_tet_indices([n + 1; 3])
        .unwrap()
        .into_iter()
        .map(|t| t.map(|v| v as usize))
        .collect();
    write_vtk(path, &points, &scalars, &tets);
}

fn write_vtk(path: &Path, points: &[[f64; 3]], scalars: &[f64], tets: &[[usize; 4]]) {
    use std::fmt::Write;
    let mut s = String::from("# vtk DataFile Version 3.0\ntest\nASCII\nDATASET UNSTRUCTURED_GRID\n");
    writeln!(s, "POINTS {} double", points.len()).unwrap();
    for p in points {
        writeln!(s, "{:e} {:e} {:e}", p[0], p[1], p[2]).unwrap();
    }
    writeln!(s, "CELLS {} {}", tets.len(), 5 * tets.len()).unwrap();
    for t in tets {
        writeln!(s, "4 {} {} {} {}", t[0], t[1], t[2], t[3]).unwrap();
    }
    writeln!(s, "CELL_TYPES {}", tets.len()).unwrap();
    for _ in tets {
        writeln!(s, "10").unwrap();
    }
    writeln!(s, "POINT_DATA {}\nSCALARS s double 1\nLOOKUP_TABLE default", points.len()).unwrap();
    for v in scalars {
        writeln!(s, "{v:e}").unwrap();
    }
    std::fs::write(path, s).unwrap();
}

/// `run --reference --json -` of `mesh` with extra arguments: the JSON.
fn run_json(dir: &Path, mesh: &Path, extra: &[&str]) -> serde_json::Value {
    let o = run_bounded(
        volbench()
            .args(["run", "--size", "48x48", "--frames", "1", "--warmup", "0", "--reference", "--json", "-", "--data"])
            .arg(mesh)
            .args(extra)
            .env("VOLBENCH_CACHE", dir.join("cache")),
    );
    assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn rmse(v: &serde_json::Value) -> f64 {
    v["error"]["rmse"].as_f64().unwrap_or_else(|| panic!("no rmse in {}", v["error"]))
}

/// The documented bound on every integrator's RMSE against the reference
/// with `exact` interpolation (results/HISTORY.md, "Run time against error: what the sweep shows").
const DOCUMENTED_RMSE: f64 = 2e-3;

#[test]
fn a_step_at_a_constant_fields_value_is_taken_alike_by_every_path() {
    // Class 9: a transfer function is right-continuous (the value after a
    // step applies at the step), in the GPU tables and in the reference. A
    // step up at the field's value renders exactly as the constant function
    // after the step (same error against the reference), a step down as the
    // transparent one: nothing to draw, which a run refuses as a blank image.
    let d = tempfile::tempdir().unwrap();
    let mesh = d.path().join("const.vtk");
    write_grid_vtk(&mesh, 3, 1.0 / 3.0, [0.0; 3], |_| 1.0);
    let point = |a: f64| format!(r#"{{"scalar": 1, "color": [1, 0.5, 0.2], "attenuation": {a}}}"#);
    let tf_file = |name: &str, points: &[f64]| {
        let tf = d.path().join(format!("{name}.json"));
        let pts: Vec<String> = points.iter().map(|&a| point(a)).collect();
        std::fs::write(&tf, format!(r#"{{"attenuation_units": "per_diagonal", "points": [{}]}}"#, pts.join(", "))).unwrap();
        tf.to_str().unwrap().to_string()
    };
    let (up, down, constant) = (tf_file("up", &[0.0, 3.0]), tf_file("down", &[3.0, 0.0]), tf_file("const", &[3.0]));
    for method in ["balanced", "vicp"] {
        for integrator in ["average", "preint", "ppi", "linear-exact"] {
            let spec = format!("{method}:integrator={integrator}");
            let run = |tf: &str| run_json(d.path(), &mesh, &["--method", &spec, "--tf", tf]);
            let (u, c) = (run(&up), run(&constant));
            // The step down leaves the field transparent: a blank image is
            // an error naming the cause (docs/bad-input.md), not a picture.
            let o = run_bounded(
                volbench()
                    .args(["run", "--size", "48x48", "--frames", "1", "--warmup", "0", "--reference", "--data"])
                    .arg(&mesh)
                    .args(["--method", &spec, "--tf", &down])
                    .env("VOLBENCH_CACHE", d.path().join("cache")),
            );
            assert!(!o.status.success() && stderr(&o).contains("transparent over the data's scalar range [1, 1]"), "{spec}: {}", stderr(&o));
            let covered = |v: &serde_json::Value| v["image"]["covered_pixels"].as_u64().unwrap();
            assert!(covered(&u) > 0 && covered(&u) == covered(&c), "{spec}: {} vs {}", covered(&u), covered(&c));
            assert!((rmse(&u) - rmse(&c)).abs() <= 1e-6, "{spec}: step {} constant {}", rmse(&u), rmse(&c));
            assert!(rmse(&c) <= 0.05, "{spec}: {}", rmse(&c));
        }
    }
}

#[test]
fn overlapping_cells_are_refused_naming_the_file_and_the_tets() {
    // Class 10: a cell repeated with one vertex moved, and a fold.
    let d = tempfile::tempdir().unwrap();
    let mut points = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]];
    let base = vec![[0, 1, 2, 3], [1, 2, 3, 4]];
    // Tet 0 again with its apex moved by 1e-3: overlaps tet 0 through face (0, 1, 2).
    points.push([1e-3, 1e-3, 1.0]);
    let near_copy = [base.clone(), vec![[0, 1, 2, 5]]].concat();
    // A fold: a cell on the same side of face (1, 2, 3) as tet 0.
    points.push([0.1, 0.1, 0.1]);
    let fold = vec![[0, 1, 2, 3], [1, 2, 3, 6]];
    for (name, tets, needle) in [("near.vtk", near_copy, "tets 0 and 2"), ("fold.vtk", fold, "tets 0 and 1")] {
        let path = d.path().join(name);
        write_vtk(&path, &points, &vec![0.5; points.len()], &tets);
        let o = run_bounded(volbench().args(["run", "--method", "vicp", "--data"]).arg(&path));
        assert_error(&o, &[name, "overlap", needle]);
    }
    // The proper neighbour on the other side is fine.
    let path = d.path().join("ok.vtk");
    write_vtk(&path, &points, &vec![0.5; points.len()], &base);
    let v = run_json(d.path(), &path, &["--method", "vicp"]);
    assert!(rmse(&v) <= DOCUMENTED_RMSE);
}

#[test]
fn a_needle_is_a_cell_and_a_flat_cell_is_not() {
    // Class 11: flatness is relative to the cell's own shape.
    let d = tempfile::tempdir().unwrap();
    let w = 1e-6;
    let mut points = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    points.extend([[1.5, 0.0, 0.0], [1.5 + w, 0.0, 0.0], [1.5, w, 0.0], [1.5, 0.0, 1.0]]);
    let tets = vec![[0, 1, 2, 3], [4, 5, 6, 7]];
    let needle = d.path().join("needle.vtk");
    write_vtk(&needle, &points, &[0.0, 1.0, 0.5, 0.2, 0.0, 1.0, 0.5, 0.2], &tets);
    let alone = d.path().join("alone.vtk");
    write_vtk(&alone, &points, &[0.0, 1.0, 0.5, 0.2, 0.0, 1.0, 0.5, 0.2], &tets[..1]);
    for method in ["balanced", "vicp"] {
        let v = run_json(d.path(), &needle, &["--method", method]);
        assert_eq!(v["dataset"]["stats"]["zero_volume"], 0, "the needle is a cell");
        // Rendered as a cell (under a pixel wide, so it adds next to nothing):
        // the image keeps the error the ordinary tet has alone.
        let without = run_json(d.path(), &alone, &["--method", method]);
        assert!(rmse(&v) <= rmse(&without) + 1e-3, "{method}: {} against {}", rmse(&v), rmse(&without));
    }
    // A cap 1e-11 high over a unit triangle is flat, at any scale.
    for scale in [1.0, 1e6] {
        let cap = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.3, 0.3, 1e-11]].map(|p: [f64; 3]| p.map(|c| c * scale));
        let path = d.path().join("cap.vtk");
        write_vtk(&path, &cap, &[0.0, 1.0, 0.5, 0.2], &[[0, 1, 2, 3]]);
        let o = run_bounded(volbench().args(["run", "--method", "vicp", "--data"]).arg(&path));
        assert_error(&o, &["cap.vtk", "zero volume"]);
    }
}

#[test]
fn little_endian_integer_scalars_are_recognised() {
    // Class 13: a BINARY legacy VTK file is big-endian; integer scalars
    // written little-endian are named as such.
    let d = tempfile::tempdir().unwrap();
    let points: [f64; 15] = [0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1., 1., 1., 1.];
    for (ty, width) in [("short", 2usize), ("unsigned_short", 2), ("int", 4), ("unsigned_int", 4), ("long", 8)] {
        for little in [true, false] {
            let mut b = b"# vtk DataFile Version 3.0\nbinary\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n".to_vec();
            b.extend(points.iter().flat_map(|v| v.to_be_bytes()));
            b.extend(b"\nCELLS 2 10\n");
            b.extend([4i32, 0, 1, 2, 3, 4, 1, 2, 3, 4].iter().flat_map(|v| v.to_be_bytes()));
            b.extend(b"\nCELL_TYPES 2\n");
            b.extend([10i32, 10].iter().flat_map(|v| v.to_be_bytes()));
            b.extend(format!("\nPOINT_DATA 5\nSCALARS s {ty} 1\nLOOKUP_TABLE default\n").bytes());
            for v in [3i64, 100, 7, 250, 40] {
                let bytes = if little { v.to_le_bytes()[..width].to_vec() } else { v.to_be_bytes()[8 - width..].to_vec() };
                b.extend(bytes);
            }
            b.push(b'\n');
            let path = d.path().join(format!("{ty}-{little}.vtk"));
            std::fs::write(&path, &b).unwrap();
            let o = run_bounded(volbench().args(["run", "--method", "vicp", "--size", "32x32", "--frames", "1", "--data"]).arg(&path));
            if little {
                assert_error(&o, &[&format!("{ty}-{little}.vtk"), "look little-endian", "write the file big-endian"]);
            } else {
                assert!(o.status.success(), "{ty}: {}", stderr(&o));
            }
        }
    }
}

#[test]
fn little_endian_volume_samples_are_recognised() {
    // Class 13, for volumes: STRUCTURED_POINTS BINARY is big-endian too.
    let d = tempfile::tempdir().unwrap();
    for (ty, little) in [("short", true), ("unsigned_short", true), ("float", true), ("short", false)] {
        let mut b = b"# vtk DataFile Version 3.0\nv\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS 4 4 4\n\
            SPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA 64\n"
            .to_vec();
        b.extend(format!("SCALARS s {ty} 1\nLOOKUP_TABLE default\n").bytes());
        for i in 0..64u16 {
            let v = 300 + 7 * i;
            b.extend(match (ty, little) {
                ("float", _) => (v as f32).to_le_bytes().to_vec(),
                (_, true) => v.to_le_bytes().to_vec(),
                (_, false) => v.to_be_bytes().to_vec(),
            });
        }
        b.push(b'\n');
        let path = d.path().join(format!("{ty}-{little}.vtk"));
        std::fs::write(&path, &b).unwrap();
        let o = run_bounded(
            volbench().args(["run", "--method", "raycast-compute", "--size", "32x32", "--frames", "1", "--data"]).arg(&path),
        );
        if little {
            assert_error(&o, &[&format!("{ty}-{little}.vtk"), "look little-endian"]);
        } else {
            assert!(o.status.success(), "{ty}: {}", stderr(&o));
        }
    }
}

#[test]
fn far_from_the_origin_renders_as_well_as_at_it() {
    // Class 18: the same grid at the origin and moved by 1e14 (its points
    // stay exact in f64: multiples of 1/4 at 1e14, where the spacing is 1/64).
    let d = tempfile::tempdir().unwrap();
    let mut results = Vec::new();
    for off in [[0.0; 3], [1e14, 0.0, 0.0], [1e14, -1e14, 5e13]] {
        let m = d.path().join(format!("g{}.vtk", results.len()));
        write_grid_vtk(&m, 4, 0.25, off, |p| p[0] + 2.0 * p[1] + 0.5 * p[2]);
        for method in ["balanced", "vicp", "balanced:sort=mpvo"] {
            let v = run_json(d.path(), &m, &["--method", method]);
            results.push((off, method, rmse(&v)));
        }
    }
    for &(off, method, e) in &results {
        let at_origin = results.iter().find(|r| r.1 == method).unwrap().2;
        assert!(e <= DOCUMENTED_RMSE && e <= at_origin * 1.25 + 2e-4, "{method} at {off:?}: rmse {e} (at the origin {at_origin})");
    }
}

#[test]
fn sizes_and_output_paths_of_sweeps_are_checked_before_any_work() {
    // Class 6: a table size too large for its integrator is refused when the
    // spec is parsed, in every command; an unwritable stress JSON too.
    let d = tempfile::tempdir().unwrap();
    let o = run_bounded(volbench().args(["compare", "--data", "post-small", "--method", "balanced:integrator=preint,table_size=4096", "--out"]).arg(d.path().join("c")));
    assert_error(&o, &["--table-size 4096 for preint", "balanced"]);
    assert!(!d.path().join("c").exists());
    let o = run_bounded(volbench().args(["pareto", "--data", "post-small", "--method", "balanced", "--table-size", "1000", "--out"]).arg(d.path().join("p")));
    assert_error(&o, &["--table-size 1000 for preint"]);
    assert!(!d.path().join("p").exists());
    // An --out directory that cannot be made: refused before any work.
    let o = run_bounded(volbench().args(["compare", "--data", "post-small", "--method", "vicp", "--out", "/proc/volbench-out"]));
    assert_error(&o, &["--out /proc/volbench-out", "cannot be created"]);
    // A read-only directory (as root too: a read-only bind is not at hand,
    // so use a path below a regular file, and /proc, which refuses new files).
    let file = d.path().join("f");
    std::fs::write(&file, b"x").unwrap();
    for bad in [file.join("s.json"), Path::new("/proc/s.json").to_path_buf()] {
        let start = Instant::now();
        let o = run_bounded(volbench().args(["stress", "--size", "16", "--json"]).arg(&bad));
        assert_error(&o, &["--json", &bad.display().to_string()]);
        assert!(start.elapsed() < Duration::from_secs(20), "refused before rendering");
    }
}
