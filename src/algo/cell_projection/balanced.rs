//! GPU-CPU balanced cell projection (Moreland 2004, thesis §4.2): the CPU runs
//! IntersectBackFace per vertex per frame and sends 4 records of 7 floats,
//! (v: 3, d: 1, s_f: 1, s_b: 1, i: 1) = 28 floats per tet. Each tet is drawn as
//! the strip 0,1,2,3,0,1 from an index buffer that is uploaded once into
//! device-local memory and never changes: strips are separated by primitive
//! restart (index 0xFFFFFFFF), so the buffer holds 7 u32 per tet (6 indices +
//! the restart marker). Only the vertex records move when the order changes.

use std::sync::Arc;

use ash::vk as raw;
use rayon::prelude::*;

use super::render;
use crate::algo::method::{MethodInfo, MethodInputs, RenderMethod};
use super::{build_pipeline, cells_f32, CellF32, CellProjector, FrameSetup, Interpolation};
use crate::algo::integrate::IntegrationTables;
use crate::mesh::{TetGeometry, TetMesh};
use crate::vk::{
    upload_static, Buffer, BufferDesc, CommandRecorder, Context, Pipeline, PipelineKey, UploadClass, UploadCounter, VertexAttribute,
    VkResult,
};

pub const FLOATS_PER_VERTEX: usize = 7;
pub const VERTICES_PER_CELL: usize = 4;
pub const FLOATS_PER_CELL: usize = FLOATS_PER_VERTEX * VERTICES_PER_CELL;
/// The strip's 6 indices plus the restart marker.
pub const INDICES_PER_CELL: usize = 7;
pub const STRIP: [u32; 6] = [0, 1, 2, 3, 0, 1];
pub const RESTART: u32 = u32::MAX;

/// The registry entry.
pub const METHOD: MethodInfo = render::method_info(
    "balanced",
    "GPU-CPU balanced cell projection (Moreland 2004): 4 vertices, 28 floats per tet per frame, static strip indices",
    &[
        render::table_6_3("balanced", "bluntfin", 4.50, 187_395),
        render::table_6_3("balanced", "oxygenpost", 2.28, 513_375),
        render::table_6_4("", 0.94),
        render::table_6_4("integrator=average", 1.31),
        render::table_6_4("integrator=linear-exact", 0.08),
    ],
    create,
);

fn create(inputs: MethodInputs) -> anyhow::Result<Box<dyn RenderMethod>> {
    let bytes = render::DeviceBytesPerCell { frame: FLOATS_PER_CELL * 4, fixed: INDICES_PER_CELL * 4 };
    render::CellProjection::create(inputs, bytes, |ctx, mesh, geometry, tables, interpolation, counter| {
        Ok(Box::new(Balanced::new(ctx, mesh, geometry, tables, interpolation, counter)?))
    })
}

/// The vertex record's attributes: position, d, s_f, s_b and the vertex's
/// index in its tet (atfs's pieces use the same record).
pub(super) fn record_attributes() -> [VertexAttribute; 5] {
    let f = |location, format, floats: u32| VertexAttribute { location, format, offset: floats * 4 };
    [
        f(0, raw::Format::R32G32B32_SFLOAT, 0),
        f(1, raw::Format::R32_SFLOAT, 3),
        f(2, raw::Format::R32_SFLOAT, 4),
        f(3, raw::Format::R32_SFLOAT, 5),
        f(4, raw::Format::R32_SFLOAT, 6),
    ]
}

pub struct Balanced {
    cells: Vec<CellF32>,
    packed: Vec<f32>,
    vertex_buffer: Buffer,
    index_buffer: Buffer,
    pipeline: Arc<Pipeline>,
    pipeline_key: PipelineKey,
    /// Cells in the last `pack`.
    drawn: usize,
}

/// The static index data: tet slot k's strip over vertices 4k..4k+3.
pub fn strip_indices(cells: usize) -> Vec<u32> {
    let mut idx = Vec::with_capacity(cells * INDICES_PER_CELL);
    for k in 0..cells as u32 {
        idx.extend(STRIP.iter().map(|&i| 4 * k + i));
        idx.push(RESTART);
    }
    idx
}

