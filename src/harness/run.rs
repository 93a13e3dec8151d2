//! One benchmark run of any registered method: warm-up, N timed frames with
//! the camera moving, then one untimed frame at the reference view (angle 0)
//! whose image and pipeline statistics are reported.
//!
//! The runner owns what every method shares: the target image, the command
//! recorder, timestamp and statistics queries, warm-up, CPU/device overlap,
//! timing, readback and the result record (`results/schema/run.schema.json`). A
//! method (`algo::method::RenderMethod`) owns its passes and per-frame data.
//!
//! Per frame, host wall time is split into the method's own CPU phases
//! (e.g. `sort`, `pack`), `upload`, `record`, `submit` and `wait`; `gpu`
//! comes from timestamps around everything recorded. By default the CPU half
//! of frame N+1 runs while the device draws frame N (`overlap`), and `frame`
//! is then the interval between frame completions; with `overlap` off each
//! frame's phases run strictly one after another. Bytes come from the
//! counters in `vk::upload`, read before and after each frame. Pipeline
//! statistics are collected in the reference-view frame only (the one
//! reported). After the timed frames, the
//! same cameras turned away from the dataset measure the frame's fixed cost
//! (`fixed`, `fixed_gpu`; docs/frame-cost.md).

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result};
use serde::Serialize;

use super::count::{self, CountReport};
use super::datasets::{Dataset, DatasetSummary};
use super::image::RgbaImage;
use super::stats::Summary;
use crate::algo::method::{DataKind, Family, MethodInputs, Phases, RenderMethod, View};
use crate::algo::registry::MethodSpec;
use crate::scene::{Camera, Projection, TransferFunction};
use crate::vk::{CommandRecorder, Context, DeviceInfo, FrameQueries, Image, PipelineStats, UploadCounter};

/// The version of the result record (`results/schema/run.schema.json`).
pub const SCHEMA_VERSION: u32 = 2;

/// How a run is driven: image size, frames, camera. Method options live in
/// the `MethodSpec`.
#[derive(Debug, Clone)]
pub struct RunConfig {
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    pub projection: Projection,
    /// Camera rotation per frame, radians.
    pub orbit_step: f64,
    /// The orbit camera's field of view narrowed this many times and aimed
    /// halfway from the centre to the bounding box's low corner (1: the
    /// orbit, the whole dataset in view; 4: a quarter of it across, most
    /// cells off-screen).
    pub zoom: f64,
    /// A camera used for every frame instead of the orbit (tests, stills).
    pub fixed_camera: Option<Camera>,
    /// Prepare frame N+1 on the CPU while the device draws frame N.
    pub overlap: bool,
    /// Ask the method for its (possibly costly) reference-view diagnostics.
    pub diagnostics: bool,
    /// Frames with nothing in view (each timed frame's camera turned away
    /// from the dataset) after the timed ones: the frame's fixed cost,
    /// reported as the phases `fixed` and `fixed_gpu` (0: not measured).
    pub fixed_frames: usize,
    /// Counted run (`--count`, under callgrind): the directory callgrind
    /// dumps into (`harness::count`). Frames then run without overlap.
    pub count_dir: Option<std::path::PathBuf>,
}

/// The phases the runner itself times (every other phase is the method's
/// own): tables that list a method's phases leave these out.
pub const RUNNER_PHASES: &[&str] = &["frame", "gpu", "upload", "record", "submit", "wait", "fixed", "fixed_gpu"];

/// Frames and warm-up together may not exceed this: a run is a benchmark,
/// not a soak test, and sample vectors are sized from it.
pub const MAX_FRAMES: usize = 100_000;

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            width: 512,
            height: 512,
            frames: 10,
            warmup: 2,
            projection: Projection::Perspective { fovy_deg: 30.0 },
            orbit_step: 5f64.to_radians(),
            zoom: 1.0,
            fixed_camera: None,
            overlap: true,
            diagnostics: false,
            fixed_frames: 5,
            count_dir: None,
        }
    }
}

impl RunConfig {
    /// Check every size before anything is allocated.
    pub fn validate(&self) -> Result<()> {
        anyhow::ensure!(self.frames >= 1, "--frames must be at least 1");
        anyhow::ensure!(
            self.frames.checked_add(self.warmup).and_then(|n| n.checked_add(self.fixed_frames)).is_some_and(|n| n <= MAX_FRAMES),
            "--frames {} + --warmup {} + --fixed-frames {} exceeds the limit of {MAX_FRAMES} frames per run",
            self.frames,
            self.warmup,
            self.fixed_frames
        );
        anyhow::ensure!(self.width > 0 && self.height > 0, "--size must be positive, got {}x{}", self.width, self.height);
        anyhow::ensure!(
            self.count_dir.is_none() || self.warmup >= 1,
            "--count needs --warmup 1 or more: the first frame compiles llvmpipe's shader variants, which is not counted"
        );
        anyhow::ensure!(self.orbit_step.is_finite(), "--orbit-step must be a finite number of degrees");
        anyhow::ensure!(
            self.zoom.is_finite() && (1e-3..=1e3).contains(&self.zoom),
            "--zoom must be a factor in [0.001, 1000], got {}",
            self.zoom
        );
        Ok(())
    }

