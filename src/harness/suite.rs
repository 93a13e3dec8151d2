//! `volbench suite`: every registered method on every shipped dataset of its
//! kind at standard settings, one command, one folder a researcher can cite:
//! `summary.json` (every run in the common schema plus the environment),
//! `summary.csv`, `report.md`, plots (PNG and SVG) and a montage of the
//! rendered images with their difference from the f64 reference. A failing
//! row is recorded and the suite goes on; a method the device cannot run is
//! recorded as skipped. Nothing here names a method: the plan is the
//! registry crossed with the shipped datasets.

use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context as _, Result};
use serde::Serialize;

use super::datasets::{self, Dataset};
use super::peers::{LocatedPeer, PeerRenderer, PeerRow};
use super::image::RgbaImage;
use super::reference_cache::reference_image;
use super::run::{run, RunConfig, RunOutput, RunResult};
use super::sweep::skip_reason;
use crate::algo::registry::{MethodSpec, Registry};
use crate::fsio;
use crate::vk::{Context, DeviceInfo};

/// How the suite runs: standard settings, or `--quick` ones.
#[derive(Debug, Clone, Serialize)]
pub struct SuiteSettings {
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    pub orbit_step_deg: f64,
    pub quick: bool,
    /// Only runs whose method or dataset name is listed (empty: all).
    pub filter: Vec<String>,
    /// Peers (`--peers`, see `harness::peers`) run on the same datasets,
    /// alternating with volbench's runs.
    pub peers: Vec<String>,
}

impl SuiteSettings {
    pub fn standard(quick: bool, filter: Vec<String>) -> Self {
        if quick {
            SuiteSettings { width: 256, height: 256, frames: 3, warmup: 1, orbit_step_deg: 5.0, quick, filter, peers: Vec::new() }
        } else {
            SuiteSettings { width: 512, height: 512, frames: 20, warmup: 3, orbit_step_deg: 5.0, quick, filter, peers: Vec::new() }
        }
    }

    fn run_config(&self) -> RunConfig {
        RunConfig {
            width: self.width,
            height: self.height,
            frames: self.frames,
            warmup: self.warmup,
            orbit_step: self.orbit_step_deg.to_radians(),
            diagnostics: true,
            ..RunConfig::default()
        }
    }
}

/// One planned run: a shipped dataset and a method at its defaults, or with
/// an option set a published figure names.
#[derive(Debug)]
pub struct PlannedRun {
    pub dataset: &'static str,
    pub spec: MethodSpec,
}

/// Every (shipped dataset, method for its kind) pair that passes the
/// filter: the defaults, then each option set a published figure about the
/// method on that dataset names (so every published ratio has its measured
/// counterpart in the same run).
pub fn plan(registry: &Registry, settings: &SuiteSettings) -> Result<Vec<PlannedRun>> {
    let keep = |name: &str| settings.filter.is_empty() || settings.filter.iter().any(|f| f == name);
    for f in &settings.filter {
        let known = datasets::NAMED.iter().any(|d| d.name == f) || registry.names().contains(&f.as_str());
        anyhow::ensure!(known, "--filter {f}: neither a registered method nor a shipped dataset (see `volbench list`)");
    }
    let mut out = Vec::new();
    for d in datasets::NAMED {
        for m in registry.for_kind(d.kind) {
            if keep(d.name) || keep(m.name) {
                let mut specs = vec![registry.parse_spec(m.name, &[])?];
                for p in m.published.iter().filter(|p| p.applies_to(d.name)) {
                    let s = registry.published_spec(p)?;
                    if !specs.iter().any(|x| x.canonical() == s.canonical()) {
                        specs.push(s);
                    }
                }
                out.extend(specs.into_iter().map(|spec| PlannedRun { dataset: d.name, spec }));
            }
        }
    }
    anyhow::ensure!(!out.is_empty(), "--filter {:?} leaves nothing to run", settings.filter);
    // A peer that is not installed is an error before anything runs.
    for p in &settings.peers {
        super::peers::locate(p)?;
    }
    Ok(out)
}

