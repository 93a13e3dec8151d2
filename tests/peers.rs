//! Peers (`volbench suite --peers vtk`, `harness::peers`) without VTK: the
//! scene volbench writes is complete and the exported dataset reads back as
//! the same data; the result parser and image reader reject bad input with
//! the file and the problem named; a missing environment is a clear error.
//! With the VTK environment installed (`bash scripts/install-vtk.sh`),
//! `cargo test --test peers -- --ignored` also runs VTK itself.

mod common;

use std::path::Path;

use volbench::algo::method::DataKind;
use volbench::harness::datasets::{self, Dataset};
use volbench::harness::peers::{self, PeerScene, PEERS};
use volbench::harness::run::RunConfig;

fn cfg() -> RunConfig {
    RunConfig { width: 40, height: 30, frames: 3, warmup: 2, ..RunConfig::default() }
}

fn scene_for(dataset: &Dataset, kind: DataKind, dir: &Path) -> Vec<(PeerScene, serde_json::Value)> {
    let vtk = PEERS.iter().find(|p| p.name == "vtk").unwrap();
    let exported = peers::write_dataset(dataset, &dir.join(format!("{}.vtk", dataset.name))).unwrap();
    let tf = dataset.default_transfer_function().unwrap();
    let renderers: Vec<_> = vtk.renderers.iter().filter(|r| r.kind == kind).collect();
    assert_eq!(renderers.len(), 2, "two VTK renderers per kind");
    renderers
        .into_iter()
        .map(|r| {
            let s = peers::scene(vtk, r, dataset, &tf, &cfg(), &exported, dir).unwrap();
            let v = serde_json::to_value(&s).unwrap();
            (s, v)
        })
        .collect()
}

fn check_scene_json(v: &serde_json::Value, kind: &str) {
    assert_eq!(v["format"], "volbench-peer-scene");
    assert_eq!(v["version"], 2);
    assert_eq!(v["peer"], "vtk");
    assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(40), Some(30)));
    assert_eq!((v["warmup"].as_u64(), v["frames"].as_u64()), (Some(2), Some(3)));
    assert_eq!(v["dataset"]["kind"], kind);
    assert!(Path::new(v["dataset"]["file"].as_str().unwrap()).is_file());
    let cams = v["cameras"].as_array().unwrap();
    assert_eq!(cams.len(), 5, "one camera per warm-up and timed frame");
    for c in cams.iter().chain([&v["reference_camera"]]) {
        for k in ["eye", "target", "up"] {
            assert_eq!(c[k].as_array().unwrap().len(), 3, "{k}");
        }
        assert_eq!(c["projection"]["kind"], "perspective");
        assert!(c["projection"]["fovy_deg"].as_f64().unwrap() > 0.0);
        assert!(c["near"].as_f64().unwrap() > 0.0 && c["far"].as_f64().unwrap() > c["near"].as_f64().unwrap());
    }
    // The orbit moves: frames differ, frame 0 is the reference view.
    assert_ne!(cams[0]["eye"], cams[1]["eye"]);
    assert_eq!(cams[0], v["reference_camera"]);
    let tf = &v["transfer_function"];
    assert!(tf["unit_distance"].as_f64().unwrap() > 0.0);
    let (c, o) = (tf["color_points"].as_array().unwrap(), tf["opacity_points"].as_array().unwrap());
    assert!(!o.is_empty() && c.len() == o.len());
    let mut last = f64::NEG_INFINITY;
    for (cp, op) in c.iter().zip(o) {
        let s = op[0].as_f64().unwrap();
        assert!(s > last, "scalars strictly increasing");
        last = s;
        assert_eq!(cp[0].as_f64().unwrap(), s);
        let a = op[1].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&a), "opacity {a}");
    }
    assert!(o.iter().any(|p| p[1].as_f64().unwrap() > 0.0), "something is visible");
    assert!(v["output"]["result"].as_str().unwrap().ends_with(".json"));
    assert!(v["output"]["image"].as_str().unwrap().ends_with(".rgba"));
}