    /// Check the image size against the device before anything is rendered
    /// or computed (the CPU reference included).
    pub fn check_device(&self, info: &DeviceInfo) -> Result<()> {
        let max = info.max_image_dimension_2d;
        anyhow::ensure!(
            self.width <= max && self.height <= max,
            "--size {}x{}: the device '{}' draws images of at most {max}x{max} (maxImageDimension2D)",
            self.width,
            self.height,
            info.name
        );
        let bytes = self.width as u64 * self.height as u64 * 16;
        anyhow::ensure!(
            bytes <= info.max_memory_allocation_size,
            "--size {}x{}: the RGBA32F target takes {bytes} bytes, more than the device's largest allocation ({})",
            self.width,
            self.height,
            info.max_memory_allocation_size
        );
        Ok(())
    }

    /// Refuses, before anything is rendered, a view in which the dataset's
    /// box covers less than a pixel across (`--zoom 0.01`, data thinner
    /// than a pixel seen edge-on): the picture would be blank and measure
    /// nothing. Orbit views only; terrain methods fly their own cameras.
    pub fn check_framing(&self, dataset: &Dataset) -> Result<()> {
        if self.fixed_camera.is_some() || dataset.kind() == DataKind::Terrain || self.width < 8 || self.height < 8 {
            return Ok(());
        }
        let vp = self.camera(dataset, 0).view_proj(self.width, self.height);
        let b = dataset.bounds();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for c in 0..8 {
            let corner = glam::DVec3::from_array(std::array::from_fn(|a| if (c >> a) & 1 == 0 { b.min[a] } else { b.max[a] }));
            let q = vp * corner.extend(1.0);
            if !(q.w > 0.0) {
                // A corner beside or behind the eye: the box is not small in view.
                return Ok(());
            }
            for a in 0..2 {
                let ndc = (q[a] / q.w).clamp(-1.0, 1.0);
                lo[a] = lo[a].min(ndc);
                hi[a] = hi[a].max(ndc);
            }
        }
        let across = [0.5 * (hi[0] - lo[0]) * self.width as f64, 0.5 * (hi[1] - lo[1]) * self.height as f64];
        if across[0] < 1.0 || across[1] < 1.0 {
            let size: [f64; 3] = std::array::from_fn(|a| b.max[a] - b.min[a]);
            anyhow::bail!(
                "'{}' covers {:.2}x{:.2} pixels of the {}x{} image at --zoom {} (its box is {:.3e} x {:.3e} x {:.3e}): \
                 less than a pixel, so the image would be blank; use --zoom 1 or more, a larger --size, \
                 or data with an extent along every axis",
                dataset.name,
                across[0],
                across[1],
                self.width,
                self.height,
                self.zoom,
                size[0],
                size[1],
                size[2]
            );
        }
        Ok(())
    }

    /// The camera of frame `f` for a method of `family`: the fixed camera,
    /// else the family's own path, else the orbit (frame 0 is the reference
    /// view).
    pub fn frame_camera(&self, dataset: &Dataset, family: &Family, f: usize) -> Camera {
        match self.fixed_camera {
            Some(c) => c,
            None => (family.camera)(&dataset.scene(), f).unwrap_or_else(|| self.camera(dataset, f)),
        }
    }

    /// The camera of frame `f` (the orbit's angle 0 is the reference view).
    pub fn camera(&self, dataset: &Dataset, f: usize) -> Camera {
        match self.fixed_camera {
            Some(c) => c,
            None if self.zoom == 1.0 => dataset.orbit_camera(f as f64 * self.orbit_step, self.projection),
            // Zoomed: aimed halfway from the centre to the bounding box's low
            // corner, so the crowd of small cells a mesh often has at its
            // centre (the oxygen post's post) leaves the view with the rest.
            None => {
                let b = dataset.bounds();
                let (c, lo) = (b.center(), b.min);
                let aim = std::array::from_fn(|k| 0.5 * (c[k] + lo[k]));
                Camera { target: aim, ..dataset.orbit_camera(f as f64 * self.orbit_step, self.projection) }.zoomed(self.zoom)
            }
        }
    }
}

