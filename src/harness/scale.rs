//! The scaling study (`volbench scale`): a tet mesh red-refined level by
//! level (`mesh::refine`, ×8 cells each), every level written as a binary
//! legacy VTK file and rendered by each method in a fresh `volbench run`
//! process (so its peak RSS is that run's alone), optionally by VTK's
//! projected tetrahedra (`--peers vtk`) on the same file; frame time and
//! every phase, tets/s, bytes per frame, static device bytes and peak RSS
//! per level, as JSON, CSV, Markdown and a log-log plot.
//!
//! What it measured is kept: the results files are rewritten, all or
//! nothing, after every finished level, so a level that fails (a full disk,
//! memory) or a stop signal leaves the complete results of the levels
//! before it; the interrupted level's own files (its mesh, the run's JSON,
//! staged temporaries) are removed, on an error and on SIGTERM, SIGINT or
//! SIGHUP alike. Before anything is made, the memory and disk the levels
//! asked for need are estimated from their sizes (known in advance,
//! `refine::RefineCounts`) and a study that would not fit is refused with
//! the figures.

use std::collections::BTreeMap;
use std::os::unix::process::CommandExt as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use anyhow::{bail, ensure, Context as _, Result};
use serde::Serialize;

use crate::algo::host_memory::vm_hwm_kb;
use crate::mesh::refine::{red_refine, refined_bytes, refined_bytes_of, RefineCounts};
use crate::mesh::TetMesh;

/// One row: a method (or peer) on one level.
#[derive(Debug, Clone, Serialize)]
pub struct ScaleRow {
    pub level: usize,
    pub cells: u64,
    pub points: u64,
    /// The method's label, or `peer vtk/projected-tetrahedra`.
    pub method: String,
    pub status: &'static str,
    pub error: Option<String>,
    /// Median frame time (ms).
    pub frame_ms: Option<f64>,
    /// Median of each phase (ms), `frame` included.
    pub phases_ms: BTreeMap<String, f64>,
    /// Median frame time per million tets (ms).
    pub ms_per_mtet: Option<f64>,
    pub tets_per_second: Option<f64>,
    pub bytes_per_frame: Option<u64>,
    /// Bytes uploaded to the device once (device-resident data).
    pub static_device_bytes: Option<u64>,
    /// Peak resident set of the run's process (VmHWM), bytes.
    pub peak_rss_bytes: Option<u64>,
    pub peak_rss_bytes_per_tet: Option<f64>,
}