#[test]
fn the_mesh_scene_is_complete_and_the_exported_mesh_reads_back_as_the_same_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let dataset = datasets::load("post-small").unwrap();
    let scenes = scene_for(&dataset, DataKind::TetMesh, dir.path());
    for (s, v) in &scenes {
        check_scene_json(v, "tet-mesh");
        assert_eq!(v["transfer_function"]["opacity_model"], "attenuation");
        assert!(v.get("sample_distance").is_none());
        // Attenuation model: the control points themselves, tau * unit distance.
        let tf = dataset.default_transfer_function().unwrap();
        assert_eq!(s.transfer_function.opacity_points.len(), tf.points.len());
        for (p, q) in tf.points.iter().zip(&s.transfer_function.opacity_points) {
            assert!((p.attenuation * s.transfer_function.unit_distance - q[1]).abs() < 1e-12);
        }
    }
    let back = datasets::load(&scenes[0].0.dataset.file).unwrap();
    let (datasets::DatasetData::TetMesh { mesh: a, .. }, datasets::DatasetData::TetMesh { mesh: b, .. }) = (&dataset.data, &back.data) else {
        panic!("a mesh")
    };
    assert_eq!((a.points.len(), a.tets.len()), (b.points.len(), b.tets.len()));
    assert_eq!(a.points, b.points);
    assert_eq!(a.scalars, b.scalars);
    assert_eq!(back.digest, dataset.digest, "the peer renders exactly volbench's mesh");
}

#[test]
fn the_volume_scene_is_complete_and_the_exported_volume_reads_back_as_the_same_samples() {
    let dir = tempfile::tempdir().unwrap();
    let dataset = datasets::load("headsq").unwrap();
    let scenes = scene_for(&dataset, DataKind::Volume, dir.path());
    let datasets::DatasetData::Volume(v) = &dataset.data else { panic!("a volume") };
    for (_, j) in &scenes {
        check_scene_json(j, "volume");
        assert_eq!(j["transfer_function"]["opacity_model"], "correction");
        let min_spacing = v.spacing().into_iter().fold(f64::INFINITY, f64::min);
        assert_eq!(j["sample_distance"].as_f64(), Some(0.5 * min_spacing));
    }
    let back = datasets::load(&scenes[0].0.dataset.file).unwrap();
    let datasets::DatasetData::Volume(w) = &back.data else { panic!("a volume") };
    assert_eq!((w.dims(), w.spacing(), w.origin()), (v.dims(), v.spacing(), v.origin()));
    assert_eq!(w.to_f32(), v.to_f32());
}

