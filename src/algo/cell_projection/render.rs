//! What VICP and balanced cell projection share as methods of the registry:
//! their options, the sweeps they take part in, and [`CellProjection`], the
//! `RenderMethod` that owns the integration tables, the visibility sort and
//! one [`CellProjector`] (the part that differs: what crosses per frame and
//! where IntersectBackFace runs). A frame is cull + sort + pack on the CPU
//! (`prepare`), the counted copy (`upload`) and one draw into the target;
//! culling (`cull`, option `cull`) leaves out cells the frame does not need
//! and re-uses an unchanged frame's data.

use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result};
use serde_json::json;

use super::cull::{Culler, FrameCull, LookupGrid};
use super::mpvo::MpvoSort;
use super::sort::{CentroidSort, SortKind, Sorter};
use super::{centroids_relative_f32, CellProjector, RelativeMesh, DrawSettings, Primitives};
use crate::algo::tet_mesh::{integrator_bound, render_origin, ExitTolerances, FrameSetup, Interpolation, MeshScale, INTEGRATOR_HELP, TABLE_SIZE_HELP};
use crate::algo::host_memory::HostMemory;
use crate::algo::integrate::{IntegrationTables, Integrator};
use crate::algo::settings::{check, choice, flag, float, int, pick, MethodSettings};
use crate::algo::method::{
    DataKind, Family, Feature, MethodInfo, MethodInputs, OptionSpec, Options, Phases, Published, PublishedFigure, RenderMethod, SceneData, View, Work,
};
use crate::mesh::TetMesh;
use crate::vk::{ColorAttachment, CommandRecorder, Context, Image, UploadCounter, VkResult};
use crate::vk::Stages;

crate::settings! {
    /// The typed settings of a cell-projection run: every option of the
    /// family. VICP chooses exit planes in the fragment stage and takes
    /// `edge_eps`; the balanced family knows them per tet
    /// (`balanced::exit_mask`), where the edge epsilon has nothing to correct,
    /// and takes `primitives` instead. `cull` is left out where a method draws
    /// every cell in its own order, e.g. sorted on the device. An option a
    /// method leaves out takes its default (a device sort culls nothing
    /// whatever `cull` says: `CellProjection::create`).
    pub struct Settings {
        integrator: Integrator = "ppi", choice::<Integrator>(), build, "", INTEGRATOR_HELP;
        table_size: usize = "0", int(0, 4096), run, "samples per side", TABLE_SIZE_HELP;
        sort: SortKind = "centroid", choice::<SortKind>(), run, "",
            "visibility order: centroid distance (radix sort) or MPVO from face adjacency";
        interpolation: Interpolation = "exact", choice::<Interpolation>(), build, "",
            "exit data across a face under perspective: exact (plane ratio), or as the papers do";
        distance_clamp: f64 = "1000", float(1.0, 1e6), run, "mesh diagonals",
            "clamp of vertex ray-plane distances (planes nearly parallel to the ray)";
        plane_ratio_max: f64 = "1000", float(1.0, 1e6), run, "", "clamp of the plane ratio u = h/e (exact interpolation)";
        edge_eps: f64 = "0", float(0.0, 0.1), run, "barycentric weight",
            "a plane whose weight is below this is an exit at distance 0 (off: drops grazing segments)";
        primitives: Primitives = "list", choice::<Primitives>(), build, "",
            "static indices of a tet's four faces: a triangle list (12 u32) or the thesis's strip with restart (7 u32)";
        cull: bool = "on", flag(), run, "",
            "skip fully transparent and off-screen cells, re-use an unchanged frame (exact: the image is unchanged)";
    }
    impl {
        /// The table size fits the integrator's table limit.
        fn check(&self) -> Result<()> {
            crate::algo::integrate::check_table_size(self.integrator, self.table_size)
        }
    }
}

