//! Hybrid terrain meshes (Paredes et al., GRAPP 2012; SPEC §4): the grid
//! with view-dependent levels of detail and embedded TINs
//! (`crate::terrain::hybrid`), drawn by methods that differ in where the PC
//! cells' tessellation happens. This module holds what they share: options,
//! the static device data (geometry buffer with the TB vertices first, the
//! NC cells' and TINs' static indices), level-of-detail selection per block,
//! the scripted fly-over camera, the pipeline and the frame's draws of NC
//! cells and TINs. The methods: `cpu` is HM's original placement
//! (tessellate on the CPU every frame, upload the triangles), `gpu` GPU HM
//! (a geometry shader per active PC-list entry, only the active PC list
//! uploaded), `compute` the same tessellation in a compute pass drawn
//! indirectly; `tables` holds the PC data both GPU methods read. All three
//! run the one tessellation (`HybridModel::tessellate`, transcribed in
//! `shaders/terrain/tessellate.glsl`), so they draw the same triangles.
//!
//! Level of detail: each block (a coarsest cell) takes the coarsest level
//! whose largest height error in the block, projected at the block's
//! nearest distance from the eye, is within `lod_error` pixels (`level`
//! forces one level everywhere). Seams: blocks of different levels meet
//! with T-junctions (the finer side has vertices the coarser edge lacks);
//! the skirt rule covers the cracks: every active block draws, with its NC
//! cells, a vertical strip hanging from its border at its level, as deep as
//! the largest grid error of any level (`HybridModel::skirt_depth`), shaded
//! as the ground at its border (see mesh.frag).
//! Skirts are vertical, so they cover nothing seen from straight above;
//! the coverage-count output leaves them out.

pub mod compute;
pub mod cpu;
pub mod gpu;
pub mod tables;

use std::sync::Arc;
use std::time::Instant;

use anyhow::Result;
use glam::{DVec3, Vec3};
use serde_json::json;

use crate::algo::method::{Family, OptionSpec, Options, OwnError, Phases, SceneData, View};
use crate::algo::settings::{choice, flag, float, int, pick, MethodSettings};
use crate::scene::{Camera, Projection};
use crate::terrain::hybrid::HybridModel;
use crate::terrain::Heightmap;
use crate::vk::{
    Blend, Buffer, BufferDesc, ColorTarget, CommandRecorder, ComputePipelineKey, Context, DescriptorSetDesc, GraphicsPipelineKey, GraphicsState,
    Image, Pipeline, PipelineKey, ShaderKey, ShaderStage, TexelBuffer, UploadClass, UploadCounter, VertexAttribute,
};
use crate::vk::{BufferUsage, Cull, Format, Topology, Winding};

crate::choices! {
    /// How the terrain is coloured.
    pub enum Colour {
        /// Shaded by height.
        Shaded = "shaded",
        /// Tinted by class (NC grid green, PC tessellation orange, TIN blue).
        Classes = "classes",
    }
}

crate::settings! {
    /// The options as typed values.
    pub struct Settings {
        lod_error: f64 = "2", float(0.01, 100000.0), run, "px",
            "largest projected height error a block's level may have (view-dependent level of detail)";
        level: i64 = "-1", int(-1, 4), run, "", "draw every block at this level (0 = finest; -1: view-dependent, by lod_error)";
        colour: Colour = "shaded", choice::<Colour>(), run, "",
            "shaded by height, or tinted by class (NC grid green, PC tessellation orange, TIN blue)";
        coverage: bool = "off", flag(), build, "",
            "count covering triangles per pixel (additive, no depth test): the coverage test's target";
        capture: bool = "off", flag(), build, "",
            "also append every emitted PC triangle to a storage buffer (tests: compared with the CPU's)";
    }
}

/// The options of `hm-cpu` and `hm-compute`; `hm-gpu` offers `capture` too.
pub const OPTIONS: &[OptionSpec] = &pick(Settings::OPTIONS, ["lod_error", "level", "colour", "coverage"]);

