//! Transfer function files: the presets reproduce the built-in transfer
//! functions, valid files read as documented, and every invalid file is an
//! error naming the file (and the point).

use std::path::{Path, PathBuf};

use volbench::harness::datasets::{load_mesh, mesh_transfer_function};
use volbench::mesh::{MeshStats, TetMesh};
use volbench::scene::tf_file::{load_tf, parse_tf, preset_path, to_json, JsonUnits};
use volbench::scene::{ControlPoint, TransferFunction};

fn tf_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/data/tf"))
}

fn assert_tf_close(a: &TransferFunction, b: &TransferFunction, tol: f64) {
    assert_eq!(a.name, b.name);
    assert_eq!(a.points.len(), b.points.len(), "{} vs {}", a.name, b.name);
    for (i, (p, q)) in a.points.iter().zip(&b.points).enumerate() {
        let close = |x: f64, y: f64| (x - y).abs() <= tol * (1.0 + x.abs().max(y.abs()));
        assert!(close(p.scalar, q.scalar), "{}: point {i} scalar {} vs {}", a.name, p.scalar, q.scalar);
        assert!(
            close(p.attenuation, q.attenuation),
            "{}: point {i} tau {} vs {}",
            a.name,
            p.attenuation,
            q.attenuation
        );
        for k in 0..3 {
            assert!(close(p.color[k], q.color[k]), "{}: point {i} colour", a.name);
        }
    }
}

/// A tiny stand-in mesh with the given name, scalar range and diagonal
/// (for the meshes' transfer functions without loading them).
fn fake_mesh(name: &str, lo: f64, hi: f64, size: f64) -> TetMesh {
    TetMesh {
        name: name.into(),
        points: vec![[0.0; 3], [size, 0.0, 0.0], [0.0, size, 0.0], [0.0, 0.0, size]],
        scalars: vec![lo, hi, lo, hi],
        tets: vec![[0, 1, 2, 3]],
        stats: MeshStats::default(),
    }
}

#[test]
fn presets_reproduce_the_builtin_transfer_functions() {
    for name in ["bluntfin", "oxygenpost", "post-small"] {
        let path = preset_path(name).unwrap_or_else(|| panic!("no preset for {name}"));
        assert_eq!(path, tf_dir().join(format!("{name}.json")));
        // On the real mesh (scalar range and diagonal as the harness sees them).
        let mesh = load_mesh(name).unwrap();
        let builtin = mesh_transfer_function(&mesh, Some(&mesh.name));
        let loaded = load_tf(&path, mesh.scalar_range(), mesh.bounds().diagonal()).unwrap();
        assert_tf_close(&loaded, &builtin, 1e-12);
        // And on made-up ranges and sizes.
        for (lo, hi, size) in [(0.0, 1.0, 1.0), (-3.5, 7.25, 1e-3), (100.0, 100.5, 250.0)] {
            let m = fake_mesh(name, lo, hi, size);
            let builtin = mesh_transfer_function(&m, Some(&m.name));
            let loaded = load_tf(&path, m.scalar_range(), m.bounds().diagonal()).unwrap();
            assert_tf_close(&loaded, &builtin, 1e-12);
        }
    }
    assert!(preset_path("no-such-mesh").is_none());
}

fn parse(text: &str) -> anyhow::Result<TransferFunction> {
    parse_tf(text, "SRC.json", "stem", (10.0, 20.0), 4.0)
}

