//! GPU-CPU balanced cell projection (Moreland 2004, thesis §4.2): the CPU runs
//! IntersectBackFace per vertex per frame and sends 4 records of 7 floats,
//! (v: 3, d: 1, s_f: 1, s_b: 1, code: 1) = 28 floats per tet. Each tet's four
//! faces are drawn from an index buffer that is uploaded once into
//! device-local memory and never changes: the thesis's strip 0,1,2,3,0,1
//! with primitive restart (7 u32 per tet), or the same faces as a triangle
//! list (12 u32 per tet, the default; `Primitives`). Only the vertex records
//! move when the order changes.
//!
//! Host memory (issue 22 item 3, docs/scaling.md): the records of the first
//! `PACK_AHEAD_BYTES` of the order are packed in `prepare`, while the device
//! draws the previous frame; the rest are packed straight into the vertex
//! buffers in `upload`, after that draw is done. So the host copy of the
//! records is bounded whatever the mesh size (meshes up to ~600 K tets are
//! packed wholly ahead, as before), and each cell keeps its planes and
//! gradient only (`PlanesTable`), its vertices gathered from the relative
//! mesh culling and the near caps share.

use std::sync::Arc;

use rayon::prelude::*;

use super::render;
use crate::algo::method::{MethodInfo, MethodInputs, RenderMethod};
use super::{build_pipeline, CellF32, CellProjector, DrawSettings, PlanesTable, RelativeMesh, StaticIndices, MAX_INDICES_PER_CELL};
use crate::algo::tet_mesh::{render_origin, FrameSetup, Interpolation};
use crate::algo::chunks::{ChunkLimits, VertexChunks};
use crate::algo::host_memory::HostMemory;
use crate::algo::integrate::IntegrationTables;
use crate::mesh::TetMesh;
use crate::vk::{
    CommandRecorder, Context, Pipeline, PipelineKey, UploadClass, UploadCounter, VertexAttribute,
    VkResult,
};
use crate::vk::Format;

pub const FLOATS_PER_VERTEX: usize = 7;
pub const VERTICES_PER_CELL: usize = 4;
pub const FLOATS_PER_CELL: usize = FLOATS_PER_VERTEX * VERTICES_PER_CELL;

/// The registry entry; the suite also runs the thesis's strip indices, so
/// the report sets the two index layouts side by side in one run, and the
/// exact visibility order (MPVO): the centroid order's mistakes move a
/// pixel's colour, never its opacity, and on a transfer function with
/// control points inside cells they can cancel part of the integrator's own
/// error (docs/methods.md, "Sorting"), so the exactly ordered run
/// is the fair yardstick for the methods that never sort.
pub const METHOD: MethodInfo = MethodInfo { suite: &["primitives=strip", "sort=mpvo"], ..BALANCED };
const BALANCED: MethodInfo = render::method_info(
    "balanced",
    "GPU-CPU balanced cell projection (Moreland 2004): 4 vertices, 28 floats per tet per frame, static indices",
    render::KNOWN_EXITS_OPTIONS,
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
    // The records are split at the device's limits (one piece per draw).
    // Host: the planes table (60) and the order past the pack-ahead budget (4).
    let bytes = render::DeviceBytesPerCell { frame: 0, fixed: FLOATS_PER_CELL * 4 + MAX_INDICES_PER_CELL * 4, host: 64 };
    let crate::algo::method::SceneData::TetMesh { mesh } = inputs.data else {
        anyhow::bail!("cell projection renders tetrahedral meshes only");
    };
    let relative = RelativeMesh::new(mesh, render_origin(mesh));
    let shared = relative.clone();
    render::CellProjection::create_sharing(inputs, bytes, relative, move |ctx, mesh, tables, draw, counter| {
        Ok(Box::new(Balanced::new(ctx, mesh, shared, tables, draw, counter)?))
    })
}

/// Host bytes of records packed ahead of the draw (see the module
/// documentation): 599,186 cells.
pub const PACK_AHEAD_BYTES: usize = 64 << 20;