/// Balanced-ProjectTet's CPU half for one tet: 4 records of 7 floats,
/// (v, d, s_f, s_b, i); with exact perspective interpolation the two
/// view-dependent slots hold u and g.(v - eye) instead (see `Interpolation`).
#[inline]
pub fn cell_records(c: &CellF32, frame: &FrameSetup, out: &mut [f32]) {
    if frame.exact_perspective() {
        let e = frame.eye;
        for i in 0..4 {
            let p = c.pos[i];
            let rel = [p[0] - e[0], p[1] - e[1], p[2] - e[2]];
            let u = frame.perspective_plane_ratio(c.plane3[i], rel);
            let g = c.gradient;
            let g_rel = g[0] * rel[0] + g[1] * rel[1] + g[2] * rel[2];
            out[i * 7..i * 7 + 7].copy_from_slice(&[p[0], p[1], p[2], u, c.scalar[i], g_rel, i as f32]);
        }
        return;
    }
    for i in 0..4 {
        let p = c.pos[i];
        let dir = frame.ray_direction(p);
        let d = frame.distance_to_opposite_plane(c.plane3[i], dir);
        let g = c.gradient;
        let sb = c.scalar[i] + (dir[0] * g[0] + dir[1] * g[1] + dir[2] * g[2]) * d;
        out[i * 7..i * 7 + 7].copy_from_slice(&[p[0], p[1], p[2], d, c.scalar[i], sb, i as f32]);
    }
}

/// The per-frame CPU work: records of the cells in `order`, written to `out`
/// (28 floats per cell), in parallel.
pub fn pack_records(cells: &[CellF32], order: &[u32], frame: &FrameSetup, out: &mut [f32]) {
    out.par_chunks_mut(FLOATS_PER_CELL)
        .zip(order.par_iter())
        .with_min_len(4096)
        .for_each(|(dst, &t)| cell_records(&cells[t as usize], frame, dst));
}

impl Balanced {
    pub fn new(
        ctx: &Arc<Context>,
        mesh: &TetMesh,
        geometry: &TetGeometry,
        tables: &IntegrationTables,
        interpolation: Interpolation,
        counter: &mut UploadCounter,
    ) -> VkResult<Self> {
        let cells = cells_f32(mesh, geometry);
        let n = cells.len();
        let index_buffer = upload_static(
            ctx,
            "balanced strip indices",
            bytemuck::cast_slice(&strip_indices(n)),
            raw::BufferUsageFlags::INDEX_BUFFER,
            counter,
        )?;
        let bytes = (n * FLOATS_PER_CELL * 4) as u64;
        let vertex_buffer =
            Buffer::new(ctx, BufferDesc::upload("balanced vertex records", bytes, raw::BufferUsageFlags::VERTEX_BUFFER))?;
        let (pipeline, pipeline_key) = build_pipeline(
            ctx,
            "cell_projection/balanced.vert",
            "cell_projection/balanced.frag",
            (FLOATS_PER_VERTEX * 4) as u32,
            &record_attributes(),
            raw::PrimitiveTopology::TRIANGLE_STRIP,
            true,
            tables,
            interpolation,
            &[],
        )?;
        Ok(Balanced { packed: vec![0f32; n * FLOATS_PER_CELL], cells, vertex_buffer, index_buffer, pipeline, pipeline_key, drawn: n })
    }
}

impl CellProjector for Balanced {
    fn cells(&self) -> usize {
        self.cells.len()
    }
    fn vertices_per_cell(&self) -> usize {
        VERTICES_PER_CELL
    }
    fn floats_per_cell(&self) -> usize {
        FLOATS_PER_CELL
    }
    fn pipeline_key(&self) -> &PipelineKey {
        &self.pipeline_key
    }

    fn drawn(&self) -> usize {
        self.drawn
    }

    fn pack(&mut self, order: &[u32], frame: &FrameSetup) {
        self.drawn = order.len().min(self.cells.len());
        pack_records(&self.cells, &order[..self.drawn], frame, &mut self.packed[..self.drawn * FLOATS_PER_CELL]);
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> VkResult<()> {
        let packed = &self.packed[..self.drawn * FLOATS_PER_CELL];
        self.vertex_buffer.write(0, bytemuck::cast_slice(packed), counter, UploadClass::FrameCells)
    }

    fn record_draw(&self, rec: &CommandRecorder, tables: &IntegrationTables, frame: &FrameSetup, counter: &mut UploadCounter) -> VkResult<()> {
        rec.bind_pipeline(&self.pipeline, Some(&tables.set));
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&frame.constants), counter);
        rec.bind_vertex_buffer(&self.vertex_buffer);
        rec.bind_index_buffer_u32(&self.index_buffer);
        rec.draw_indexed((self.drawn * INDICES_PER_CELL) as u32);
        Ok(())
    }
}