/// A level's mesh and the f64 reference's time on it.
#[derive(Debug, Clone, Serialize)]
pub struct ScaleLevel {
    pub level: usize,
    pub cells: u64,
    pub points: u64,
    pub file: String,
    pub refine_ms: f64,
    /// The f64 CPU reference's time for one image at the run size, when run.
    pub reference_ms: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ScaleReport {
    pub schema: &'static str,
    pub dataset: String,
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    pub levels: Vec<ScaleLevel>,
    pub rows: Vec<ScaleRow>,
}

pub use crate::algo::chunks::available_memory;

/// `mesh` refined once, after checking that the refinement fits in the
/// host memory available now (`available`: bytes; `None`: unchecked).
pub fn refine_checked(mesh: &TetMesh, level: usize, available: Option<u64>) -> Result<TetMesh> {
    let need = refined_bytes(mesh);
    if let Some(avail) = available {
        ensure!(
            need <= avail as u128,
            "level {level}: refining {} tets to {} needs about {:.1} GiB of host memory, {:.1} GiB are available; use fewer --levels",
            mesh.tets.len(),
            mesh.tets.len() as u128 * 8,
            need as f64 / (1u64 << 30) as f64,
            avail as f64 / (1u64 << 30) as f64
        );
    }
    red_refine(mesh).with_context(|| format!("refining level {level}"))
}

/// Runs `cmd` to completion, polling its peak RSS (VmHWM) from /proc while
/// it runs; returns its output status, stderr and the last VmHWM read.
/// The child runs in a process group of its own, registered with the
/// study's clean-up (a stop signal stops it and removes what it staged).
pub fn run_measured(mut cmd: Command) -> Result<(std::process::ExitStatus, String, Option<u64>)> {
    let mut staged = staging();
    let mut child = cmd.stdout(Stdio::null()).stderr(Stdio::piped()).process_group(0).spawn().context("starting the run")?;
    staged.child = Some(child.id());
    staged.children.push(child.id());
    drop(staged);
    let status_path = PathBuf::from(format!("/proc/{}/status", child.id()));
    // stderr is drained on a thread (a chatty child never blocks), its
    // head and tail kept (a child that prints without end costs kilobytes).
    let stderr = super::child::Drain::start(child.stderr.take(), super::child::KEEP);
    let mut peak = None;
    let status = loop {
        if let Some(status) = child.try_wait().context("waiting for the run")? {
            break status;
        }
        if let Some(kb) = std::fs::read_to_string(&status_path).ok().and_then(|t| vm_hwm_kb(&t)) {
            peak = Some(peak.unwrap_or(0).max(kb * 1024));
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    staging().child = None;
    let err = stderr.finish(Duration::from_secs(2)).text();
    Ok((status, err, peak))
}

/// The row of a `volbench run --json` result.
pub fn row_from_run(level: usize, method: &str, json: &serde_json::Value, peak: Option<u64>) -> ScaleRow {
    let cells = json.get("cells").and_then(|c| c.as_u64()).unwrap_or(0);
    let points = json.get("points").and_then(|c| c.as_u64()).unwrap_or(0);
    let mut phases_ms = BTreeMap::new();
    if let Some(t) = json.get("time_ms").and_then(|t| t.as_object()) {
        for (k, v) in t {
            if let Some(m) = v.get("median").and_then(|m| m.as_f64()) {
                phases_ms.insert(k.clone(), m);
            }
        }
    }
    let frame_ms = phases_ms.get("frame").copied();
    let per_tet = |v: Option<f64>| v.filter(|_| cells > 0).map(|v| v / cells as f64);
    ScaleRow {
        level,
        cells,
        points,
        method: method.to_string(),
        status: "ok",
        error: None,
        frame_ms,
        ms_per_mtet: per_tet(frame_ms).map(|v| v * 1e6),
        tets_per_second: frame_ms.filter(|f| *f > 0.0).map(|f| cells as f64 / (f * 1e-3)),
        phases_ms,
        bytes_per_frame: json.pointer("/upload/bytes_per_frame").and_then(|b| b.as_u64()),
        static_device_bytes: json.pointer("/upload/static_bytes").and_then(|b| b.as_u64()),
        peak_rss_bytes: peak,
        peak_rss_bytes_per_tet: per_tet(peak.map(|p| p as f64)),
    }
}

/// A failed row.
pub fn failed_row(level: usize, mesh: &TetMesh, method: &str, error: String) -> ScaleRow {
    ScaleRow {
        level,
        cells: mesh.tets.len() as u64,
        points: mesh.points.len() as u64,
        method: method.to_string(),
        status: "failed",
        error: Some(error),
        frame_ms: None,
        phases_ms: BTreeMap::new(),
        ms_per_mtet: None,
        tets_per_second: None,
        bytes_per_frame: None,
        static_device_bytes: None,
        peak_rss_bytes: None,
        peak_rss_bytes_per_tet: None,
    }
}

/// One `volbench run` of `spec` on the mesh file, in a fresh process.
pub fn run_method(exe: &Path, file: &Path, spec: &str, level: usize, label: &str, args: &[String], json: &Path) -> Result<ScaleRow> {
    let _ = std::fs::remove_file(json);
    let mut cmd = Command::new(exe);
    cmd.args(["run", "--data"]).arg(file).args(["--method", spec]).args(args).arg("--json").arg(json);
    let (status, err, peak) = run_measured(cmd)?;
    if !status.success() {
        bail!("{status}: {}", crate::fsio::clip_child_output(err.trim()));
    }
    let text = std::fs::read_to_string(json).with_context(|| format!("reading {}", json.display()))?;
    let v: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{}: not JSON", json.display()))?;
    Ok(row_from_run(level, label, &v, peak))
}

/// Elapsed milliseconds of `f`.
pub fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = Instant::now();
    let v = f();
    (v, t.elapsed().as_secs_f64() * 1e3)
}

/// What `volbench scale` runs.
#[derive(Debug, Clone)]
pub struct ScaleSettings {
    /// A shipped tet mesh or a mesh file.
    pub dataset: String,
    /// Refinements after level 0.
    pub levels: usize,
    /// (canonical spec, label) per method.
    pub specs: Vec<(String, String)>,
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    /// The f64 reference is timed on levels with at most this many tets.
    pub reference_max_cells: u64,
    pub peers: Vec<String>,
    /// How a mesh file's cell array is shown (`--cell-data`): the levels are
    /// written and read back as point fields, so constant cells are refused.
    pub cell_data: crate::mesh::cell_data::CellData,
}

/// What the level being measured has made so far: removed when the level
/// fails or the process is told to stop (`stop_cleanly_on_signals`).
struct Staging {
    /// The level's files (its mesh, the run's JSON, a peer's scene).
    files: Vec<PathBuf>,
    /// Where this process's and its children's staged temporaries lie.
    dirs: Vec<PathBuf>,
    /// The running child's process group.
    child: Option<u32>,
    /// Every child of the level (their temporaries, if stopped).
    children: Vec<u32>,
}

static STAGING: Mutex<Staging> = Mutex::new(Staging { files: Vec::new(), dirs: Vec::new(), child: None, children: Vec::new() });

fn staging() -> std::sync::MutexGuard<'static, Staging> {
    STAGING.lock().unwrap_or_else(|e| e.into_inner())
}

impl Staging {
    /// Stop the running child, remove the level's files and every
    /// temporary this process or the level's children staged.
    fn clean(&mut self) {
        if let Some(group) = self.child.take() {
            super::child::kill_group_id(group);
            wait_gone(group);
        }
        for f in self.files.drain(..) {
            let _ = std::fs::remove_file(f);
        }
        for d in &self.dirs {
            crate::fsio::remove_staged_by(d, std::process::id());
            for &c in &self.children {
                crate::fsio::remove_staged_by(d, c);
            }
        }
        self.children.clear();
    }

