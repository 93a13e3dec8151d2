//! `hm-gpu`: GPU HM (Paredes et al., GRAPP 2012, §3). The PC cells are
//! tessellated by a geometry shader, one invocation per active PC-list
//! entry (`shaders/terrain/pc.geom`, running the shared transcription of
//! the CPU tessellation). Static on the device: the geometry (TB vertices
//! first) and the TB coordinates and chain list as texel buffers (the
//! paper's TBOs), and the PC list as vertex input. Per frame only the
//! active PC list crosses: a u32 index per active entry, drawn as an
//! indexed point list.
//!
//! The geometry shader's output is bounded by the device
//! (maxGeometryOutputVertices, maxGeometryTotalOutputComponents: on
//! lavapipe 1024 components, 8 a vertex, so 42 triangles). A cell whose
//! tessellation has more triangles gets one PC-list entry per slice of
//! that many (its part); every invocation runs the whole tessellation and
//! emits only its slice, so no triangle is dropped. `work` counts the
//! active cells that took one invocation (`pc_cells_single`) and those
//! split (`pc_cells_split`, `gs_invocations` in all); the pipeline
//! statistics' geometry-shader primitives equal `pc_triangles`.
//!
//! `capture=on` (a test option, needs vertexPipelineStoresAndAtomics) also
//! appends every emitted triangle to a storage buffer, which
//! `diagnostics` fingerprints beside the CPU's.

use std::sync::Arc;

use anyhow::{bail, Result};
use serde_json::json;

use super::tables::{triangle_digest, PcTables};
use super::{Settings, TerrainScene, COMPARE, SWEEP};
use crate::algo::method::{DataKind, Feature, MethodInfo, MethodInputs, OptionSpec, Phases, RenderMethod, SceneData, View, Work};
use crate::algo::settings::MethodSettings;
use crate::vk::{
    Buffer, BufferDesc, CommandRecorder, DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc, Image,
    Pipeline, PipelineKey, TexelBuffer, UploadClass, UploadCounter,
};
use crate::vk::{BufferUsage, Format, Stages};

/// Output components per emitted vertex as the validation layer counts
/// them: gl_Position (4) and `world` (4).
const COMPONENTS_PER_VERTEX: u32 = 8;

/// The family's options, `capture` (a test option) among them.
const OPTIONS: &[OptionSpec] = Settings::OPTIONS;

pub const METHOD: MethodInfo = MethodInfo {
    name: "hm-gpu",
    data: DataKind::Terrain,
    summary: "GPU HM: active PC cells tessellated by a geometry shader, one invocation per PC-list entry; per frame only the active PC list is uploaded",
    options: OPTIONS,
    features: &[Feature::GeometryShader],
    sweep: SWEEP,
    compare: COMPARE,
    suite: &[],
    stress: &[],
    published: &[],
    family: super::FAMILY,
    create,
};

/// Triangles one geometry-shader invocation may emit on this device.
pub fn max_triangles(info: &crate::vk::DeviceInfo) -> u32 {
    info.max_geometry_output_vertices.min(info.max_geometry_total_output_components / COMPONENTS_PER_VERTEX) / 3
}

fn create(inputs: MethodInputs) -> Result<Box<dyn RenderMethod>> {
    let SceneData::Terrain(map) = inputs.data else { bail!("hm-gpu renders terrains only") };
    let ctx = inputs.ctx;
    let info = &ctx.info;
    let max_tris = check_device(info, &Settings::from_options(inputs.options)?)?;
    let scene = TerrainScene::new(ctx, map, inputs.options, inputs.width, inputs.height, inputs.counter)?;
    let tables = PcTables::build(&scene.model)?;
    let counter = inputs.counter;
    let pc_list = PcList::of(&tables, max_tris);
    let bytes: &[u8] = bytemuck::cast_slice(&pc_list.entries);
    let mut list = Buffer::new(ctx, BufferDesc::upload("hm-gpu PC list", bytes.len() as u64, BufferUsage::VERTEX))?;
    list.write(0, bytes, counter, UploadClass::Static)?;
    let tb = texel(ctx, "hm-gpu TB coordinates", bytemuck::cast_slice(&tables.tb_xy), Format::Rg32Float, counter)?;
    let chains = texel(ctx, "hm-gpu chain list", bytemuck::cast_slice(&tables.chains), Format::Rgba32Uint, counter)?;
    let m = &scene.model;
    let entry_first = pc_list.entry_first;
    let capacity = tables.frame_capacity(m, |k, i| (entry_first[k][i + 1] - entry_first[k][i]) as u64) as usize;
    let active = Buffer::new(ctx, BufferDesc::upload("hm-gpu active PC list", (capacity.max(1) * 4) as u64, BufferUsage::INDEX))?;
    let max_pc_tris = tables.frame_capacity(m, |k, i| tables.cells[k][i][3] as u64);
    let capture = if scene.settings.capture { Some(capture_buffer(ctx, max_pc_tris)?) } else { None };
    let (set, desc) = tables_set(ctx, [&scene.geometry, &tb, &chains], capture.as_ref())?;
    let key = scene.settings.pc_geometry_key(max_tris, desc);
    let pipeline = crate::algo::pipelines::get(ctx, &key)?;
    Ok(Box::new(HmGpu {
        scene,
        tables,
        _tb: tb,
        _chains: chains,
        list,
        entry_first,
        active,
        active_list: Vec::with_capacity(capacity),
        capacity,
        set,
        pipeline,
        key,
        capture,
        max_tris,
        max_pc_tris,
        gs_limits: (info.max_geometry_output_vertices, info.max_geometry_total_output_components),
        frame: FrameCounts::default(),
    }))
}

