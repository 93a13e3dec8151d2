//! `hm-compute` (beyond the paper): the PC tessellation of `hm-gpu` in a
//! compute pass, as renderers without geometry shaders do it. One
//! invocation per active PC cell runs the shared transcription of the CPU
//! tessellation (`shaders/terrain/pc.comp`), allocates its output range
//! by the cell's triangle count (an atomic add on the indexed-draw
//! arguments' count) and writes indices into the static geometry to a
//! device-local buffer, which the render pass then draws with one
//! indirect indexed draw. No output limit applies, so no cell is split.
//!
//! Per frame the active PC list crosses (a u32 cell index per active PC
//! cell) and the 24-byte draw-arguments header is reset from the host.
//! Cells land in the output in the order the atomics grant, so the order
//! of cells varies between frames; each cell's triangles are contiguous and
//! in the CPU's order (`diagnostics` fingerprints the sorted list).
//!
//! Phases: the CPU's `lod` (level selection) and `pack` (the active list);
//! on the device, timestamps split each frame into the tessellation pass
//! and the render pass (`details.device_phases_ms`, medians over the run's
//! frames, read back once each frame has completed).

use std::sync::Arc;

use anyhow::{bail, Result};
use serde_json::json;

use super::gpu::texel;
use super::tables::{triangle_digest, PcTables};
use super::{pc_compute_key, TerrainScene, COMPARE, OPTIONS, SWEEP};
use crate::algo::method::{DataKind, MethodInfo, MethodInputs, Phases, RenderMethod, SceneData, View, Work};
use crate::vk::{
    Buffer, BufferDesc, CommandRecorder, DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc, Image, Pipeline,
    PipelineKey, TexelBuffer, TimestampPool, UploadClass, UploadCounter,
};
use crate::vk::{BufferUsage, Format, Stages, TimestampAt};

pub const METHOD: MethodInfo = MethodInfo {
    name: "hm-compute",
    data: DataKind::Terrain,
    summary: "hybrid terrain meshes: active PC cells tessellated in a compute pass into a device index buffer, drawn indirectly",
    options: OPTIONS,
    features: &[],
    sweep: SWEEP,
    compare: COMPARE,
    suite: &[],
    stress: &[],
    published: &[],
    family: super::FAMILY,
    create,
};

const LOCAL_SIZE: u64 = 64;
/// The tessellation pass's push constants (`Push` in `terrain/pc.comp`;
/// `tests/shader_interfaces.rs` checks the two agree).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TessPush {
    /// Active PC cells.
    pub count: u32,
    /// The grid's first geometry index and row length (`terrain/tessellate.glsl`).
    pub grid_base: u32,
    pub grid_width: u32,
    /// Indices the output holds.
    pub capacity: u32,
}

/// The draw arguments the pass fills (`Draw` in `terrain/pc.comp`:
/// VkDrawIndexedIndirectCommand) and its error count; reset every frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DrawArgs {
    pub index_count: u32,
    pub instance_count: u32,
    pub first_index: u32,
    pub vertex_offset: i32,
    pub first_instance: u32,
    /// Cells whose triangles did not fit (never: the output holds the largest frame).
    pub errors: u32,
}

/// No triangles yet, one instance.
const DRAW_RESET: DrawArgs = DrawArgs { index_count: 0, instance_count: 1, first_index: 0, vertex_offset: 0, first_instance: 0, errors: 0 };