impl Settings {
    /// The build-time choices every projector and the near caps are made
    /// with: their shaders' defines and pipeline keys come from it.
    pub fn draw(&self) -> DrawSettings {
        DrawSettings { interpolation: self.interpolation, integrator: self.integrator, primitives: self.primitives }
    }

    pub fn tolerances(&self) -> ExitTolerances {
        ExitTolerances {
            distance_clamp_diagonals: self.distance_clamp,
            plane_ratio_max: self.plane_ratio_max as f32,
            edge_eps: self.edge_eps as f32,
        }
    }
}

/// VICP's options.
pub const OPTIONS: &[OptionSpec] = &pick(
    Settings::OPTIONS,
    ["integrator", "table_size", "sort", "interpolation", "distance_clamp", "plane_ratio_max", "edge_eps", "cull"],
);
/// The balanced family's.
pub const KNOWN_EXITS_OPTIONS: &[OptionSpec] = &pick(
    Settings::OPTIONS,
    ["integrator", "table_size", "sort", "interpolation", "distance_clamp", "plane_ratio_max", "primitives", "cull"],
);
/// A method that draws every cell in its own order (a device sort).
pub const KNOWN_EXITS_OPTIONS_WITHOUT_CULL: &[OptionSpec] = &pick(
    Settings::OPTIONS,
    ["integrator", "table_size", "sort", "interpolation", "distance_clamp", "plane_ratio_max", "primitives"],
);

/// The run-time-against-error sweep: every integrator (tables at three
/// sizes for ppi) under both interpolations and both sorts.
pub const SWEEP: &[&str] = &[
    "integrator=average,interpolation=paper,sort=centroid",
    "integrator=preint,table_size=128,interpolation=paper,sort=centroid",
    "integrator=ppi,table_size=128,interpolation=paper,sort=centroid",
    "integrator=ppi,table_size=512,interpolation=paper,sort=centroid",
    "integrator=ppi,table_size=1024,interpolation=paper,sort=centroid",
    "integrator=linear-exact,interpolation=paper,sort=centroid",
    "integrator=average,interpolation=paper,sort=mpvo",
    "integrator=preint,table_size=128,interpolation=paper,sort=mpvo",
    "integrator=ppi,table_size=128,interpolation=paper,sort=mpvo",
    "integrator=ppi,table_size=512,interpolation=paper,sort=mpvo",
    "integrator=ppi,table_size=1024,interpolation=paper,sort=mpvo",
    "integrator=linear-exact,interpolation=paper,sort=mpvo",
    "integrator=average,interpolation=exact,sort=centroid",
    "integrator=preint,table_size=128,interpolation=exact,sort=centroid",
    "integrator=ppi,table_size=128,interpolation=exact,sort=centroid",
    "integrator=ppi,table_size=512,interpolation=exact,sort=centroid",
    "integrator=ppi,table_size=1024,interpolation=exact,sort=centroid",
    "integrator=linear-exact,interpolation=exact,sort=centroid",
    "integrator=average,interpolation=exact,sort=mpvo",
    "integrator=preint,table_size=128,interpolation=exact,sort=mpvo",
    "integrator=ppi,table_size=128,interpolation=exact,sort=mpvo",
    "integrator=ppi,table_size=512,interpolation=exact,sort=mpvo",
    "integrator=ppi,table_size=1024,interpolation=exact,sort=mpvo",
    "integrator=linear-exact,interpolation=exact,sort=mpvo",
];

/// `compare` shows the accurate default beside the papers' interpolation,
/// so the documented methods are still reproduced side by side.
pub const COMPARE: &[&str] = &["", "interpolation=paper"];