/// A user's file (`suite --data FILE`): the peer is given the original file,
/// its format for VTK's reader, and the scalar volbench renders.
#[test]
fn a_users_file_is_given_to_the_peer_as_the_original_with_its_scalar() {
    let dir = tempfile::tempdir().unwrap();
    let vtu = dir.path().join("m.vtu");
    common::user_files::write_vtu(&vtu);
    let vtk = &PEERS[0];
    let pt = vtk.renderers.iter().find(|r| r.kind == DataKind::TetMesh).unwrap();
    // The reader's choice is named too (the default point array), so both sides read the same array.
    for (source, array) in [(vtu.display().to_string(), Some("temp")), (format!("{}#velocity", vtu.display()), Some("velocity"))] {
        let dataset = datasets::load(&source).unwrap();
        let d = peers::original_dataset(&dataset, "mine", &source).unwrap();
        assert!(d.original && d.solution_file.is_none());
        assert_eq!((d.name.as_str(), d.format.as_str(), d.kind.as_str()), ("mine", "vtu", "tet-mesh"));
        assert_eq!(Path::new(&d.file), std::fs::canonicalize(&vtu).unwrap(), "the original file, not an export");
        assert_eq!(d.digest, dataset.digest);
        assert_eq!(d.scalar, peers::PeerScalar { array: array.map(str::to_string), association: "point".into(), cell_data: None });
        let scene = peers::scene(vtk, pt, &dataset, &dataset.default_transfer_function().unwrap(), &cfg(), &d, dir.path()).unwrap();
        let v = serde_json::to_value(&scene).unwrap();
        assert_eq!(v["version"], 2);
        assert_eq!(v["dataset"]["format"], "vtu");
        assert_eq!(v["dataset"]["original"], true);
        assert_eq!(v["dataset"]["scalar"]["association"], "point");
        assert_eq!(v["dataset"]["scalar"]["array"], array.map_or(serde_json::Value::Null, |a| a.into()));
        assert!(v["dataset"].get("solution_file").is_none());
        assert!(v["output"]["image"].as_str().unwrap().contains("mine-peer-vtk-projected-tetrahedra"));
    }
    // Volbench's export names its one array.
    let small = datasets::load("post-small").unwrap();
    let e = peers::write_dataset(&small, &dir.path().join("e.vtk")).unwrap();
    assert!(!e.original);
    assert_eq!(e.scalar.array.as_deref(), Some("scalars"));
    // A volume by content under another name; a PLOT3D pair gives both files.
    let v = datasets::load("hydrogen").unwrap();
    let src = volbench::data_dir::data_dir().join("volumes").join("hydrogen.vti");
    if src.is_file() {
        let renamed = dir.path().join("h.dat");
        std::fs::copy(&src, &renamed).unwrap();
        let d = peers::original_dataset(&v, "h", &renamed.display().to_string()).unwrap();
        assert_eq!((d.format.as_str(), d.kind.as_str()), ("vti", "volume"));
    }
    let xyz = volbench::data_dir::data_dir().join("plot3d/bluntfinxyz.bin");
    let d = peers::original_dataset(&small, "fin", &xyz.display().to_string()).unwrap();
    assert_eq!(d.format, "plot3d");
    assert!(d.solution_file.as_deref().is_some_and(|q| q.ends_with("bluntfinq.bin")), "{:?}", d.solution_file);
    // A scene from another protocol version is refused by the peer's parser
    // (the result says which version it speaks).
    assert_eq!(peers::FORMAT_VERSION, 2);
}

#[test]
fn a_renderer_of_another_kind_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let dataset = datasets::load("post-small").unwrap();
    let vtk = &PEERS[0];
    let exported = peers::write_dataset(&dataset, &dir.path().join("m.vtk")).unwrap();
    let gpu = vtk.renderers.iter().find(|r| r.kind == DataKind::Volume).unwrap();
    let e = peers::scene(vtk, gpu, &dataset, &dataset.default_transfer_function().unwrap(), &cfg(), &exported, dir.path()).unwrap_err().to_string();
    assert!(e.contains(gpu.name) && e.contains("tet-mesh"), "{e}");
}

fn good_result(s: &PeerScene) -> serde_json::Value {
    serde_json::json!({
        "format": "volbench-peer-result", "version": 2, "peer": "vtk", "renderer": s.renderer,
        "class": "vtkProjectedTetrahedraMapper", "library_version": "9.7.2", "window": "vtkEGLRenderWindow",
        "gl_renderer": "llvmpipe", "load_ms": 10.0, "setup_ms": 1.0,
        "warmup_ms": [5.0, 4.0], "frame_ms": [3.0, 3.5, 2.5],
        "image": { "file": Path::new(&s.output.image).file_name().unwrap().to_str().unwrap(),
                   "width": 40, "height": 30, "format": "rgba8", "rows": "top-down" }
    })
}

