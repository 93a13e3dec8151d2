//! Device-resident balanced cell projection (beyond the thesis): the cells
//! (positions, scalars, opposite-face planes, gradient) are uploaded once
//! into device-local texel buffers; each frame only the visibility order
//! crosses to the device, one u32 per tet. A compute pass
//! (`resident_expand.comp`) runs what the balanced method's CPU does per
//! tet (IntersectBackFace from the stored planes), once per tet on every
//! core, into device-local vertex records, which balanced's own pipeline
//! draws through the same static indices, batch by batch (`RECORDS_BATCH`
//! cells into one records buffer). What is left per frame on the
//! CPU is the sort: the answer to "where does the time go once the bytes
//! are gone".

use std::sync::Arc;


use super::balanced::{records_pipeline, FLOATS_PER_CELL, VERTICES_PER_CELL};
use super::render;
use super::{build_pipeline, CellF32, CellMaker, CellProjector, DrawSettings, Primitives, StaticIndices, MAX_INDICES_PER_CELL};
use crate::algo::tet_mesh::{FrameConstants, FrameSetup};
use crate::algo::chunks::{self, ChunkLimits, TexelChunks};
use crate::algo::host_memory::HostMemory;
use crate::algo::integrate::IntegrationTables;
use crate::algo::method::{MethodInfo, MethodInputs, RenderMethod};
use crate::mesh::TetMesh;
use crate::vk::{
    Buffer, BufferDesc, CommandRecorder, ComputePipelineKey, Context, DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc,
    Pipeline, PipelineKey, ShaderKey, ShaderStage, UploadClass, UploadCounter, VkResult,
};
use crate::vk::{BufferUsage, ColorAttachment, Format, Image, Stages};

/// Per tet per frame: its index in the order.
pub const BYTES_PER_CELL_PER_FRAME: usize = 4;
/// The stored cell (`stored_cell.glsl`): 4 × (position, scalar),
/// 4 × (plane, unused), (gradient, unused).
pub const FLOATS_PER_STORED_CELL: usize = 36;
/// Invocations per workgroup of `resident_expand.comp`.
const EXPAND_GROUP: usize = 64;
/// Cells expanded and drawn per batch (docs/scaling.md, "Host memory";
/// measured in results/HISTORY.md): the one records buffer holds a batch (112 MiB), whatever the
/// mesh, instead of 112 bytes per tet. Not smaller: batches that fit the
/// cache (32,768 cells, 3.5 MiB) measured slower, since each batch's pass
/// ends with the rasterizer drained while the next expansion runs.
pub const RECORDS_BATCH: usize = 1 << 20;
/// Test knob (tests and measurements only, docs/scaling.md):
/// `VOLBENCH_TEST_RESIDENT_BATCH=N` expands and draws N cells per batch, so
/// a small mesh takes the many-batch path a large one does.
pub const RESIDENT_BATCH_VAR: &str = crate::switches::TEST_RESIDENT_BATCH;

/// Cells per batch: `RECORDS_BATCH` or the knob's count.
fn records_batch() -> VkResult<usize> {
    Ok(crate::switches::int(RESIDENT_BATCH_VAR)?.map_or(RECORDS_BATCH, |n| usize::try_from(n).unwrap_or(usize::MAX)))
}

/// The registry entry.
pub const METHOD: MethodInfo = render::method_info(
    "resident",
    "device-resident balanced cell projection: cells stored once on the device, 4 bytes per tet per frame (the order)",
    render::KNOWN_EXITS_OPTIONS,
    &[],
    create,
);

fn create(inputs: MethodInputs) -> anyhow::Result<Box<dyn RenderMethod>> {
    // The order is split at the device's limits and in batches (one piece
    // per draw); the records are one batch's, whatever the mesh (at most
    // RECORDS_BATCH cells: a fixed 112 MiB, not a per-cell cost).
    let bytes = render::DeviceBytesPerCell {
        frame: 0,
        fixed: BYTES_PER_CELL_PER_FRAME + MAX_INDICES_PER_CELL * 4 + FLOATS_PER_STORED_CELL * 4,
        // The order's copy.
        host: 4,
    };
    render::CellProjection::create(inputs, bytes, |ctx, mesh, tables, draw, counter| {
        Ok(Box::new(Resident::new(ctx, mesh, tables, draw, counter)?))
    })
}

/// One batch's piece of the order: its order buffer (a count, then the
/// cells) and the expansion's descriptor set (the cells, this order, the
/// shared records).
struct Piece {
    order: Buffer,
    set: DescriptorSet,
}