/// The stress suite: every integrator, interpolation and sort.
pub const STRESS: &[&str] = &[
    "integrator=average,interpolation=paper,sort=centroid",
    "integrator=preint,interpolation=paper,sort=centroid",
    "integrator=ppi,interpolation=paper,sort=centroid",
    "integrator=linear-exact,interpolation=paper,sort=centroid",
    "integrator=average,interpolation=exact,sort=centroid",
    "integrator=preint,interpolation=exact,sort=centroid",
    "integrator=ppi,interpolation=exact,sort=centroid",
    "integrator=linear-exact,interpolation=exact,sort=centroid",
    "integrator=average,interpolation=paper,sort=mpvo",
    "integrator=preint,interpolation=paper,sort=mpvo",
    "integrator=ppi,interpolation=paper,sort=mpvo",
    "integrator=linear-exact,interpolation=paper,sort=mpvo",
    "integrator=average,interpolation=exact,sort=mpvo",
    "integrator=preint,interpolation=exact,sort=mpvo",
    "integrator=ppi,interpolation=exact,sort=mpvo",
    "integrator=linear-exact,interpolation=exact,sort=mpvo",
];

/// A cell-projection method's registry entry: what the two methods share
/// (options, sweeps, kind), with the name, summary, published figures and
/// constructor that differ.
pub const fn method_info(
    name: &'static str,
    summary: &'static str,
    options: &'static [OptionSpec],
    published: &'static [Published],
    create: fn(MethodInputs) -> Result<Box<dyn RenderMethod>>,
) -> MethodInfo {
    MethodInfo {
        name,
        data: DataKind::TetMesh,
        summary,
        options,
        features: &[Feature::DepthClamp],
        sweep: SWEEP,
        compare: COMPARE,
        stress: STRESS,
        suite: &[],
        published,
        family: FAMILY,
        create,
    }
}

/// What the cell-projection methods register once: their settings' checks,
/// their bounds, and `cull`, which the suite's culling scenes toggle.
pub const FAMILY: Family = Family {
    name: "cell-projection",
    check: check::<Settings>,
    accuracy_bound,
    culling_option: Some("cull"),
    placement: None,
    camera: |_, _| None,
};

/// The max |error| each integrator is held to in the stress suite where no
/// limitation is documented. Measured on the control scene ("baseline", exact
/// interpolation) at 128x128: 2.0e-3 (average: its model error), 6.2e-4
/// (preint: table interpolation), 3.1e-5 (ppi, linear-exact: f32
/// arithmetic). One more error shows at single pixels in any case: the
/// rasterizer snaps vertices to 1/256 pixel, so a ray passing within that of
/// a cell's silhouette edge (the mesh's outline, a nearly edge-on face) can
/// gain or miss that cell's corner segment where the f64 reference does not
/// (measured up to 2.9e-4: baseline at 64x64, needles-caps at 128x128). The
/// bounds: 5e-3, 2e-3, 1e-3 and 1e-3 (2.5x the measured maximum or more).
/// The papers' interpolation under perspective is not exact (README:
/// "Perspective"): its rows are held to the same integrator bound against
/// the f64 model of that interpolation (`reference::render_papers_model`),
/// and the stress suite adds the model's own distance from the reference,
/// derived per image (`stress::Extra::PapersModel`; docs/stress.md).
/// Orthographic views use the exact bounds, and there `exact` interpolation
/// is the same computation as `paper` (None: rendered once).
pub fn accuracy_bound(options: &Options, perspective: bool) -> Option<f64> {
    let s = Settings::from_options(options).ok()?;
    if !perspective && s.interpolation == Interpolation::Exact {
        return None;
    }
    Some(integrator_bound(s.integrator))
}



/// Where Table 6.3 figures come from (one source: the report pairs figures
/// of one source on one dataset into ratios).
pub const TABLE_6_3_SOURCE: &str = "Moreland, PhD thesis 2004, Table 6.3 (Quadro FX 3000, 800x800)";