#[test]
fn the_result_parser_rejects_bad_results_naming_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let dataset = datasets::load("post-small").unwrap();
    let (scene, _) = scene_for(&dataset, DataKind::TetMesh, dir.path()).remove(0);
    let ok = good_result(&scene);
    let r = peers::parse_result(&ok.to_string(), &scene, "r.json").unwrap();
    assert_eq!(r.frame_ms, [3.0, 3.5, 2.5]);
    type Case = (&'static str, Box<dyn Fn(&mut serde_json::Value)>, &'static str);
    let cases: Vec<Case> = vec![
        ("not JSON", Box::new(|v| *v = serde_json::json!("x")), "not a peer result"),
        ("wrong format", Box::new(|v| v["format"] = "other".into()), "format 'other'"),
        ("newer version", Box::new(|v| v["version"] = 3.into()), "version 3"),
        ("other renderer", Box::new(|v| v["renderer"] = "gpu-raycast".into()), "gpu-raycast"),
        ("too few frames", Box::new(|v| v["frame_ms"] = serde_json::json!([1.0])), "1 timed"),
        ("negative time", Box::new(|v| v["frame_ms"][1] = (-1.0).into()), "-1"),
        ("text time", Box::new(|v| v["setup_ms"] = "fast".into()), "not a peer result"),
        ("wrong size", Box::new(|v| v["image"]["width"] = 41.into()), "41x30"),
        ("wrong layout", Box::new(|v| v["image"]["rows"] = "bottom-up".into()), "bottom-up"),
        ("other file", Box::new(|v| v["image"]["file"] = "../../etc/passwd".into()), "not the one asked for"),
        ("missing field", Box::new(|v| _ = v.as_object_mut().unwrap().remove("frame_ms")), "frame_ms"),
        ("unknown field", Box::new(|v| v["surprise"] = 1.into()), "surprise"),
    ];
    for (what, change, needle) in cases {
        let mut v = ok.clone();
        change(&mut v);
        let e = format!("{:#}", peers::parse_result(&v.to_string(), &scene, "peers/r.json").unwrap_err());
        assert!(e.contains("peers/r.json") && e.contains(needle), "{what}: {e}");
    }
}

#[test]
fn the_image_reader_checks_the_size() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("i.rgba");
    std::fs::write(&p, vec![255u8; 2 * 3 * 4]).unwrap();
    let img = peers::read_image(&p, 2, 3).unwrap();
    assert_eq!(img.pixels, vec![[1.0f32; 4]; 6]);
    for (w, h) in [(3, 3), (2, 2)] {
        let e = format!("{:#}", peers::read_image(&p, w, h).unwrap_err());
        assert!(e.contains("i.rgba") && e.contains("bytes"), "{e}");
    }
}

#[test]
fn a_missing_environment_or_unknown_peer_is_a_clear_error_before_anything_runs() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_volbench"))
        .args(["suite", "--quick", "--peers", "vtk", "--out"])
        .arg(tempfile::tempdir().unwrap().path().join("out"))
        .env("VOLBENCH_VTK_VENV", "/nonexistent/venv")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent/venv") && err.contains("scripts/install-vtk.sh"), "{err}");
    assert!(!err.contains("suite: ["), "nothing ran: {err}");
    let e = peers::locate("paraview").unwrap_err().to_string();
    assert!(e.contains("paraview") && e.contains("vtk"), "{e}");
    // `--rounds` needs peers and is bounded.
    for (args, needle) in [(&["--rounds", "2"][..], "--peers"), (&["--peers", "vtk", "--rounds", "21"][..], "--rounds")] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_volbench")).args(["suite", "--quick"]).args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle) && !err.contains("suite: ["), "{args:?}: {err}");
    }
}