/// What the terrain methods register once: no image reference (they measure
/// their own height error), and one tessellation placed three ways.
pub const FAMILY: Family = Family {
    name: "terrain",
    check: crate::algo::settings::check::<Settings>,
    accuracy_bound: |_, _| None,
    culling_option: None,
    placement: Some(PLACEMENT),
    camera: |data, frame| match data {
        SceneData::Terrain(map) => Some(fly_over(map, frame)),
        SceneData::TetMesh { .. } | SceneData::Volume(_) => None,
    },
};

/// The work the three methods share (`Family::placement`).
pub const PLACEMENT: &str = "PC-cell tessellation (NC cells, TINs and skirts drawn alike)";

impl Settings {
    /// The level every block is drawn at, when one is forced (`level` >= 0).
    pub fn forced_level(&self) -> Option<usize> {
        usize::try_from(self.level).ok()
    }

    /// Tinted by class.
    pub fn classes(&self) -> bool {
        self.colour == Colour::Classes
    }
}

/// Time against geometric error: the projected-error threshold.
pub const SWEEP: &[&str] = &["lod_error=0.5", "lod_error=1", "lod_error=2", "lod_error=4", "lod_error=8", "lod_error=16", "lod_error=64"];
pub const COMPARE: &[&str] = &["", "colour=classes"];

/// Class tints (rgb): NC grid, PC tessellation, TIN.
const TINT_NC: [f32; 3] = [0.35, 0.75, 0.3];
const TINT_PC: [f32; 3] = [1.0, 0.55, 0.1];
const TINT_TIN: [f32; 3] = [0.25, 0.45, 1.0];

/// The push constants of every terrain draw (`shaders/terrain/common.glsl`;
/// `tests/shader_interfaces.rs` checks the two agree).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Push {
    pub view_proj: [[f32; 4]; 4],
    /// The class colour (NC / PC tessellation / TIN).
    pub tint: Vec3,
    /// How much of it: 0.85 with `colour=classes`, else 0 (the height colours).
    pub tint_mix: f32,
    /// Unit direction towards the light.
    pub light: Vec3,
    /// The lowest and highest height.
    pub height_lo: f32,
    pub height_hi: f32,
    /// The grid's first geometry index and row length, for the PC
    /// tessellators (`terrain/tessellate.glsl`).
    pub grid_base: u32,
    pub grid_width: u32,
}

/// The size of [`Push`], as the pipelines' push-constant range.
pub const PUSH_BYTES: u32 = std::mem::size_of::<Push>() as u32;

/// The camera of frame `frame` of the fly-over: once around an ellipse
/// over the middle of the terrain every 120 frames, 0.25 of the terrain's
/// width above its highest point, looking ahead and down.
pub fn fly_over(map: &Heightmap, frame: usize) -> Camera {
    let [ex, ey] = map.extent();
    let (lo, hi) = map.range();
    let t = (frame % 120) as f64 / 120.0 * std::f64::consts::TAU;
    let c = DVec3::new(0.5 * ex, 0.5 * ey, lo);
    let at = |t: f64| c + DVec3::new(0.3 * ex * t.cos(), 0.3 * ey * t.sin(), 0.0);
    let size = ex.max(ey);
    let eye = at(t) + DVec3::new(0.0, 0.0, hi - lo + 0.25 * size);
    let ahead = at(t + 0.9);
    Camera {
        eye: eye.into(),
        target: [ahead.x, ahead.y, 0.5 * (lo + hi)],
        up: [0.0, 0.0, 1.0],
        projection: Projection::Perspective { fovy_deg: 50.0 },
        near: 0.002 * size,
        // Beyond the farthest ground point also when the heights span more
        // than the domain's width (a tall, narrow grid was clipped away whole).
        far: (3.0 * size).max(1.1 * (ex * ex + ey * ey + (hi - lo + 0.25 * size).powi(2)).sqrt()),
    }
}

