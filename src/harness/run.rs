//! One benchmark run of a cell-projection method: warm-up, N timed frames with
//! the camera orbiting, then one untimed frame at the reference view (angle 0)
//! whose image and pipeline statistics are reported.
//!
//! Per frame, host wall time is split into sort, pack, upload, record, submit
//! and wait; GPU time comes from timestamps. Bytes come from the counters in
//! `vk::upload`, read before and after each frame.

use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result};
use serde::Serialize;

use super::image::RgbaImage;
use super::stats::Summary;
use crate::algo::cell_projection::{self, sort::CentroidSort, FrameSetup, Method};
use crate::algo::integrate::IntegrationTables;
use crate::mesh::{MeshStats, TetGeometry, TetMesh};
use crate::scene::{Camera, Projection, TransferFunction};
use crate::vk::{CommandRecorder, Context, DeviceInfo, FrameQueries, Image, PipelineStats, UploadCounter};

#[derive(Debug, Clone)]
pub struct RunConfig {
    pub method: Method,
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    pub projection: Projection,
    /// Camera rotation per frame, radians.
    pub orbit_step: f64,
    /// A camera used for every frame instead of the orbit (tests, stills).
    pub fixed_camera: Option<Camera>,
}

impl RunConfig {
    pub fn new(method: Method) -> Self {
        RunConfig {
            method,
            width: 512,
            height: 512,
            frames: 10,
            warmup: 2,
            projection: Projection::Perspective { fovy_deg: 30.0 },
            orbit_step: 5f64.to_radians(),
            fixed_camera: None,
        }
    }

    /// The camera of frame `f` (the orbit's angle 0 is the reference view).
    pub fn camera(&self, bounds: &crate::mesh::Bounds, f: usize) -> Camera {
        match self.fixed_camera {
            Some(c) => c,
            None => Camera::orbit(bounds, f as f64 * self.orbit_step, self.projection),
        }
    }
}

/// Bytes that crossed to the device, measured by the counters.
#[derive(Debug, Clone, Serialize)]
pub struct UploadReport {
    /// Everything per frame: cell records plus frame constants.
    pub bytes_per_frame: u64,
    /// Cell records per frame divided by the number of cells.
    pub bytes_per_cell: f64,
    pub floats_per_cell: f64,
    pub cell_bytes_per_frame: u64,
    pub constant_bytes_per_frame: u64,
    /// One-time uploads (index buffer, tables), not part of any frame.
    pub static_bytes: u64,
    pub vertices_per_cell: usize,
    /// The counters themselves for the last timed frame and for set-up.
    pub frame_counters: UploadCounter,
    pub setup_counters: UploadCounter,
}

#[derive(Debug, Clone, Serialize)]
pub struct TimeReport {
    pub frame: Summary,
    pub sort: Summary,
    pub pack: Summary,
    pub upload: Summary,
    pub record: Summary,
    pub submit: Summary,
    pub wait: Summary,
    pub gpu: Summary,
    /// Table construction and pipeline creation, apart from frames.
    pub setup_ms: f64,
    pub table_build_ms: f64,
    /// Raw per-frame samples (ms), in frame order.
    pub samples: FrameSamples,
}

#[derive(Debug, Clone, Default, Serialize)]
pub struct FrameSamples {
    pub frame: Vec<f64>,
    pub sort: Vec<f64>,
    pub pack: Vec<f64>,
    pub upload: Vec<f64>,
    pub record: Vec<f64>,
    pub submit: Vec<f64>,
    pub wait: Vec<f64>,
    pub gpu: Vec<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ImageReport {
    pub covered_pixels: usize,
    pub non_finite_pixels: usize,
    pub camera: Camera,
}

#[derive(Debug, Clone, Serialize)]
pub struct RunResult {
    pub method: &'static str,
    pub mesh: String,
    pub cells: usize,
    pub points: usize,
    pub mesh_stats: MeshStats,
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    pub projection: Projection,
    pub orbit_step_deg: f64,
    pub transfer_function: String,
    pub upload: UploadReport,
    pub time_ms: TimeReport,
    pub cells_per_second: f64,
    /// Pipeline statistics of the reference-view frame (deterministic).
    pub stats: Option<PipelineStats>,
    pub image: ImageReport,
    pub device: DeviceInfo,
    pub volbench_version: &'static str,
}

pub struct RunOutput {
    pub result: RunResult,
    pub image: RgbaImage,
}

/// What stays the same across methods for one mesh: its geometry and the
/// sort, so that both methods draw exactly the same order.
pub struct Scene<'a> {
    pub mesh: &'a TetMesh,
    pub geometry: &'a TetGeometry,
    pub tf: &'a TransferFunction,
}

fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