/// The machine a suite ran on.
#[derive(Debug, Clone, Serialize)]
pub struct Environment {
    pub device: DeviceInfo,
    pub cpu_model: String,
    pub cores: usize,
    /// lavapipe's thread count (`LP_NUM_THREADS`), when set.
    pub lp_num_threads: Option<String>,
    pub git_sha: &'static str,
    pub volbench_version: &'static str,
    pub started_utc: String,
}

impl Environment {
    pub fn of(ctx: &Context) -> Self {
        let cpu_model = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|t| t.lines().find(|l| l.starts_with("model name")).and_then(|l| l.split_once(':')).map(|(_, v)| v.trim().to_string()))
            .unwrap_or_else(|| "unknown".into());
        Environment {
            device: ctx.info.clone(),
            cpu_model,
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            lp_num_threads: std::env::var("LP_NUM_THREADS").ok(),
            git_sha: env!("VOLBENCH_GIT_SHA"),
            volbench_version: env!("CARGO_PKG_VERSION"),
            started_utc: utc_now(),
        }
    }
}

/// The current UTC time as `YYYYMMDDTHHMMSSZ` (for run ids).
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (days, rem) = (secs / 86400, secs % 86400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}{m:02}{d:02}T{:02}{:02}{:02}Z", rem / 3600, (rem / 60) % 60, rem % 60)
}

/// One row of the suite: the run's record, or why it failed or was skipped.
#[derive(Debug, Clone, Serialize)]
pub struct SuiteRow {
    pub dataset: String,
    pub method: String,
    /// The method and its non-default options (`balanced:integrator=average`).
    pub label: String,
    pub status: &'static str,
    pub message: Option<String>,
    /// Position in the suite's run order (peers' runs counted too).
    pub sequence: usize,
    pub result: Option<RunResult>,
}

/// What `summary.json` holds.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub environment: Environment,
    pub settings: SuiteSettings,
    pub runs: Vec<SuiteRow>,
    /// Peers' runs (`--peers`), apart from volbench's: other programs'
    /// renderers on the same data, view and transfer function.
    pub peers: Vec<PeerRow>,
}