/// Moreland's thesis Table 6.3: VICP against balanced, frames per second at
/// the defaults (pre-integrated colour, Quadro FX 3000, 800x800).
pub const fn table_6_3(method: &'static str, dataset: &'static str, fps: f64, cells: u64) -> Published {
    Published {
        method,
        dataset: Some(dataset),
        options: "",
        figure: PublishedFigure::Fps { fps, cells },
        source: TABLE_6_3_SOURCE,
        note: "In 2004 the 132 floats per tet VICP sends (against 28) cost AGP transfer and vertex work; on lavapipe \
               an upload is a memcpy and the serial triangle front end and the fragment work dominate (PLATFORM.md), \
               so the 4.7x fewer bytes buy a smaller speed-up; on a discrete GPU the ratio moves towards the thesis's.",
    }
}

/// Moreland's thesis Table 6.4: the integrators' cost on the blunt fin, in
/// frames per second (partial pre-integration is the default).
pub const fn table_6_4(options: &'static str, fps: f64) -> Published {
    Published {
        method: "balanced",
        dataset: Some("bluntfin"),
        options,
        figure: PublishedFigure::Fps { fps, cells: 187_395 },
        source: "Moreland, PhD thesis 2004, Table 6.4 (integrator cost, blunt fin)",
        note: "The integrators differ only in fragment work. Where per-triangle work dominates the frame (lavapipe's \
               serial front end), their relative cost shrinks towards 1; a 2004 GPU spent most of its time in the \
               fragment stage, where the exact form's erf/Dawson evaluations cost an order of magnitude.",
    }
}

/// Builds one projector; the methods differ only here (a closure, so that a
/// projector can keep what its constructor was given, e.g. atfs the
/// transfer function).
pub trait ProjectorBuilder:
    FnOnce(&Arc<Context>, &TetMesh, &IntegrationTables, DrawSettings, &mut UploadCounter) -> VkResult<Box<dyn CellProjector>>
{
}
impl<F> ProjectorBuilder for F where
    F: FnOnce(&Arc<Context>, &TetMesh, &IntegrationTables, DrawSettings, &mut UploadCounter) -> VkResult<Box<dyn CellProjector>>
{
}

/// Bytes a projector needs per cell: on the device, per-frame records in one
/// allocation plus static data; on the host, what it keeps between frames
/// (checked before anything is allocated, `chunks::check_memory`).
#[derive(Debug, Clone, Copy)]
pub struct DeviceBytesPerCell {
    /// Per-frame bytes per cell in one allocation (0 when the projector
    /// splits them at the device's limits, `algo::chunks`: then in `fixed`).
    pub frame: usize,
    pub fixed: usize,
    /// Host bytes per cell the projector keeps (its `host_bytes` at the
    /// oxygen post, rounded up).
    pub host: usize,
}

/// Host bytes per cell every cell projection keeps beside its projector's:
/// culling and the near caps' relative mesh, the sort's centroids, keys and
/// order (57 at the oxygen post, `details.host_memory`), rounded up.
pub const SHARED_HOST_BYTES_PER_CELL: usize = 64;

/// Cell projection as a registry method.
pub struct CellProjection {
    tables: IntegrationTables,
    projector: Box<dyn CellProjector>,
    sorter: Sorter,
    scale: MeshScale,
    settings: Settings,
    /// A centroid sort and MPVO's constraints for the order diagnostics
    /// (built only when the run asks for diagnostics).
    check: Option<(CentroidSort, MpvoSort)>,
    prepared: Option<FrameSetup>,
    mesh_stats: crate::mesh::MeshStats,
    culler: Culler,
    /// MPVO's order with the culled cells left out.
    filtered: Vec<u32>,
    /// The prepared frame re-uses the data already on the device.
    reused: bool,
    /// What the last prepared (not re-used) frame skipped.
    last_cull: Option<FrameCull>,
    /// The cells around the eye cut by the near plane (`near`).
    near: super::near::NearCaps,
    /// The mesh the run holds for this method (`details.host_memory`).
    scene_memory: HostMemory,
    /// The culler's and near caps' shared mesh (counted once).
    relative: Arc<RelativeMesh>,
    ctx: Arc<Context>,
}