/// A stand-in for VTK's peer (`VOLBENCH_VTK_VENV` pointing at it): called
/// as `python SCRIPT --scene FILE`, it writes a result with the scene's
/// frame counts and a white image, and fails on one call.
const FAKE_PEER: &str = r#"#!/bin/sh
# A stand-in for VTK's peer in volbench's tests: called as
# `python SCRIPT --scene FILE`, it writes a result with the scene's frame
# counts and a white image, and fails (exit 3) on call number $FAKE_PEER_FAIL_AT.
scene="$3"
n=$(( $(cat "$FAKE_PEER_CALLS" 2>/dev/null || echo 0) + 1 ))
echo "$n" > "$FAKE_PEER_CALLS"
if [ "$n" = "${FAKE_PEER_FAIL_AT:-0}" ]; then echo "fake peer: call $n fails" >&2; exit 3; fi
top() { grep -m1 "^  \"$1\": " "$scene" | sed 's/^[^:]*: //; s/[",]//g'; }
out() { grep -m1 "^    \"$1\": " "$scene" | sed 's/^[^:]*: //; s/[",]//g'; }
w=$(top width); h=$(top height); frames=$(top frames); warmup=$(top warmup)
renderer=$(top renderer); result=$(out result); image=$(out image)
ms_list() { i=0; s=""; while [ $i -lt "$1" ]; do s="$s${s:+, }2.5"; i=$((i + 1)); done; echo "[$s]"; }
head -c $((w * h * 4)) /dev/zero | tr '\000' '\377' > "$image"
cat > "$result" <<JSON
{"format": "volbench-peer-result", "version": 2, "peer": "vtk", "renderer": "$renderer",
 "class": "fake", "library_version": "0", "window": "none", "gl_renderer": "none",
 "load_ms": 1.0, "setup_ms": 1.0, "warmup_ms": $(ms_list "$warmup"), "frame_ms": $(ms_list "$frames"),
 "image": {"file": "$(basename "$image")", "width": $w, "height": $h, "format": "rgba8", "rows": "top-down"}}
JSON
"#;

/// The rounds against a peer in CI, where VTK is not installed: a peer
/// that fails in the second round of its first renderer. That renderer
/// keeps its first round and says why the second failed (its scene kept
/// for a rerun), the other renderer completes both rounds, and the suite's
/// exit status says a round failed.
#[test]
fn a_failed_round_is_reported_and_fails_the_suite() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = tempfile::tempdir().unwrap();
    let python = dir.path().join("venv/bin/python");
    std::fs::create_dir_all(python.parent().unwrap()).unwrap();
    std::fs::write(&python, FAKE_PEER).unwrap();
    std::fs::set_permissions(&python, std::fs::Permissions::from_mode(0o755)).unwrap();
    let out = dir.path().join("out");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_volbench"))
        .args(["suite", "--quick", "--peers", "vtk", "--rounds", "2", "--filter", "post-small", "--out"])
        .arg(&out)
        .env("VOLBENCH_VTK_VENV", dir.path().join("venv"))
        .env("FAKE_PEER_CALLS", dir.path().join("calls"))
        // Two first-pass runs, then projected tetrahedra's rounds 1 and 2.
        .env("FAKE_PEER_FAIL_AT", "4")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{err}");
    assert!(err.contains("the rounds of 1 of 2 peer renderers failed"), "{err}");
    assert_eq!(std::fs::read_to_string(dir.path().join("calls")).unwrap().trim(), "6");
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    let matched = summary["matched"].as_array().unwrap();
    assert_eq!(matched.len(), 2);
    let (failed, complete) = (&matched[0], &matched[1]);
    assert_eq!(failed["renderer"], "projected-tetrahedra");
    assert_eq!(failed["rounds"].as_array().unwrap().len(), 1);
    let why = failed["message"].as_str().unwrap();
    assert!(why.starts_with("round 2:") && why.contains("call 4 fails"), "{why}");
    assert_eq!(complete["rounds"].as_array().unwrap().len(), 2);
    assert!(complete["message"].is_null());
    assert_eq!(complete["rounds"][1]["reversed"], true);
    for m in matched {
        assert_eq!(m["labels"].as_array().unwrap().len(), 2);
        assert_eq!(m["ratios"].as_array().unwrap().len(), 2);
    }
    let peers = out.join("peers");
    assert!(peers.join("post-small-peer-vtk-projected-tetrahedra-round1.json").is_file());
    assert!(!peers.join("post-small-peer-vtk-projected-tetrahedra-round2.json").exists());
    assert!(peers.join("post-small-peer-vtk-projected-tetrahedra-round2.scene.json").is_file(), "a failed round's scene is kept");
    assert!(!peers.join("post-small-peer-vtk-unstructured-raycast-round2.scene.json").exists());
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("(1); failed: round 2:") && report.contains("(2) |"), "{report}");
}

