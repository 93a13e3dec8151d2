//! View-independent cell projection (Weiler, Kraus, Ertl 2002): every tet is
//! sent as 12 vertex records (4 faces x 3 vertices) of 11 floats,
//! (v: 3, s_v: 1, P_v: 3, g: 3, i: 1) = 132 floats; all view-dependent work
//! happens in the vertex stage. Records don't depend on the view, so they are
//! built once; per frame the CPU only gathers them in sorted order. The
//! gathered records are split at the device's limits (`algo::chunks`, as
//! balanced's): one vertex buffer and one draw per piece, in order.

use std::sync::Arc;

use rayon::prelude::*;

use super::render;
use crate::algo::method::{MethodInfo, MethodInputs, RenderMethod};
use super::{build_pipeline, cells_f32, CellProjector, DrawSettings, FACES};
use crate::algo::tet_mesh::FrameSetup;
use crate::algo::chunks::{ChunkLimits, VertexChunks};
use crate::algo::host_memory::HostMemory;
use crate::algo::integrate::IntegrationTables;
use crate::mesh::TetMesh;
use crate::vk::{CommandRecorder, Context, Pipeline, PipelineKey, UploadCounter, VertexAttribute, VkResult};
use crate::vk::{Format, Topology};

pub const FLOATS_PER_VERTEX: usize = 11;
pub const VERTICES_PER_CELL: usize = 12;
pub const FLOATS_PER_CELL: usize = FLOATS_PER_VERTEX * VERTICES_PER_CELL;

/// The registry entry.
pub const METHOD: MethodInfo = render::method_info(
    "vicp",
    "view-independent cell projection (Weiler, Kraus, Ertl 2002): 12 vertices, 132 floats per tet per frame",
    render::OPTIONS,
    &[
        render::table_6_3("vicp", "bluntfin", 3.30, 187_395),
        render::table_6_3("vicp", "oxygenpost", 1.34, 513_375),
    ],
    create,
);

fn create(inputs: MethodInputs) -> anyhow::Result<Box<dyn RenderMethod>> {
    // The records are split at the device's limits (one piece per draw).
    // Host: the view-independent records and this frame's, packed.
    let bytes = render::DeviceBytesPerCell { frame: 0, fixed: FLOATS_PER_CELL * 4, host: 2 * FLOATS_PER_CELL * 4 };
    render::CellProjection::create(inputs, bytes, |ctx, mesh, tables, draw, _counter| {
        Ok(Box::new(Vicp::new(ctx, mesh, tables, &draw)?))
    })
}

pub struct Vicp {
    /// The view-independent records, FLOATS_PER_CELL per tet, in mesh order.
    records: Vec<f32>,
    /// This frame's records in draw order.
    packed: Vec<f32>,
    /// The packed records in pieces (one buffer holds at most
    /// maxMemoryAllocationSize bytes), one draw each.
    vertex_buffers: VertexChunks,
    pipeline: Arc<Pipeline>,
    pipeline_key: PipelineKey,
    cells: usize,
    /// Cells in the last `pack`.
    drawn: usize,
}

/// The 12 records of one tet.
pub fn cell_records(c: &super::CellF32, out: &mut [f32]) {
    let mut w = 0;
    for face in FACES {
        for (i, &v) in face.iter().enumerate() {
            let rec = [
                c.pos[v][0], c.pos[v][1], c.pos[v][2],
                c.scalar[v],
                c.plane3[v][0], c.plane3[v][1], c.plane3[v][2],
                c.gradient[0], c.gradient[1], c.gradient[2],
                i as f32,
            ];
            out[w..w + FLOATS_PER_VERTEX].copy_from_slice(&rec);
            w += FLOATS_PER_VERTEX;
        }
    }
}

impl Vicp {
    pub fn new(
        ctx: &Arc<Context>,
        mesh: &TetMesh,
        tables: &IntegrationTables,
        draw: &DrawSettings,
    ) -> VkResult<Self> {
        let cells = cells_f32(mesh);
        let n = cells.len();
        let mut records = vec![0f32; n * FLOATS_PER_CELL];
        records.par_chunks_mut(FLOATS_PER_CELL).zip(cells.par_iter()).for_each(|(out, c)| cell_records(c, out));
        let per_draw = ChunkLimits::of(ctx)?.allocation_chunk((FLOATS_PER_CELL * 4) as u64).max(1);
        let vertex_buffers = VertexChunks::new(ctx, "vicp vertex records", n, FLOATS_PER_CELL * 4, per_draw)?;
        let f = |location, format, floats: u32| VertexAttribute { location, format, offset: floats * 4 };
        let attributes = [
            f(0, Format::Rgb32Float, 0),
            f(1, Format::R32Float, 3),
            f(2, Format::Rgb32Float, 4),
            f(3, Format::Rgb32Float, 7),
            f(4, Format::R32Float, 10),
        ];
        let (pipeline, pipeline_key) = build_pipeline(
            ctx,
            "cell_projection/vicp.vert",
            "cell_projection/vicp.frag",
            (FLOATS_PER_VERTEX * 4) as u32,
            &attributes,
            Topology::TriangleList,
            false,
            tables,
            draw,
            &[],
            &[],
        )?;
        Ok(Vicp { packed: vec![0f32; records.len()], records, vertex_buffers, pipeline, pipeline_key, cells: n, drawn: n })
    }
}

impl CellProjector for Vicp {
    fn cells(&self) -> usize {
        self.cells
    }
    fn vertices_per_cell(&self) -> usize {
        VERTICES_PER_CELL
    }
    fn floats_per_cell(&self) -> usize {
        FLOATS_PER_CELL
    }
    fn host_bytes(&self, memory: &mut HostMemory) {
        memory.vec("projector: view-independent records", &self.records);
        memory.vec("projector: packed records", &self.packed);
    }

    fn pipeline_key(&self) -> &PipelineKey {
        &self.pipeline_key
    }
    fn device_chunks(&self) -> serde_json::Value {
        self.vertex_buffers.describe("cells")
    }

    fn drawn(&self) -> usize {
        self.drawn
    }

    fn pack(&mut self, order: &[u32], _frame: &FrameSetup) {
        self.drawn = order.len().min(self.cells);
        let records = &self.records;
        self.packed.par_chunks_mut(FLOATS_PER_CELL).zip(order.par_iter()).for_each(|(dst, &t)| {
            let t = t as usize * FLOATS_PER_CELL;
            dst.copy_from_slice(&records[t..t + FLOATS_PER_CELL]);
        });
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> VkResult<()> {
        self.vertex_buffers.write(&self.packed[..self.drawn * FLOATS_PER_CELL], FLOATS_PER_CELL, counter)
    }

    fn record_draw(&self, rec: &CommandRecorder, tables: &IntegrationTables, frame: &FrameSetup, counter: &mut UploadCounter) -> VkResult<()> {
        rec.bind_pipeline(&self.pipeline, Some(&tables.set));
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&frame.constants), counter);
        // One draw per piece of the sorted records, in order (back-to-front
        // compositing is kept across pieces).
        for (buffer, cells) in self.vertex_buffers.drawn(self.drawn) {
            rec.bind_vertex_buffer(buffer);
            rec.draw((cells.len() * VERTICES_PER_CELL) as u32);
        }
        Ok(())
    }
}