/// The triangles one invocation may emit on this device, after checking
/// that it has geometry shaders emitting at least one, and the stores
/// `capture=on` needs.
fn check_device(info: &crate::vk::DeviceInfo, settings: &Settings) -> Result<u32> {
    if !info.features.geometry_shader {
        bail!("hm-gpu: device '{}' has no geometry shaders", info.name);
    }
    let max_tris = max_triangles(info);
    if max_tris == 0 {
        bail!(
            "hm-gpu: device '{}' lets a geometry shader emit {} vertices / {} components, not one triangle",
            info.name,
            info.max_geometry_output_vertices,
            info.max_geometry_total_output_components
        );
    }
    if settings.capture && !info.features.vertex_pipeline_stores_and_atomics {
        bail!("hm-gpu: capture=on needs vertexPipelineStoresAndAtomics, which device '{}' lacks", info.name);
    }
    Ok(max_tris)
}

/// The PC list: per level, per cell, one entry per slice of `max_tris`
/// triangles (its part in bits 8 on of the third word).
struct PcList {
    entries: Vec<[u32; 4]>,
    /// Per level, per PC cell: its first entry (and one past the last).
    entry_first: Vec<Vec<u32>>,
}

impl PcList {
    fn of(tables: &PcTables, max_tris: u32) -> PcList {
        let (mut entries, mut entry_first) = (Vec::new(), Vec::new());
        for cells in &tables.cells {
            let mut first = Vec::with_capacity(cells.len() + 1);
            for e in cells {
                first.push(entries.len() as u32);
                for part in 0..e[3].div_ceil(max_tris).max(1) {
                    entries.push([e[0], e[1], e[2] | part << 8, e[3]]);
                }
            }
            first.push(entries.len() as u32);
            entry_first.push(first);
        }
        PcList { entries, entry_first }
    }
}

/// `capture=on`'s buffer: a header (count, errors, capacity in indices,
/// set per frame) and room for the largest frame's PC triangles.
fn capture_buffer(ctx: &Arc<crate::vk::Context>, max_pc_tris: u64) -> Result<Buffer> {
    let size = (16 + 12 * max_pc_tris.max(1)) as usize;
    let mut b = Buffer::new(ctx, BufferDesc::upload("hm-gpu capture", size as u64, BufferUsage::STORAGE))?;
    b.write_staging(0, bytemuck::cast_slice(&[0u32, 0, (3 * max_pc_tris) as u32, 0]))?;
    Ok(b)
}

/// The geometry stage's set: the geometry, TB coordinates and chain list
/// (the paper's TBOs), and the capture buffer when there is one.
fn tables_set(ctx: &Arc<crate::vk::Context>, texels: [&TexelBuffer; 3], capture: Option<&Buffer>) -> Result<(DescriptorSet, DescriptorSetDesc)> {
    let stages = Stages::GEOMETRY;
    let mut desc = DescriptorSetDesc::new(&[(DescriptorKind::UniformTexelBuffer, stages); 3]);
    let mut resources: Vec<DescriptorResource> = texels.into_iter().map(DescriptorResource::UniformTexelBuffer).collect();
    if let Some(b) = capture {
        desc = desc.with(DescriptorKind::StorageBuffer, stages);
        resources.push(DescriptorResource::StorageBuffer(b));
    }
    Ok((DescriptorSet::new(ctx, "hm-gpu tables", &desc, &resources)?, desc))
}

/// A static texel buffer holding `bytes` (counted as static upload).
pub(super) fn texel(ctx: &Arc<crate::vk::Context>, name: &str, bytes: &[u8], format: Format, counter: &mut UploadCounter) -> Result<TexelBuffer> {
    // An empty table still needs one texel for its view.
    let padded: Vec<u8> = if bytes.is_empty() { vec![0; 16] } else { bytes.to_vec() };
    let size = padded.len() as u64;
    let mut t = TexelBuffer::new(ctx, BufferDesc::upload(name, size, BufferUsage::UNIFORM_TEXEL), format)?;
    t.buffer.write(0, &padded, counter, UploadClass::Static)?;
    Ok(t)
}

#[derive(Debug, Clone, Copy, Default)]
struct FrameCounts {
    single: u64,
    split: u64,
    pc_triangles: u64,
}