pub struct Resident {
    cells: usize,
    /// Cells in the last `pack` (the first `drawn` entries of `order`).
    drawn: usize,
    /// The order's copy: the device may still read the order buffers while
    /// the next frame is sorted (`run_overlapped`).
    order: Vec<u32>,
    /// The order drawn in pieces of at most `per_draw` cells (a batch, or
    /// less where one storage binding sees fewer), each expanded into
    /// `records` and drawn before the next is expanded.
    pieces: Vec<Piece>,
    per_draw: usize,
    /// One piece's vertex records (device-local), rewritten per piece.
    records: Buffer,
    cell_chunks: TexelChunks,
    indices: StaticIndices,
    expand: Arc<Pipeline>,
    pipeline: Arc<Pipeline>,
    pipeline_key: PipelineKey,
}

/// The stored image of one cell (9 RGBA32F texels).
pub(super) fn stored(c: &CellF32) -> [f32; FLOATS_PER_STORED_CELL] {
    let mut out = [0f32; FLOATS_PER_STORED_CELL];
    for i in 0..4 {
        out[4 * i..4 * i + 4].copy_from_slice(&[c.pos[i][0], c.pos[i][1], c.pos[i][2], c.scalar[i]]);
        out[16 + 4 * i..16 + 4 * i + 3].copy_from_slice(&c.plane3[i]);
    }
    out[32..35].copy_from_slice(&c.gradient);
    out
}

impl Resident {
    pub fn new(
        ctx: &Arc<Context>,
        mesh: &TetMesh,
        tables: &IntegrationTables,
        draw: DrawSettings,
        counter: &mut UploadCounter,
    ) -> VkResult<Self> {
        let n = mesh.tets.len();
        let batch = records_batch()?;
        let limits = ChunkLimits::of(ctx)?;
        let cells = upload_cell_chunks(ctx, "resident cells", mesh, &limits, counter)?;
        // The order's binding holds its count too; the records' binding a
        // piece's records.
        let per_draw = cells_per_draw(&limits, draw.primitives)
            .min(limits.storage_chunk(4).saturating_sub(1))
            .min(limits.storage_chunk((FLOATS_PER_CELL * 4) as u64))
            .min(batch)
            .max(1);
        let ranges = chunks::ranges(n, per_draw);
        let records = Buffer::new(
            ctx,
            BufferDesc::device_local(
                "resident vertex records (one batch)",
                (ranges[0].len().max(1) * FLOATS_PER_CELL * 4) as u64,
                BufferUsage::STORAGE | BufferUsage::VERTEX,
            ),
        )?;
        // Every piece draws from the start of the same indices.
        let indices = StaticIndices::upload(ctx, "resident indices", draw.primitives, ranges[0].len(), counter)?;
        let desc = expand_set_desc(cells.buffers.len());
        let pieces = ranges
            .iter()
            .enumerate()
            .map(|(k, piece)| {
                let label = if ranges.len() == 1 { String::new() } else { format!(" [{k}]") };
                let len = piece.len().max(1);
                let order = Buffer::new(
                    ctx,
                    BufferDesc::upload(&format!("resident order{label}"), ((len + 1) * 4) as u64, BufferUsage::STORAGE),
                )?;
                let mut resources = vec![
                    DescriptorResource::StorageTexelBuffer(&cells.buffers[0]),
                    DescriptorResource::StorageBuffer(&order),
                    DescriptorResource::StorageBuffer(&records),
                ];
                resources.extend(cells.buffers[1..].iter().map(DescriptorResource::StorageTexelBuffer));
                let set = DescriptorSet::new(ctx, &format!("resident cells, order and records{label}"), &desc, &resources)?;
                Ok(Piece { order, set })
            })
            .collect::<VkResult<Vec<_>>>()?;
        let expand = expand_pipeline(ctx, draw, &cells, desc)?;
        // The draw is balanced's: its vertex stage reads the records.
        let (pipeline, pipeline_key) = records_pipeline(ctx, tables, draw)?;
        Ok(Resident {
            cells: n,
            drawn: n,
            order: vec![0; n],
            pieces,
            per_draw,
            records,
            cell_chunks: cells,
            indices,
            expand,
            pipeline,
            pipeline_key,
        })
    }

    /// Cells of piece `k` in the last `pack`.
    fn piece_len(&self, k: usize) -> usize {
        let start = k * self.per_draw;
        self.drawn.min(start + self.per_draw).saturating_sub(start)
    }
}