/// VTK itself, when installed: both mesh renderers on the small post, in a
/// real suite run; their images must match volbench's reference closely.
#[test]
#[ignore = "needs VTK: bash scripts/install-vtk.sh, then cargo test --test peers -- --ignored"]
fn vtk_renders_the_small_post_in_the_suite() {
    use volbench::harness::suite::{plan, run_suite, SuiteSettings};
    use volbench::vk::{Context, ContextDesc};
    let registry = volbench::algo::registry::builtin();
    let settings = SuiteSettings {
        width: 64,
        height: 64,
        frames: 2,
        warmup: 1,
        peers: vec!["vtk".into()],
        rounds: 2,
        ..SuiteSettings::standard(true, vec!["post-small".into()])
    };
    let planned = plan(&registry, &settings).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let ctx = std::sync::Arc::new(Context::new(&ContextDesc { device: None, validation: true }).unwrap());
    let summary = run_suite(&ctx, &registry, &planned, &settings, dir.path(), |_, _| {}).unwrap();
    let names: Vec<&str> = summary.peers.iter().map(|p| p.renderer.as_str()).collect();
    assert_eq!(names, ["projected-tetrahedra", "unstructured-raycast"]);
    for p in &summary.peers {
        assert_eq!(p.status, "ok", "{:?}", p.message);
        assert_eq!(p.frame_samples_ms.len(), 2);
        let e = p.error.unwrap();
        assert!(e.rmse < 0.05, "{} RMSE {}", p.renderer, e.rmse);
        assert!(p.covered_pixels.unwrap() > 500);
    }
    // Alternating: volbench, peer, volbench, peer, then volbench's remaining runs.
    let seq: Vec<usize> = summary.runs.iter().map(|r| r.sequence).collect();
    assert_eq!(seq[..2], [0, 2]);
    assert!(seq[2..].iter().all(|&s| s >= 4), "{seq:?}");
    assert_eq!(summary.peers.iter().map(|p| p.sequence).collect::<Vec<_>>(), [1, 3]);
    let report = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(report.contains("Peers measured in the same run") && report.contains("| post-small | balanced | vtk/projected-tetrahedra |"), "{report}");
    assert!(report.contains("At matched error") && report.contains("| post-small | vtk/projected-tetrahedra |"), "{report}");
    // Each peer again with its two fastest matched runs, in two rounds:
    // the first run, the peer, the second; then the other way round.
    assert_eq!(summary.matched.len(), 2, "{:?}", summary.matched);
    for m in &summary.matched {
        assert!(m.message.is_none(), "{m:?}");
        assert_eq!(m.labels.len(), 2, "{m:?}");
        assert_eq!(m.rounds.iter().map(|r| r.reversed).collect::<Vec<_>>(), [false, true]);
        for r in &m.rounds {
            assert!(r.peer_ms > 0.0 && r.volbench_ms.len() == 2 && r.volbench_ms.iter().all(|&x| x > 0.0));
        }
        let (label, ratio) = m.quoted().unwrap();
        let (other_label, other) = m.other().unwrap();
        let i = m.labels.iter().position(|l| l == label).unwrap();
        assert_eq!(m.labels[1 - i], other_label);
        let ratios = |j: usize| m.rounds.iter().map(|r| r.peer_ms / r.volbench_ms[j]).collect::<Vec<_>>();
        assert_eq!(ratio.median, volbench::harness::stats::Summary::of(&ratios(i)).median);
        assert_eq!(other.median, volbench::harness::stats::Summary::of(&ratios(1 - i)).median);
        assert!(ratio.median >= other.median);
        let peer = summary.peers.iter().find(|p| p.renderer == m.renderer).unwrap();
        let candidates: Vec<&str> = summary.matched_runs(peer).iter().take(2).map(|(x, _, _)| x.label.as_str()).collect();
        assert_eq!(candidates, m.labels.iter().map(String::as_str).collect::<Vec<_>>());
        for k in 1..=2 {
            assert!(dir.path().join(format!("peers/post-small-peer-vtk-{}-round{k}.json", m.renderer)).is_file());
            assert!(!dir.path().join(format!("peers/post-small-peer-vtk-{}-round{k}.scene.json", m.renderer)).exists());
        }
    }
    assert!(report.contains("alternating rounds") && report.contains("(2) |"), "{report}");
    let csv = std::fs::read_to_string(dir.path().join("summary.csv")).unwrap();
    assert!(csv.starts_with("source,dataset,method,"), "{csv}");
    assert!(csv.lines().any(|l| l.starts_with("volbench,post-small,balanced,")), "{csv}");
    assert!(csv.lines().any(|l| l.starts_with("vtk,post-small,\"projected-tetrahedra\",")), "{csv}");
    assert!(dir.path().join("runs/post-small-peer-vtk-projected-tetrahedra.png").is_file());
    assert!(!dir.path().join("peers/post-small.vtk").exists(), "the exported copy is removed");
}