/// A camera above the domain looking straight down, orthographic, framing
/// exactly the domain's height (the coverage test's view).
pub fn top_down(model: &HybridModel, lo: f64, hi: f64) -> Camera {
    let (w, h) = (model.domain[0] as f64 * model.spacing[0], model.domain[1] as f64 * model.spacing[1]);
    Camera {
        eye: [0.5 * w, 0.5 * h, hi + 10.0],
        target: [0.5 * w, 0.5 * h, lo],
        up: [0.0, 1.0, 0.0],
        projection: Projection::Orthographic { height: h },
        near: 1.0,
        far: hi - lo + 20.0,
    }
}

/// The family's pipeline keys, all made here from the settings (and the
/// device's facts hm-gpu's geometry stage is compiled for).
impl Settings {
    /// The build-time options as the mesh shaders' defines.
    fn defines(&self) -> Vec<(&'static str, &'static str)> {
        if self.coverage {
            vec![("COVERAGE", "1")]
        } else {
            Vec::new()
        }
    }

    /// A drawing pipeline's key: the shared fragment stage (shaded, or the
    /// coverage count), blend and depth by the settings; the vertex input is
    /// one 16-byte attribute (a position, or a PC-list entry).
    fn draw_key(&self, vertex: ShaderKey, geometry: Option<ShaderKey>, attribute: VertexAttribute, topology: Topology, sets: Vec<DescriptorSetDesc>) -> PipelineKey {
        PipelineKey::Graphics(GraphicsPipelineKey {
            vertex,
            geometry,
            fragment: ShaderKey::new("terrain/mesh.frag", ShaderStage::Fragment, &self.defines()),
            state: GraphicsState {
                vertex_stride: 16,
                attributes: vec![attribute],
                topology,
                primitive_restart: false,
                cull: Cull::None,
                front_face: Winding::CounterClockwise,
                targets: vec![ColorTarget::rgba32f(if self.coverage { Blend::Additive } else { Blend::None })],
                depth_test: !self.coverage,
                depth_clamp: false,
            },
            push_constant_bytes: PUSH_BYTES,
            sets,
        })
    }

    /// The triangles every method draws from the geometry buffer (NC cells,
    /// TINs, skirts, and hm-cpu's and hm-compute's PC triangles).
    pub fn mesh_key(&self) -> PipelineKey {
        let position = VertexAttribute { location: 0, format: Format::Rgba32Float, offset: 0 };
        self.draw_key(ShaderKey::new("terrain/mesh.vert", ShaderStage::Vertex, &[]), None, position, Topology::TriangleList, vec![])
    }

    /// hm-gpu's PC cells: a point per PC-list entry, tessellated by the
    /// geometry stage, which emits at most `max_tris` triangles (the
    /// device's bound) and, with `capture`, appends them to a buffer; its
    /// tables at set 0.
    pub fn pc_geometry_key(&self, max_tris: u32, tables: DescriptorSetDesc) -> PipelineKey {
        let max_tris = max_tris.to_string();
        let mut defines = vec![("MAX_TRIS", max_tris.as_str())];
        if self.capture {
            defines.push(("CAPTURE", "1"));
        }
        let entry = VertexAttribute { location: 0, format: Format::Rgba32Uint, offset: 0 };
        self.draw_key(
            ShaderKey::new("terrain/pc.vert", ShaderStage::Vertex, &[]),
            Some(ShaderKey::new("terrain/pc.geom", ShaderStage::Geometry, &defines)),
            entry,
            Topology::PointList,
            vec![tables],
        )
    }
}

/// hm-compute's tessellation pass (no option changes it): its tables at
/// set 0, `push_bytes` of push constants (`compute::TessPush`).
pub fn pc_compute_key(tables: DescriptorSetDesc, push_bytes: u32) -> PipelineKey {
    PipelineKey::Compute(ComputePipelineKey { shader: ShaderKey::new("terrain/pc.comp", ShaderStage::Compute, &[]), push_constant_bytes: push_bytes, sets: vec![tables] })
}