/// The one set of `resident_expand.comp`: the stored cells (chunk 0), the
/// piece's order, its records, then the other chunks of the cells
/// (`CELL_CHUNK_BINDING` 3).
fn expand_set_desc(cell_chunks: usize) -> DescriptorSetDesc {
    let compute = Stages::COMPUTE;
    let mut desc = DescriptorSetDesc::new(&[
        (DescriptorKind::StorageTexelBuffer, compute),
        (DescriptorKind::StorageBuffer, compute),
        (DescriptorKind::StorageBuffer, compute),
    ]);
    for _ in 1..cell_chunks {
        desc = desc.with(DescriptorKind::StorageTexelBuffer, compute);
    }
    desc
}

/// The expansion's compute pipeline: the frame constants as the draw's
/// push constants; the cells, order and records in set 0.
fn expand_pipeline(
    ctx: &Arc<Context>,
    draw: DrawSettings,
    cells: &TexelChunks,
    desc: DescriptorSetDesc,
) -> VkResult<Arc<Pipeline>> {
    let chunked = cells.defines("CELL");
    let mut defines: Vec<(&str, &str)> = draw.exit_defines();
    defines.extend(chunked.iter().map(|(k, v)| (k.as_str(), v.as_str())));
    if cells.buffers.len() > 1 {
        defines.push(("CELL_CHUNK_BINDING", "3"));
    }
    let key = PipelineKey::Compute(ComputePipelineKey {
        shader: ShaderKey::new("cell_projection/resident_expand.comp", ShaderStage::Compute, &defines),
        push_constant_bytes: std::mem::size_of::<FrameConstants>() as u32,
        sets: vec![desc],
    });
    crate::algo::pipelines::get(ctx, &key)
}

/// Cells one draw may cover: its piece of the order within one storage
/// binding, its indices within one allocation.
fn cells_per_draw(limits: &ChunkLimits, primitives: Primitives) -> usize {
    limits.storage_chunk(4).min(limits.allocation_chunk(4 * primitives.indices_per_cell() as u64)).max(1)
}

/// Set 1 of `resident.vert` (resident-gpusort's draw): the stored cells (a
/// storage texel buffer of RGBA32F, `FLOATS_PER_STORED_CELL / 4` texels per
/// cell: each vertex stage invocation reads all of its cell, and an
/// imageLoad is one inlined lookup where a storage-buffer load with a
/// per-vertex index is, on llvmpipe, a loop over the SIMD lanes per
/// component and a texelFetch a call, integrate.rs) and the order (a
/// storage buffer, one u32 per vertex); cells beyond one texel buffer in
/// `cell_chunks - 1` more bindings after them (`CELL_CHUNK_BINDING` in
/// stored_cell.glsl).
pub(super) fn set_desc(cell_chunks: usize) -> DescriptorSetDesc {
    let vertex = Stages::VERTEX;
    let mut desc = DescriptorSetDesc::new(&[(DescriptorKind::StorageTexelBuffer, vertex), (DescriptorKind::StorageBuffer, vertex)]);
    for _ in 1..cell_chunks {
        desc = desc.with(DescriptorKind::StorageTexelBuffer, vertex);
    }
    desc
}

/// resident-gpusort's pipeline: `resident.vert` (vertices from the stored
/// cells, set 1) and balanced's fragment stage.
pub(super) fn resident_pipeline(
    ctx: &Arc<Context>,
    tables: &IntegrationTables,
    draw: DrawSettings,
    cells: &TexelChunks,
) -> VkResult<(Arc<Pipeline>, PipelineKey)> {
    let chunked = cells.defines("CELL");
    let mut defines: Vec<(&str, &str)> = chunked.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
    if !defines.is_empty() {
        defines.push(("CELL_CHUNK_BINDING", "2"));
    }
    build_pipeline(
        ctx,
        "cell_projection/resident.vert",
        "cell_projection/balanced.frag",
        0,
        &[],
        draw.primitives.topology(),
        draw.primitives.primitive_restart(),
        tables,
        &draw,
        &[set_desc(cells.buffers.len())],
        &defines,
    )
}

pub(super) fn cells_and_order_set(ctx: &Arc<Context>, name: &str, cells: &TexelChunks, order: &Buffer) -> VkResult<DescriptorSet> {
    let mut resources = vec![DescriptorResource::StorageTexelBuffer(&cells.buffers[0]), DescriptorResource::StorageBuffer(order)];
    resources.extend(cells.buffers[1..].iter().map(DescriptorResource::StorageTexelBuffer));
    DescriptorSet::new(ctx, name, &set_desc(cells.buffers.len()), &resources)
}