fn create(inputs: MethodInputs) -> Result<Box<dyn RenderMethod>> {
    let SceneData::Terrain(map) = inputs.data else { bail!("hm-compute renders terrains only") };
    let ctx = inputs.ctx;
    let scene = TerrainScene::new(ctx, map, inputs.options, inputs.width, inputs.height, inputs.counter)?;
    let tables = PcTables::build(&scene.model)?;
    let counter = inputs.counter;
    let m = &scene.model;
    // All levels' cell entries in one table; a level's cells from its offset.
    let mut level_first = Vec::new();
    let mut cells: Vec<[u32; 4]> = Vec::new();
    for c in &tables.cells {
        level_first.push(cells.len() as u32);
        cells.extend_from_slice(c);
    }
    if cells.is_empty() {
        cells.push([0; 4]);
    }
    let storage = BufferUsage::STORAGE;
    let bytes: &[u8] = bytemuck::cast_slice(&cells);
    let mut cell_table = Buffer::new(ctx, BufferDesc::upload("hm-compute PC cells", bytes.len() as u64, storage))?;
    cell_table.write(0, bytes, counter, UploadClass::Static)?;
    let tb = texel(ctx, "hm-compute TB coordinates", bytemuck::cast_slice(&tables.tb_xy), Format::Rg32Float, counter)?;
    let chains = texel(ctx, "hm-compute chain list", bytemuck::cast_slice(&tables.chains), Format::Rgba32Uint, counter)?;
    let capacity_cells = tables.frame_capacity(m, |_, _| 1).max(1);
    let capacity_indices = 3 * tables.frame_capacity(m, |k, i| tables.cells[k][i][3] as u64).max(1);
    let capacity_u32 = u32::try_from(capacity_indices).map_err(|_| anyhow::anyhow!("hm-compute: {capacity_indices} PC indices per frame"))?;
    let active = Buffer::new(ctx, BufferDesc::upload("hm-compute active PC cells", 4 * capacity_cells, storage))?;
    let draw = Buffer::new(ctx, BufferDesc::upload("hm-compute draw arguments", std::mem::size_of::<DrawArgs>() as u64, storage | BufferUsage::INDIRECT))?;
    let output = Buffer::new(
        ctx,
        BufferDesc::device_local("hm-compute PC triangles", 4 * capacity_indices, storage | BufferUsage::INDEX | BufferUsage::TRANSFER_SRC),
    )?;
    let stages = Stages::COMPUTE;
    let desc = DescriptorSetDesc::new(&[
        (DescriptorKind::StorageBuffer, stages),
        (DescriptorKind::StorageBuffer, stages),
        (DescriptorKind::UniformTexelBuffer, stages),
        (DescriptorKind::UniformTexelBuffer, stages),
        (DescriptorKind::StorageBuffer, stages),
        (DescriptorKind::StorageBuffer, stages),
    ]);
    let set = DescriptorSet::new(
        ctx,
        "hm-compute tables",
        &desc,
        &[
            DescriptorResource::StorageBuffer(&cell_table),
            DescriptorResource::StorageBuffer(&active),
            DescriptorResource::UniformTexelBuffer(&tb),
            DescriptorResource::UniformTexelBuffer(&chains),
            DescriptorResource::StorageBuffer(&draw),
            DescriptorResource::StorageBuffer(&output),
        ],
    )?;
    let key = pc_compute_key(desc, std::mem::size_of::<TessPush>() as u32);
    let pipeline = crate::algo::pipelines::get(ctx, &key)?;
    Ok(Box::new(HmCompute {
        scene,
        tables,
        level_first,
        _cell_table: cell_table,
        _tb: tb,
        _chains: chains,
        active,
        draw,
        output,
        active_list: Vec::with_capacity(capacity_cells as usize),
        capacity_cells: capacity_cells as usize,
        capacity_indices: capacity_u32,
        set,
        pipeline,
        key,
        pc_triangles: 0,
        timestamps: TimestampPool::new(ctx, "hm-compute timestamps", 3)?,
        recorded: false,
        device_ms: Vec::new(),
        ctx: ctx.clone(),
    }))
}

pub struct HmCompute {
    scene: TerrainScene,
    tables: PcTables,
    /// Offset of each level's cells in the cell table.
    level_first: Vec<u32>,
    _cell_table: Buffer,
    _tb: TexelBuffer,
    _chains: TexelBuffer,
    active: Buffer,
    /// Draw arguments the compute pass completes (host-visible: reset per frame).
    draw: Buffer,
    output: Buffer,
    active_list: Vec<u32>,
    capacity_cells: usize,
    capacity_indices: u32,
    set: DescriptorSet,
    pipeline: Arc<Pipeline>,
    key: PipelineKey,
    pc_triangles: u64,
    /// Frame start, tessellation pass done, render pass done.
    timestamps: TimestampPool,
    recorded: bool,
    /// Per completed frame: (tessellation pass, render pass) ms.
    device_ms: Vec<(f64, f64)>,
    ctx: Arc<crate::vk::Context>,
}

fn median(v: impl Iterator<Item = f64>) -> Option<f64> {
    let mut v: Vec<f64> = v.collect();
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| v[v.len() / 2])
}

impl HmCompute {
    /// The draw arguments the last frame's pass wrote.
    fn draw_args(&self) -> Result<DrawArgs> {
        let bytes = self.draw.read()?;
        bytemuck::try_pod_read_unaligned(&bytes[..std::mem::size_of::<DrawArgs>()]).map_err(|e| anyhow::anyhow!("hm-compute draw arguments: {e}"))
    }
}