    /// The level is complete and its results written: its files are results now.
    fn keep(&mut self) {
        self.files.clear();
        self.children.clear();
    }
}

/// Wait (at most 2 s) until process `pid` has ended (gone, or a zombie):
/// a process killed during a write must not create a file after the sweep.
fn wait_gone(pid: u32) {
    let stat = PathBuf::from(format!("/proc/{pid}/stat"));
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(2) {
        match std::fs::read_to_string(&stat) {
            // The state follows the parenthesised command name.
            Ok(t) if t.rsplit_once(") ").is_some_and(|(_, rest)| !rest.starts_with('Z')) => std::thread::sleep(Duration::from_millis(5)),
            _ => return,
        }
    }
}

/// On SIGTERM, SIGINT or SIGHUP: stop the running child, remove the
/// interrupted level's files (the results of the finished levels are
/// complete on disk already), and exit with 128 + the signal's number.
fn stop_cleanly_on_signals() -> Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    static INSTALLED: std::sync::OnceLock<()> = std::sync::OnceLock::new();
    if INSTALLED.get().is_some() {
        return Ok(());
    }
    let mut signals = signal_hook::iterator::Signals::new([SIGTERM, SIGINT, SIGHUP]).context("installing the stop-signal handler")?;
    let _ = INSTALLED.set(());
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            // Taken while no results file is being written (the writer holds it).
            let mut s = staging();
            s.clean();
            crate::progress!(
                "volbench: scale: stopped by signal {signal}: the finished levels' results are kept, the interrupted level's files removed"
            );
            std::process::exit(128 + signal);
        }
    });
    Ok(())
}

/// One level's sizes and what making and measuring it needs.
#[derive(Debug, Clone, Copy)]
pub struct LevelEstimate {
    pub level: usize,
    pub counts: RefineCounts,
    /// Host memory at the level's peak: the refinement that makes it
    /// (`refine::refined_bytes`), or the mesh held by this process and by
    /// the run's (and a second copy here for the reference and the peers).
    pub memory_bytes: u128,
    /// Its mesh file (`peers::tet_mesh_file_bytes`).
    pub file_bytes: u128,
}

/// What a study needs, before any of it is made.
#[derive(Debug, Clone)]
pub struct Estimate {
    pub levels: Vec<LevelEstimate>,
    /// The largest level's memory.
    pub memory_bytes: u128,
    /// Every level's mesh file, the peers' images and the results files
    /// (with their staged copies).
    pub disk_bytes: u128,
}

/// Disk the results files take besides the meshes: JSON, CSV, Markdown
/// and the plots, each staged beside the old copy while replaced (their
/// size grows with the rows; a few hundred kilobytes in practice).
pub const RESULTS_DISK_BYTES: u128 = 16 << 20;

/// A mesh held in memory: f64 points and scalars, u32 tets.
fn mesh_bytes(c: &RefineCounts) -> u128 {
    c.points * 32 + c.tets * 16
}

fn mesh_title(name: &str, level: usize) -> String {
    format!("volbench scale: {name} red-refined {level} times")
}

