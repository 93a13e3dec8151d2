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
use crate::algo::cell_projection::mpvo::{MpvoSort, OrderCheck};
use crate::algo::cell_projection::sort::{CentroidSort, SortKind, Sorter};
use crate::algo::cell_projection::{self, CellProjector, ExitTolerances, FrameSetup, Interpolation, MeshScale, Method};
use crate::algo::integrate::{IntegrationTables, Integrator};
use crate::mesh::{MeshStats, TetGeometry, TetMesh};
use crate::scene::{Camera, Projection, TransferFunction};
use crate::vk::{CommandRecorder, Context, DeviceInfo, FrameQueries, Image, PipelineStats, UploadCounter};

#[derive(Debug, Clone)]
pub struct RunConfig {
    pub method: Method,
    pub interpolation: Interpolation,
    pub integrator: Integrator,
    /// Side of the integrator's table; 0 = its default.
    pub table_size: usize,
    pub sort: SortKind,
    /// Also check the centroid order of the reference view against MPVO's
    /// face constraints (costs an MPVO build when sorting by centroid).
    pub check_visibility: bool,
    pub tolerances: ExitTolerances,
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    pub projection: Projection,
    /// Camera rotation per frame, radians.
    pub orbit_step: f64,
    /// A camera used for every frame instead of the orbit (tests, stills).
    pub fixed_camera: Option<Camera>,
    /// Prepare frame N+1 on the CPU while the device draws frame N.
    pub overlap: bool,
}