#[test]
fn valid_files_read_as_documented() {
    // Absolute scalars, attenuation per world unit, defaults.
    let tf = parse(r#"{"points": [{"scalar": 12, "color": [0, 0.5, 1], "attenuation": 2.5}]}"#).unwrap();
    assert_eq!(tf.name, "stem");
    assert_eq!(tf.points, vec![ControlPoint { scalar: 12.0, color: [0.0, 0.5, 1.0], attenuation: 2.5 }]);

    // Relative scalars, per diagonal (diagonal 4), a step, opacity forms.
    let tf = parse(
        r#"{
        "name": "x", "scalar_units": "relative", "attenuation_units": "per_diagonal", "unit_length": 0.5,
        "points": [
            {"scalar": 0, "color": [0, 0, 0], "attenuation": 8},
            {"scalar": 0.5, "color": [1, 1, 1], "opacity": 0.75},
            {"scalar": 0.5, "color": [1, 0, 0], "opacity": 0.5, "unit_length": 0.25},
            {"scalar": 1, "color": [0, 1, 0], "opacity": 0}
        ]}"#,
    )
    .unwrap();
    assert_eq!(tf.name, "x");
    let s: Vec<f64> = tf.points.iter().map(|p| p.scalar).collect();
    assert_eq!(s, vec![10.0, 15.0, 15.0, 20.0]);
    let tau: Vec<f64> = tf.points.iter().map(|p| p.attenuation).collect();
    // 8 per diagonal = 2 per unit; opacity 0.75 over 0.5 diagonal = 2 units:
    // tau = ln 4 / 2; opacity 0.5 over 1 unit: ln 2.
    let expected = [2.0, 4f64.ln() / 2.0, 2f64.ln(), 0.0];
    for (t, e) in tau.iter().zip(expected) {
        assert!((t - e).abs() < 1e-15, "{tau:?}");
    }
    // Opacity is what a slab of unit_length accumulates.
    let slab = 1.0 - (-tf.points[1].attenuation * 2.0).exp();
    assert!((slab - 0.75).abs() < 1e-15);

    // Opacity per world unit.
    let tf = parse(r#"{"points": [{"scalar": 0, "color": [1, 1, 1], "opacity": 0.5, "unit_length": 2}]}"#).unwrap();
    assert!((tf.points[0].attenuation - 2f64.ln() / 2.0).abs() < 1e-16);
}

#[test]
fn json_round_trips() {
    let tf = TransferFunction {
        name: "rt".into(),
        points: vec![
            ControlPoint { scalar: -0.1, color: [0.1, 0.2, 0.3], attenuation: 1.0 / 3.0 },
            ControlPoint { scalar: 0.7, color: [1.0, 0.0, 0.5], attenuation: 0.0 },
            ControlPoint { scalar: 0.7, color: [0.25, 0.5, 0.75], attenuation: 1e-7 },
            ControlPoint { scalar: 3.0e5, color: [0.0, 1.0, 1.0], attenuation: 123.456 },
        ],
    };
    let text = to_json(&tf, JsonUnits::Absolute).unwrap();
    let back = parse_tf(&text, "mem", "mem", (0.0, 1.0), 1.0).unwrap();
    assert_eq!(back, tf, "absolute units are lossless\n{text}");

    let units = JsonUnits::RelativeTo { scalar_range: (-0.1, 3.0e5), mesh_diagonal: 7.5 };
    let text = to_json(&tf, units).unwrap();
    assert!(text.contains("\"relative\"") && text.contains("\"per_diagonal\""), "{text}");
    let back = parse_tf(&text, "mem", "mem", (-0.1, 3.0e5), 7.5).unwrap();
    assert_tf_close(&back, &tf, 1e-12);

    // The presets written back relative to their mesh and read again.
    let mesh = fake_mesh("bluntfin", 0.193, 4.978, 2.0);
    let builtin = mesh_transfer_function(&mesh, Some(&mesh.name));
    let units = JsonUnits::RelativeTo { scalar_range: mesh.scalar_range(), mesh_diagonal: mesh.bounds().diagonal() };
    let back =
        parse_tf(&to_json(&builtin, units).unwrap(), "mem", "mem", mesh.scalar_range(), mesh.bounds().diagonal())
            .unwrap();
    assert_tf_close(&back, &builtin, 1e-12);
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn invalid_files_name_the_file_and_point() {
    let dir = tempfile::tempdir().unwrap();
    let point =
        |body: &str| format!(r#"{{"points": [{{"scalar": 0, "color": [0, 0, 0], "attenuation": 1}}, {body}]}}"#);
    // (file name, contents, what the error must also say)
    let cases: Vec<(&str, String, &str)> = vec![
        ("not_json.json", "{ points: ".into(), "invalid"),
        ("no_points.json", r#"{"name": "x"}"#.into(), "points"),
        ("empty.json", r#"{"points": []}"#.into(), "empty"),
        ("unknown_key.json", r#"{"pionts": [], "points": []}"#.into(), "pionts"),
        ("bad_units.json", r#"{"scalar_units": "percent", "points": []}"#.into(), "percent"),
        ("unsorted.json", point(r#"{"scalar": -1, "color": [0, 0, 0], "attenuation": 1}"#), "point 1"),
        ("nan_scalar.json", point(r#"{"scalar": "NaN", "color": [0, 0, 0], "attenuation": 1}"#), "point 1"),
        // JSON has no infinities: an overflowing number is a syntax error,
        // located by line and column.
        ("huge_scalar.json", point(r#"{"scalar": 1e400, "color": [0, 0, 0], "attenuation": 1}"#), "column"),
        ("color_range.json", point(r#"{"scalar": 1, "color": [0, 1.5, 0], "attenuation": 1}"#), "point 1"),
        ("color_neg.json", point(r#"{"scalar": 1, "color": [-0.1, 0, 0], "attenuation": 1}"#), "point 1"),
        ("color_len.json", point(r#"{"scalar": 1, "color": [0, 0], "attenuation": 1}"#), "point 1"),
        ("negative_tau.json", point(r#"{"scalar": 1, "color": [0, 0, 0], "attenuation": -1}"#), "point 1"),
        ("opacity_one.json", point(r#"{"scalar": 1, "color": [0, 0, 0], "opacity": 1, "unit_length": 1}"#), "point 1"),
        (
            "opacity_neg.json",
            point(r#"{"scalar": 1, "color": [0, 0, 0], "opacity": -0.5, "unit_length": 1}"#),
            "point 1",
        ),
        ("no_unit_length.json", point(r#"{"scalar": 1, "color": [0, 0, 0], "opacity": 0.5}"#), "point 1"),
        (
            "zero_unit_length.json",
            point(r#"{"scalar": 1, "color": [0, 0, 0], "opacity": 0.5, "unit_length": 0}"#),
            "point 1",
        ),
        (
            "both.json",
            point(r#"{"scalar": 1, "color": [0, 0, 0], "opacity": 0.5, "unit_length": 1, "attenuation": 1}"#),
            "point 1",
        ),
        ("neither.json", point(r#"{"scalar": 1, "color": [0, 0, 0]}"#), "point 1"),
        (
            "unit_without_opacity.json",
            point(r#"{"scalar": 1, "color": [0, 0, 0], "attenuation": 1, "unit_length": 1}"#),
            "point 1",
        ),
        ("point_typo.json", point(r#"{"scalar": 1, "colour": [0, 0, 0], "attenuation": 1}"#), "point 1"),
        (
            "relative_range.json",
            r#"{"scalar_units": "relative", "points": [{"scalar": 1.5, "color": [0, 0, 0], "attenuation": 1}]}"#.into(),
            "point 0",
        ),
        (
            "top_unit_length.json",
            r#"{"unit_length": -2, "points": [{"scalar": 0, "color": [0, 0, 0], "opacity": 0.1}]}"#.into(),
            "unit_length",
        ),
    ];
    for (name, text, what) in &cases {
        let path = write(dir.path(), name, text);
        let err = load_tf(&path, (0.0, 1.0), 1.0).expect_err(name);
        let msg = format!("{err:#}");
        assert!(msg.contains(&path.display().to_string()), "{name}: error does not name the file: {msg}");
        assert!(msg.contains(what), "{name}: error does not say '{what}': {msg}");
    }
    let missing = dir.path().join("missing.json");
    let msg = format!("{:#}", load_tf(&missing, (0.0, 1.0), 1.0).unwrap_err());
    assert!(msg.contains("missing.json"), "{msg}");
}

// ---------------------------------------------------------------- issue 8

#[test]
fn structure_errors_say_what_is_wrong() {
    let ok_point = r#"{"scalar": 0, "color": [0, 0, 0], "attenuation": 1}"#;
    let cases: Vec<(&str, String, &str)> = vec![
        // Not an object at the top level.
        ("array", format!("[{ok_point}]"), "expected an object at the top level"),
        ("array", format!("[{ok_point}]"), "found an array"),
        ("number", "42".into(), "found a number"),
        ("string", r#""points""#.into(), "found a string"),
        ("null", "null".into(), "found null"),
        ("empty", " \n".into(), "the file is empty"),
        // A key given twice, anywhere (serde_json would keep the last silently).
        ("dup_top", format!(r#"{{"points": [{ok_point}], "points": []}}"#), r#"duplicate key "points""#),
        ("dup_name", format!(r#"{{"name": "a", "points": [{ok_point}], "name": "b"}}"#), r#"duplicate key "name""#),
        (
            "dup_point",
            r#"{"points": [{"scalar": 0, "color": [0, 0, 0], "attenuation": 1, "attenuation": 0}]}"#.into(),
            r#"duplicate key "attenuation""#,
        ),
        (
            "dup_units",
            format!(r#"{{"scalar_units": "relative", "scalar_units": "absolute", "points": [{ok_point}]}}"#),
            "line 1 column",
        ),
    ];
    for (name, text, what) in &cases {
        let e = format!("{:#}", parse_tf(text, "SRC.json", "stem", (0.0, 1.0), 1.0).unwrap_err());
        assert!(e.starts_with("SRC.json: "), "{name}: {e}");
        assert!(e.contains(what), "{name}: expected '{what}' in: {e}");
    }
    // Equal keys in different objects are fine.
    parse_tf(&format!(r#"{{"points": [{ok_point}, {ok_point}]}}"#), "SRC.json", "stem", (0.0, 1.0), 1.0).unwrap();
}

#[test]
fn attenuation_must_fit_f32_and_not_all_be_zero() {
    let tf = |body: &str, diag: f64| parse_tf(body, "SRC.json", "stem", (0.0, 1.0), diag);
    let cases = [
        (
            r#"{"points": [{"scalar": 0, "color": [0, 0, 0], "attenuation": 1},
                           {"scalar": 1, "color": [1, 1, 1], "opacity": 0.5, "unit_length": 1e-320}]}"#,
            1.0,
            "SRC.json: point 1: attenuation inf per world unit",
        ),
        (r#"{"points": [{"scalar": 0, "color": [0, 0, 0], "attenuation": 1e300}]}"#, 1.0, "point 0: attenuation 1e300"),
        (r#"{"points": [{"scalar": 0, "color": [0, 0, 0], "attenuation": 3.5e38}]}"#, 1.0, "beyond the f32 range"),
        (
            r#"{"attenuation_units": "per_diagonal", "points": [{"scalar": 0, "color": [0, 0, 0], "attenuation": 1e30}]}"#,
            1e-12,
            "point 0: attenuation 1e42 per world unit (after the unit conversions) is beyond the f32 range",
        ),
        (
            r#"{"points": [{"scalar": 0, "color": [1, 1, 1], "attenuation": 0}, {"scalar": 1, "color": [1, 0, 0], "opacity": 0, "unit_length": 1}]}"#,
            1.0,
            "SRC.json: every control point has attenuation 0, so nothing would be drawn",
        ),
        (
            r#"{"attenuation_units": "per_diagonal", "points": [{"scalar": 0, "color": [0, 0, 0], "attenuation": 1}]}"#,
            0.0,
            "the mesh is degenerate (all points at one place), not this file",
        ),
    ];
    for (body, diag, what) in cases {
        let e = format!("{:#}", tf(body, diag).unwrap_err());
        assert!(e.contains(what), "expected '{what}' in: {e}");
    }
    // The largest f32 attenuation, and zero on some points, are fine.
    tf(r#"{"points": [{"scalar": 0, "color": [0, 0, 0], "attenuation": 3.4e38}]}"#, 1.0).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "ox.json", &std::fs::read_to_string(tf_dir().join("oxygenpost.json")).unwrap());
    assert_eq!(load_tf(&path, (0.0, 1.0), 1.0).unwrap().points[0].attenuation, 0.0);
}

/// A constant field (a degenerate scalar range, e.g. PLOT3D density 0
/// everywhere) must not put a step at the field's value: the GPU table and
/// the CPU reference could take different sides of it.
#[test]
fn constant_field_has_no_step_at_its_value() {
    let body = r#"{"scalar_units": "relative", "points": [
        {"scalar": 0, "color": [0, 0, 1], "attenuation": 1},
        {"scalar": 0.5, "color": [0, 1, 0], "attenuation": 2},
        {"scalar": 1, "color": [1, 0, 0], "attenuation": 3}]}"#;
    for v in [0.0, 1.0, -250.0, 1e-9, 7e6] {
        let tf = parse_tf(body, "SRC.json", "stem", (v, v), 1.0).unwrap();
        let s: Vec<f64> = tf.points.iter().map(|p| p.scalar).collect();
        assert!(s[0] < v && v < s[2] && (s[1] - v).abs() <= 1e-15 * v.abs().max(1.0), "{v}: {s:?}");
        // Continuous at v: the same value on either side and at v.
        let at = |x: f64| tf.eval(x);
        let eps = (s[2] - s[0]) * 1e-9;
        for x in [v - eps, v, v + eps] {
            let (c, tau) = at(x);
            assert!((c[1] - 1.0).abs() < 1e-6 && (tau - 2.0).abs() < 1e-6, "{v}: at {x}: {c:?} {tau}");
        }
        // The range written back is the one read.
        let units = JsonUnits::RelativeTo { scalar_range: (v, v), mesh_diagonal: 1.0 };
        let back = parse_tf(&to_json(&tf, units).unwrap(), "mem", "stem", (v, v), 1.0).unwrap();
        assert_tf_close(&back, &tf, 1e-12);
    }
    // A mesh whose field is constant, through the file loader.
    let mesh = fake_mesh("const", 4.0, 4.0, 1.0);
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "const.json", body);
    let tf = load_tf(&path, mesh.scalar_range(), mesh.bounds().diagonal()).unwrap();
    assert_eq!(tf.eval(4.0), ([0.0, 1.0, 0.0], 2.0));
}

/// Every file under `tests/regressions/tf_json/` (inputs that once loaded
/// wrongly, or found by the `tf_json` fuzz target) is read without a panic;
/// the expected error is checked where known.
#[test]
fn regression_inputs() {
    let known: &[(&str, &str)] = &[
        ("top-level-array.json", "expected an object at the top level (a transfer function is a JSON object"),
        ("duplicate-key-in-point.json", r#"duplicate key "attenuation" at line 1 column"#),
        ("duplicate-points.json", r#"duplicate key "points" at line 1 column"#),
        ("unit-length-1e-320.json", "point 1: attenuation inf per world unit (after the unit conversions) is beyond the f32 range"),
        ("all-attenuation-zero.json", "every control point has attenuation 0"),
    ];
    let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/regressions/tf_json"));
    let mut seen = 0;
    for entry in std::fs::read_dir(&root).unwrap_or_else(|e| panic!("{}: {e}", root.display())) {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let r = std::panic::catch_unwind(|| load_tf(&path, (0.0, 1.0), 1.0)).unwrap_or_else(|_| panic!("{name} panicked"));
        if let Some((_, what)) = known.iter().find(|(k, _)| *k == name) {
            let e = format!("{:#}", r.expect_err(&name));
            assert!(e.starts_with(&format!("{}: ", path.display())) && e.contains(what), "{name}: expected '{what}' in: {e}");
        }
        seen += 1;
    }
    assert!(seen >= known.len(), "regression inputs missing under {}", root.display());
}

/// Deterministic mutations of the presets through the parser: no panic, and
/// every error names the file (the stable-toolchain counterpart of the
/// `tf_json` fuzz target).
#[test]
fn mutated_files_never_panic() {
    let seeds: Vec<String> = ["bluntfin", "oxygenpost", "post-small"]
        .iter()
        .map(|n| std::fs::read_to_string(tf_dir().join(format!("{n}.json"))).unwrap())
        .collect();
    let pieces = [
        "\"points\": []", "\"scalar\": 1e-320", "\"unit_length\": 1e-320", "\"opacity\": 0.5", ", \"scalar\": 2",
        "[", "]", "{", "}", ",", "\"", "1e400", "-0", "null", "\"relative\"", "\"per_diagonal\"", "0", "9",
    ];
    let mut state = 0x7F4A_7C15_9E37_79B9u64;
    let mut next = |n: usize| {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545F4914F6CDD1D) >> 33) as usize % n.max(1)
    };
    let (mut ok, mut total) = (0, 0);
    for seed in &seeds {
        for _ in 0..700 {
            let mut t: Vec<char> = seed.chars().collect();
            for _ in 0..1 + next(3) {
                let at = next(t.len() + 1);
                match next(3) {
                    0 if at < t.len() => {
                        t.remove(at);
                    }
                    1 => t.splice(at..at, pieces[next(pieces.len())].chars()).for_each(drop),
                    _ => t.truncate(at),
                }
            }
            let text: String = t.into_iter().collect();
            for (range, diag) in [((0.0, 1.0), 1.0), ((3.0, 3.0), 1e-6)] {
                let r = std::panic::catch_unwind(|| parse_tf(&text, "m.json", "m", range, diag))
                    .unwrap_or_else(|_| panic!("panic on {text:?}"));
                match r {
                    Ok(tf) => {
                        ok += 1;
                        assert!(tf.points.iter().all(|p| p.attenuation.is_finite() && p.attenuation <= f32::MAX as f64));
                    }
                    Err(e) => assert!(format!("{e:#}").starts_with("m.json: "), "{e:#}"),
                }
                total += 1;
            }
        }
    }
    assert!(ok > 0 && ok < total, "{ok} of {total} mutated files loaded");
}