/// Test knob (tests only, docs/scaling.md): `VOLBENCH_TEST_PACK_AHEAD_BYTES=N`
/// packs at most N bytes of records ahead, so a small mesh takes the path a
/// large one does.
pub const PACK_AHEAD_VAR: &str = crate::switches::TEST_PACK_AHEAD_BYTES;

/// Cells packed ahead: `PACK_AHEAD_BYTES` or the knob's bytes, in records.
fn pack_ahead_cells() -> VkResult<usize> {
    let bytes = match crate::switches::int(PACK_AHEAD_VAR)? {
        None => PACK_AHEAD_BYTES,
        Some(n) => usize::try_from(n).unwrap_or(usize::MAX),
    };
    Ok(bytes / (FLOATS_PER_CELL * 4))
}

/// The vertex record's attributes: position, d, s_f, s_b and the vertex's
/// index in its tet (atfs's pieces use the same record).
pub(super) fn record_attributes() -> [VertexAttribute; 5] {
    let f = |location, format, floats: u32| VertexAttribute { location, format, offset: floats * 4 };
    [
        f(0, Format::Rgb32Float, 0),
        f(1, Format::R32Float, 3),
        f(2, Format::R32Float, 4),
        f(3, Format::R32Float, 5),
        f(4, Format::R32Float, 6),
    ]
}

/// The draw of balanced's records (vertex buffers of 4 records per tet,
/// `balanced.vert` + `balanced.frag`); resident draws the records its
/// compute pass writes with it too.
pub(super) fn records_pipeline(ctx: &Arc<Context>, tables: &IntegrationTables, draw: DrawSettings) -> VkResult<(Arc<Pipeline>, PipelineKey)> {
    build_pipeline(
        ctx,
        "cell_projection/balanced.vert",
        "cell_projection/balanced.frag",
        (FLOATS_PER_VERTEX * 4) as u32,
        &record_attributes(),
        draw.primitives.topology(),
        draw.primitives.primitive_restart(),
        tables,
        &draw,
        &[],
        &[],
    )
}

/// Vertex buffers for `count` cells' (or ATFS's pieces') 4 records, split
/// at the device's limits (one draw per buffer), and the static indices
/// of one draw, which every draw uses from their start.
pub(super) fn split_records(
    ctx: &Arc<Context>,
    name: &str,
    count: usize,
    draw: DrawSettings,
    counter: &mut UploadCounter,
) -> VkResult<(StaticIndices, VertexChunks)> {
    let limits = ChunkLimits::of(ctx)?;
    // A draw's index values and count are u32 (the top value is the
    // primitive-restart marker).
    let per_draw = limits
        .allocation_chunk((FLOATS_PER_CELL * 4) as u64)
        .min(limits.allocation_chunk(4 * draw.primitives.indices_per_cell() as u64))
        .min((u32::MAX as usize - 1) / MAX_INDICES_PER_CELL)
        .max(1);
    let indices = StaticIndices::upload(ctx, &format!("{name} indices"), draw.primitives, count.min(per_draw), counter)?;
    let records = VertexChunks::new(ctx, &format!("{name} vertex records"), count, FLOATS_PER_CELL * 4, per_draw)?;
    Ok((indices, records))
}

pub struct Balanced {
    cells: PlanesTable,
    /// The records of the order's first `ahead.len() / FLOATS_PER_CELL`
    /// cells, packed in `prepare` (at most `pack_ahead_cells()`).
    ahead: Vec<f32>,
    ahead_cells: usize,
    /// The rest of the order, packed in `upload` with `frame`.
    rest: Vec<u32>,
    frame: Option<FrameSetup>,
    /// The records in pieces (one buffer holds at most
    /// maxMemoryAllocationSize bytes), drawn one draw each, in order.
    vertex_buffers: VertexChunks,
    indices: StaticIndices,
    pipeline: Arc<Pipeline>,
    pipeline_key: PipelineKey,
    /// Cells in the last `pack`.
    drawn: usize,
}