/// What a frame draws, chosen on the CPU.
#[derive(Debug, Clone, Default)]
pub struct ActiveSet {
    /// Level per block.
    pub levels: Vec<u8>,
    /// Static index ranges (first, count) of the active NC cells.
    pub nc_draws: Vec<(u32, u32)>,
    pub nc_cells: u64,
    /// Static index ranges of the active blocks' skirts.
    pub skirt_draws: Vec<(u32, u32)>,
    pub skirt_triangles: u64,
    /// Active PC cells: (level, index in that level's PC list).
    pub pc_cells: Vec<(u8, u32)>,
    /// Height error of the frame's grid against the finest samples (world
    /// units): RMS over the domain and largest.
    pub rms_error: f64,
    pub max_error: f64,
}

/// The device data and pipeline every hybrid-mesh method shares.
pub struct TerrainScene {
    pub model: HybridModel,
    pub settings: Settings,
    /// World positions, TB vertices first; also a texel buffer (RGBA32F)
    /// the geometry shader reads (the paper's TBO).
    pub geometry: TexelBuffer,
    /// NC indices of every level, then the TINs'.
    pub static_indices: Buffer,
    /// Offset of each level's NC indices in `static_indices`.
    level_offsets: Vec<u32>,
    /// Offset of each level's skirt indices in `static_indices`.
    skirt_offsets: Vec<u32>,
    tin_first: u32,
    pub pipeline: Arc<Pipeline>,
    pub key: PipelineKey,
    pub depth: Option<Image>,
    pub active: ActiveSet,
    range: (f64, f64),
    block_bounds: Vec<([f64; 3], [f64; 3])>,
    pub build_ms: f64,
}

fn bytes_of<T: bytemuck::Pod>(v: &[T]) -> &[u8] {
    bytemuck::cast_slice(v)
}

impl TerrainScene {
    pub fn new(ctx: &Arc<Context>, map: &Heightmap, options: &Options, width: u32, height: u32, counter: &mut UploadCounter) -> Result<Self> {
        let settings = Settings::from_options(options)?;
        let t0 = Instant::now();
        let model = HybridModel::build(map)?;
        let build_ms = t0.elapsed().as_secs_f64() * 1e3;
        if let Some(l) = settings.forced_level() {
            anyhow::ensure!(l < model.levels.len(), "option 'level' = {l}: '{}' has levels 0 to {}", map.name, model.levels.len() - 1);
        }
        let geo = bytes_of(&model.vertices);
        let usage = BufferUsage::VERTEX | BufferUsage::UNIFORM_TEXEL;
        let mut geometry = TexelBuffer::new(ctx, BufferDesc::upload("terrain geometry", geo.len() as u64, usage), Format::Rgba32Float)?;
        geometry.buffer.write(0, geo, counter, UploadClass::Static)?;
        let mut all = Vec::new();
        let (mut level_offsets, mut skirt_offsets) = (Vec::new(), Vec::new());
        for l in &model.levels {
            level_offsets.push(all.len() as u32);
            all.extend_from_slice(&l.nc_indices);
            skirt_offsets.push(all.len() as u32);
            all.extend_from_slice(&l.skirt_indices);
        }
        let tin_first = all.len() as u32;
        all.extend_from_slice(&model.tin_indices);
        let idx = bytes_of(&all);
        let mut static_indices = Buffer::new(ctx, BufferDesc::upload("terrain static indices", idx.len() as u64, BufferUsage::INDEX))?;
        static_indices.write(0, idx, counter, UploadClass::Static)?;
        let key = settings.mesh_key();
        let pipeline = crate::algo::pipelines::get(ctx, &key)?;
        let depth = if settings.coverage { None } else { Some(Image::depth_target(ctx, "terrain depth", width, height)?) };
        let range = map.range();
        let bs = model.block_side as f64;
        let block_bounds = (0..model.blocks[1])
            .flat_map(|by| (0..model.blocks[0]).map(move |bx| (bx, by)))
            .map(|(bx, by)| {
                let (x0, y0) = (bx as f64 * bs, by as f64 * bs);
                let mut lo = f64::MAX;
                let mut hi = f64::MIN;
                for j in y0 as usize..=(y0 + bs) as usize {
                    for i in x0 as usize..=(x0 + bs) as usize {
                        let z = map.height(i, j) as f64;
                        lo = lo.min(z);
                        hi = hi.max(z);
                    }
                }
                let s = model.spacing;
                ([x0 * s[0], y0 * s[1], lo], [(x0 + bs) * s[0], (y0 + bs) * s[1], hi])
            })
            .collect();
        Ok(TerrainScene {
            model,
            settings,
            geometry,
            static_indices,
            level_offsets,
            skirt_offsets,
            tin_first,
            pipeline,
            key,
            depth,
            active: ActiveSet::default(),
            range,
            block_bounds,
            build_ms,
        })
    }