/// Bytes that crossed to the device, measured by the counters.
#[derive(Debug, Clone, Serialize)]
pub struct UploadReport {
    /// Everything per frame: per-frame data plus frame constants.
    pub bytes_per_frame: u64,
    /// Per-frame data that scales with the dataset (cell records, active
    /// lists), apart from the constants.
    pub cell_bytes_per_frame: u64,
    pub constant_bytes_per_frame: u64,
    /// Per-frame data divided by the cells drawn in that frame (methods that
    /// process cells; absent otherwise): the record each drawn cell costs
    /// (VICP 528, balanced 112, resident 4 bytes), whatever culling skipped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bytes_per_cell: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub floats_per_cell: Option<f64>,
    /// Per-frame data divided by the mesh's cell count: what culling saved
    /// shows here (equal to `bytes_per_cell` when nothing is culled).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bytes_per_mesh_cell: Option<f64>,
    /// One-time uploads (index buffers, tables, volumes), not part of any frame.
    pub static_bytes: u64,
    /// The counters themselves for the last timed frame and for set-up.
    pub frame_counters: UploadCounter,
    pub setup_counters: UploadCounter,
}

/// Median/min/max per phase (`frame`, `gpu`, the method's own phases,
/// `upload`, `record`, `submit`, `wait`; `fixed` and `fixed_gpu`, the frame
/// and GPU time of a frame with nothing in view), set-up times, and every
/// raw sample.
#[derive(Debug, Clone, Serialize)]
pub struct TimeReport {
    #[serde(flatten)]
    pub phases: BTreeMap<String, Summary>,
    /// Table construction and pipeline creation, apart from frames.
    pub setup_ms: f64,
    pub table_build_ms: f64,
    /// Raw per-frame samples (ms) by phase, in frame order.
    pub samples: BTreeMap<String, Vec<f64>>,
}

impl TimeReport {
    pub fn phase(&self, name: &str) -> Summary {
        self.phases.get(name).copied().unwrap_or_default()
    }
}

/// What a frame processed, and how much per second at the median frame time.
#[derive(Debug, Clone, Serialize)]
pub struct WorkReport {
    #[serde(flatten)]
    pub counts: BTreeMap<&'static str, u64>,
    pub per_second: BTreeMap<&'static str, f64>,
}

/// One of the method's per-frame counts over the timed frames (e.g. cells
/// a culling rule skipped): every frame's value, their sum and the number
/// of frames.
#[derive(Debug, Clone, Serialize)]
pub struct FrameCountReport {
    pub total: u64,
    pub frames: usize,
    pub per_frame: Vec<u64>,
}

/// The rasterizer's work in the reference-view frame, from the pipeline
/// statistics: primitives assembled, primitives out of clipping, fragment
/// shader invocations; `"unavailable"` (with the reason) on a device without
/// pipeline-statistics queries.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum RasterizerReport {
    Counts { primitives_in: u64, primitives_after_clipping: u64, fragment_invocations: u64 },
    Unavailable(String),
}