/// The study's needs, level by level, from `mesh` (level 0).
pub fn estimate(mesh: &TetMesh, name: &str, s: &ScaleSettings) -> Estimate {
    let mut counts = RefineCounts::of(mesh);
    let mut levels = Vec::new();
    for level in 0..=s.levels {
        let refine = if level > 0 {
            let before = counts;
            counts = counts.refined();
            refined_bytes_of(before.points, before.tets)
        } else {
            0
        };
        let copies = if counts.tets <= u128::from(s.reference_max_cells) || !s.peers.is_empty() { 3 } else { 2 };
        let file = super::peers::tet_mesh_file_bytes(counts.points, counts.tets, &mesh_title(name, level));
        levels.push(LevelEstimate { level, counts, memory_bytes: refine.max(copies * mesh_bytes(&counts)), file_bytes: file });
    }
    let images = s.peers.len() as u128 * (u128::from(s.width) * u128::from(s.height) * 4 + (64 << 10)) * levels.len() as u128;
    Estimate {
        memory_bytes: levels.iter().map(|l| l.memory_bytes).max().unwrap_or(0),
        disk_bytes: levels.iter().map(|l| l.file_bytes).sum::<u128>() + images + RESULTS_DISK_BYTES,
        levels,
    }
}

fn gib(b: u128) -> String {
    format!("{:.2} GiB", b as f64 / (1u64 << 30) as f64)
}

impl Estimate {
    /// Refuse, with the figures, a study that needs more host memory than
    /// `memory` or more disk than `disk` (bytes available; `None`: unknown,
    /// not checked).
    pub fn check(&self, memory: Option<u64>, disk: Option<u64>, out: &Path) -> Result<()> {
        let last = self.levels.last().map_or(0, |l| l.level);
        let mut problems = Vec::new();
        if let Some(avail) = memory.filter(|&a| self.memory_bytes > u128::from(a)) {
            let worst = self.levels.iter().max_by_key(|l| l.memory_bytes).expect("level 0 at least");
            problems.push(format!(
                "host memory: about {} at level {} ({} tets), {} available (MemAvailable)",
                gib(self.memory_bytes),
                worst.level,
                worst.counts.tets,
                gib(u128::from(avail))
            ));
        }
        if let Some(free) = disk.filter(|&f| self.disk_bytes > u128::from(f)) {
            let files: Vec<String> = self.levels.iter().map(|l| format!("L{} {}", l.level, gib(l.file_bytes))).collect();
            problems.push(format!(
                "disk: about {} in {} (meshes {}; results {}), {} free there",
                gib(self.disk_bytes),
                out.display(),
                files.join(", "),
                gib(RESULTS_DISK_BYTES),
                gib(u128::from(free))
            ));
        }
        ensure!(
            problems.is_empty(),
            "--levels {last}: the study would not fit: {}; use fewer --levels or a smaller mesh",
            problems.join("; ")
        );
        Ok(())
    }
}

/// Bytes free for an unprivileged writer on the file system that holds
/// `dir` (or its nearest existing ancestor, when it does not exist yet).
pub fn available_disk(dir: &Path) -> Option<u64> {
    let existing = dir.ancestors().map(|a| if a.as_os_str().is_empty() { Path::new(".") } else { a }).find(|a| a.exists())?;
    let v = rustix::fs::statvfs(existing).ok()?;
    Some(v.f_bavail.saturating_mul(v.f_frsize))
}

/// Write the results so far, all or nothing: `scale.json`, `.csv` and
/// `.md` together (a failure leaves the previous ones), then the plots.
pub fn write_results(out: &Path, r: &ScaleReport) -> Result<()> {
    let json = super::report::json_bytes(r)?;
    let csv = csv(r);
    let md = markdown(r);
    let (pj, pc, pm) = (out.join("scale.json"), out.join("scale.csv"), out.join("scale.md"));
    crate::fsio::write_all(&[(pj.as_path(), json.as_slice()), (pc.as_path(), csv.as_bytes()), (pm.as_path(), md.as_bytes())])?;
    plots(out, r)
}

/// The study: the estimate checked, then every level refined, written to
/// `out/meshes/`, run by each method in a fresh process of `exe`, and by
/// the peers; the results written after each level (`write_results`).
pub fn study(exe: &Path, s: &ScaleSettings, out: &Path, mut progress: impl FnMut(&str)) -> Result<ScaleReport> {
    use super::datasets::{self, DatasetData};
    let loaded = datasets::load_with(&s.dataset, s.cell_data)?;
    let name = loaded.name.clone();
    let DatasetData::TetMesh { mesh, .. } = loaded.data else {
        bail!("--data {}: a {} dataset; scale refines tetrahedral meshes", s.dataset, loaded.kind().name());
    };
    if let Some(info) = mesh.stats.scalar.as_ref().filter(|_| !mesh.stats.vertex_origin.is_empty()) {
        bail!(
            "--data {}: its scalar is the cell array '{}', shown constant per cell; scale writes each level as a mesh \
             with point data and reads it back, which cannot keep cells constant: use --cell-data average",
            s.dataset,
            info.array
        );
    }
    let peers = s.peers.iter().map(|p| super::peers::locate(p)).collect::<Result<Vec<_>>>()?;
    estimate(&mesh, &name, s).check(available_memory(), available_disk(out), out)?;
    stop_cleanly_on_signals()?;
    let _lock = crate::fsio::lock_out_dir("--out", out)?;
    let meshes = out.join("meshes");
    std::fs::create_dir_all(&meshes).with_context(|| format!("creating {}", meshes.display()))?;
    staging().dirs = vec![out.to_path_buf(), meshes.clone(), out.join("peers")];
    let json = out.join(".run.json");
    let mut report = ScaleReport {
        schema: "volbench-scale/1",
        dataset: name.clone(),
        width: s.width,
        height: s.height,
        frames: s.frames,
        warmup: s.warmup,
        levels: Vec::new(),
        rows: Vec::new(),
    };
    let mut mesh = mesh;
    for level in 0..=s.levels {
        let kept = if level == 0 {
            "no level finished: no results written".to_string()
        } else {
            format!("scale.json, .csv and .md in {} hold levels 0 to {}", out.display(), level - 1)
        };
        let done = run_level(exe, s, out, &name, level, &mut mesh, &peers, &json, &mut report, &mut progress);
        if let Err(e) = done {
            staging().clean();
            return Err(e.context(format!("level {level} ({kept}; its own files removed)")));
        }
    }
    let _ = std::fs::remove_file(&json);
    Ok(report)
}