pub fn run_cell_projection(ctx: &Arc<Context>, scene: &Scene, cfg: &RunConfig) -> Result<RunOutput> {
    anyhow::ensure!(cfg.width > 0 && cfg.height > 0, "image size must be positive, got {}x{}", cfg.width, cfg.height);
    anyhow::ensure!(cfg.frames > 0, "--frames must be at least 1");
    let mesh = scene.mesh;
    let setup_start = Instant::now();
    let mut setup_counter = UploadCounter::default();
    let tables = IntegrationTables::new(ctx, scene.tf, mesh.scalar_range(), &mut setup_counter)
        .context("building the integration tables")?;
    let mut method = cell_projection::create(ctx, cfg.method, mesh, scene.geometry, &tables, &mut setup_counter)
        .with_context(|| format!("setting up {} for mesh '{}'", cfg.method.name(), mesh.name))?;
    let target = Image::render_target(ctx, "cell projection target", cfg.width, cfg.height)?;
    let recorder = CommandRecorder::new(ctx, "frame")?;
    let queries = FrameQueries::new(ctx)?;
    let mut sorter = CentroidSort::new(cell_projection::centroids_f32(scene.geometry));
    let setup_ms = ms(setup_start.elapsed());

    let bounds = mesh.bounds();
    let diagonal = bounds.diagonal();
    let mut counter = UploadCounter::default();
    let mut samples = FrameSamples::default();
    let mut last_frame_counters = UploadCounter::default();

    // One frame: returns its pipeline statistics.
    let mut frame = |camera: &Camera, timed: bool, counter: &mut UploadCounter| -> Result<Option<PipelineStats>> {
        let before = *counter;
        let setup = FrameSetup::new(camera, cfg.width, cfg.height, &tables, diagonal);
        let t0 = Instant::now();
        let order = sorter.sort(camera);
        let t1 = Instant::now();
        method.pack(order, &setup);
        let t2 = Instant::now();
        method.upload(counter).context("uploading vertex records")?;
        let t3 = Instant::now();
        recorder.begin()?;
        queries.reset(&recorder);
        recorder.begin_rendering(&target, [0.0; 4]);
        queries.begin(&recorder);
        method.record_draw(&recorder, &tables, &setup, counter);
        queries.end(&recorder);
        recorder.end_rendering();
        let t4 = Instant::now();
        let submit = recorder.submit_and_wait()?;
        let t5 = Instant::now();
        let (gpu_ms, stats) = queries.results()?;
        if timed {
            samples.sort.push(ms(t1 - t0));
            samples.pack.push(ms(t2 - t1));
            samples.upload.push(ms(t3 - t2));
            samples.record.push(ms(t4 - t3));
            samples.submit.push(ms(submit.submit));
            samples.wait.push(ms(submit.wait));
            samples.frame.push(ms(t5 - t0));
            samples.gpu.push(gpu_ms);
            last_frame_counters = counter.since(&before);
        }
        Ok(stats)
    };

    let total = cfg.warmup + cfg.frames;
    for f in 0..total {
        let camera = cfg.camera(&bounds, f);
        frame(&camera, f >= cfg.warmup, &mut counter).with_context(|| format!("frame {f}"))?;
    }
    // The reference view, untimed: its image and statistics are reported.
    let reference_camera = cfg.camera(&bounds, 0);
    let mut scratch = UploadCounter::default();
    let stats = frame(&reference_camera, false, &mut scratch).context("reference-view frame")?;
    drop(frame);
    let pixels = target.read_rgba32f(ctx).context("reading back the image")?;
    ctx.check_validation().context("Vulkan validation")?;

    let image = RgbaImage { width: cfg.width, height: cfg.height, pixels };
    let cells = method.cells();
    let fc = last_frame_counters;
    let cell_bytes = fc.frame_cell_bytes();
    let bytes_per_cell = if cells > 0 { cell_bytes as f64 / cells as f64 } else { 0.0 };
    let upload = UploadReport {
        bytes_per_frame: fc.frame_bytes(),
        bytes_per_cell,
        floats_per_cell: bytes_per_cell / 4.0,
        cell_bytes_per_frame: cell_bytes,
        constant_bytes_per_frame: fc.frame_constant_bytes(),
        static_bytes: setup_counter.static_bytes(),
        vertices_per_cell: method.vertices_per_cell(),
        frame_counters: fc,
        setup_counters: setup_counter,
    };
    let frame_summary = Summary::of(&samples.frame);
    let time_ms = TimeReport {
        frame: frame_summary,
        sort: Summary::of(&samples.sort),
        pack: Summary::of(&samples.pack),
        upload: Summary::of(&samples.upload),
        record: Summary::of(&samples.record),
        submit: Summary::of(&samples.submit),
        wait: Summary::of(&samples.wait),
        gpu: Summary::of(&samples.gpu),
        setup_ms,
        table_build_ms: tables.build_ms,
        samples,
    };
    let cells_per_second = if frame_summary.median > 0.0 { cells as f64 / (frame_summary.median * 1e-3) } else { 0.0 };
    let result = RunResult {
        method: cfg.method.name(),
        mesh: mesh.name.clone(),
        cells,
        points: mesh.points.len(),
        mesh_stats: mesh.stats.clone(),
        width: cfg.width,
        height: cfg.height,
        frames: cfg.frames,
        warmup: cfg.warmup,
        projection: reference_camera.projection,
        orbit_step_deg: cfg.orbit_step.to_degrees(),
        transfer_function: scene.tf.name.clone(),
        upload,
        time_ms,
        cells_per_second,
        stats,
        image: ImageReport {
            covered_pixels: image.covered_pixels(),
            non_finite_pixels: image.non_finite_pixels(),
            camera: reference_camera,
        },
        device: ctx.info.clone(),
        volbench_version: env!("CARGO_PKG_VERSION"),
    };
    Ok(RunOutput { result, image })
}