/// The cells as `resident.vert` reads them, uploaded once into device-local
/// memory, made chunk by chunk while they stream through the staging buffer
/// (no host copy of all of them is ever held), in as many texel buffers as
/// `limits` need (`algo::chunks`).
pub(super) fn upload_cell_chunks(
    ctx: &Arc<Context>,
    name: &str,
    mesh: &TetMesh,
    limits: &ChunkLimits,
    counter: &mut UploadCounter,
) -> VkResult<TexelChunks> {
    use rayon::prelude::*;
    const CELL_BYTES: usize = FLOATS_PER_STORED_CELL * 4;
    let maker = CellMaker::new(mesh);
    let format = Format::Rgba32Float;
    let per_chunk = limits.texel_chunk(CELL_BYTES as u64, (CELL_BYTES / 16) as u64);
    TexelChunks::upload(ctx, &format!("mesh '{}': {name}", mesh.name), mesh.tets.len(), CELL_BYTES, format, per_chunk, counter, |first, bytes| {
        bytes.par_chunks_mut(CELL_BYTES).with_min_len(1024).enumerate().for_each(|(i, dst)| {
            dst.copy_from_slice(bytemuck::cast_slice(&stored(&maker.cell(mesh, first + i))));
        });
    })
}

impl CellProjector for Resident {
    fn cells(&self) -> usize {
        self.cells
    }
    fn vertices_per_cell(&self) -> usize {
        VERTICES_PER_CELL
    }
    fn floats_per_cell(&self) -> usize {
        BYTES_PER_CELL_PER_FRAME / 4
    }
    fn pipeline_key(&self) -> &PipelineKey {
        &self.pipeline_key
    }
    fn device_chunks(&self) -> serde_json::Value {
        serde_json::json!({ "cell_buffers": self.cell_chunks.buffers.len(), "cells_per_buffer": self.cell_chunks.per_chunk, "draws": self.pieces.len(), "cells_per_draw": self.per_draw })
    }

    fn drawn(&self) -> usize {
        self.drawn
    }

    fn host_bytes(&self, memory: &mut HostMemory) {
        memory.vec("projector: order copy", &self.order);
    }

    fn pack(&mut self, order: &[u32], _frame: &FrameSetup) {
        self.drawn = order.len().min(self.cells);
        self.order[..self.drawn].copy_from_slice(&order[..self.drawn]);
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> VkResult<()> {
        // Each piece's buffer: its length (a per-frame constant), then its
        // cells.
        for k in 0..self.pieces.len() {
            let start = k * self.per_draw;
            let len = self.piece_len(k);
            if len > 0 || k == 0 {
                let buffer = &mut self.pieces[k].order;
                buffer.write(0, bytemuck::bytes_of(&(len as u32)), counter, UploadClass::FrameConstants)?;
                buffer.write(4, bytemuck::cast_slice(&self.order[start..start + len]), counter, UploadClass::FrameCells)?;
            }
        }
        Ok(())
    }

    /// Piece by piece, in order: the expansion (one dispatch) into the one
    /// records buffer, then balanced's draw of them in a rendering pass of
    /// its own (the first clears the target, the others keep it); the next
    /// expansion overwrites the records only after the draw. Back-to-front
    /// compositing is kept across pieces. (The expansion is not timed apart: lavapipe's
    /// timestamps around a dispatch do not wait for it; its cost is in
    /// `gpu`, and counted in `device`.)
    fn record_composite(
        &mut self,
        rec: &CommandRecorder,
        target: &Image,
        tables: &IntegrationTables,
        frame: &FrameSetup,
        counter: &mut UploadCounter,
    ) -> VkResult<bool> {
        for (k, piece) in self.pieces.iter().enumerate() {
            let count = self.piece_len(k);
            if count == 0 && k > 0 {
                break;
            }
            // The previous draw read the records this expansion writes.
            rec.vertex_input_to_compute();
            rec.bind_compute(&self.expand, &[&piece.set])?;
            if k == 0 {
                rec.push_constants(&self.expand, bytemuck::bytes_of(&frame.constants), counter);
            }
            rec.dispatch_groups(count.div_ceil(EXPAND_GROUP) as u64)?;
            rec.compute_to_vertex_input();
            if k == 0 {
                rec.begin_rendering(target, [0.0; 4]);
            } else {
                rec.begin_rendering_targets(&[ColorAttachment { image: target, clear: None }])?;
            }
            rec.bind_pipeline(&self.pipeline, Some(&tables.set));
            if k == 0 {
                rec.push_constants(&self.pipeline, bytemuck::bytes_of(&frame.constants), counter);
            }
            rec.bind_vertex_buffer(&self.records);
            self.indices.draw(rec, count);
            rec.end_rendering();
        }
        Ok(true)
    }
}