/// One level: refined, written, run, and the results rewritten.
#[allow(clippy::too_many_arguments)]
fn run_level(
    exe: &Path,
    s: &ScaleSettings,
    out: &Path,
    name: &str,
    level: usize,
    mesh: &mut TetMesh,
    peers: &[super::peers::LocatedPeer],
    json: &Path,
    report: &mut ScaleReport,
    progress: &mut impl FnMut(&str),
) -> Result<()> {
    use super::datasets::Dataset;
    let meshes = out.join("meshes");
    let file = meshes.join(format!("{name}-L{level}.vtk"));
    staging().files = vec![file.clone(), json.to_path_buf()];
    let refine_ms = if level > 0 {
        progress(&format!("level {level}: refining {} tets", mesh.tets.len()));
        let (refined, ms) = timed(|| refine_checked(mesh, level, available_memory()));
        *mesh = refined?;
        ms
    } else {
        0.0
    };
    super::peers::write_tet_mesh(mesh, &mesh_title(name, level), &file)?;
    let cells = mesh.tets.len() as u64;
    let run_args: Vec<String> = vec![
        "--size".into(),
        format!("{}x{}", s.width, s.height),
        "--frames".into(),
        s.frames.to_string(),
        "--warmup".into(),
        s.warmup.to_string(),
    ];
    for (spec, label) in &s.specs {
        progress(&format!("level {level} ({cells} tets): {label}"));
        let row = run_method(exe, &file, spec, level, label, &run_args, json).unwrap_or_else(|e| failed_row(level, mesh, label, format!("{e:#}")));
        report.rows.push(row);
    }
    let needs_dataset = cells <= s.reference_max_cells || !peers.is_empty();
    let dataset = needs_dataset.then(|| Dataset::from_mesh(mesh.clone(), false, file.to_string_lossy().into_owned()));
    let mut reference_ms = None;
    if let Some(ds) = dataset.as_ref().filter(|_| cells <= s.reference_max_cells) {
        progress(&format!("level {level}: f64 reference"));
        let tf = ds.default_transfer_function()?;
        let camera = ds.orbit_camera(0.0, crate::scene::Projection::Perspective { fovy_deg: 30.0 });
        let (image, ms) = timed(|| ds.reference_image(&tf, &camera, s.width, s.height));
        image?;
        reference_ms = Some(ms);
    }
    for peer in peers {
        let Some(ds) = &dataset else { break };
        // VTK's projected tetrahedra: the cell-projection peer (its
        // unstructured ray caster is not what the study sets beside).
        for renderer in peer.renderers_for(ds.kind()).filter(|r| r.name == "projected-tetrahedra") {
            let label = format!("peer {}/{}", peer.peer.name, renderer.name);
            progress(&format!("level {level} ({cells} tets): {label}"));
            let row = run_peer_level(peer, renderer, ds, s, level, &file, out).unwrap_or_else(|e| failed_row(level, mesh, &label, format!("{e:#}")));
            report.rows.push(row);
        }
    }
    report.levels.push(ScaleLevel {
        level,
        cells,
        points: mesh.points.len() as u64,
        file: file.to_string_lossy().into_owned(),
        refine_ms,
        reference_ms,
    });
    // The results written while no stop signal can interrupt them (the
    // handler waits for the lock); then the level's files are results.
    let mut staged = staging();
    let _ = std::fs::remove_file(json);
    write_results(out, report).context("writing the results")?;
    staged.keep();
    Ok(())
}

