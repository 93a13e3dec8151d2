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
use super::plots::{Bar, Marker, ScatterPoint, Tile};
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
    /// Counted (`--count`): each run counts its timed frames' instructions
    /// (`harness::count`); no CPU reference, no diagnostics.
    pub counted: bool,
    /// The counted child's dump directory.
    #[serde(skip)]
    pub count_dir: Option<std::path::PathBuf>,
}

impl SuiteSettings {
    pub fn standard(quick: bool, filter: Vec<String>) -> Self {
        if quick {
            SuiteSettings { width: 256, height: 256, frames: 3, warmup: 1, orbit_step_deg: 5.0, quick, filter, peers: Vec::new(), counted: false, count_dir: None }
        } else {
            SuiteSettings { width: 512, height: 512, frames: 20, warmup: 3, orbit_step_deg: 5.0, quick, filter, peers: Vec::new(), counted: false, count_dir: None }
        }
    }

    /// The counted suite (`--count`): the quick one at 64x64 and 2 timed
    /// frames (a count repeats without many samples; CI's budget).
    pub fn counted(mut self, count_dir: Option<std::path::PathBuf>) -> Self {
        if count_dir.is_some() {
            if self.quick {
                (self.width, self.height, self.frames, self.warmup) = (64, 64, 2, 1);
            }
            self.counted = true;
            self.count_dir = count_dir;
        }
        self
    }

    fn run_config(&self) -> RunConfig {
        RunConfig {
            width: self.width,
            height: self.height,
            frames: self.frames,
            warmup: self.warmup,
            orbit_step: self.orbit_step_deg.to_radians(),
            diagnostics: self.count_dir.is_none(),
            overlap: self.count_dir.is_none(),
            count_dir: self.count_dir.clone(),
            ..RunConfig::default()
        }
    }
}

/// One planned run: a shipped dataset and a method at its defaults, or with
/// an option set a published figure names; or a culling scene.
#[derive(Debug)]
pub struct PlannedRun {
    pub dataset: &'static str,
    pub spec: MethodSpec,
    pub scene: Scene,
}

impl PlannedRun {
    /// How the run is named in rows and reports: the spec's label, and the
    /// scene when it is not the standard one (`balanced:cull=off @zoomed`).
    pub fn label(&self) -> String {
        match self.scene {
            Scene::Standard => self.spec.label(),
            s => format!("{} @{}", self.spec.label(), s.name()),
        }
    }

    /// The montage a run's image goes to: its dataset, and the scene when
    /// it is not the standard one (another view, another reference).
    fn montage_group(&self) -> String {
        match self.scene {
            Scene::Standard => self.dataset.to_string(),
            s => format!("{}@{}", self.dataset, s.name()),
        }
    }

    fn file_stem(&self) -> String {
        match self.scene {
            Scene::Standard => self.spec.file_stem(),
            s => format!("{}@{}", self.spec.file_stem(), s.name()),
        }
    }
}

/// The view and transfer function of a run: the standard orbit with the
/// dataset's preset, or one of the scenes where culling matters
/// (`algo::cell_projection::cull`), each run with culling on and off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Scene {
    Standard,
    /// The dataset's `<name>-band` transfer function (`data/tf/`): opaque
    /// only in a narrow band of the scalar range, most cells transparent.
    Transparent,
    /// The orbit zoomed in [`ZOOM`] times (`RunConfig::zoom`: aimed off
    /// the centre): most cells off-screen.
    Zoomed,
    /// The orbit's first view for every frame.
    Still,
}

/// The zoomed scene's factor.
pub const ZOOM: f64 = 4.0;

/// The datasets the culling scenes run on (the oxygen post: its preset and
/// its `oxygenpost-band` transfer function).
pub const CULL_SCENE_DATASETS: &[&str] = &["oxygenpost"];

impl Scene {
    pub const CULLING: [Scene; 3] = [Scene::Transparent, Scene::Zoomed, Scene::Still];