    /// Choose each block's level and the active NC draws and PC cells.
    pub fn select(&mut self, view: &View, phases: &mut Phases) {
        let t0 = Instant::now();
        let m = &self.model;
        let nblocks = self.block_bounds.len();
        let top = m.levels.len() - 1;
        let eye = DVec3::from(view.camera.eye);
        // Pixels per world unit at distance 1 (perspective) or everywhere.
        let (scale, perspective) = match view.camera.projection {
            Projection::Perspective { fovy_deg } => (view.height as f64 / (2.0 * (0.5 * fovy_deg.to_radians()).tan()), true),
            Projection::Orthographic { height } => (view.height as f64 / height, false),
        };
        let mut a = ActiveSet { levels: vec![0; nblocks], ..Default::default() };
        let mut sse = 0.0;
        for b in 0..nblocks {
            let level = match self.settings.forced_level() {
                Some(l) => l,
                None => {
                    let (lo, hi) = self.block_bounds[b];
                    let nearest = DVec3::new(eye.x.clamp(lo[0], hi[0]), eye.y.clamp(lo[1], hi[1]), eye.z.clamp(lo[2], hi[2]));
                    let d = if perspective { (nearest - eye).length().max(1e-9) } else { 1.0 };
                    (0..=top).rev().find(|&k| m.levels[k].error_max[b] * scale / d <= self.settings.lod_error).unwrap_or(0)
                }
            };
            a.levels[b] = level as u8;
            let l = &m.levels[level];
            let r = &l.nc_by_block[b];
            if r.end > r.start {
                // Merge with the previous range when contiguous.
                let first = self.level_offsets[level] + r.start;
                match a.nc_draws.last_mut() {
                    Some((f, c)) if *f + *c == first => *c += r.end - r.start,
                    _ => a.nc_draws.push((first, r.end - r.start)),
                }
                a.nc_cells += ((r.end - r.start) / 6) as u64;
            }
            let r = &l.skirt_by_block[b];
            if r.end > r.start && !self.settings.coverage {
                let first = self.skirt_offsets[level] + r.start;
                match a.skirt_draws.last_mut() {
                    Some((f, c)) if *f + *c == first => *c += r.end - r.start,
                    _ => a.skirt_draws.push((first, r.end - r.start)),
                }
                a.skirt_triangles += ((r.end - r.start) / 3) as u64;
            }
            a.pc_cells.extend((l.pc_by_block[b].start..l.pc_by_block[b].end).map(|i| (level as u8, i)));
            sse += l.error_sse[b];
            a.max_error = a.max_error.max(l.error_max[b]);
        }
        a.rms_error = (sse / m.samples.max(1) as f64).sqrt();
        self.active = a;
        phases.ended("lod", t0.elapsed().as_secs_f64() * 1e3);
        phases.own_error(self.own_error());
    }