/// The record's last float codes, exactly in f32, `i | exits << 2 | flags
/// << 6 | piece << 8`: the vertex's index i in the tet, the tet's exit mask
/// (bit k: the plane opposite vertex k is an exit plane for the rays through
/// the tet, see `exit_mask`), and for atfs's pieces their flags and
/// transfer-function interval (`shaders/cell_projection/record.glsl`).
pub const CODE_EXITS_SHIFT: u32 = 2;
pub const CODE_FLAGS_SHIFT: u32 = 6;
pub const CODE_PIECE_SHIFT: u32 = 8;
/// Pieces (intervals) a code can name and stay exact in f32 (2^24).
pub const CODE_MAX_PIECES: u32 = 1 << (24 - CODE_PIECE_SHIFT);

/// The tet's exit mask from the view-dependent value c_k at each vertex k
/// (the ray-plane distance t_k, or the plane ratio u_k with exact
/// perspective; `limit` is its clamp). Plane k is an exit plane for every
/// ray through the tet when 0 < c_k < limit / 2 (the ray meets it ahead; a
/// value at the clamp means a ray parallel to the plane or the eye in it,
/// which never crosses it): a property of the tet and the eye, not of the
/// fragment. The fragment stage used to recover it from interpolated values
/// and their screen-space derivatives (`exit_planes` in
/// `shaders/common/exit.glsl`, still VICP's rule); known
/// per tet, it costs the fragment nothing and rounding cannot flip it.
#[inline]
pub fn exit_mask(c: [f32; 4], limit: f32) -> u32 {
    let half = 0.5 * limit;
    (0..4).fold(0, |m, k| m | (u32::from(c[k] > 0.0 && c[k] < half) << k))
}

/// Balanced-ProjectTet's CPU half for one tet: 4 records of 7 floats,
/// (v, c, s_f, b, code): c is the vertex's ray-plane distance t (or, with
/// exact perspective interpolation, the plane ratio u; see
/// `Interpolation`); b is the scalar s_b where the ray through the vertex
/// meets the opposite plane (`paper` interpolation), or with exact
/// interpolation the gradient term that gives the exit scalar anywhere on
/// the face, g.(v - eye) under perspective and g.view_dir orthographic;
/// code as `CODE_EXITS_SHIFT` describes, with piece 0.
#[inline]
pub fn cell_records(c: &CellF32, frame: &FrameSetup, out: &mut [f32]) {
    let g = c.gradient;
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut value = [0f32; 4];
    let mut slot = [0f32; 4];
    let limit;
    if frame.exact_perspective() {
        let e = frame.eye;
        for i in 0..4 {
            let p = c.pos[i];
            let rel = [p[0] - e[0], p[1] - e[1], p[2] - e[2]];
            value[i] = frame.perspective_plane_ratio(c.plane3[i], rel);
            slot[i] = dot(g, rel);
        }
        limit = frame.plane_ratio_max;
    } else {
        let exact = frame.interpolation == Interpolation::Exact;
        for i in 0..4 {
            let dir = frame.ray_direction(c.pos[i]);
            let d = frame.distance_to_opposite_plane(c.plane3[i], dir);
            value[i] = d;
            slot[i] = if exact { dot(g, dir) } else { c.scalar[i] + dot(dir, g) * d };
        }
        limit = frame.max_distance;
    }
    let exits = exit_mask(value, limit) << CODE_EXITS_SHIFT;
    for i in 0..4 {
        let p = c.pos[i];
        let code = (i as u32 | exits) as f32;
        out[i * 7..i * 7 + 7].copy_from_slice(&[p[0], p[1], p[2], value[i], c.scalar[i], slot[i], code]);
    }
}

/// The per-frame CPU work: records of the cells in `order`, written to `out`
/// (28 floats per cell), in parallel.
pub fn pack_records(cells: &PlanesTable, order: &[u32], frame: &FrameSetup, out: &mut [f32]) {
    out.par_chunks_mut(FLOATS_PER_CELL)
        .zip(order.par_iter())
        .with_min_len(4096)
        .for_each(|(dst, &t)| cell_records(&cells.cell(t as usize), frame, dst));
}