fn run_peer_level(
    peer: &super::peers::LocatedPeer,
    renderer: &'static super::peers::PeerRenderer,
    ds: &super::datasets::Dataset,
    s: &ScaleSettings,
    level: usize,
    file: &Path,
    out: &Path,
) -> Result<ScaleRow> {
    use super::peers;
    let cfg = super::run::RunConfig { width: s.width, height: s.height, frames: s.frames, warmup: s.warmup, ..Default::default() };
    let exported = peers::PeerDataset {
        name: ds.name.clone(),
        kind: ds.kind().name().to_string(),
        file: file.to_string_lossy().into_owned(),
        format: "vtk-legacy-unstructured-grid".into(),
        digest: ds.digest.clone(),
        original: false,
        solution_file: None,
        scalar: peers::PeerScalar { array: Some("scalars".into()), ..Default::default() },
    };
    let dir = out.join("peers");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let tf = ds.default_transfer_function()?;
    let scene = peers::scene(peer.peer, renderer, ds, &tf, &cfg, &exported, &dir)?;
    let scene_path = dir.join(format!("{}-L{level}.json", scene.stem()));
    staging().files.push(scene_path.clone());
    let (result, _image) = peers::run_peer(peer, &scene, &scene_path)?;
    let frame = super::stats::Summary::of(&result.frame_ms).median;
    let v = serde_json::json!({
        "cells": ds.summary().counts.get("cells"),
        "points": ds.summary().counts.get("points"),
        "time_ms": { "frame": { "median": frame } },
    });
    Ok(row_from_run(level, &format!("peer {}/{}", peer.peer.name, renderer.name), &v, None))
}

/// The rows as CSV (one line per method and level, the common phases).
pub fn csv(r: &ScaleReport) -> String {
    let mut phases: Vec<&String> = r.rows.iter().flat_map(|row| row.phases_ms.keys()).collect();
    phases.sort();
    phases.dedup();
    let mut out = String::from("level,cells,points,method,status,frame_ms,ms_per_mtet,tets_per_second,bytes_per_frame,static_device_bytes,peak_rss_bytes,peak_rss_bytes_per_tet");
    for p in &phases {
        out += &format!(",{p}_ms");
    }
    out += "\n";
    let o = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6}"));
    let u = |v: Option<u64>| v.map_or(String::new(), |v| v.to_string());
    for row in &r.rows {
        out += &format!(
            "{},{},{},\"{}\",{},{},{},{},{},{},{},{}",
            row.level,
            row.cells,
            row.points,
            row.method,
            row.status,
            o(row.frame_ms),
            o(row.ms_per_mtet),
            o(row.tets_per_second),
            u(row.bytes_per_frame),
            u(row.static_device_bytes),
            u(row.peak_rss_bytes),
            o(row.peak_rss_bytes_per_tet)
        );
        for p in &phases {
            out += &format!(",{}", o(row.phases_ms.get(*p).copied()));
        }
        out += "\n";
    }
    out
}

/// The report as Markdown: levels, then one row per method and level.
pub fn markdown(r: &ScaleReport) -> String {
    let mut out = format!(
        "# Scaling: {} red-refined, {}x{}, {} timed frames (+{} warm-up)\n\n| level | tets | points | refine ms | f64 reference ms |\n|---:|---:|---:|---:|---:|\n",
        super::report::md_cell(&r.dataset), r.width, r.height, r.frames, r.warmup
    );
    for l in &r.levels {
        let reference = l.reference_ms.map_or("-".into(), |v| format!("{v:.0}"));
        out += &format!("| {} | {} | {} | {:.0} | {reference} |\n", l.level, l.cells, l.points, l.refine_ms);
    }
    out += "\n| method | level | tets | frame ms | ms per M tets | M tets/s | bytes/frame | static device bytes | peak RSS MB | RSS bytes/tet | phases (median ms) |\n";
    out += "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
    let f = |v: Option<f64>, d: usize| v.map_or("-".into(), |v| format!("{v:.d$}"));
    let cell = super::report::md_cell;
    for row in &r.rows {
        if let Some(e) = &row.error {
            out += &format!("| {} | {} | {} | failed: {} | | | | | | | |\n", cell(&row.method), row.level, row.cells, cell(e));
            continue;
        }
        let phases: Vec<String> = row.phases_ms.iter().filter(|(k, _)| k.as_str() != "frame").map(|(k, v)| format!("{k} {v:.1}")).collect();
        out += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            cell(&row.method),
            row.level,
            row.cells,
            f(row.frame_ms, 1),
            f(row.ms_per_mtet, 1),
            f(row.tets_per_second.map(|t| t / 1e6), 2),
            row.bytes_per_frame.map_or("-".into(), |b| b.to_string()),
            row.static_device_bytes.map_or("-".into(), |b| b.to_string()),
            f(row.peak_rss_bytes.map(|b| b as f64 / 1e6), 0),
            f(row.peak_rss_bytes_per_tet, 0),
            cell(&phases.join(", "))
        );
    }
    out
}

