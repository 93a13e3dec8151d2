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
}

impl SuiteSettings {
    pub fn standard(quick: bool, filter: Vec<String>) -> Self {
        if quick {
            SuiteSettings { width: 256, height: 256, frames: 3, warmup: 1, orbit_step_deg: 5.0, quick, filter }
        } else {
            SuiteSettings { width: 512, height: 512, frames: 20, warmup: 3, orbit_step_deg: 5.0, quick, filter }
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

/// One planned run: a shipped dataset and a method at its defaults.
#[derive(Debug)]
pub struct PlannedRun {
    pub dataset: &'static str,
    pub spec: MethodSpec,
}

/// Every (shipped dataset, method for its kind) pair that passes the filter.
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
                out.push(PlannedRun { dataset: d.name, spec: registry.parse_spec(m.name, &[])? });
            }
        }
    }
    anyhow::ensure!(!out.is_empty(), "--filter {:?} leaves nothing to run", settings.filter);
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
    pub status: &'static str,
    pub message: Option<String>,
    pub result: Option<RunResult>,
}

/// What `summary.json` holds.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub environment: Environment,
    pub settings: SuiteSettings,
    pub runs: Vec<SuiteRow>,
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
    let mut summary = Summary { environment: Environment::of(ctx), settings: settings.clone(), runs: Vec::new() };
    let mut images: Vec<(String, RgbaImage, Option<RgbaImage>)> = Vec::new();
    let mut loaded: Option<(&str, Dataset)> = None;
    for (i, p) in plan.iter().enumerate() {
        let label = format!("{} on {}", p.spec.info.name, p.dataset);
        progress(i, &label);
        let mut row = SuiteRow { dataset: p.dataset.into(), method: p.spec.info.name.into(), status: "ok", message: None, result: None };
        if let Some(why) = skip_reason(&p.spec, &ctx.info) {
            (row.status, row.message) = ("skipped", Some(why));
            summary.runs.push(row);
            continue;
        }
        if loaded.as_ref().is_none_or(|(n, _)| *n != p.dataset) {
            loaded = Some((p.dataset, datasets::load(p.dataset)?));
        }
        let Some((_, dataset)) = &loaded else { continue };
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
        summary.runs.push(row);
        fsio::write_output(&out.join("summary.json"), &super::report::json_bytes(&summary)?)?;
    }
    fsio::write_output(&out.join("summary.json"), &super::report::json_bytes(&summary)?)?;
    fsio::write_output(&out.join("summary.csv"), csv(&summary).as_bytes())?;
    fsio::write_output(&out.join("report.md"), report(&summary, &registry.published()).as_bytes())?;
    super::plots::bar_charts(&out.join("plots"), &summary)?;
    if !images.is_empty() {
        super::plots::montage(&out.join("montage.png"), &images)?;
    }
    Ok(summary)
}

/// One line per run: the figures a spreadsheet wants.
pub fn csv(s: &Summary) -> String {
    let mut t = String::from(
        "dataset,method,status,frame_ms_median,gpu_ms_median,bytes_per_frame,bytes_per_cell,static_bytes,cells_per_second,rmse,max_abs,message\n",
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
        let _ = writeln!(t, "{},{},{},{f},{g},{b},{bc},{st},{cps},{rmse},{max},{}", r.dataset, r.method, r.status, q(r.message.as_deref().unwrap_or("")));
    }
    t
}

/// The report: environment, the runs table, and measured figures set
/// beside the published ones as ratios between methods on the same dataset
/// (absolute times from other hardware are not comparable; ratios are).
pub fn report(s: &Summary, published: &[crate::algo::method::Published]) -> String {
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
                    r.method,
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
                let _ = writeln!(t, "| {} | {} | {}: {} |||||||||", r.dataset, r.method, r.status, r.message.as_deref().unwrap_or("").replace('|', "/"));
            }
        }
    }
    // Ratios between two methods on one dataset, measured and published.
    let mut ratios = String::new();
    let ok: Vec<&RunResult> = s.runs.iter().filter_map(|r| r.result.as_ref()).collect();
    for a in &ok {
        for b in &ok {
            if a.mesh != b.mesh || a.method >= b.method {
                continue;
            }
            let pa = published.iter().find(|p| p.method == a.method && p.dataset == a.mesh);
            let pb = published.iter().find(|p| p.method == b.method && p.dataset == b.mesh);
            if let (Some(pa), Some(pb)) = (pa, pb) {
                if a.cells_per_second > 0.0 && b.cells_per_second > 0.0 {
                    let _ = writeln!(
                        ratios,
                        "| {} | {} / {} | {:.2} | {:.2} | {} |",
                        a.mesh,
                        b.method,
                        a.method,
                        b.cells_per_second / a.cells_per_second,
                        pb.cells_per_second / pa.cells_per_second,
                        pa.source
                    );
                }
            }
        }
    }
    if !ratios.is_empty() {
        t += "\n## Measured against published, as ratios of cells per second\n\n| dataset | ratio | measured | published | source |\n|---|---|---:|---:|---|\n";
        t += &ratios;
    }
    t += "\nPlots: `plots/frame_time.{png,svg}`, `plots/bytes_per_frame.{png,svg}`; images and their ×10 difference from the f64 reference: `montage.png`, `runs/`.\n";
    t
}