impl RenderMethod for HmCompute {
    fn prepare(&mut self, view: &View, phases: &mut Phases) -> Result<()> {
        self.scene.select(view, phases);
        let t0 = std::time::Instant::now();
        self.active_list.clear();
        self.pc_triangles = 0;
        for &(level, i) in &self.scene.active.pc_cells {
            self.active_list.push(self.level_first[level as usize] + i);
            self.pc_triangles += self.tables.cells[level as usize][i as usize][3] as u64;
        }
        phases.ended("pack", t0.elapsed().as_secs_f64() * 1e3);
        if self.active_list.len() > self.capacity_cells {
            bail!("hm-compute: {} active PC cells exceed the {} sized for", self.active_list.len(), self.capacity_cells);
        }
        Ok(())
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> Result<()> {
        // The previous frame has completed (the runner waited for it).
        if self.recorded {
            if let Some(t) = self.timestamps.read() {
                self.device_ms.push((t[0], t[1] - t[0]));
            }
        }
        if !self.active_list.is_empty() {
            self.active.write(0, bytemuck::cast_slice(&self.active_list), counter, UploadClass::FrameCells)?;
        }
        self.draw.write(0, bytemuck::bytes_of(&DRAW_RESET), counter, UploadClass::FrameConstants)?;
        Ok(())
    }

    fn record(&mut self, rec: &CommandRecorder, target: &Image, view: &View, counter: &mut UploadCounter) -> Result<()> {
        let n = self.active_list.len() as u64;
        self.timestamps.reset(rec);
        self.timestamps.write(rec, 0, TimestampAt::Start)?;
        if n > 0 {
            // The previous frame's draw read the output and the arguments.
            rec.draw_fetch_to_compute();
            rec.bind_compute(&self.pipeline, &[&self.set])?;
            let m = &self.scene.model;
            let push = TessPush { count: n as u32, grid_base: m.grid_base, grid_width: m.domain[0] + 1, capacity: self.capacity_indices };
            rec.push_constants(&self.pipeline, bytemuck::bytes_of(&push), counter);
            rec.dispatch([n.div_ceil(LOCAL_SIZE) as u32, 1, 1])?;
            rec.compute_to_graphics();
        }
        self.timestamps.write(rec, 1, TimestampAt::ComputeDone)?;
        let pc_push = self.scene.record_static(rec, target, view, counter)?;
        if n > 0 {
            rec.bind_index_buffer_u32(&self.output);
            rec.push_constants(&self.scene.pipeline, bytemuck::bytes_of(&pc_push), counter);
            rec.draw_indexed_indirect(&self.draw, 0)?;
        }
        rec.end_rendering();
        self.timestamps.write(rec, 2, TimestampAt::GraphicsDone)?;
        self.recorded = true;
        // The draw arguments' count and error word are read on the host.
        rec.compute_to_host();
        Ok(())
    }

    fn work(&self) -> Work {
        let a = &self.scene.active;
        Work::default()
            .with("nc_cells", a.nc_cells)
            .with("pc_cells", a.pc_cells.len() as u64)
            .with("pc_triangles", self.pc_triangles)
            .with("skirt_triangles", a.skirt_triangles)
            .with("triangles", a.nc_cells * 2 + self.pc_triangles + self.scene.tin_triangles() + a.skirt_triangles)
    }

    fn details(&self) -> serde_json::Value {
        let h = self.draw_args().ok();
        self.scene.details(json!({
            "name": "compute",
            "pc_upload": "the active PC list (a u32 cell index per active PC cell) and the 24-byte indirect-draw header, every frame",
            "pc_capacity_indices": self.capacity_indices,
            "largest_ring": self.tables.max_ring,
            "last_frame_indices": h.map(|h| h.index_count),
            "tessellation_errors": h.map(|h| h.errors),
            "compute_pipeline": { "key": self.key.id(), "name": self.key.name() },
            "device_phases_ms": {
                "tessellate": median(self.device_ms.iter().map(|t| t.0)),
                "render": median(self.device_ms.iter().map(|t| t.1)),
                "frames": self.device_ms.len(),
                "what": "device time of the compute tessellation pass and of the render pass (NC, TIN, skirts, PC draw), medians over the run's completed frames",
            },
        }))
    }

    fn diagnostics(&mut self, _view: &View) -> Result<Option<serde_json::Value>> {
        let h = self.draw_args()?;
        let count = h.index_count.min(self.capacity_indices) as u64;
        let readback = Buffer::new(&self.ctx, BufferDesc::readback("hm-compute readback", 4 * count.max(1)))?;
        let rec = CommandRecorder::new(&self.ctx, "hm-compute readback")?;
        rec.begin()?;
        if count > 0 {
            rec.compute_to_transfer();
            rec.copy_buffer(&self.output, &readback, 4 * count)?;
            rec.transfer_to_host();
        }
        rec.submit_and_wait()?;
        let words: &[u32] = bytemuck::try_cast_slice(&readback.read()?[..4 * count as usize]).map_err(|e| anyhow::anyhow!("hm-compute readback: {e}"))?;
        let (triangles, digest) = triangle_digest(words);
        Ok(Some(json!({ "pc_triangles": triangles, "pc_digest": digest, "tessellation_errors": h.errors })))
    }

    fn table_build_ms(&self) -> f64 {
        self.scene.build_ms
    }


}