/// Log-log plots of frame time and peak RSS against tets, one line per
/// method: `<dir>/scale_time.{png,svg}` and `<dir>/scale_memory.{png,svg}`.
pub fn plots(dir: &Path, r: &ScaleReport) -> Result<()> {
    super::plots::register_font()?;
    let mut methods: Vec<&str> = r.rows.iter().map(|x| x.method.as_str()).collect();
    methods.dedup();
    let mut seen = Vec::new();
    methods.retain(|m| if seen.contains(m) { false } else { seen.push(*m); true });
    type Pick = fn(&ScaleRow) -> Option<f64>;
    let charts: [(&str, String, Pick); 2] = [
        ("scale_time", format!("median frame time (ms) against tets, {} refined, {}x{}", r.dataset, r.width, r.height), |x| x.frame_ms),
        ("scale_memory", format!("peak resident memory (MB) against tets, {} refined", r.dataset), |x| x.peak_rss_bytes.map(|b| b as f64 / 1e6)),
    ];
    for (name, title, pick) in charts {
        let series: Vec<(String, Vec<(f64, f64)>)> = methods
            .iter()
            .map(|m| {
                let pts = r.rows.iter().filter(|x| x.method == *m).filter_map(|x| Some((x.cells as f64, pick(x)?))).filter(|p| p.0 > 0.0 && p.1 > 0.0).collect();
                (m.to_string(), pts)
            })
            .filter(|(_, p): &(String, Vec<(f64, f64)>)| !p.is_empty())
            .collect();
        if series.is_empty() {
            continue;
        }
        let (w, h) = (900u32, 600u32);
        let mut rgb = vec![0u8; (w * h * 3) as usize];
        draw_loglog(plotters::prelude::BitMapBackend::with_buffer(&mut rgb, (w, h)), &title, &series)?;
        super::image::write_rgb8_png(&dir.join(format!("{name}.png")), w, h, &rgb)?;
        let mut svg = String::new();
        draw_loglog(plotters::prelude::SVGBackend::with_string(&mut svg, (w, h)), &title, &series)?;
        crate::fsio::write_output(&dir.join(format!("{name}.svg")), svg.as_bytes())?;
    }
    Ok(())
}