/// VTK itself, when installed, on a user's file (`suite --data FILE`): the
/// peer reads the original `.vtu` of hexahedra with its own reader and
/// tetrahedralizes it with its own filter; its image agrees with volbench's
/// of the same view within the two images' errors against the f64 reference.
#[test]
#[ignore = "needs VTK: bash scripts/install-vtk.sh, then cargo test --test peers -- --ignored"]
fn vtk_reads_a_users_original_file_in_the_suite() {
    use volbench::harness::suite::{plan, run_suite, SuiteSettings};
    use volbench::vk::{Context, ContextDesc};
    let dir = tempfile::tempdir().unwrap();
    let vtu = dir.path().join("user.vtu");
    common::user_files::write_vtu(&vtu);
    let registry = volbench::algo::registry::builtin();
    let settings = SuiteSettings {
        width: 64,
        height: 64,
        frames: 1,
        warmup: 0,
        peers: vec!["vtk".into()],
        data: vec![vtu.display().to_string()],
        ..SuiteSettings::standard(true, vec!["tet-raycast".into()])
    };
    let planned = plan(&registry, &settings).unwrap();
    let ctx = std::sync::Arc::new(Context::new(&ContextDesc { device: None, validation: true }).unwrap());
    let summary = run_suite(&ctx, &registry, &planned, &settings, &dir.path().join("out"), |_, _| {}).unwrap();
    // The plain method's run (the suite also runs its adaptive variants).
    let plain = summary.runs.iter().find(|r| r.label == "tet-raycast").unwrap();
    let ours = plain.result.as_ref().and_then(|r| r.error.as_ref()).unwrap().rmse;
    assert_eq!(summary.peers.len(), 2);
    for p in &summary.peers {
        assert_eq!(p.status, "ok", "{:?}", p.message);
        assert_eq!(p.input.as_deref(), Some("vtu"), "the original file");
        let peer = p.error.unwrap().rmse;
        let vs = &p.vs_volbench;
        // One agreement per volbench run of the dataset.
        assert_eq!(vs.len(), summary.runs.len());
        let vs = vs.iter().find(|a| a.label == "tet-raycast").unwrap();
        assert!(vs.rmse <= peer + ours + 1e-6, "{}: {} vs volbench, {peer} + {ours} vs f64", p.renderer, vs.rmse);
        // VTK's unstructured ray caster misses pixels along the cell faces
        // through the view's centre (this grid's mid-planes): 5.4e-2 at 64².
        let bound = if p.renderer == "projected-tetrahedra" { 0.02 } else { 0.1 };
        assert!(peer < bound, "{} RMSE {peer}", p.renderer);
    }
    assert!(vtu.is_file(), "the user's file is not removed");
    let report = std::fs::read_to_string(dir.path().join("out/report.md")).unwrap();
    assert!(report.contains("| user | vtk/projected-tetrahedra | original file (vtu) |"), "{report}");
}