pub struct HmGpu {
    scene: TerrainScene,
    tables: PcTables,
    _tb: TexelBuffer,
    _chains: TexelBuffer,
    /// The static PC list (vertex input).
    list: Buffer,
    /// Per level, per PC cell: its first entry (and one past the last).
    entry_first: Vec<Vec<u32>>,
    /// This frame's active entries (index buffer).
    active: Buffer,
    active_list: Vec<u32>,
    capacity: usize,
    set: DescriptorSet,
    pipeline: Arc<Pipeline>,
    key: PipelineKey,
    capture: Option<Buffer>,
    max_tris: u32,
    max_pc_tris: u64,
    /// The device's maxGeometryOutputVertices, maxGeometryTotalOutputComponents.
    gs_limits: (u32, u32),
    frame: FrameCounts,
}

impl RenderMethod for HmGpu {
    fn prepare(&mut self, view: &View, phases: &mut Phases) -> Result<()> {
        self.scene.select(view, phases);
        let t0 = std::time::Instant::now();
        self.active_list.clear();
        let mut f = FrameCounts::default();
        for &(level, i) in &self.scene.active.pc_cells {
            let (k, i) = (level as usize, i as usize);
            let (a, b) = (self.entry_first[k][i], self.entry_first[k][i + 1]);
            self.active_list.extend(a..b);
            if b - a > 1 {
                f.split += 1;
            } else {
                f.single += 1;
            }
            f.pc_triangles += self.tables.cells[k][i][3] as u64;
        }
        self.frame = f;
        phases.ended("pack", t0.elapsed().as_secs_f64() * 1e3);
        if self.active_list.len() > self.capacity {
            bail!("hm-gpu: {} active PC entries exceed the {} sized for", self.active_list.len(), self.capacity);
        }
        Ok(())
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> Result<()> {
        if !self.active_list.is_empty() {
            self.active.write(0, bytemuck::cast_slice(&self.active_list), counter, UploadClass::FrameCells)?;
        }
        if let Some(c) = &mut self.capture {
            // Test instrumentation, not the method's traffic: not counted.
            c.write_staging(0, bytemuck::cast_slice(&[0u32, 0]))?;
        }
        Ok(())
    }

    fn record(&mut self, rec: &CommandRecorder, target: &Image, view: &View, counter: &mut UploadCounter) -> Result<()> {
        let pc_push = self.scene.record_static(rec, target, view, counter)?;
        if !self.active_list.is_empty() {
            rec.bind_graphics(&self.pipeline, &[&self.set])?;
            rec.bind_vertex_buffer(&self.list);
            rec.bind_index_buffer_u32(&self.active);
            rec.push_constants(&self.pipeline, bytemuck::bytes_of(&pc_push), counter);
            rec.draw_indexed_range(0, self.active_list.len() as u32);
        }
        rec.end_rendering();
        if self.capture.is_some() {
            rec.storage_to_host(Stages::GEOMETRY);
        }
        Ok(())
    }

    fn work(&self) -> Work {
        let a = &self.scene.active;
        let f = &self.frame;
        Work::default()
            .with("nc_cells", a.nc_cells)
            .with("pc_cells", a.pc_cells.len() as u64)
            .with("pc_cells_single", f.single)
            .with("pc_cells_split", f.split)
            .with("gs_invocations", self.active_list.len() as u64)
            .with("pc_triangles", f.pc_triangles)
            .with("skirt_triangles", a.skirt_triangles)
            .with("triangles", a.nc_cells * 2 + f.pc_triangles + self.scene.tin_triangles() + a.skirt_triangles)
    }

    fn details(&self) -> serde_json::Value {
        let mut d = self.scene.details(json!({
            "name": "gpu",
            "pc_upload": "the active PC list: a u32 PC-list index per active entry, every frame",
            "gs_max_triangles": self.max_tris,
            "gs_limits": { "max_geometry_output_vertices": self.gs_limits.0, "max_geometry_total_output_components": self.gs_limits.1, "components_per_vertex": COMPONENTS_PER_VERTEX },
            "pc_list_entries": self.entry_first.iter().map(|f| f.last().copied().unwrap_or(0) - f.first().copied().unwrap_or(0)).sum::<u32>(),
            "pc_capacity_entries": self.capacity,
            "largest_ring": self.tables.max_ring,
            "pipeline": { "key": self.key.id(), "name": self.key.name() },
        }));
        d["variant"]["active_split_cells"] = json!(self.frame.split);
        d
    }

    fn diagnostics(&mut self, _view: &View) -> Result<Option<serde_json::Value>> {
        let Some(c) = &self.capture else { return Ok(None) };
        let words: &[u32] = bytemuck::try_cast_slice(c.read()?).map_err(|e| anyhow::anyhow!("hm-gpu capture: {e}"))?;
        let (count, errors) = (words[0] as usize, words[1]);
        if count > 3 * self.max_pc_tris as usize {
            bail!("hm-gpu capture: {count} indices overflow the {} captured", 3 * self.max_pc_tris);
        }
        let (triangles, digest) = triangle_digest(&words[4..4 + count]);
        Ok(Some(json!({ "pc_triangles": triangles, "pc_digest": digest, "tessellation_errors": errors })))
    }

    fn table_build_ms(&self) -> f64 {
        self.scene.build_ms
    }


}