    /// Push constants for a draw tinted `tint`.
    fn push(&self, view: &View, tint: [f32; 3]) -> Push {
        let m = view.camera.view_proj(view.width, view.height);
        let light = (-view.camera.forward() + DVec3::new(0.3, 0.2, 1.0)).normalize();
        Push {
            view_proj: m.to_cols_array_2d().map(|c| c.map(|x| x as f32)),
            tint: tint.into(),
            tint_mix: if self.settings.classes() { 0.85 } else { 0.0 },
            light: light.as_vec3(),
            height_lo: self.range.0 as f32,
            height_hi: self.range.1 as f32,
            grid_base: self.model.grid_base,
            grid_width: self.model.domain[0] + 1,
        }
    }

    /// Begin the frame's rendering and draw the active NC cells and the
    /// TINs; the method then draws its PC triangles with `pc_tint`'s push
    /// constants bound (returned).
    pub fn record_static(&self, rec: &CommandRecorder, target: &Image, view: &View, counter: &mut UploadCounter) -> Result<Push> {
        match &self.depth {
            Some(d) => rec.begin_rendering_with_depth(target, [0.0; 4], d)?,
            None => rec.begin_rendering(target, [0.0; 4]),
        }
        rec.bind_graphics(&self.pipeline, &[])?;
        rec.bind_vertex_buffer(&self.geometry.buffer);
        rec.bind_index_buffer_u32(&self.static_indices);
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&self.push(view, TINT_NC)), counter);
        for &(first, count) in self.active.nc_draws.iter().chain(&self.active.skirt_draws) {
            rec.draw_indexed_range(first, count);
        }
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&self.push(view, TINT_TIN)), counter);
        rec.draw_indexed_range(self.tin_first, self.model.tin_indices.len() as u32);
        Ok(self.push(view, TINT_PC))
    }

    /// The frame's height error (see `ActiveSet`).
    pub fn own_error(&self) -> OwnError {
        OwnError {
            rmse: self.active.rms_error,
            max_abs: self.active.max_error,
            what: "height error of the frame's grid levels against the full-resolution samples (grid part; height units)",
        }
    }

    pub fn tin_triangles(&self) -> u64 {
        self.model.tin_indices.len() as u64 / 3
    }

    /// Facts for the result's details.
    pub fn details(&self, variant: serde_json::Value) -> serde_json::Value {
        let m = &self.model;
        let levels: Vec<serde_json::Value> = (0..m.levels.len())
            .map(|k| {
                let (nc, cc, pc) = m.counts(k);
                json!({ "side": m.levels[k].side, "cells": m.levels[k].cells, "nc": nc, "cc": cc, "pc": pc })
            })
            .collect();
        let mut histogram = vec![0u32; m.levels.len()];
        for &l in &self.active.levels {
            histogram[l as usize] += 1;
        }
        json!({
            "family": "terrain",
            // The suite sets the three placements of this work side by side.
            "same_work": PLACEMENT,
            "variant": variant,
            "domain_cells": m.domain,
            "cropped": m.cropped,
            "spacing": m.spacing,
            "blocks": m.blocks,
            "block_side": m.block_side,
            "levels": levels,
            "tb_vertices": m.tb_xy.len(),
            "tin_interior_vertices": m.tin_interior,
            "tin_triangles": self.tin_triangles(),
            "patches": m.patches.iter().map(|p| json!({ "name": p.name, "polygon_vertices": p.polygon.len(), "tb_vertices": p.tb.end - p.tb.start })).collect::<Vec<_>>(),
            "lod_error_px": self.settings.lod_error,
            "forced_level": self.settings.forced_level(),
            "blocks_per_level": histogram,
            "active_nc_cells": self.active.nc_cells,
            "active_pc_cells": self.active.pc_cells.len(),
            "geometric_error": { "rms": self.active.rms_error, "max": self.active.max_error, "unit": "height units against the full-resolution grid (grid part)" },
            "model_build_ms": self.build_ms,
            "pipeline": { "key": self.key.id(), "name": self.key.name() },
            "seams": "skirts: every block hangs a vertical strip from its border at its level (see algo::terrain)",
            "skirt_depth": m.skirt_depth,
            "active_skirt_triangles": self.active.skirt_triangles,
        })
    }
}