/// Run the plan; each row's JSON, PNG and difference PNG go to
/// `out/runs/` as it completes, and `summary.json` is rewritten after each.
pub fn run_suite(
    ctx: &Arc<Context>,
    registry: &Registry,
    plan: &[PlannedRun],
    settings: &SuiteSettings,
    out: &Path,
    mut progress: impl FnMut(usize, &str),
) -> Result<Summary> {
    let cfg = settings.run_config();
    cfg.check_device(&ctx.info)?;
    let runs_dir = out.join("runs");
    std::fs::create_dir_all(&runs_dir).with_context(|| format!("creating {}", runs_dir.display()))?;
    let mut summary = Summary { environment: Environment::of(ctx), settings: settings.clone(), runs: Vec::new(), peers: Vec::new() };
    let mut images: Vec<(String, RgbaImage, Option<RgbaImage>)> = Vec::new();
    let located: Vec<LocatedPeer> = settings.peers.iter().map(|p| super::peers::locate(p)).collect::<Result<_>>()?;
    let peers_dir = out.join("peers");
    if !located.is_empty() {
        std::fs::create_dir_all(&peers_dir).with_context(|| format!("creating {}", peers_dir.display()))?;
    }
    let mut loaded: Option<(&str, Dataset)> = None;
    // Peer renderers still to run on the current dataset, and its exported copy.
    let mut pending: Vec<(&LocatedPeer, &'static PeerRenderer)> = Vec::new();
    let mut export: Option<(std::path::PathBuf, super::peers::PeerDataset)> = None;
    let mut sequence = 0usize;
    for (i, p) in plan.iter().enumerate() {
        let label = format!("{} on {}", p.spec.label(), p.dataset);
        progress(i, &label);
        let first_of_dataset = i == 0 || plan[i - 1].dataset != p.dataset;
        let last_of_dataset = plan.get(i + 1).is_none_or(|n| n.dataset != p.dataset);
        if loaded.as_ref().is_none_or(|(n, _)| *n != p.dataset) {
            loaded = Some((p.dataset, datasets::load(p.dataset)?));
        }
        let Some((_, dataset)) = &loaded else { continue };
        if first_of_dataset {
            // Popped from the end: reversed so they run in their listed order.
            pending = located.iter().flat_map(|l| l.renderers_for(dataset.kind()).map(move |r| (l, r))).collect();
            pending.reverse();
        }
        let mut row = SuiteRow {
            dataset: p.dataset.into(),
            method: p.spec.info.name.into(),
            label: p.spec.label(),
            status: "ok",
            message: None,
            sequence,
            result: None,
        };
        sequence += 1;
        if let Some(why) = skip_reason(&p.spec, &ctx.info) {
            (row.status, row.message) = ("skipped", Some(why));
        } else {
            let outcome = (|| -> Result<(RunOutput, Option<RgbaImage>)> {
                let tf = dataset.default_transfer_function();
                let mut r = run(ctx, &p.spec, dataset, &tf, &cfg)?;
                let stem = format!("{}-{}", p.dataset, p.spec.file_stem());
                let (json, png, dpng) = (runs_dir.join(format!("{stem}.json")), runs_dir.join(format!("{stem}.png")), runs_dir.join(format!("{stem}-diff.png")));
                // A method with its own error (terrain) has no image reference.
                let diff = if r.result.error.is_none() {
                    let reference = reference_image(dataset, &tf, &r.result.image.camera, cfg.width, cfg.height)?;
                    Some(r.attach_error(&reference)?)
                } else {
                    None
                };
                let bytes = [super::report::json_bytes(&r.result)?, r.image.png_bytes()?];
                match &diff {
                    Some(d) => fsio::write_all(&[(&json, &bytes[0]), (&png, &bytes[1]), (&dpng, &d.png_bytes()?)])?,
                    None => fsio::write_all(&[(&json, &bytes[0]), (&png, &bytes[1])])?,
                }
                Ok((r, diff))
            })();
            match outcome {
                Ok((r, diff)) => {
                    images.push((label.clone(), r.image, diff));
                    row.result = Some(r.result);
                }
                Err(e) => (row.status, row.message) = ("failed", Some(format!("{e:#}"))),
            }
        }
        summary.runs.push(row);
        // Peers alternate with volbench's runs on the same dataset (one after
        // each run; the rest after the dataset's last run), so that machine
        // noise hits both.
        let take = if last_of_dataset { pending.len() } else { pending.len().min(1) };
        for _ in 0..take {
            let Some((peer, renderer)) = pending.pop() else { break };
            let label = format!("peer {}/{} on {}", peer.peer.name, renderer.name, p.dataset);
            progress(i, &label);
            let (row, shown) = run_peer_row(peer, renderer, dataset, &cfg, &peers_dir, &runs_dir, &mut export, sequence);
            sequence += 1;
            if let Some((image, diff)) = shown {
                images.push((label, image, Some(diff)));
            }
            summary.peers.push(row);
        }
        if last_of_dataset {
            // The exported copy is only the peers' input: not a result.
            if let Some((path, _)) = export.take() {
                let _ = std::fs::remove_file(path);
            }
        }
        fsio::write_output(&out.join("summary.json"), &super::report::json_bytes(&summary)?)?;
    }
    fsio::write_output(&out.join("summary.json"), &super::report::json_bytes(&summary)?)?;
    fsio::write_output(&out.join("summary.csv"), csv(&summary).as_bytes())?;
    fsio::write_output(&out.join("report.md"), report(&summary, registry).as_bytes())?;
    super::plots::bar_charts(&out.join("plots"), &summary)?;
    if !images.is_empty() {
        super::plots::montage(&out.join("montage.png"), &images)?;
    }
    Ok(summary)
}

/// One peer renderer on one dataset: the dataset exported once per dataset
/// (`export`), the scene written, the peer run, its image compared with the
/// same f64 reference as volbench's runs. A failure is the row's status.
#[allow(clippy::too_many_arguments)]
fn run_peer_row(
    peer: &LocatedPeer,
    renderer: &'static PeerRenderer,
    dataset: &Dataset,
    cfg: &RunConfig,
    peers_dir: &Path,
    runs_dir: &Path,
    export: &mut Option<(std::path::PathBuf, super::peers::PeerDataset)>,
    sequence: usize,
) -> (PeerRow, Option<(RgbaImage, RgbaImage)>) {
    use super::peers as pe;
    let mut row = PeerRow {
        peer: peer.peer.name.into(),
        renderer: renderer.name.into(),
        class: renderer.class.into(),
        dataset: dataset.name.clone(),
        status: "ok",
        message: None,
        sequence,
        library_version: None,
        gl_renderer: None,
        opacity_model: None,
        frame_ms: None,
        frame_samples_ms: Vec::new(),
        setup_ms: None,
        error: None,
        covered_pixels: None,
    };
    let outcome = (|| -> Result<(pe::PeerResult, RgbaImage, RgbaImage, super::image::ImageError, String)> {
        if export.is_none() {
            let path = peers_dir.join(format!("{}.vtk", dataset.name));
            let d = pe::write_dataset(dataset, &path).with_context(|| format!("exporting '{}' for the peers", dataset.name))?;
            *export = Some((path, d));
        }
        let Some((_, exported)) = export.as_ref() else { anyhow::bail!("internal: dataset not exported") };
        let tf = dataset.default_transfer_function();
        let scene = pe::scene(peer.peer, renderer, dataset, &tf, cfg, exported, peers_dir)?;
        let stem = scene.stem();
        let reference_camera = scene.reference_camera;
        let (result, image) = pe::run_peer(peer, &scene, &peers_dir.join(format!("{stem}.scene.json")))?;
        let reference = reference_image(dataset, &tf, &reference_camera, cfg.width, cfg.height)?;
        let error = image.compare(&reference.image)?;
        let diff = image.difference(&reference.image);
        let (png, dpng) = (runs_dir.join(format!("{stem}.png")), runs_dir.join(format!("{stem}-diff.png")));
        let bytes = [image.png_bytes()?, diff.png_bytes()?];
        fsio::write_all(&[(&png, &bytes[0]), (&dpng, &bytes[1])])?;
        // The raw image was only the transport; the PNG is the record.
        let _ = std::fs::remove_file(&scene.output.image);
        Ok((result, image, diff, error, scene.transfer_function.opacity_model))
    })();
    match outcome {
        Ok((result, image, diff, error, model)) => {
            row.library_version = Some(result.library_version);
            row.gl_renderer = Some(result.gl_renderer);
            row.opacity_model = Some(model);
            row.frame_ms = Some(super::stats::Summary::of(&result.frame_ms));
            row.frame_samples_ms = result.frame_ms;
            row.setup_ms = Some(result.load_ms + result.setup_ms);
            row.error = Some(error);
            row.covered_pixels = Some(image.covered_pixels());
            (row, Some((image, diff)))
        }
        Err(e) => {
            (row.status, row.message) = ("failed", Some(format!("{e:#}")));
            (row, None)
        }
    }
}

/// The peers' section of the report: each peer renderer's frame time and
/// error against the same f64 reference, and each volbench run's speed
/// ratio to it (measured in this run, alternating, so the ratio is
/// comparable where absolute times across machines are not).
pub fn peer_report(s: &Summary) -> String {
    if s.peers.is_empty() {
        return String::new();
    }
    let mut t = String::from(
        "\n## Peers measured in the same run\n\nOther programs' renderers given the same data, camera path, transfer function and image size, \
         run alternating with volbench's runs. A peer frame is its Render() plus glFinish (VTK: WaitForCompletion); \
         its image is compared with the same f64 reference (RGBA, 8-bit framebuffer). \
         The transfer function is encoded for each renderer's opacity model (`attenuation`: exact; `correction`: resampled, see `harness::peers`).\n\n\
         | dataset | peer | renderer (class) | status | frame ms median [min, max] | RMSE vs f64 | max err | opacity model |\n|---|---|---|---|---|---:|---:|---|\n",
    );
    for p in &s.peers {
        match (&p.frame_ms, &p.error) {
            (Some(f), Some(e)) => {
                let _ = writeln!(
                    t,
                    "| {} | {} {} | {} (`{}`) | ok | {:.1} [{:.1}, {:.1}] | {:.2e} | {:.2e} | {} |",
                    p.dataset,
                    p.peer,
                    p.library_version.as_deref().unwrap_or(""),
                    p.renderer,
                    p.class,
                    f.median,
                    f.min,
                    f.max,
                    e.rmse,
                    e.max_abs,
                    p.opacity_model.as_deref().unwrap_or("")
                );
            }
            _ => {
                let _ = writeln!(
                    t,
                    "| {} | {} | {} (`{}`) | {}: {} |||||",
                    p.dataset,
                    p.peer,
                    p.renderer,
                    p.class,
                    p.status,
                    p.message.as_deref().unwrap_or("").replace('|', "/")
                );
            }
        }
    }
    let mut ratios = String::new();
    for r in &s.runs {
        let Some(x) = &r.result else { continue };
        let ours = x.time_ms.phase("frame").median;
        for p in s.peers.iter().filter(|p| p.dataset == r.dataset) {
            let (Some(f), Some(e)) = (&p.frame_ms, &p.error) else { continue };
            if ours > 0.0 {
                let _ = writeln!(
                    ratios,
                    "| {} | {} | {}/{} | {:.1} | {:.1} | **{:.2}** | {} | {:.2e} |",
                    r.dataset,
                    r.label,
                    p.peer,
                    p.renderer,
                    ours,
                    f.median,
                    f.median / ours,
                    x.error.as_ref().map_or("-".into(), |e| format!("{:.2e}", e.rmse)),
                    e.rmse
                );
            }
        }
    }
    if !ratios.is_empty() {
        t += "\nSpeed ratio = peer's median frame time / volbench's (above 1: volbench is faster), same run, same machine.\n\n\
              | dataset | volbench method | peer | volbench ms | peer ms | speed ratio | volbench RMSE | peer RMSE |\n|---|---|---|---:|---:|---:|---:|---:|\n";
        t += &ratios;
    }
    t
}

/// One line per run: the figures a spreadsheet wants.
pub fn csv(s: &Summary) -> String {
    let mut t = String::from(
        "dataset,method,label,status,frame_ms_median,gpu_ms_median,bytes_per_frame,bytes_per_cell,static_bytes,cells_per_second,rmse,max_abs,message\n",
    );
    for r in &s.runs {
        let q = |x: &str| format!("\"{}\"", x.replace('"', "\"\""));
        let (f, g, b, bc, st, cps, rmse, max) = match &r.result {
            Some(x) => (
                format!("{:.3}", x.time_ms.phase("frame").median),
                format!("{:.3}", x.time_ms.phase("gpu").median),
                x.upload.bytes_per_frame.to_string(),
                x.upload.bytes_per_cell.map_or(String::new(), |v| format!("{v}")),
                x.upload.static_bytes.to_string(),
                format!("{:.0}", x.cells_per_second),
                x.error.as_ref().map_or(String::new(), |e| format!("{:.6e}", e.rmse)),
                x.error.as_ref().map_or(String::new(), |e| format!("{:.6e}", e.max_abs)),
            ),
            None => Default::default(),
        };
        let _ = writeln!(
            t,
            "{},{},{},{},{f},{g},{b},{bc},{st},{cps},{rmse},{max},{}",
            r.dataset,
            r.method,
            q(&r.label),
            r.status,
            q(r.message.as_deref().unwrap_or(""))
        );
    }
    t
}

/// The report: environment, the runs table, and measured figures set
/// beside the published ones as ratios between methods on the same dataset
/// (absolute times from other hardware are not comparable; ratios are).
pub fn report(s: &Summary, registry: &Registry) -> String {
    let e = &s.environment;
    let mut t = format!(
        "# volbench suite {}\n\nDevice {} ({}, {}), CPU {} ({} cores, LP_NUM_THREADS {}), volbench {} at {}. \
         Settings: {}x{}, {} timed frames after {} warm-up, camera orbiting {}° per frame{}.\n\n",
        e.started_utc,
        e.device.name,
        e.device.driver_name,
        e.device.driver_info,
        e.cpu_model,
        e.cores,
        e.lp_num_threads.as_deref().unwrap_or("unset"),
        e.volbench_version,
        e.git_sha,
        s.settings.width,
        s.settings.height,
        s.settings.frames,
        s.settings.warmup,
        s.settings.orbit_step_deg,
        if s.settings.quick { " (--quick)" } else { "" },
    );
    t += "| dataset | method | status | frame ms median [min, max] | GPU ms | MB/frame | bytes/cell | static KB | M cells/s | RMSE vs f64 | max err |\n";
    t += "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|\n";
    for r in &s.runs {
        match &r.result {
            Some(x) => {
                let f = x.time_ms.phase("frame");
                let _ = writeln!(
                    t,
                    "| {} | {} | ok | {:.1} [{:.1}, {:.1}] | {:.1} | {:.2} | {} | {:.1} | {:.3} | {} | {} |",
                    r.dataset,
                    r.label,
                    f.median,
                    f.min,
                    f.max,
                    x.time_ms.phase("gpu").median,
                    x.upload.bytes_per_frame as f64 / 1e6,
                    x.upload.bytes_per_cell.map_or("-".into(), |v| format!("{v:.0}")),
                    x.upload.static_bytes as f64 / 1e3,
                    x.cells_per_second / 1e6,
                    x.error.as_ref().map_or("-".into(), |e| format!("{:.2e}", e.rmse)),
                    x.error.as_ref().map_or("-".into(), |e| format!("{:.2e}", e.max_abs)),
                );
            }
            None => {
                let _ = writeln!(t, "| {} | {} | {}: {} |||||||||", r.dataset, r.label, r.status, r.message.as_deref().unwrap_or("").replace('|', "/"));
            }
        }
    }
    t += &published_ratios(s, registry);
    t += &peer_report(s);
    t += "\nPlots: `plots/frame_time.{png,svg}`, `plots/bytes_per_frame.{png,svg}`; images and their ×10 difference from the f64 reference: `montage.png`, `runs/`.\n";
    t
}

/// Every published figure set beside its measured counterpart, as ratios
/// inside this run: two frame rates from one source on one dataset (methods
/// or option sets) against the same two measured; a "defaults up to N×
/// faster" claim against the measured speed-up on each dataset.
fn published_ratios(s: &Summary, registry: &Registry) -> String {
    use crate::algo::method::PublishedFigure;
    // The measured median frame time of a published figure's run.
    let measured = |p: &crate::algo::method::Published, dataset: &str| -> Option<(f64, String)> {
        let spec = registry.published_spec(p).ok()?;
        let canonical = spec.canonical();
        let r = s.runs.iter().filter_map(|r| r.result.as_ref()).find(|r| r.mesh == dataset && r.spec == canonical)?;
        Some((r.time_ms.phase("frame").median, spec.label()))
    };
    let default_time = |method: &str, dataset: &str| -> Option<f64> {
        let spec = registry.parse_spec(method, &[]).ok()?.canonical();
        s.runs.iter().filter_map(|r| r.result.as_ref()).find(|r| r.mesh == dataset && r.spec == spec).map(|r| r.time_ms.phase("frame").median)
    };
    let published = registry.published();
    let mut rows = String::new();
    for (i, p) in published.iter().enumerate() {
        for q in &published[i + 1..] {
            let (Some(d), Some(fp), Some(fq)) = (p.dataset, p.fps(), q.fps()) else { continue };
            if q.source != p.source || q.dataset != p.dataset {
                continue;
            }
            let (Some((tp, lp)), Some((tq, lq))) = (measured(p, d), measured(q, d)) else { continue };
            if tp <= 0.0 || tq <= 0.0 {
                continue;
            }
            let (m, pubr) = (tp / tq, fq / fp);
            let verdict = if (m / pubr - 1.0).abs() <= 0.25 { "agrees (within 25 %)" } else if m > pubr { "larger here" } else { "smaller here" };
            let _ = writeln!(rows, "| {d} | {lq} ÷ {lp} | {m:.2} | {pubr:.2} | {verdict} | {} |", p.source);
        }
    }
    for p in &published {
        let PublishedFigure::DefaultsFasterUpTo(bound) = p.figure else { continue };
        let Ok(off) = registry.published_spec(p) else { continue };
        let (off_spec, l_off) = (off.canonical(), off.label());
        // Every run of the figure's option set, on each dataset it speaks about.
        for r in s.runs.iter().filter_map(|r| r.result.as_ref()).filter(|r| r.spec == off_spec && p.applies_to(&r.mesh)) {
            let t_off = r.time_ms.phase("frame").median;
            let Some(t_def) = default_time(p.method, &r.mesh).filter(|&t| t > 0.0) else { continue };
            let m = t_off / t_def;
            let verdict = if m <= bound * 1.1 { "within the claim" } else { "beyond the claim" };
            let _ = writeln!(rows, "| {} | {} ÷ {l_off} | {m:.2} | up to {bound:.1} | {verdict} | {} |", r.mesh, p.method, p.source);
        }
    }
    // Cells drawn per frame (a method drawing cells more than once): the
    // growth over the mesh's cell count, measured from the run's work counts.
    for p in &published {
        let PublishedFigure::CellsRendered { rendered, cells } = p.figure else { continue };
        let Ok(spec) = registry.published_spec(p) else { continue };
        let canonical = spec.canonical();
        for r in s.runs.iter().filter_map(|r| r.result.as_ref()).filter(|r| r.spec == canonical && p.applies_to(&r.mesh)) {
            let (Some(&drawn), Some(&n)) = (r.work.counts.get("pieces"), r.work.counts.get("cells")) else { continue };
            if n == 0 || cells == 0 {
                continue;
            }
            let (m, pubr) = (drawn as f64 / n as f64, rendered as f64 / cells as f64);
            let verdict = if (m / pubr - 1.0).abs() <= 0.25 { "agrees (within 25 %)" } else if m > pubr { "larger here" } else { "smaller here" };
            let _ = writeln!(
                rows,
                "| {} | {} cells drawn ÷ cells ({drawn} for {n}; published {rendered} for {cells}) | {m:.2} | {pubr:.2} | {verdict} | {} |",
                r.mesh,
                spec.label(),
                p.source
            );
        }
    }
    if rows.is_empty() {
        return String::new();
    }
    let mut notes = String::new();
    let mut seen = Vec::new();
    for p in &published {
        if rows.contains(p.source) && !seen.contains(&p.source) {
            seen.push(p.source);
            let _ = writeln!(notes, "- {}: {}", p.source, p.note);
        }
    }
    rows += "\nWhy a ratio here differs from the paper's:\n\n";
    rows += &notes;
    format!(
        "\n## Measured against published, as speed ratios inside this run\n\n\
         Absolute times from the papers' hardware are not comparable with this machine; ratios between \
         runs on one dataset are. A ratio a ÷ b is how many times faster a ran than b (frame rate of a over \
         frame rate of b; published: the paper's two frame rates); \"cells drawn ÷ cells\" is how many times a \
         method draws the mesh's cell count per frame (counts, not speeds).\n\n\
         | dataset | ratio | measured | published | | source |\n|---|---|---:|---:|---|---|\n{rows}"
    )
}