impl Balanced {
    pub fn new(
        ctx: &Arc<Context>,
        mesh: &TetMesh,
        relative: Arc<RelativeMesh>,
        tables: &IntegrationTables,
        draw: DrawSettings,
        counter: &mut UploadCounter,
    ) -> VkResult<Self> {
        let cells = PlanesTable::new(mesh, relative)?;
        let n = cells.len();
        let ahead_cells = pack_ahead_cells()?.min(n);
        let (indices, vertex_buffers) = split_records(ctx, "balanced", n, draw, counter)?;
        let (pipeline, pipeline_key) = records_pipeline(ctx, tables, draw)?;
        Ok(Balanced {
            ahead: vec![0f32; ahead_cells * FLOATS_PER_CELL],
            ahead_cells,
            rest: Vec::new(),
            frame: None,
            cells,
            vertex_buffers,
            indices,
            pipeline,
            pipeline_key,
            drawn: n,
        })
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
    fn device_chunks(&self) -> serde_json::Value {
        self.vertex_buffers.describe("cells")
    }

    fn drawn(&self) -> usize {
        self.drawn
    }

    fn host_bytes(&self, memory: &mut HostMemory) {
        self.cells.host_bytes(memory);
        memory.bounded("projector: records packed ahead (at most PACK_AHEAD_BYTES)", crate::algo::host_memory::vec_bytes(&self.ahead));
        memory.vec("projector: order packed in upload", &self.rest);
    }

    fn pack(&mut self, order: &[u32], frame: &FrameSetup) {
        self.drawn = order.len().min(self.cells.len());
        let ahead = self.drawn.min(self.ahead_cells);
        pack_records(&self.cells, &order[..ahead], frame, &mut self.ahead[..ahead * FLOATS_PER_CELL]);
        self.rest.clear();
        // Exactly the largest rest so far (no amortised doubling).
        self.rest.reserve_exact(self.drawn - ahead);
        self.rest.extend_from_slice(&order[ahead..self.drawn]);
        self.frame = Some(*frame);
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> VkResult<()> {
        let ahead = self.drawn.min(self.ahead_cells);
        for (buffer, range) in self.vertex_buffers.drawn_mut(self.drawn) {
            let (start, end) = (range.start, range.end);
            // The part packed ahead: copied.
            let copied = end.min(ahead).max(start);
            if copied > start {
                let packed = &self.ahead[start * FLOATS_PER_CELL..copied * FLOATS_PER_CELL];
                buffer.write(0, bytemuck::cast_slice(packed), counter, UploadClass::FrameCells)?;
            }
            // The rest: packed straight into the mapped buffer (the device
            // is done with the previous frame's records by now).
            if end > copied {
                let frame = self.frame.as_ref().ok_or_else(|| crate::vk::VkError::Invalid("balanced: upload before pack".into()))?;
                let bytes = buffer.mapped_for_write()?;
                let dst: &mut [f32] = bytemuck::try_cast_slice_mut(bytes)
                    .map_err(|e| crate::vk::VkError::Invalid(format!("balanced vertex records: mapped memory as f32: {e}")))?;
                let out = &mut dst[(copied - start) * FLOATS_PER_CELL..(end - start) * FLOATS_PER_CELL];
                pack_records(&self.cells, &self.rest[copied - ahead..end - ahead], frame, out);
                counter.add_direct(UploadClass::FrameCells, (out.len() * 4) as u64);
            }
        }
        Ok(())
    }

    fn record_draw(&self, rec: &CommandRecorder, tables: &IntegrationTables, frame: &FrameSetup, counter: &mut UploadCounter) -> VkResult<()> {
        rec.bind_pipeline(&self.pipeline, Some(&tables.set));
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&frame.constants), counter);
        // One draw per piece of the sorted records, in order (back-to-front
        // compositing is kept across pieces).
        for (buffer, cells) in self.vertex_buffers.drawn(self.drawn) {
            rec.bind_vertex_buffer(buffer);
            self.indices.draw(rec, cells.len());
        }
        Ok(())
    }
}