    pub fn name(self) -> &'static str {
        match self {
            Scene::Standard => "standard",
            Scene::Transparent => "transparent",
            Scene::Zoomed => "zoomed",
            Scene::Still => "still",
        }
    }

    /// The run configuration of this scene from the suite's.
    fn config(self, cfg: &RunConfig) -> RunConfig {
        match self {
            Scene::Standard | Scene::Transparent => cfg.clone(),
            // Its magnified cells make a frame several times a standard
            // one: a third of the timed frames keeps the suite's budget.
            Scene::Zoomed => RunConfig { zoom: ZOOM, frames: (cfg.frames / 3).max(1), ..cfg.clone() },
            Scene::Still => RunConfig { orbit_step: 0.0, ..cfg.clone() },
        }
    }

    /// The transfer function of this scene on `dataset`.
    fn transfer_function(self, dataset: &Dataset) -> Result<crate::scene::TransferFunction> {
        match self {
            Scene::Transparent => {
                let path = crate::data_dir::data_dir().join("tf").join(format!("{}-band.json", dataset.name));
                dataset.load_transfer_function(&path)
            }
            _ => dataset.default_transfer_function(),
        }
    }
}

/// Every (shipped dataset, method for its kind) pair that passes the
/// filter: the defaults, then each option set a published figure about the
/// method on that dataset names (so every published ratio has its measured
/// counterpart in the same run), then the method's own suite sets
/// (`MethodInfo::suite`: the cheap end of its accuracy trade-off).
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
                let published = m.published.iter().filter(|p| p.applies_to(d.name)).map(|p| registry.published_spec(p));
                let own = m.suite.iter().map(|o| registry.parse_spec(&format!("{}:{o}", m.name), &[]));
                for s in published.chain(own) {
                    let s = s?;
                    if !specs.iter().any(|x| x.canonical() == s.canonical()) {
                        specs.push(s);
                    }
                }
                out.extend(specs.into_iter().map(|spec| PlannedRun { dataset: d.name, spec, scene: Scene::Standard }));
            }
        }
        // The culling scenes: the first methods with their family's culling
        // option (`Family::culling_option`: the papers' VICP and balanced;
        // --quick: the first only), culling on and off (the unchanged-image
        // check and the speed-up). Every method culls alike (tests/cull.rs);
        // more would not fit the suite's budget.
        if CULL_SCENE_DATASETS.contains(&d.name) {
            let culling: Vec<_> = registry
                .for_kind(d.kind)
                .filter(|m| (keep(d.name) || keep(m.name)) && m.culling_option().is_some())
                .take(if settings.quick { 1 } else { 2 })
                .collect();
            // --quick leaves out the zoomed scene: magnified cells cost many
            // more fragments (the CI budget).
            for scene in Scene::CULLING.into_iter().filter(|&s| !(settings.quick && s == Scene::Zoomed)) {
                for m in &culling {
                    let option = m.culling_option().unwrap_or_default();
                    for cull in ["on", "off"] {
                        let spec = registry.parse_spec(&format!("{}:{option}={cull}", m.name), &[])?;
                        out.push(PlannedRun { dataset: d.name, spec, scene });
                    }
                }
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
    /// The view and transfer function (`standard`, or a culling scene).
    pub scene: Scene,
    /// Position in the suite's run order (peers' runs counted too).
    pub sequence: usize,
    pub result: Option<RunResult>,
    /// The work the method's family shares with other placements of it
    /// (`Family::placement`; the placement report groups by it).
    #[serde(skip)]
    pub placement: Option<&'static str>,
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
    /// Each culling scene's culled image against the unculled one.
    pub cull_checks: Vec<CullCheck>,
}

/// The unchanged-image check of one culling scene: the reference-view image
/// of a method with its culling option on against the same with it off.
#[derive(Debug, Clone, Serialize)]
pub struct CullCheck {
    pub dataset: String,
    pub scene: Scene,
    pub method: String,
    /// The option toggled (`Family::culling_option`).
    #[serde(skip)]
    pub option: &'static str,
    pub rmse: f64,
    pub max_abs: f64,
}

/// `spec` with its culling option on.
fn cull_on(registry: &Registry, spec: &MethodSpec) -> Result<MethodSpec> {
    let option = spec.info.culling_option().unwrap_or_default();
    registry.parse_spec(&format!("{}:{option}=on", spec.info.name), &[])
}

/// Whether a run of `info` with `options` culls (`None`: the method has no
/// culling option).
fn culling(info: &crate::algo::method::MethodInfo, options: &crate::algo::method::Options) -> Option<bool> {
    info.culling_option().and_then(|o| options.flag(o).ok())
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
    let mut summary =
        Summary { environment: Environment::of(ctx), settings: settings.clone(), runs: Vec::new(), peers: Vec::new(), cull_checks: Vec::new() };
    // Every image shown, by montage group, with the run's label; and the
    // reference image of each group.
    let mut images: Vec<(String, String, Tile)> = Vec::new();
    let mut references: Vec<(String, RgbaImage)> = Vec::new();
    let located: Vec<LocatedPeer> = settings.peers.iter().map(|p| super::peers::locate(p)).collect::<Result<_>>()?;
    let peers_dir = out.join("peers");
    if !located.is_empty() {
        std::fs::create_dir_all(&peers_dir).with_context(|| format!("creating {}", peers_dir.display()))?;
    }
    let mut loaded: Option<(&str, std::result::Result<Dataset, String>)> = None;
    // Peer renderers still to run on the current dataset, and its exported copy.
    let mut pending: Vec<(&LocatedPeer, &'static PeerRenderer)> = Vec::new();
    let mut export: Option<(std::path::PathBuf, super::peers::PeerDataset)> = None;
    let mut sequence = 0usize;
    for (i, p) in plan.iter().enumerate() {
        let label = format!("{} on {}", p.label(), p.dataset);
        progress(i, &label);
        let first_of_dataset = i == 0 || plan[i - 1].dataset != p.dataset;
        let last_of_dataset = plan.get(i + 1).is_none_or(|n| n.dataset != p.dataset);
        if loaded.as_ref().is_none_or(|(n, _)| *n != p.dataset) {
            loaded = Some((p.dataset, datasets::load(p.dataset).map_err(|e| format!("{e:#}"))));
        }
        let Some((_, loaded_dataset)) = &loaded else { continue };
        // A dataset that cannot be loaded fails its rows; the suite goes on.
        let dataset = match loaded_dataset {
            Ok(d) => d,
            Err(why) => {
                pending.clear();
                summary.runs.push(SuiteRow {
                    dataset: p.dataset.into(),
                    method: p.spec.info.name.into(),
                    label: p.label(),
                    scene: p.scene,
                    status: "failed",
                    message: Some(format!("loading {}: {why}", p.dataset)),
                    sequence,
                    result: None,
                    placement: p.spec.info.family.placement,
                });
                sequence += 1;
                fsio::write_output(&out.join("summary.json"), &super::report::json_bytes(&summary)?)?;
                continue;
            }
        };
        if first_of_dataset {
            // Popped from the end: reversed so they run in their listed order.
            pending = located.iter().flat_map(|l| l.renderers_for(dataset.kind()).map(move |r| (l, r))).collect();
            pending.reverse();
        }
        let mut row = SuiteRow {
            dataset: p.dataset.into(),
            method: p.spec.info.name.into(),
            label: p.label(),
            scene: p.scene,
            status: "ok",
            message: None,
            sequence,
            result: None,
            placement: p.spec.info.family.placement,
        };
        sequence += 1;
        if let Some(why) = skip_reason(&p.spec, &ctx.info) {
            (row.status, row.message) = ("skipped", Some(why));
        } else {
            let group = p.montage_group();
            let outcome = (|| -> Result<(RunOutput, Option<RgbaImage>)> {
                let tf = p.scene.transfer_function(dataset)?;
                let cfg = p.scene.config(&cfg);
                let mut r = run(ctx, &p.spec, dataset, &tf, &cfg)?;
                let stem = format!("{}-{}", p.dataset, p.file_stem());
                let (json, png, dpng) = (runs_dir.join(format!("{stem}.json")), runs_dir.join(format!("{stem}.png")), runs_dir.join(format!("{stem}-diff.png")));
                // A method with its own error (terrain) has no image reference.
                let diff = if r.result.error.is_none() && settings.count_dir.is_none() {
                    let reference = reference_image(dataset, &tf, &r.result.image.camera, cfg.width, cfg.height)?;
                    if !references.iter().any(|(g, _)| *g == group) {
                        references.push((group.clone(), reference.image.clone()));
                    }
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
                    // A culling scene's pair: the culled image against the
                    // unculled one (the unchanged-image check).
                    if p.scene != Scene::Standard && culling(&p.spec.info, &p.spec.options) == Some(false) {
                        let on = PlannedRun { dataset: p.dataset, spec: cull_on(registry, &p.spec)?, scene: p.scene };
                        let on_label = format!("{} on {}", on.label(), p.dataset);
                        if let Some((_, _, on)) = images.iter().find(|(_, l, _)| *l == on_label) {
                            let e = on.image.compare(&r.image)?;
                            summary.cull_checks.push(CullCheck {
                                dataset: p.dataset.into(),
                                scene: p.scene,
                                method: p.spec.info.name.into(),
                                option: p.spec.info.culling_option().unwrap_or_default(),
                                rmse: e.rmse,
                                max_abs: e.max_abs,
                            });
                        }
                    }
                    images.push((group, label.clone(), Tile { label: p.label(), image: r.image, diff }));
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
                let tile = Tile { label: format!("peer {}/{}", peer.peer.name, renderer.name), image, diff: Some(diff) };
                images.push((p.dataset.to_string(), label, tile));
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
    figures(out, &summary, &images, &references)?;
    Ok(summary)
}

/// The suite's pictures, per dataset: `montage-<group>.png` (the reference,
/// then each run beside its ×10 difference), and in `plots/` the frame time
/// with its min–max spread (`frame_time-<dataset>`, peers in their own
/// colour), the bytes per frame (`bytes_per_frame-<dataset>`) and the frame
/// time against the error with the Pareto front (`time_error-<dataset>.png`,
/// standard scene, peers included).
fn figures(out: &Path, s: &Summary, images: &[(String, String, Tile)], references: &[(String, RgbaImage)]) -> Result<()> {
    use super::run::ErrorKind;
    let mut groups: Vec<&str> = Vec::new();
    for (g, _, _) in images {
        if !groups.contains(&g.as_str()) {
            groups.push(g);
        }
    }
    for g in groups {
        let tiles: Vec<Tile> = images.iter().filter(|(x, _, _)| x == g).map(|(_, _, t)| t.clone()).collect();
        let reference = references.iter().find(|(x, _)| x == g).map(|(_, r)| r);
        super::plots::montage(&out.join(format!("montage-{g}.png")), g, reference, &tiles)?;
    }
    let plots = out.join("plots");
    let device = &s.environment.device.name;
    let mut datasets: Vec<&str> = Vec::new();
    for d in s.runs.iter().map(|r| r.dataset.as_str()).chain(s.peers.iter().map(|p| p.dataset.as_str())) {
        if !datasets.contains(&d) {
            datasets.push(d);
        }
    }
    for d in datasets {
        let ok = || s.runs.iter().filter(move |r| r.dataset == d).filter_map(|r| Some((r, r.result.as_ref()?)));
        let peers = || s.peers.iter().filter(move |p| p.dataset == d).filter_map(|p| Some((p, p.frame_ms.as_ref()?)));
        let times: Vec<Bar> = ok()
            .map(|(r, x)| {
                let f = x.time_ms.phase("frame");
                Bar { label: r.label.clone(), median: f.median, spread: Some((f.min, f.max)), peer: false }
            })
            .chain(peers().map(|(p, f)| Bar { label: format!("peer {}/{}", p.peer, p.renderer), median: f.median, spread: Some((f.min, f.max)), peer: true }))
            .collect();
        let size = format!("{}x{}", s.settings.width, s.settings.height);
        let title = format!("{d}: frame time (ms), median and min–max of {} frames, {size}, {device}", s.settings.frames);
        super::plots::bar_chart(&plots, &format!("frame_time-{d}"), &title, &times)?;
        let bytes: Vec<Bar> =
            ok().map(|(r, x)| Bar { label: r.label.clone(), median: x.upload.bytes_per_frame as f64 / 1e6, spread: None, peer: false }).collect();
        super::plots::bar_chart(&plots, &format!("bytes_per_frame-{d}"), &format!("{d}: bytes crossing to the device per frame (MB)"), &bytes)?;
        // Standard scene only: the culling scenes have other views and references.
        let mut points: Vec<ScatterPoint> = ok()
            .filter(|(r, _)| r.scene == Scene::Standard)
            .filter_map(|(r, x)| {
                let e = x.error.as_ref()?;
                Some(ScatterPoint {
                    label: r.label.clone(),
                    series: r.method.clone(),
                    marker: if e.compared == ErrorKind::Image { Marker::Filled } else { Marker::Ring },
                    time_ms: x.time_ms.phase("frame").median,
                    error: e.rmse,
                    on_front: false,
                })
            })
            .chain(peers().filter_map(|(p, f)| {
                Some(ScatterPoint {
                    label: format!("peer {}/{}", p.peer, p.renderer),
                    series: format!("peer {}/{}", p.peer, p.renderer),
                    marker: Marker::Triangle,
                    time_ms: f.median,
                    error: p.error.as_ref()?.rmse,
                    on_front: false,
                })
            }))
            .collect();
        if points.is_empty() {
            continue;
        }
        super::plots::mark_front(&mut points, |p| Some((p.time_ms, p.error)), |p, on| p.on_front = on);
        // A method with its own error (terrain) says what it measures.
        let own = ok().find_map(|(_, x)| x.error.as_ref().filter(|e| e.compared == ErrorKind::Own));
        let y_desc = if own.is_some() { "RMSE (the method's own measure, see report)" } else { "RMSE against the f64 reference image" };
        let note = "filled: volbench run\nring: own error measure\ntriangle: peer (same run)";
        super::plots::time_error_scatter(&plots.join(format!("time_error-{d}.png")), &format!("{d}: frame time against error, {size}"), y_desc, note, &points)?;
    }
    Ok(())
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
        let tf = dataset.default_transfer_function()?;
        let scene = pe::scene(peer.peer, renderer, dataset, &tf, cfg, exported, peers_dir)?;
        let stem = scene.stem();
        let reference_camera = scene.reference_camera;
        let (result, image) = pe::run_peer(peer, &scene, &peers_dir.join(format!("{stem}.scene.json")))?;
        let reference = reference_image(dataset, &tf, &reference_camera, cfg.width, cfg.height)?;
        // A blank picture is a failure, not a result (docs/bad-input.md).
        let expected = reference.image.covered_pixels();
        anyhow::ensure!(
            image.covered_pixels() > 0 || expected == 0,
            "peer {}/{} returned an empty image although the f64 reference covers {expected} pixels",
            peer.peer.name,
            renderer.name
        );
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
    // Peers render the standard scene only: a culling scene (another
    // transfer function or camera) is no like-for-like comparison.
    for r in s.runs.iter().filter(|r| r.scene == Scene::Standard) {
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
    t += &matched_error(s);
    t
}

/// Speed at matched error: per peer renderer, the fastest volbench run on
/// the same dataset whose image error is no larger than the peer's (a
/// faster but less accurate run would not be a like-for-like comparison).
fn matched_error(s: &Summary) -> String {
    use super::run::ErrorKind;
    let mut rows = String::new();
    for p in &s.peers {
        let (Some(f), Some(pe)) = (&p.frame_ms, &p.error) else { continue };
        let fastest = s
            .runs
            .iter()
            .filter(|r| r.dataset == p.dataset && r.scene == Scene::Standard)
            .filter_map(|r| {
                let x = r.result.as_ref()?;
                let e = x.error.as_ref().filter(|e| e.compared == ErrorKind::Image && e.rmse <= pe.rmse)?;
                Some((r, x.time_ms.phase("frame").median, e.rmse))
            })
            .filter(|(_, ms, _)| *ms > 0.0)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let (label, ms, rmse) = match fastest {
            Some((r, ms, rmse)) => (r.label.as_str(), format!("{ms:.1}"), format!("{rmse:.2e}")),
            None => ("none as accurate", "-".into(), "-".into()),
        };
        let ratio = fastest.map_or("-".into(), |(_, ms, _)| format!("**{:.2}**", f.median / ms));
        let _ = writeln!(rows, "| {} | {}/{} | {:.1} | {:.2e} | {label} | {ms} | {rmse} | {ratio} |", p.dataset, p.peer, p.renderer, f.median, pe.rmse);
    }
    if rows.is_empty() {
        return rows;
    }
    format!(
        "\nAt matched error: the fastest volbench run of this suite on the dataset whose RMSE against the f64 reference is \
         no larger than the peer's, and the speed ratio (peer ms / volbench ms).\n\n\
         | dataset | peer | peer ms | peer RMSE | fastest volbench run at most as far from the reference | volbench ms | volbench RMSE | speed ratio |\n\
         |---|---|---:|---:|---|---:|---:|---:|\n{rows}"
    )
}

/// One line per run, volbench's and the peers' (`source`), with the
/// figures a spreadsheet wants; a peer has no bytes or GPU time to report.
pub fn csv(s: &Summary) -> String {
    let mut t = String::from(
        "source,dataset,method,label,status,frame_ms_median,gpu_ms_median,bytes_per_frame,bytes_per_cell,static_bytes,cells_per_second,rmse,max_abs,message\n",
    );
    let q = |x: &str| format!("\"{}\"", x.replace('"', "\"\""));
    for r in &s.runs {
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
            "volbench,{},{},{},{},{f},{g},{b},{bc},{st},{cps},{rmse},{max},{}",
            r.dataset,
            r.method,
            q(&r.label),
            r.status,
            q(r.message.as_deref().unwrap_or(""))
        );
    }
    for p in &s.peers {
        let f = p.frame_ms.as_ref().map_or(String::new(), |f| format!("{:.3}", f.median));
        let rmse = p.error.as_ref().map_or(String::new(), |e| format!("{:.6e}", e.rmse));
        let max = p.error.as_ref().map_or(String::new(), |e| format!("{:.6e}", e.max_abs));
        let _ = writeln!(
            t,
            "{},{},{},{},{},{f},,,,,,{rmse},{max},{}",
            p.peer,
            p.dataset,
            q(&p.renderer),
            q(&format!("{} {} ({})", p.peer, p.renderer, p.class)),
            p.status,
            q(p.message.as_deref().unwrap_or(""))
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
    t += "| dataset | method | status | frame ms median [min, max] | GPU ms | MB/frame | bytes/cell | static KB | M cells/s | error RMSE | max err |\n";
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
    t += &error_legend(s);
    t += &published_ratios(s, registry);
    t += &placement_report(s);
    t += &cull_report(s);
    t += &peer_report(s);
    t += "\nPictures, per dataset: `plots/time_error-<dataset>.png` (frame time against error, the Pareto front joined, peers included), \
          `plots/frame_time-<dataset>.{png,svg}` (median with the min–max spread), `plots/bytes_per_frame-<dataset>.{png,svg}`; \
          `montage-<dataset>.png`: the f64 reference, then each run beside its ×10 difference from it; every image in `runs/`.\n";
    t
}

/// What the runs table's error columns compare: the f64 reference image,
/// or (rows listed by name) a method's own measure in its own unit.
fn error_legend(s: &Summary) -> String {
    use super::run::ErrorKind;
    let mut t = String::from("\nError columns: the reference-view image against the f64 CPU reference image (RGBA in [0, 1])");
    let own: Vec<String> = s
        .runs
        .iter()
        .filter_map(|r| {
            let e = r.result.as_ref()?.error.as_ref()?;
            (e.compared == ErrorKind::Own).then(|| format!("{} / {}: {}", r.dataset, r.label, e.reference))
        })
        .collect();
    if own.is_empty() {
        t += ".\n";
    } else {
        t += ", except these rows, which report the method's own measure:\n\n";
        for line in own {
            let _ = writeln!(t, "- {line}");
        }
    }
    t
}

/// Runs that do the same work in different places (a method's family
/// names the work, `Family::placement`; e.g. the terrain methods' PC-cell
/// tessellation on the CPU, in a geometry shader, in a compute pass), per
/// dataset, set side by side with the first such run as the base: frame
/// time, device time and per-frame bytes as ratios inside this run, with
/// the work counts that must agree between them.
fn placement_report(s: &Summary) -> String {
    type Group<'a> = (String, String, Vec<(&'a str, &'a RunResult)>);
    let mut groups: Vec<Group> = Vec::new();
    for r in &s.runs {
        let Some(x) = &r.result else { continue };
        let Some(work) = r.placement else { continue };
        match groups.iter_mut().find(|g| g.0 == r.dataset && g.1 == work) {
            Some(g) => g.2.push((&r.label, x)),
            None => groups.push((r.dataset.clone(), work.to_string(), vec![(&r.label, x)])),
        }
    }
    let mut t = String::new();
    for (dataset, work, runs) in groups.iter().filter(|g| g.2.len() >= 2) {
        let (_, base) = runs[0];
        let (bf, bg, bb) = (base.time_ms.phase("frame").median, base.time_ms.phase("gpu").median, base.upload.bytes_per_frame);
        let _ = write!(
            t,
            "\n## {dataset}: {work}, placed differently\n\nRatios against `{}` inside this run (speed: its frame time ÷ the run's; bytes: the run's ÷ its). \
             Counts are the reference view's.\n\n| run | frame ms | speed × | GPU ms | GPU speed × | bytes/frame | bytes × | static KB | CPU phases ms | work |\n|---|---:|---:|---:|---:|---:|---:|---:|---|---|\n",
            runs[0].0
        );
        for (label, x) in runs {
            let (f, g) = (x.time_ms.phase("frame").median, x.time_ms.phase("gpu").median);
            let phases: Vec<String> =
                x.time_ms.phases.iter().filter(|(k, _)| !super::run::RUNNER_PHASES.contains(&k.as_str())).map(|(k, v)| format!("{k} {:.2}", v.median)).collect();
            let work: Vec<String> = x.work.counts.iter().map(|(k, v)| format!("{k} {v}")).collect();
            let ratio = |a: f64, b: f64| if b > 0.0 { format!("{:.2}", a / b) } else { "-".into() };
            let _ = writeln!(
                t,
                "| {label} | {f:.2} | {} | {g:.2} | {} | {} | {} | {:.1} | {} | {} |",
                ratio(bf, f),
                ratio(bg, g),
                x.upload.bytes_per_frame,
                ratio(x.upload.bytes_per_frame as f64, bb as f64),
                x.upload.static_bytes as f64 / 1e3,
                phases.join(", "),
                work.join(", "),
            );
        }
    }
    t
}

/// The culling scenes: per method, what each rule skipped, the frame time
/// with culling on and off and the speed-up, the rasterizer's work both
/// ways, and the unchanged-image check (culled against unculled image).
pub fn cull_report(s: &Summary) -> String {
    if s.cull_checks.is_empty() {
        return String::new();
    }
    let find = |c: &CullCheck, on: bool| {
        s.runs.iter().find(|r| r.dataset == c.dataset && r.scene == c.scene && r.method == c.method && r.result.as_ref().is_some_and(|x| x.options.flag(c.option).ok() == Some(on)))
    };
    let per_frame = |x: &RunResult, k: &str| x.frame_counts.get(k).filter(|c| c.frames > 0).map_or(0.0, |c| c.total as f64 / c.frames as f64);
    let mut t = String::from(
        "\n## Culling: skipping what a scene does not need\n\n\
         Each scene runs the first tetrahedral methods with culling on (`cull=on`, the default) and off (the zoomed scene \
         times a third of the suite's frames: its frames cost several standard ones). Skipped per timed frame \
         (mean): cells whose table lookups read zero attenuation (transparent), other cells outside the view volume \
         (off-screen); frames re-used: frames with the same view and transfer function as the one before (no cull, sort, \
         pack or upload; the draw is repeated). Primitives in / fragments: pipeline statistics of the reference-view frame, \
         culled / unculled. The image check compares the culled and the unculled reference-view image (culling is exact: \
         RMSE 0 expected, ≤ 1e-6 required).\n\n\
         | dataset | scene | method | cells | transparent | off-screen | frames re-used | drawn | frame ms culled | unculled | speed-up | MB/frame culled / unculled | primitives in | fragments | RMSE culled vs unculled | image |\n\
         |---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---|---|---:|---|\n",
    );
    for c in &s.cull_checks {
        let (Some(on), Some(off)) = (find(c, true).and_then(|r| r.result.as_ref()), find(c, false).and_then(|r| r.result.as_ref())) else { continue };
        let (f_on, f_off) = (on.time_ms.phase("frame").median, off.time_ms.phase("frame").median);
        let reused = on.frame_counts.get("cull.reused").map_or(0, |x| x.total);
        let stats = |x: &RunResult| x.stats.map_or(("-".to_string(), "-".to_string()), |st| (st.input_primitives.to_string(), st.fragment_invocations.to_string()));
        let ((p_on, fr_on), (p_off, fr_off)) = (stats(on), stats(off));
        let _ = writeln!(
            t,
            "| {} | {} | {} | {} | {:.0} | {:.0} | {}/{} | {:.0} | {:.1} | {:.1} | **{:.2}** | {:.2} / {:.2} | {p_on} / {p_off} | {fr_on} / {fr_off} | {:.2e} | {} |",
            c.dataset,
            c.scene.name(),
            c.method,
            on.work.counts.get("cells").copied().unwrap_or(0),
            per_frame(on, "cull.transparent"),
            per_frame(on, "cull.frustum"),
            reused,
            on.frames,
            per_frame(on, "cells_drawn"),
            f_on,
            f_off,
            if f_on > 0.0 { f_off / f_on } else { 0.0 },
            on.upload.bytes_per_frame as f64 / 1e6,
            off.upload.bytes_per_frame as f64 / 1e6,
            c.rmse,
            if c.rmse <= 1e-6 { "unchanged" } else { "**CHANGED**" },
        );
    }
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