impl RasterizerReport {
    pub fn of(stats: Option<&PipelineStats>, device: &str) -> Self {
        match stats {
            Some(s) => RasterizerReport::Counts {
                primitives_in: s.input_primitives,
                primitives_after_clipping: s.clipping_primitives,
                fragment_invocations: s.fragment_invocations,
            },
            None => RasterizerReport::Unavailable(format!("unavailable: device '{device}' has no pipelineStatisticsQuery")),
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct ImageReport {
    pub width: u32,
    pub height: u32,
    pub covered_pixels: usize,
    pub non_finite_pixels: usize,
    pub camera: Camera,
}

/// How frames were driven.
#[derive(Debug, Clone, Serialize)]
pub struct ViewReport {
    pub projection: Projection,
    pub orbit_step_deg: f64,
    /// `RunConfig::zoom`.
    pub zoom: f64,
    pub fixed_camera: bool,
}

/// One run, in the schema every method family shares.
#[derive(Debug, Clone, Serialize)]
pub struct RunResult {
    pub schema_version: u32,
    pub method: &'static str,
    /// `name:key=value,...` with every option written out.
    pub spec: String,
    pub options: crate::algo::method::Options,
    pub dataset: DatasetSummary,
    /// The dataset's name and, for meshes, its cell and point counts
    /// (kept from schema 1; `dataset` has them all).
    pub mesh: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cells: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub points: Option<u64>,
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    /// CPU work of frame N+1 overlapped with the device's frame N.
    pub overlap: bool,
    pub view: ViewReport,
    pub transfer_function: String,
    pub upload: UploadReport,
    pub time_ms: TimeReport,
    pub work: WorkReport,
    /// `work.per_second.cells` (kept from schema 1; 0 for methods without cells).
    pub cells_per_second: f64,
    /// Pipeline statistics of the reference-view frame (deterministic).
    pub stats: Option<PipelineStats>,
    /// The rasterizer's share of `stats`, or why there is none.
    pub rasterizer: RasterizerReport,
    /// The method's per-frame counts over the timed frames (cell projection:
    /// `cull.transparent`, `cull.frustum`, `cull.reused`, `cells_drawn`).
    pub frame_counts: BTreeMap<String, FrameCountReport>,
    pub image: ImageReport,
    /// The reference-view image against the f64 CPU reference, when asked for.
    pub error: Option<ErrorReport>,
    /// The method family's own section (`family` names it).
    pub details: serde_json::Value,
    /// The method's reference-view diagnostics, when asked for.
    pub diagnostics: Option<serde_json::Value>,
    /// Instructions per phase of the timed frames (`--count`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<CountReport>,
    pub device: DeviceInfo,
    pub volbench_version: &'static str,
    /// The commit the binary was built from (`-dirty` with local changes).
    pub git_sha: &'static str,
    /// The environment switches set that change what is measured
    /// (`crate::switches::recorded`: every `VOLBENCH_TEST_*` knob, the
    /// validation layer, the device choice); empty in an ordinary run.
    pub env_switches: BTreeMap<String, String>,
}

/// Error of a run: its image against the f64 reference (RGBA, values in
/// [0, 1]), or a method's own measure where no image reference exists.
#[derive(Debug, Clone, Serialize)]
pub struct ErrorReport {
    pub compared: ErrorKind,
    pub rmse: f64,
    pub max_abs: f64,
    pub psnr_db: f64,
    /// What the reference is: renderer, dataset, view, size, transfer function.
    pub reference: String,
    /// CPU time the reference took (not part of any frame; 0 when cached).
    pub reference_ms: f64,
    pub reference_cached: bool,
    /// Why a cached reference was not used and was recomputed.
    pub reference_recomputed: Option<String>,
}

/// What an `ErrorReport` measures, so a report never labels a height error
/// as an image error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ErrorKind {
    /// The reference-view image against the f64 CPU reference image.
    Image,
    /// The method's own measure (`Phases::own_error`); `reference` says what, with the unit.
    Own,
}

pub struct RunOutput {
    pub result: RunResult,
    pub image: RgbaImage,
}

impl RunOutput {
    /// Compare this run's image with a reference image and record the error.
    pub fn attach_error(&mut self, reference: &super::reference_cache::Reference) -> Result<RgbaImage> {
        let e = self.image.compare(&reference.image)?;
        self.result.error = Some(ErrorReport {
            compared: ErrorKind::Image,
            rmse: e.rmse,
            max_abs: e.max_abs,
            psnr_db: e.psnr_db,
            reference: reference.what.clone(),
            reference_ms: reference.compute_ms,
            reference_cached: reference.cached,
            reference_recomputed: reference.recomputed.clone(),
        });
        Ok(self.image.difference(&reference.image))
    }
}

fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Wall and GPU time of one frame's phases, in milliseconds.
#[derive(Debug, Clone, Default)]
pub struct FrameTiming {
    /// The method's CPU phases (`prepare`).
    pub method: Phases,
    pub upload: f64,
    pub record: f64,
    pub submit: f64,
    pub wait: f64,
    pub frame: f64,
    pub gpu: f64,
}

/// Everything one method needs to draw frames: the method, the target, the
/// recorder and the queries. Built once; `frame` is the per-frame path that
/// runs and benchmarks time.
pub struct MethodSession {
    method: Box<dyn RenderMethod>,
    target: Image,
    recorder: CommandRecorder,
    queries: FrameQueries,
    width: u32,
    height: u32,
    /// The view prepared and waiting for `submit`.
    prepared: Option<View>,
    /// One-time uploads made while building the session.
    pub setup_counter: UploadCounter,
    pub setup_ms: f64,
}

impl MethodSession {
    pub fn new(
        ctx: &Arc<Context>,
        spec: &MethodSpec,
        dataset: &Dataset,
        tf: &TransferFunction,
        cfg: &RunConfig,
    ) -> Result<Self> {
        cfg.validate()?;
        cfg.check_device(&ctx.info)?;
        spec.check_renders(dataset.kind(), &dataset.name)?;
        cfg.check_framing(dataset)?;
        if let Some(why) = spec.info.unsupported_reason(&ctx.info) {
            anyhow::bail!("method '{}' cannot run here: {why}", spec.info.name);
        }
        let start = Instant::now();
        let mut setup_counter = UploadCounter::default();
        let method = (spec.info.create)(MethodInputs {
            ctx,
            data: dataset.scene(),
            tf,
            options: &spec.options,
            width: cfg.width,
            height: cfg.height,
            diagnostics: cfg.diagnostics,
            counter: &mut setup_counter,
            samples: dataset.take_handed_samples(),
        })
        .with_context(|| format!("setting up {} for '{}'", spec.canonical(), dataset.name))?;
        let target = Image::render_target(ctx, "frame target", cfg.width, cfg.height)?;
        let recorder = CommandRecorder::new(ctx, "frame")?;
        let queries = FrameQueries::new(ctx)?;
        Ok(MethodSession {
            method,
            target,
            recorder,
            queries,
            width: cfg.width,
            height: cfg.height,
            prepared: None,
            setup_counter,
            setup_ms: ms(start.elapsed()),
        })
    }

    /// Whether frames collect pipeline statistics (on when built). Only the
    /// reference-view frame's statistics are reported, so `run` switches
    /// them off for the timed and fixed-cost frames.
    pub fn set_statistics(&mut self, on: bool) {
        self.queries.set_statistics(on);
    }

    pub fn method(&self) -> &dyn RenderMethod {
        self.method.as_ref()
    }

    pub fn method_mut(&mut self) -> &mut dyn RenderMethod {
        self.method.as_mut()
    }

    fn view(&self, camera: &Camera) -> View {
        View { camera: *camera, width: self.width, height: self.height }
    }

    /// Prepare, upload, draw and wait for one frame seen by `camera`; bytes
    /// crossing to the device are added to `counter`.
    pub fn frame(&mut self, camera: &Camera, counter: &mut UploadCounter) -> Result<(FrameTiming, Option<PipelineStats>)> {
        let t0 = Instant::now();
        let mut timing = self.prepare(camera)?;
        self.submit(counter, &mut timing)?;
        let stats = self.wait(&mut timing)?;
        timing.frame = ms(t0.elapsed());
        Ok((timing, stats))
    }

    /// The CPU half of a frame (the device may still be drawing the
    /// previous one).
    pub fn prepare(&mut self, camera: &Camera) -> Result<FrameTiming> {
        let view = self.view(camera);
        let mut timing = FrameTiming::default();
        self.method.prepare(&view, &mut timing.method)?;
        count::phase_end("prepare");
        self.prepared = Some(view);
        Ok(timing)
    }

    /// Upload the prepared frame, record and submit it (no wait). The
    /// previous submission must have been waited for.
    pub fn submit(&mut self, counter: &mut UploadCounter, timing: &mut FrameTiming) -> Result<()> {
        let view = self.prepared.take().context("submit without a prepared frame")?;
        let t0 = Instant::now();
        self.method.upload(counter)?;
        count::phase_end("upload");
        let t1 = Instant::now();
        let rec = &self.recorder;
        rec.begin()?;
        self.queries.reset(rec);
        self.queries.begin(rec);
        self.method.record(rec, &self.target, &view, counter)?;
        self.queries.end(rec);
        count::phase_end("record");
        let t2 = Instant::now();
        timing.upload = ms(t1 - t0);
        timing.record = ms(t2 - t1);
        timing.submit = ms(rec.submit()?);
        Ok(())
    }

    /// Wait for the submitted frame and read its GPU time and statistics.
    pub fn wait(&mut self, timing: &mut FrameTiming) -> Result<Option<PipelineStats>> {
        timing.wait = ms(self.recorder.wait()?);
        count::phase_end("device");
        let (gpu, stats) = self.queries.results()?;
        timing.gpu = gpu;
        self.method.after_frame(&mut timing.method)?;
        count::phase_end("finish");
        Ok(stats)
    }

    /// Run `cameras` with the CPU half of each frame overlapping the device's
    /// work on the previous one (on lavapipe the device's vertex stage and
    /// binning run on one core and leave the other free). Each returned
    /// `frame` time is the interval between consecutive frame completions,
    /// i.e. steady-state throughput.
    pub fn run_overlapped(&mut self, cameras: &[Camera], counter: &mut UploadCounter) -> Result<Vec<(FrameTiming, UploadCounter)>> {
        let mut out = Vec::with_capacity(cameras.len());
        let Some(first) = cameras.first() else { return Ok(out) };
        let mut last_done = Instant::now();
        let mut current = self.prepare(first)?;
        let mut before = *counter;
        self.submit(counter, &mut current)?;
        let mut bytes = counter.since(&before);
        for next in cameras.iter().skip(1).map(Some).chain(std::iter::once(None)) {
            let prepared = next.map(|c| self.prepare(c)).transpose();
            // Wait for the frame in flight even when preparing the next one
            // failed: nothing may be left running on the device.
            self.wait(&mut current).context("waiting for a frame")?;
            let prepared = prepared?;
            let done = Instant::now();
            current.frame = ms(done - last_done);
            last_done = done;
            out.push((std::mem::take(&mut current), bytes));
            if let Some(p) = prepared {
                current = p;
                before = *counter;
                self.submit(counter, &mut current)?;
                bytes = counter.since(&before);
            }
        }
        Ok(out)
    }

    /// Run `cameras` overlapped (`run_overlapped`) or each frame's phases
    /// one after another (`frame`); the timing and bytes of every frame.
    pub fn run_frames(&mut self, cameras: &[Camera], overlap: bool, counter: &mut UploadCounter) -> Result<Vec<(FrameTiming, UploadCounter)>> {
        if overlap {
            return self.run_overlapped(cameras, counter);
        }
        let mut out = Vec::with_capacity(cameras.len());
        for (f, camera) in cameras.iter().enumerate() {
            let before = *counter;
            let (timing, _) = self.frame(camera, counter).with_context(|| format!("frame {f}"))?;
            out.push((timing, counter.since(&before)));
        }
        Ok(out)
    }

    /// The last frame's image.
    pub fn read_image(&self, ctx: &Arc<Context>) -> Result<RgbaImage> {
        let pixels = self.target.read_rgba32f(ctx).context("reading back the image")?;
        Ok(RgbaImage { width: self.width, height: self.height, pixels })
    }
}

/// The method's details with the process's peak resident set so far
/// (`process_peak_rss_bytes`, VmHWM; beside `host_memory`, which counts the
/// method's own structures): load, build and frames, and on lavapipe the
/// device allocations too.
fn with_peak_rss(mut details: serde_json::Value) -> serde_json::Value {
    if let (serde_json::Value::Object(m), Some(b)) = (&mut details, crate::algo::host_memory::peak_rss_bytes()) {
        m.insert("process_peak_rss_bytes".into(), b.into());
    }
    details
}

/// Raw samples by phase name, and the method's per-frame counts.
#[derive(Default)]
struct Samples(BTreeMap<String, Vec<f64>>, BTreeMap<String, Vec<u64>>);

impl Samples {
    fn push(&mut self, t: &FrameTiming) {
        for &(name, n) in &t.method.1 {
            self.1.entry(name.to_string()).or_default().push(n);
        }
        let mut add = |k: &str, v: f64| self.0.entry(k.to_string()).or_default().push(v);
        for &(name, v) in &t.method.0 {
            add(name, v);
        }
        add("upload", t.upload);
        add("record", t.record);
        add("submit", t.submit);
        add("wait", t.wait);
        add("frame", t.frame);
        add("gpu", t.gpu);
    }

    /// A frame with nothing in view: its frame and GPU time as `fixed` and
    /// `fixed_gpu`, its counts as `fixed.<name>` (e.g. `fixed.cells_drawn`,
    /// which says whether the view was really empty).
    fn push_fixed(&mut self, t: &FrameTiming) {
        for &(name, n) in &t.method.1 {
            self.1.entry(format!("fixed.{name}")).or_default().push(n);
        }
        self.0.entry("fixed".into()).or_default().push(t.frame);
        self.0.entry("fixed_gpu".into()).or_default().push(t.gpu);
    }
}

/// A picture that cannot be right is a failed run, not a result: NaN or Inf
/// pixels, or nothing drawn although the orbit camera frames the dataset and
/// the transfer function is not transparent over the dataset's range.
fn check_image(image: &RgbaImage, dataset: &Dataset, tf: &TransferFunction, cfg: &RunConfig) -> Result<()> {
    let bad = image.non_finite_pixels();
    anyhow::ensure!(bad == 0, "'{}': {bad} pixels of the image are NaN or Inf", dataset.name);
    let (lo, hi) = dataset.scalar_range();
    // Images of a few pixels a side may legitimately miss a dataset between
    // their pixel centres; the check needs at least 8 on each side.
    let big_enough = image.width >= 8 && image.height >= 8;
    if image.covered_pixels() == 0 && big_enough && cfg.fixed_camera.is_none() && !tf.visible_over(lo, hi, dataset.bounds().diagonal()) {
        // Right, but no result: a blank picture measures nothing.
        anyhow::bail!(
            "'{}' rendered an empty image: transfer function '{}' is transparent over the data's scalar range [{lo}, {hi}] \
             (give a transfer function that is opaque somewhere in it, --tf)",
            dataset.name,
            tf.name
        );
    }
    if image.covered_pixels() == 0 && big_enough && cfg.fixed_camera.is_none() {
        anyhow::bail!(
            "'{}' rendered an empty image although the camera frames it and transfer function '{}' is not \
             transparent over its scalar range [{lo}, {hi}]",
            dataset.name,
            tf.name
        );
    }
    Ok(())
}

/// Run `spec` on `dataset` as `cfg` says.
pub fn run(ctx: &Arc<Context>, spec: &MethodSpec, dataset: &Dataset, tf: &TransferFunction, cfg: &RunConfig) -> Result<RunOutput> {
    let mut session = MethodSession::new(ctx, spec, dataset, tf, cfg)?;
    session.set_statistics(false);
    let cameras: Vec<Camera> = (0..cfg.warmup + cfg.frames).map(|f| cfg.frame_camera(dataset, &spec.info.family, f)).collect();
    let mut timed = if let Some(dir) = &cfg.count_dir {
        counted_frames(&mut session, cfg, &cameras, dir)?
    } else {
        timed_frames(&mut session, cfg, &cameras)?
    };
    fixed_cost_frames(&mut session, cfg, &cameras, &mut timed.samples)?;
    // The reference view, untimed: its image and statistics are reported.
    let reference_camera = cfg.frame_camera(dataset, &spec.info.family, 0);
    session.set_statistics(true);
    let (reference_timing, stats) = session.frame(&reference_camera, &mut UploadCounter::default()).context("reference-view frame")?;
    let image = session.read_image(ctx)?;
    ctx.check_validation().context("Vulkan validation")?;
    check_image(&image, dataset, tf, cfg)?;
    let reference_view = session.view(&reference_camera);
    let diagnostics = if cfg.diagnostics { session.method_mut().diagnostics(&reference_view)? } else { None };
    let reference = ReferenceFrame { camera: reference_camera, timing: reference_timing, stats, diagnostics };
    let result = run_result(ctx, spec, dataset, tf, cfg, &session, timed, reference, &image);
    Ok(RunOutput { result, image })
}

/// What the timed frames measured: their samples, the last one's upload
/// counters, and (`--count`) the instructions per phase.
struct Timed {
    samples: Samples,
    last_frame_counters: UploadCounter,
    counted: Option<CountReport>,
}

/// The reference view's frame, untimed: its camera, timing, statistics
/// and the method's diagnostics.
struct ReferenceFrame {
    camera: Camera,
    timing: FrameTiming,
    stats: Option<PipelineStats>,
    diagnostics: Option<serde_json::Value>,
}

/// The warm-up and timed frames, overlapped as `cfg` says.
fn timed_frames(session: &mut MethodSession, cfg: &RunConfig, cameras: &[Camera]) -> Result<Timed> {
    let mut counter = UploadCounter::default();
    let mut timed = Timed { samples: Samples::default(), last_frame_counters: UploadCounter::default(), counted: None };
    for (f, (timing, bytes)) in session.run_frames(cameras, cfg.overlap, &mut counter)?.into_iter().enumerate() {
        if f >= cfg.warmup {
            timed.samples.push(&timing);
            timed.last_frame_counters = bytes;
        }
    }
    Ok(timed)
}

/// Counted: the warm-up uncounted, then each timed frame's phases one
/// after another, dumped at each boundary into `dir` (`harness::count`).
fn counted_frames(session: &mut MethodSession, cfg: &RunConfig, cameras: &[Camera], dir: &std::path::Path) -> Result<Timed> {
    let mut counter = UploadCounter::default();
    let mut timed = Timed { samples: Samples::default(), last_frame_counters: UploadCounter::default(), counted: None };
    for (f, camera) in cameras.iter().enumerate() {
        let before = counter;
        if f == cfg.warmup {
            count::take_dumps(dir)?;
            crate::vk::valgrind::start();
        }
        if f >= cfg.warmup {
            count::frame_start();
        }
        let frame = session.frame(camera, &mut counter).with_context(|| format!("frame {f}"));
        if f + 1 == cameras.len() || frame.is_err() {
            crate::vk::valgrind::stop();
        }
        let (timing, _) = frame?;
        if f >= cfg.warmup {
            timed.samples.push(&timing);
            timed.last_frame_counters = counter.since(&before);
        }
    }
    timed.counted = Some(count::report(&count::take_dumps(dir)?, cfg.frames)?);
    Ok(timed)
}

/// The fixed cost: the timed frames' cameras turned away from the
/// dataset, so no cell, ray hit or terrain tile is in view and what is
/// left is what every frame pays (clear, queries, submit, fence, the
/// method's per-pixel and per-frame passes). Bytes are not counted.
/// A counted run counts only the timed frames: its fixed frames are skipped.
fn fixed_cost_frames(session: &mut MethodSession, cfg: &RunConfig, cameras: &[Camera], samples: &mut Samples) -> Result<()> {
    let fixed_frames = if cfg.count_dir.is_some() { 0 } else { cfg.fixed_frames };
    let empty: Vec<Camera> = cameras.iter().skip(cfg.warmup).cycle().take(fixed_frames).map(Camera::turned_away).collect();
    for (timing, _) in session.run_frames(&empty, cfg.overlap, &mut UploadCounter::default()).context("fixed-cost frames")? {
        samples.push_fixed(&timing);
    }
    Ok(())
}

/// The bytes uploaded per frame, per cell drawn (`cells_drawn` of the
/// last timed frame, else the mesh's `cells`) and per mesh cell.
fn upload_report(session: &MethodSession, cells: Option<u64>, samples: &Samples, fc: UploadCounter) -> UploadReport {
    let cell_bytes = fc.frame_cell_bytes();
    // The last timed frame's cells drawn (culling may skip some), else all.
    let drawn = samples.1.get("cells_drawn").and_then(|v| v.last().copied()).or(cells);
    let bytes_per_cell = drawn.filter(|&n| n > 0).map(|n| cell_bytes as f64 / n as f64);
    let bytes_per_mesh_cell = cells.filter(|&n| n > 0).map(|n| cell_bytes as f64 / n as f64);
    UploadReport {
        bytes_per_frame: fc.frame_bytes(),
        cell_bytes_per_frame: cell_bytes,
        constant_bytes_per_frame: fc.frame_constant_bytes(),
        bytes_per_cell,
        floats_per_cell: bytes_per_cell.map(|b| b / 4.0),
        bytes_per_mesh_cell,
        static_bytes: session.setup_counter.static_bytes(),
        frame_counters: fc,
        setup_counters: session.setup_counter,
    }
}

/// The run's result from what it measured.
#[allow(clippy::too_many_arguments)]
fn run_result(
    ctx: &Arc<Context>,
    spec: &MethodSpec,
    dataset: &Dataset,
    tf: &TransferFunction,
    cfg: &RunConfig,
    session: &MethodSession,
    timed: Timed,
    reference: ReferenceFrame,
    image: &RgbaImage,
) -> RunResult {
    let Timed { samples, last_frame_counters, counted } = timed;
    let ReferenceFrame { camera: reference_camera, timing: reference_timing, stats, diagnostics } = reference;
    let method = session.method();
    let work = method.work();
    let upload = upload_report(session, work.0.get("cells").copied(), &samples, last_frame_counters);
    let phases: BTreeMap<String, Summary> = samples.0.iter().map(|(k, v)| (k.clone(), Summary::of(v))).collect();
    let median_s = phases.get("frame").map_or(0.0, |s| s.median * 1e-3);
    let per_second: BTreeMap<&'static str, f64> =
        work.0.iter().map(|(&k, &n)| (k, if median_s > 0.0 { n as f64 / median_s } else { 0.0 })).collect();
    let cells_per_second = per_second.get("cells").copied().unwrap_or(0.0);
    let frame_counts = samples
        .1
        .into_iter()
        .map(|(k, v)| (k, FrameCountReport { total: v.iter().sum(), frames: v.len(), per_frame: v }))
        .collect();
    let time_ms = TimeReport { phases, setup_ms: session.setup_ms, table_build_ms: method.table_build_ms(), samples: samples.0 };
    let summary = dataset.summary();
    RunResult {
        schema_version: SCHEMA_VERSION,
        method: spec.info.name,
        spec: spec.canonical(),
        options: spec.options.clone(),
        mesh: dataset.name.clone(),
        cells: summary.counts.get("cells").copied(),
        points: summary.counts.get("points").copied(),
        dataset: summary,
        width: cfg.width,
        height: cfg.height,
        frames: cfg.frames,
        warmup: cfg.warmup,
        overlap: cfg.overlap,
        view: ViewReport {
            projection: reference_camera.projection,
            orbit_step_deg: cfg.orbit_step.to_degrees(),
            zoom: cfg.zoom,
            fixed_camera: cfg.fixed_camera.is_some(),
        },
        transfer_function: tf.name.clone(),
        upload,
        time_ms,
        work: WorkReport { counts: work.0.clone(), per_second },
        cells_per_second,
        rasterizer: RasterizerReport::of(stats.as_ref(), &ctx.info.name),
        stats,
        frame_counts,
        image: ImageReport {
            width: cfg.width,
            height: cfg.height,
            covered_pixels: image.covered_pixels(),
            non_finite_pixels: image.non_finite_pixels(),
            camera: reference_camera,
        },
        // A method that measures its own error (no image reference exists).
        error: reference_timing.method.2.map(|e| ErrorReport {
            compared: ErrorKind::Own,
            rmse: e.rmse,
            max_abs: e.max_abs,
            psnr_db: f64::INFINITY,
            reference: e.what.into(),
            reference_ms: 0.0,
            reference_cached: false,
            reference_recomputed: None,
        }),
        details: with_peak_rss(method.details()),
        diagnostics,
        count: counted,
        device: ctx.info.clone(),
        volbench_version: env!("CARGO_PKG_VERSION"),
        git_sha: env!("VOLBENCH_GIT_SHA"),
        env_switches: crate::switches::recorded(),
    }
}