impl CellProjection {
    pub fn create(inputs: MethodInputs, bytes: DeviceBytesPerCell, build: impl ProjectorBuilder) -> Result<Box<dyn RenderMethod>> {
        Self::create_for_stages(inputs, bytes, Stages::FRAGMENT, build)
    }

    /// `create` for a projector that reads the relative mesh too (balanced
    /// gathers its vertices from it): `relative` must be the mesh's at its
    /// `render_origin` (`RelativeMesh::new`), shared with culling and the
    /// near caps, so it is held once.
    pub fn create_sharing(
        inputs: MethodInputs,
        bytes: DeviceBytesPerCell,
        relative: Arc<RelativeMesh>,
        build: impl ProjectorBuilder,
    ) -> Result<Box<dyn RenderMethod>> {
        Self::create_inner(inputs, bytes, Stages::FRAGMENT, Some(relative), build)
    }

    /// `create` with the integration tables visible to `stages` (a
    /// projector that integrates in a compute stage adds COMPUTE; the near
    /// caps keep integrating in the fragment stage).
    pub fn create_for_stages(
        inputs: MethodInputs,
        bytes: DeviceBytesPerCell,
        stages: Stages,
        build: impl ProjectorBuilder,
    ) -> Result<Box<dyn RenderMethod>> {
        Self::create_inner(inputs, bytes, stages, None, build)
    }

    fn create_inner(
        inputs: MethodInputs,
        bytes: DeviceBytesPerCell,
        stages: Stages,
        relative: Option<Arc<RelativeMesh>>,
        build: impl ProjectorBuilder,
    ) -> Result<Box<dyn RenderMethod>> {
        let SceneData::TetMesh { mesh } = inputs.data else {
            anyhow::bail!("cell projection renders tetrahedral meshes only");
        };
        let settings = Settings::from_options(inputs.options)?;
        let ctx = inputs.ctx;
        // Refuse meshes the device cannot hold before allocating anything.
        let info = &ctx.info;
        crate::mesh::check_fits(mesh.tets.len(), bytes.frame, info.max_memory_allocation_size)
            .with_context(|| format!("mesh '{}' on {}: the per-frame records in one allocation", mesh.name, info.name))?;
        crate::algo::chunks::check_memory(info, mesh.tets.len(), bytes.frame + bytes.fixed, bytes.host + SHARED_HOST_BYTES_PER_CELL)
            .with_context(|| format!("mesh '{}' on {}", mesh.name, info.name))?;
        // A typical cell size: the bounding box shared out among the cells.
        let length_scale = mesh.bounds().diagonal() / (mesh.tets.len().max(1) as f64).cbrt();
        let tables = IntegrationTables::for_stages(
            ctx,
            inputs.tf,
            mesh.scalar_range(),
            settings.integrator,
            settings.table_size,
            length_scale,
            stages,
            inputs.counter,
        )
        .context("building the integration tables")?;
        let draw = settings.draw();
        let projector = build(ctx, mesh, &tables, draw, inputs.counter)?;
        let pieces = projector.pieces_set().map(|s| s.desc.clone());
        let origin = render_origin(mesh);
        let relative = relative.unwrap_or_else(|| RelativeMesh::new(mesh, origin));
        let near = super::near::NearCaps::new(ctx, relative.clone(), &tables, &draw, pieces)?;
        let sorter = Sorter::new(settings.sort, mesh);
        // Cells a device sort orders are all drawn: culling is off for it.
        let culler = Culler::shared(mesh, relative.clone(), inputs.tf, LookupGrid::of(&tables), settings.cull && !projector.sorts_on_device());
        let check = inputs.diagnostics.then(|| {
            (CentroidSort::with_origin(centroids_relative_f32(mesh, origin), origin), MpvoSort::from_mesh(mesh))
        });
        Ok(Box::new(CellProjection {
            tables,
            projector,
            sorter,
            scale: MeshScale::of(mesh),
            settings,
            check,
            prepared: None,
            mesh_stats: mesh.stats.clone(),
            culler,
            filtered: Vec::new(),
            reused: false,
            last_cull: None,
            near,
            relative,
            scene_memory: {
                let mut m = HostMemory::default();
                m.scene_mesh(mesh);
                m
            },
            ctx: ctx.clone(),
        }))
    }