fn draw_loglog<B: plotters::prelude::DrawingBackend>(backend: B, title: &str, series: &[(String, Vec<(f64, f64)>)]) -> Result<()> {
    use plotters::prelude::*;
    let root = backend.into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let all = series.iter().flat_map(|s| s.1.iter());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in all {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(20)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (x0 / 1.5..x1 * 1.5).log_scale().with_key_points(super::plots::log_ticks(x0 / 1.5, x1 * 1.5)),
                (y0 / 1.5..y1 * 1.5).log_scale().with_key_points(super::plots::log_ticks(y0 / 1.5, y1 * 1.5)),
            )
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("tets")
            .label_style(("sans-serif", 14))
            .x_label_formatter(&|v| super::plots::count_label(*v))
            .y_label_formatter(&|v| if *v >= 10.0 { format!("{v:.0}") } else { format!("{v:.1}") })
            .draw().map_err(|e| e.to_string())?;
        for (i, (name, pts)) in series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(name.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled()))).map_err(|e| e.to_string())?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
        Ok(())
    };
    draw().map_err(|e| anyhow::anyhow!("drawing '{title}': {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vm_hwm_is_read_in_kb() {
        assert_eq!(vm_hwm_kb("Name:\tx\nVmPeak:\t  10 kB\nVmHWM:\t  1234 kB\n"), Some(1234));
        assert_eq!(vm_hwm_kb("Name:\tx\n"), None);
    }

    fn one_tet() -> TetMesh {
        let mut m = TetMesh {
            name: "t".into(),
            points: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            scalars: vec![0.0; 4],
            tets: vec![[0, 1, 2, 3]],
            stats: Default::default(),
        };
        m.validate("t").unwrap();
        m
    }

    fn settings(levels: usize) -> ScaleSettings {
        ScaleSettings {
            dataset: "t".into(),
            levels,
            specs: Vec::new(),
            width: 64,
            height: 64,
            frames: 1,
            warmup: 0,
            reference_max_cells: 0,
            peers: Vec::new(),
            cell_data: Default::default(),
        }
    }

    #[test]
    fn the_estimate_knows_every_level_and_refuses_with_the_figures() {
        let m = one_tet();
        let d = tempfile::tempdir().unwrap();
        // The sizes of every level, before any is made; level 0's file is
        // the size the writer writes.
        let two = estimate(&m, "t", &settings(2));
        let real = red_refine(&red_refine(&m).unwrap()).unwrap();
        assert_eq!((two.levels[2].counts.tets, two.levels[2].counts.points), (64, real.points.len() as u128));
        let file = d.path().join("t.vtk");
        super::super::peers::write_tet_mesh(&real, &mesh_title("t", 2), &file).unwrap();
        assert_eq!(two.levels[2].file_bytes, u128::from(std::fs::metadata(&file).unwrap().len()));
        // Two sizes against one budget: 2 levels fit, 8 do not (memory and
        // disk both named, with the level, the figures and the way out).
        let eight = estimate(&m, "t", &settings(8));
        assert_eq!(eight.levels[8].counts.tets, 1 << 24);
        let (mem, disk) = (512u64 << 20, 256u64 << 20);
        two.check(Some(mem), Some(disk), d.path()).unwrap();
        assert!(eight.memory_bytes > u128::from(mem) && two.memory_bytes < u128::from(mem));
        let e = eight.check(Some(mem), Some(disk), d.path()).unwrap_err().to_string();
        assert!(e.contains("--levels 8") && e.contains("host memory") && e.contains("at level 8 (16777216 tets)"), "{e}");
        assert!(e.contains("0.50 GiB available") && e.contains("use fewer --levels"), "{e}");
        assert!(e.contains("disk: about") && e.contains("L8 "), "{e}");
        // Disk alone, and unknown figures are not checked.
        let e = two.check(Some(mem), Some(1000), d.path()).unwrap_err().to_string();
        assert!(e.contains("disk") && !e.contains("host memory"), "{e}");
        eight.check(None, None, d.path()).unwrap();
        assert!(available_disk(&d.path().join("not/yet")).is_some_and(|b| b > 0));
    }

    #[test]
    fn a_failed_results_write_keeps_the_previous_complete_files() {
        let d = tempfile::tempdir().unwrap();
        let m = one_tet();
        let mut r = ScaleReport { schema: "volbench-scale/1", dataset: "t".into(), width: 8, height: 8, frames: 1, warmup: 0, levels: Vec::new(), rows: Vec::new() };
        let level = |l: usize| ScaleLevel { level: l, cells: 8u64.pow(l as u32), points: 4, file: String::new(), refine_ms: 1.0, reference_ms: None };
        r.levels.push(level(0));
        r.rows.push(failed_row(0, &m, "balanced", "x".into()));
        write_results(d.path(), &r).unwrap();
        let json = std::fs::read(d.path().join("scale.json")).unwrap();
        // Level 1: scale.md is now a directory, so nothing of the set is
        // replaced and no temporary is left.
        std::fs::remove_file(d.path().join("scale.md")).unwrap();
        std::fs::create_dir(d.path().join("scale.md")).unwrap();
        r.levels.push(level(1));
        r.rows.push(failed_row(1, &m, "balanced", "y".into()));
        let e = format!("{:#}", write_results(d.path(), &r).unwrap_err());
        assert!(e.contains("scale.md") && e.contains("directory"), "{e}");
        assert_eq!(std::fs::read(d.path().join("scale.json")).unwrap(), json);
        assert!(std::fs::read_to_string(d.path().join("scale.csv")).unwrap().lines().count() == 2);
        let temps = std::fs::read_dir(d.path()).unwrap().filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().ends_with(".tmp")).count();
        assert_eq!(temps, 0);
    }

    #[test]
    fn a_label_or_error_cannot_forge_a_row() {
        let m = one_tet();
        let mut r = ScaleReport { schema: "volbench-scale/1", dataset: "t\n| x |".into(), width: 8, height: 8, frames: 1, warmup: 0, levels: Vec::new(), rows: Vec::new() };
        r.rows.push(failed_row(0, &m, "a|b", "line\n| forged | 0 | 1 |".into()));
        let md = markdown(&r);
        assert!(!md.lines().any(|l| l.starts_with("| forged")), "{md}");
        assert!(md.contains("| a\\|b | 0 | 1 | failed: line\\n\\| forged"), "{md}");
    }

    #[test]
    fn refinement_beyond_memory_is_a_clear_error() {
        let m = one_tet();
        let e = refine_checked(&m, 3, Some(100)).unwrap_err().to_string();
        assert!(e.contains("level 3") && e.contains("host memory") && e.contains("--levels"), "{e}");
        assert_eq!(refine_checked(&m, 1, None).unwrap().tets.len(), 8);
    }
}