impl RunConfig {
    pub fn new(method: Method) -> Self {
        RunConfig {
            method,
            interpolation: Interpolation::Paper,
            integrator: Integrator::Ppi,
            table_size: 0,
            sort: SortKind::Centroid,
            check_visibility: false,
            tolerances: ExitTolerances::default(),
            width: 512,
            height: 512,
            frames: 10,
            warmup: 2,
            projection: Projection::Perspective { fovy_deg: 30.0 },
            orbit_step: 5f64.to_radians(),
            fixed_camera: None,
            overlap: true,
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
    pub interpolation: &'static str,
    pub integrator: &'static str,
    /// Side of the integrator's table (0: none).
    pub table_size: usize,
    pub sort: &'static str,
    /// Centroid order of the reference view checked against MPVO's face
    /// constraints (`check_visibility`): how many it violates, how many cells.
    pub centroid_order: Option<OrderCheck>,
    pub tolerances: ExitTolerances,
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
    /// CPU work of frame N+1 overlapped with the device's frame N.
    pub overlap: bool,
    pub transfer_function: String,
    pub upload: UploadReport,
    pub time_ms: TimeReport,
    pub cells_per_second: f64,
    /// Pipeline statistics of the reference-view frame (deterministic).
    pub stats: Option<PipelineStats>,
    pub image: ImageReport,
    /// The reference-view image against the f64 CPU reference, when asked for.
    pub error: Option<ErrorReport>,
    pub device: DeviceInfo,
    pub volbench_version: &'static str,
    /// The commit the binary was built from (`-dirty` with local changes).
    pub git_sha: &'static str,
}

/// Error of an image against the f64 reference (RGBA, values in [0, 1]).
#[derive(Debug, Clone, Serialize)]
pub struct ErrorReport {
    pub rmse: f64,
    pub max_abs: f64,
    pub psnr_db: f64,
    /// What the reference is: renderer, mesh, view, size, transfer function.
    pub reference: String,
    /// CPU time the reference took (not part of any frame; 0 when cached).
    pub reference_ms: f64,
    pub reference_cached: bool,
}

impl RunOutput {
    /// Compare this run's image with a reference image and record the error.
    pub fn attach_error(&mut self, reference: &super::reference_cache::Reference) -> Result<RgbaImage> {
        let e = self.image.compare(&reference.image)?;
        self.result.error = Some(ErrorReport {
            rmse: e.rmse,
            max_abs: e.max_abs,
            psnr_db: e.psnr_db,
            reference: reference.what.clone(),
            reference_ms: reference.compute_ms,
            reference_cached: reference.cached,
        });
        Ok(self.image.difference(&reference.image))
    }
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

/// Wall and GPU time of one frame's phases, in milliseconds.
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameTiming {
    pub sort: f64,
    pub pack: f64,
    pub upload: f64,
    pub record: f64,
    pub submit: f64,
    pub wait: f64,
    pub frame: f64,
    pub gpu: f64,
}

/// Everything one method needs to draw frames of one scene: tables, the
/// method's buffers and pipeline, the target, the sort. Built once; `frame`
/// is the per-frame path that runs and benchmarks time.
pub struct CellProjectionSession {
    tables: IntegrationTables,
    method: Box<dyn CellProjector>,
    target: Image,
    recorder: CommandRecorder,
    queries: FrameQueries,
    sorter: Sorter,
    scale: MeshScale,
    interpolation: Interpolation,
    pub tolerances: ExitTolerances,
    /// The packed frame waiting for `submit`.
    prepared: Option<FrameSetup>,
    width: u32,
    height: u32,
    /// One-time uploads made while building the session.
    pub setup_counter: UploadCounter,
    pub setup_ms: f64,
}

impl CellProjectionSession {
    pub fn new(ctx: &Arc<Context>, scene: &Scene, cfg: &RunConfig) -> Result<Self> {
        let (width, height) = (cfg.width, cfg.height);
        anyhow::ensure!(width > 0 && height > 0, "image size must be positive, got {width}x{height}");
        let (method, interpolation) = (cfg.method, cfg.interpolation);
        let mesh = scene.mesh;
        // Refuse meshes the device cannot hold before allocating anything:
        // the per-frame vertex buffer must fit one allocation, and it plus
        // the static index data must fit device memory.
        let (vertex_bytes, static_bytes) = match method {
            Method::Vicp => (cell_projection::vicp::FLOATS_PER_CELL * 4, 0),
            Method::Balanced => {
                (cell_projection::balanced::FLOATS_PER_CELL * 4, cell_projection::balanced::INDICES_PER_CELL * 4)
            }
        };
        let info = &ctx.info;
        crate::mesh::check_fits(mesh.tets.len(), vertex_bytes, info.max_memory_allocation_size)
            .and_then(|()| crate::mesh::check_fits(mesh.tets.len(), vertex_bytes + static_bytes, info.device_local_heap_bytes))
            .with_context(|| format!("mesh '{}' with {} on {}", mesh.name, method.name(), info.name))?;
        let start = Instant::now();
        let mut setup_counter = UploadCounter::default();
        // A typical cell size: the bounding box shared out among the cells.
        let length_scale = mesh.bounds().diagonal() / (mesh.tets.len().max(1) as f64).cbrt();
        let tables = IntegrationTables::new(
            ctx,
            scene.tf,
            mesh.scalar_range(),
            cfg.integrator,
            cfg.table_size,
            length_scale,
            &mut setup_counter,
        )
        .context("building the integration tables")?;
        let method = cell_projection::create(ctx, method, interpolation, mesh, scene.geometry, &tables, &mut setup_counter)
            .with_context(|| format!("setting up {} for mesh '{}'", method.name(), mesh.name))?;
        let target = Image::render_target(ctx, "cell projection target", width, height)?;
        let recorder = CommandRecorder::new(ctx, "frame")?;
        let queries = FrameQueries::new(ctx)?;
        let sorter = Sorter::new(cfg.sort, mesh, scene.geometry);
        Ok(CellProjectionSession {
            tables,
            method,
            target,
            recorder,
            queries,
            sorter,
            scale: MeshScale::of(mesh),
            interpolation,
            tolerances: cfg.tolerances,
            prepared: None,
            width,
            height,
            setup_counter,
            setup_ms: ms(start.elapsed()),
        })
    }

    pub fn method(&self) -> &dyn CellProjector {
        self.method.as_ref()
    }

    pub fn table_size(&self) -> usize {
        self.tables.table_size
    }

    pub fn table_build_ms(&self) -> f64 {
        self.tables.build_ms
    }

    /// Sort, pack, upload, draw and wait for one frame seen by `camera`;
    /// bytes crossing to the device are added to `counter`.
    pub fn frame(&mut self, camera: &Camera, counter: &mut UploadCounter) -> Result<(FrameTiming, Option<PipelineStats>)> {
        let t0 = Instant::now();
        let mut timing = self.prepare(camera);
        self.submit(counter, &mut timing)?;
        let stats = self.wait(&mut timing)?;
        timing.frame = ms(t0.elapsed());
        Ok((timing, stats))
    }

    /// The CPU half of a frame: sort and pack (the device may still be
    /// drawing the previous frame: packing writes host memory only).
    pub fn prepare(&mut self, camera: &Camera) -> FrameTiming {
        let setup = FrameSetup::new(
            camera,
            self.width,
            self.height,
            &self.tables,
            &self.scale,
            self.interpolation,
            &self.tolerances,
        );
        let t0 = Instant::now();
        let order = self.sorter.sort(camera);
        let t1 = Instant::now();
        self.method.pack(order, &setup);
        let t2 = Instant::now();
        self.prepared = Some(setup);
        FrameTiming { sort: ms(t1 - t0), pack: ms(t2 - t1), ..FrameTiming::default() }
    }

    /// Upload the prepared frame, record and submit it (no wait). The
    /// previous submission must have been waited for.
    pub fn submit(&mut self, counter: &mut UploadCounter, timing: &mut FrameTiming) -> Result<()> {
        let setup = self.prepared.take().context("submit without a prepared frame")?;
        let t0 = Instant::now();
        self.method.upload(counter).context("uploading vertex records")?;
        let t1 = Instant::now();
        let rec = &self.recorder;
        rec.begin()?;
        self.queries.reset(rec);
        rec.begin_rendering(&self.target, [0.0; 4]);
        self.queries.begin(rec);
        self.method.record_draw(rec, &self.tables, &setup, counter);
        self.queries.end(rec);
        rec.end_rendering();
        let t2 = Instant::now();
        timing.upload = ms(t1 - t0);
        timing.record = ms(t2 - t1);
        timing.submit = ms(rec.submit()?);
        Ok(())
    }

    /// Wait for the submitted frame and read its GPU time and statistics.
    pub fn wait(&mut self, timing: &mut FrameTiming) -> Result<Option<PipelineStats>> {
        timing.wait = ms(self.recorder.wait()?);
        let (gpu, stats) = self.queries.results()?;
        timing.gpu = gpu;
        Ok(stats)
    }

    /// Run `cameras` with the CPU half of each frame overlapping the device's
    /// work on the previous one (what "balanced" means on a real GPU; on
    /// lavapipe the device's vertex stage and binning run on one core and
    /// leave the other free). Each returned `frame` time is the interval
    /// between consecutive frame completions, i.e. steady-state throughput.
    pub fn run_overlapped(&mut self, cameras: &[Camera], counter: &mut UploadCounter) -> Result<Vec<(FrameTiming, UploadCounter)>> {
        let mut out = Vec::with_capacity(cameras.len());
        let Some(first) = cameras.first() else { return Ok(out) };
        let mut last_done = Instant::now();
        let mut current = self.prepare(first);
        let mut before = *counter;
        self.submit(counter, &mut current)?;
        let mut bytes = counter.since(&before);
        for next in cameras.iter().skip(1).map(Some).chain(std::iter::once(None)) {
            let prepared = next.map(|c| self.prepare(c));
            self.wait(&mut current).context("waiting for a frame")?;
            let done = Instant::now();
            current.frame = ms(done - last_done);
            last_done = done;
            out.push((current, bytes));
            if let Some(p) = prepared {
                current = p;
                before = *counter;
                self.submit(counter, &mut current)?;
                bytes = counter.since(&before);
            }
        }
        Ok(out)
    }

    /// The last frame's image.
    pub fn read_image(&self, ctx: &Arc<Context>) -> Result<RgbaImage> {
        let pixels = self.target.read_rgba32f(ctx).context("reading back the image")?;
        Ok(RgbaImage { width: self.width, height: self.height, pixels })
    }
}

impl FrameSamples {
    fn push(&mut self, t: &FrameTiming) {
        self.sort.push(t.sort);
        self.pack.push(t.pack);
        self.upload.push(t.upload);
        self.record.push(t.record);
        self.submit.push(t.submit);
        self.wait.push(t.wait);
        self.frame.push(t.frame);
        self.gpu.push(t.gpu);
    }
}

pub fn run_cell_projection(ctx: &Arc<Context>, scene: &Scene, cfg: &RunConfig) -> Result<RunOutput> {
    anyhow::ensure!(cfg.frames > 0, "--frames must be at least 1");
    let mesh = scene.mesh;
    let mut session = CellProjectionSession::new(ctx, scene, cfg)?;
    let bounds = mesh.bounds();
    let mut counter = UploadCounter::default();
    let mut samples = FrameSamples::default();
    let mut last_frame_counters = UploadCounter::default();

    if cfg.overlap {
        let cameras: Vec<Camera> = (0..cfg.warmup + cfg.frames).map(|f| cfg.camera(&bounds, f)).collect();
        for (f, (timing, bytes)) in session.run_overlapped(&cameras, &mut counter)?.into_iter().enumerate() {
            if f >= cfg.warmup {
                samples.push(&timing);
                last_frame_counters = bytes;
            }
        }
    } else {
        for f in 0..cfg.warmup + cfg.frames {
            let before = counter;
            let (timing, _) = session.frame(&cfg.camera(&bounds, f), &mut counter).with_context(|| format!("frame {f}"))?;
            if f >= cfg.warmup {
                samples.push(&timing);
                last_frame_counters = counter.since(&before);
            }
        }
    }
    // The reference view, untimed: its image and statistics are reported.
    let reference_camera = cfg.camera(&bounds, 0);
    let (_, stats) = session.frame(&reference_camera, &mut UploadCounter::default()).context("reference-view frame")?;
    let image = session.read_image(ctx)?;
    ctx.check_validation().context("Vulkan validation")?;

    let centroid_order = if cfg.check_visibility {
        let origin = cell_projection::render_origin(mesh);
        let mut centroid =
            CentroidSort::with_origin(cell_projection::centroids_relative_f32(scene.geometry, origin), origin);
        let order = centroid.sort(&reference_camera).to_vec();
        Some(MpvoSort::new(mesh, scene.geometry).check_order(&order, &reference_camera))
    } else {
        None
    };
    let method = session.method();
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
        static_bytes: session.setup_counter.static_bytes(),
        vertices_per_cell: method.vertices_per_cell(),
        frame_counters: fc,
        setup_counters: session.setup_counter,
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
        setup_ms: session.setup_ms,
        table_build_ms: session.table_build_ms(),
        samples,
    };
    let cells_per_second = if frame_summary.median > 0.0 { cells as f64 / (frame_summary.median * 1e-3) } else { 0.0 };
    let result = RunResult {
        method: cfg.method.name(),
        interpolation: cfg.interpolation.name(),
        integrator: cfg.integrator.name(),
        table_size: session.table_size(),
        sort: cfg.sort.name(),
        centroid_order,
        tolerances: cfg.tolerances,
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
        overlap: cfg.overlap,
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
        error: None,
        device: ctx.info.clone(),
        volbench_version: env!("CARGO_PKG_VERSION"),
        git_sha: env!("VOLBENCH_GIT_SHA"),
    };
    Ok(RunOutput { result, image })
}