    fn frame_setup(&self, view: &View) -> FrameSetup {
        FrameSetup::new(
            &view.camera,
            view.width,
            view.height,
            &self.tables,
            &self.scale,
            self.settings.interpolation,
            &self.settings.tolerances(),
        )
    }
}

fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

impl RenderMethod for CellProjection {
    fn prepare(&mut self, view: &View, phases: &mut Phases) -> Result<()> {
        let setup = self.frame_setup(view);
        let (camera, w, h) = (&view.camera, view.width, view.height);
        self.reused = self.culler.unchanged(camera, w, h);
        let t0 = Instant::now();
        // A projector that sorts on the device draws every cell in its own
        // order: nothing is culled or sorted here for it.
        let device_sort = self.projector.sorts_on_device();
        if !self.reused {
            let culled = if device_sort { None } else { self.culler.cull(camera, w, h) };
            let t1 = Instant::now();
            if self.culler.enabled() {
                phases.ended("cull", ms(t1 - t0));
            }
            let order: &[u32] = match (device_sort, culled.is_some(), &mut self.sorter) {
                (true, _, _) => &[],
                (false, false, sorter) => sorter.sort(camera),
                // Cull before sorting: the same order as filtering the full one.
                (false, true, Sorter::Centroid(s)) => s.sort_subset(camera, self.culler.survivors()),
                // The full exact order, filtered (see `cull`: transitivity).
                (false, true, Sorter::Mpvo(s)) => {
                    let full = s.sort(camera);
                    self.culler.filter_order(full, &mut self.filtered);
                    &self.filtered
                }
            };
            let t2 = Instant::now();
            if !device_sort {
                phases.ended("sort", ms(t2 - t1));
            }
            self.projector.pack(order, &setup);
            // Near caps are per-frame records too (none unless the eye is in
            // the mesh); a re-used frame keeps the ones on the device.
            self.near.prepare(camera, &setup, &*self.projector);
            phases.ended("pack", ms(t2.elapsed()));
            for (name, ms) in self.projector.pack_phases() {
                phases.add(name, ms);
            }
            self.last_cull = culled;
            self.culler.remember(camera, w, h);
        } else {
            // Nothing to do: the device holds this view's data.
            phases.add("cull", 0.0);
            if !device_sort {
                phases.add("sort", 0.0);
            }
            phases.add("pack", 0.0);
            for (name, _) in self.projector.pack_phases() {
                phases.add(name, 0.0);
            }
        }
        let c = self.last_cull.unwrap_or_default();
        phases.count("cells_drawn", self.projector.drawn() as u64);
        phases.count("cull.transparent", c.transparent);
        phases.count("cull.frustum", c.frustum);
        phases.count("cull.reused", u64::from(self.reused));
        self.prepared = Some(setup);
        Ok(())
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> Result<()> {
        if self.reused {
            return Ok(());
        }
        self.projector.upload(counter).context("uploading vertex records")?;
        self.near.upload(&self.ctx, counter).context("uploading near caps")
    }

    fn record(&mut self, rec: &CommandRecorder, target: &Image, _view: &View, counter: &mut UploadCounter) -> Result<()> {
        let setup = self.prepared.take().context("record without a prepared frame")?;
        self.projector.record_before_draw(rec, &setup, counter).context("recording the device sort")?;
        if self.projector.record_composite(rec, target, &self.tables, &setup, counter).context("recording the compositing pass")? {
            if self.near.vertices() > 0 {
                rec.begin_rendering_targets(&[ColorAttachment { image: target, clear: None }])?;
                let drawn = self.near.record(rec, &self.tables, self.projector.pieces_set(), &setup, counter);
                rec.end_rendering();
                drawn?;
            }
            return Ok(());
        }
        rec.begin_rendering(target, [0.0; 4]);
        let drawn = self
            .projector
            .record_draw(rec, &self.tables, &setup, counter)
            .and_then(|()| self.near.record(rec, &self.tables, self.projector.pieces_set(), &setup, counter));
        rec.end_rendering();
        drawn?;
        Ok(())
    }

    fn work(&self) -> Work {
        // Near caps (the cells around the eye) are per-frame cell data too.
        let work = Work::default()
            .with("cells", self.projector.cells() as u64)
            .with("cells_drawn", self.projector.drawn() as u64)
            .with("near_cap_vertices", self.near.vertices() as u64);
        let work = self.projector.work_counts().into_iter().fold(work, |w, (name, n)| w.with(name, n));
        match self.projector.pieces() {
            Some(p) => work.with("pieces", p as u64).with("pieces_drawn", self.projector.pieces_drawn() as u64),
            None => work,
        }
    }

    fn details(&self) -> serde_json::Value {
        let mut memory = self.scene_memory.clone();
        self.projector.host_bytes(&mut memory);
        self.sorter.host_bytes(&mut memory);
        memory.vec("sort: mpvo order with culled cells left out", &self.filtered);
        self.relative.host_bytes(&mut memory);
        self.culler.host_bytes(&mut memory);
        self.near.host_bytes(&mut memory);
        json!({
            "host_memory": memory.to_json(self.projector.cells()),
            "family": "cell-projection",
            "vertices_per_cell": self.projector.vertices_per_cell(),
            "floats_per_cell_by_construction": self.projector.floats_per_cell(),
            "table_size": self.tables.table_size,
            "pipeline": { "key": self.projector.pipeline_key().id(), "name": self.projector.pipeline_key().name() },
            "device_chunks": self.projector.device_chunks(),
            "tolerances": self.settings.tolerances(),
            "mesh_stats": self.mesh_stats,
            "cull": {
                "enabled": self.culler.enabled(),
                "transparent_cells": self.culler.transparent_cells(),
                "rules": "cull.transparent: cells whose table lookups read zero attenuation; cull.frustum: other cells \
                          with all four vertices outside one clip plane; cull.reused: 1 when the frame re-used the previous \
                          frame's data (same camera, size, transfer function: no cull, sort, pack or upload; the draw is repeated)",
            },
            "pieces": self.projector.pieces().map(|p| {
                let n = self.projector.cells().max(1) as f64;
                json!({
                    "per_frame": p,
                    "drawn_per_frame": self.projector.pieces_drawn(),
                    "growth_over_cells": p as f64 / n - 1.0,
                    "bytes_per_original_cell_by_construction": (p * self.projector.floats_per_cell() * 4) as f64 / n,
                })
            }),
        })
    }

    /// How many of MPVO's face constraints the centroid order of this view
    /// violates (costs an MPVO build; `volbench compare`, `pareto`).
    fn diagnostics(&mut self, view: &View) -> Result<Option<serde_json::Value>> {
        let Some((centroid, mpvo)) = self.check.as_mut() else { return Ok(None) };
        let order = centroid.sort(&view.camera).to_vec();
        Ok(Some(json!({ "centroid_order": mpvo.check_order(&order, &view.camera) })))
    }

    fn table_build_ms(&self) -> f64 {
        self.tables.build_ms
    }

    fn after_frame(&mut self, phases: &mut Phases) -> Result<()> {
        for (name, ms) in self.projector.device_phases().context("reading the projector's timestamps")? {
            phases.add(name, ms);
        }
        Ok(())
    }
}
