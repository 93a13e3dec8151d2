//! Device-resident balanced cell projection (beyond the thesis): the cells
//! (positions, scalars, opposite-face planes, gradient) are uploaded once
//! into a device-local storage buffer; each frame only the visibility order
//! crosses to the device, one u32 per tet. The vertex stage runs what the
//! balanced method's CPU does per vertex (IntersectBackFace from the stored
//! planes) and feeds balanced's fragment stage unchanged, through the same
//! static strips. What is left per frame on the CPU is the sort: the
//! answer to "where does the time go once the bytes are gone".

use std::sync::Arc;

use ash::vk as raw;

use super::balanced::VERTICES_PER_CELL;
use super::render;
use super::{build_pipeline, CellF32, CellMaker, CellProjector, FrameSetup, DrawSettings, StaticIndices, MAX_INDICES_PER_CELL};
use crate::algo::host_memory::HostMemory;
use crate::algo::integrate::IntegrationTables;
use crate::algo::method::{MethodInfo, MethodInputs, RenderMethod};
use crate::mesh::TetMesh;
use crate::vk::{
    upload_static_streamed, Buffer, BufferDesc, CommandRecorder, Context, DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc,
    Pipeline, PipelineKey, TexelBuffer, UploadClass, UploadCounter, VkError, VkResult,
};

/// Per tet per frame: its index in the order.
pub const BYTES_PER_CELL_PER_FRAME: usize = 4;
/// The stored cell (`Cell` in `resident.vert`): 4 × (position, scalar),
/// 4 × (plane, unused), (gradient, unused).
pub const FLOATS_PER_STORED_CELL: usize = 36;

/// The registry entry.
pub const METHOD: MethodInfo = render::method_info(
    "resident",
    "device-resident balanced cell projection: cells stored once on the device, 4 bytes per tet per frame (the order)",
    render::KNOWN_EXITS_OPTIONS,
    &[],
    create,
);

fn create(inputs: MethodInputs) -> anyhow::Result<Box<dyn RenderMethod>> {
    let bytes = render::DeviceBytesPerCell {
        frame: BYTES_PER_CELL_PER_FRAME,
        fixed: MAX_INDICES_PER_CELL * 4 + FLOATS_PER_STORED_CELL * 4,
    };
    render::CellProjection::create(inputs, bytes, |ctx, mesh, tables, draw, counter| {
        Ok(Box::new(Resident::new(ctx, mesh, tables, draw, counter)?))
    })
}

pub struct Resident {
    cells: usize,
    /// Cells in the last `pack` (the first `drawn` entries of `order`).
    drawn: usize,
    order: Vec<u32>,
    order_buffer: Buffer,
    _cell_buffer: TexelBuffer,
    indices: StaticIndices,
    set: DescriptorSet,
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
        let cell_buffer = upload_cells(ctx, "resident cells", mesh, counter)?;
        let usage = raw::BufferUsageFlags::STORAGE_BUFFER;
        let indices = StaticIndices::upload(ctx, "resident indices", draw.primitives, n, counter)?;
        let order_buffer = Buffer::new(ctx, BufferDesc::upload("resident order", (n.max(1) * 4) as u64, usage))?;
        let set = cells_and_order_set(ctx, "resident cells and order", &cell_buffer, &order_buffer)?;
        let (pipeline, pipeline_key) = resident_pipeline(ctx, tables, draw)?;
        Ok(Resident {
            cells: n,
            drawn: n,
            order: vec![0; n],
            order_buffer,
            _cell_buffer: cell_buffer,
            indices,
            set,
            pipeline,
            pipeline_key,
        })
    }
}

/// Set 1 of `resident.vert`: the stored cells (a uniform texel buffer of
/// RGBA32F, `FLOATS_PER_STORED_CELL / 4` texels per cell: each vertex stage
/// invocation reads all of its cell, and a texel fetch is one lookup where
/// a storage-buffer load with a per-vertex index is, on llvmpipe, a loop
/// over the SIMD lanes per component) and the order (a storage buffer, one
/// u32 per vertex).
pub(super) fn set_desc() -> DescriptorSetDesc {
    let vertex = raw::ShaderStageFlags::VERTEX;
    DescriptorSetDesc::new(&[(DescriptorKind::UniformTexelBuffer, vertex), (DescriptorKind::StorageBuffer, vertex)])
}

/// The pipeline of both resident methods: `resident.vert` (vertices from
/// the stored cells, set 1) and balanced's fragment stage.
pub(super) fn resident_pipeline(ctx: &Arc<Context>, tables: &IntegrationTables, draw: DrawSettings) -> VkResult<(Arc<Pipeline>, PipelineKey)> {
    build_pipeline(
        ctx,
        "cell_projection/resident.vert",
        "cell_projection/balanced.frag",
        0,
        &[],
        draw.primitives.topology(),
        draw.primitives.primitive_restart(),
        tables,
        draw.interpolation,
        &[set_desc()],
    )
}

pub(super) fn cells_and_order_set(ctx: &Arc<Context>, name: &str, cells: &TexelBuffer, order: &Buffer) -> VkResult<DescriptorSet> {
    DescriptorSet::new(ctx, name, &set_desc(), &[DescriptorResource::UniformTexelBuffer(cells), DescriptorResource::StorageBuffer(order)])
}

/// The cells as `resident.vert` reads them, uploaded once into device-local
/// memory, made chunk by chunk while they stream through the staging buffer
/// (no host copy of all of them is ever held); a mesh with more texels than
/// the device's texel-buffer limit is an error naming it.
pub(super) fn upload_cells(ctx: &Arc<Context>, name: &str, mesh: &TetMesh, counter: &mut UploadCounter) -> VkResult<TexelBuffer> {
    use rayon::prelude::*;
    let n = mesh.tets.len();
    let texels = n as u64 * (FLOATS_PER_STORED_CELL / 4) as u64;
    let limit = u64::from(ctx.info.max_texel_buffer_elements);
    if texels > limit {
        return Err(VkError::Invalid(format!(
            "mesh '{}': {n} cells need {texels} texels, above the device's maxTexelBufferElements ({limit})",
            mesh.name
        )));
    }
    const CELL_BYTES: usize = FLOATS_PER_STORED_CELL * 4;
    let maker = CellMaker::new(mesh);
    let usage = raw::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
    let buffer = upload_static_streamed(ctx, name, (n * CELL_BYTES) as u64, CELL_BYTES as u64, usage, counter, |offset, chunk| {
        let first = offset as usize / CELL_BYTES;
        chunk.par_chunks_mut(CELL_BYTES).with_min_len(1024).enumerate().for_each(|(i, dst)| {
            dst.copy_from_slice(bytemuck::cast_slice(&stored(&maker.cell(mesh, first + i))));
        });
    })?;
    TexelBuffer::over(ctx, buffer, raw::Format::R32G32B32A32_SFLOAT)
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
        self.order_buffer.write(0, bytemuck::cast_slice(&self.order[..self.drawn]), counter, UploadClass::FrameCells)
    }

    fn record_draw(&self, rec: &CommandRecorder, tables: &IntegrationTables, frame: &FrameSetup, counter: &mut UploadCounter) -> VkResult<()> {
        let sets: [&DescriptorSet; 2] = [&tables.set, &self.set];
        rec.bind_graphics(&self.pipeline, &sets)?;
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&frame.constants), counter);
        self.indices.draw(rec, self.drawn);
        Ok(())
    }
}
