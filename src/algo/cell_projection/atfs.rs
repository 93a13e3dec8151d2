//! Adaptive transfer function sampling (Moreland 2004, thesis §4.3):
//! balanced cell projection plus clipping at the transfer function's
//! control-point isovalues. Partial pre-integration and the exact linear
//! form assume colour and attenuation linear along a cell's segment; where
//! the segment crosses a control point they are not. So each cell is drawn
//! once per transfer-function interval its scalar range overlaps (a
//! "piece"), and the fragment stage clips the ray segment to the piece's
//! scalar interval, where the transfer function is exactly linear.
//!
//! Per piece per frame the CPU sends balanced's 4 records of 7 floats; the
//! last float codes the vertex's index in the tet, the interval's index and
//! whether the piece is the cell's lowest or highest (its outer bound then
//! unbounded, so f32 rounding at the cell's extreme scalars clips nothing).
//! The intervals (bounds, colour and attenuation at the lower bound and
//! their slope) are a small static storage buffer read by the vertex stage.
//! Which intervals a cell overlaps depends only on its scalars, so the
//! piece count, the static strip indices and the device memory are fixed
//! per mesh and transfer function; the order of a cell's pieces depends on
//! the view: along any ray the scalar is linear inside a cell, so pieces
//! are met in the order of their distance in scalar from the value the
//! cell's linear field extrapolates to at the eye, and they are drawn
//! farthest first (back to front, like the cells).
//!
//! The packed pieces are split at the device's limits (`algo::chunks`, as
//! balanced's records): one vertex buffer and one draw per run of pieces,
//! in order (a cell's pieces may straddle two draws; the draws keep the
//! order).

use std::sync::Arc;

use anyhow::{ensure, Context as _, Result};
use rayon::prelude::*;

use super::balanced::{
    cell_records, CODE_FLAGS_SHIFT, CODE_MAX_PIECES, CODE_PIECE_SHIFT, FLOATS_PER_CELL, FLOATS_PER_VERTEX, VERTICES_PER_CELL};
use super::render;
use super::{build_pipeline, cells_f32, CellF32, CellProjector, DrawSettings, StaticIndices, MAX_INDICES_PER_CELL};
use crate::algo::tet_mesh::{scalar_map, FrameSetup};
use crate::algo::chunks::VertexChunks;
use crate::algo::host_memory::HostMemory;
use crate::algo::integrate::IntegrationTables;
use crate::algo::method::{MethodInfo, MethodInputs, Published, PublishedFigure, RenderMethod};
use crate::mesh::TetMesh;
use crate::scene::transfer_function::TABLE_MAX;
use crate::scene::TransferFunction;
use crate::vk::{
    upload_static, Buffer, CommandRecorder, Context, DescriptorSet, DescriptorSetDesc, Pipeline, PipelineKey,
    StorageBufferSet, UploadCounter, VkError, VkResult,
};
use crate::vk::{BufferUsage, Stages};

/// Floats per drawn piece per frame: balanced's record.
pub const FLOATS_PER_PIECE: usize = FLOATS_PER_CELL;
/// Intervals a vertex code can name (`balanced::CODE_PIECE_SHIFT`: the code
/// is i | exits << 2 | flags << 6 | j << 8 in an f32, exact below 2^24).
pub const MAX_INTERVALS: usize = CODE_MAX_PIECES as usize;
/// Flags of the code: the piece is its cell's lowest / highest.
const LOWEST: u32 = 1;
const HIGHEST: u32 = 2;
/// The bound of the outer intervals (scalars reach the device mapped to
/// [0, 1]; `atfs.vert` uses the same value).
const UNBOUNDED: f32 = 1e30;

const TABLE_6_2_SOURCE: &str = "Moreland, PhD thesis 2004, Table 6.2 (tets rendered with adaptive transfer function sampling)";
const TABLE_6_2_NOTE: &str = "How many pieces a cell makes depends on how many control points the transfer function \
    has and where they fall in the mesh's scalar range: the thesis's transfer functions are not ours (the presets in \
    src/harness/datasets.rs), so the growth is set beside the thesis's as a count of the same kind, not as a \
    reproduction.";

/// Thesis Table 6.2 (tets rendered) and Table 6.3 (frame rate; the thesis
/// ran this method with average colour and attenuation, the other two with
/// pre-integration; its tets per second, 327 K and 397 K, count pieces:
/// 1.312 x 249,278 and 0.599 x 662,625).
const PUBLISHED: &[Published] = &[
    render::table_6_3("atfs", "bluntfin", 1.312, 187_395),
    render::table_6_3("atfs", "oxygenpost", 0.599, 513_375),
    Published {
        method: "atfs",
        dataset: Some("bluntfin"),
        options: "",
        figure: PublishedFigure::CellsRendered { rendered: 249_278, cells: 187_395 },
        source: TABLE_6_2_SOURCE,
        note: TABLE_6_2_NOTE,
    },
    Published {
        method: "atfs",
        dataset: Some("oxygenpost"),
        options: "",
        figure: PublishedFigure::CellsRendered { rendered: 662_625, cells: 513_375 },
        source: TABLE_6_2_SOURCE,
        note: TABLE_6_2_NOTE,
    },
];

/// The registry entry.
pub const METHOD: MethodInfo = render::method_info(
    "atfs",
    "adaptive transfer function sampling (Moreland 2004): balanced cell projection drawn once per transfer-function \
     interval a cell spans, segments clipped at control-point isovalues (28 floats per piece)",
    render::KNOWN_EXITS_OPTIONS,
    PUBLISHED,
    create,
);

/// One transfer-function interval as the vertex stage reads it
/// (`Interval` in `atfs.vert`), scalars in the device's units (`scalar_map`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct IntervalGpu {
    /// Colour and attenuation at scalar `bounds[2]`.
    pub base: [f32; 4],
    /// Their change per unit scalar.
    pub slope: [f32; 4],
    /// Lowest and highest scalar, the scalar of `base`, unused.
    pub bounds: [f32; 4],
}

/// The transfer function cut at its control points: `breaks` are the
/// distinct control-point scalars in device units (ascending); interval j
/// runs from `breaks[j - 1]` to `breaks[j]` (unbounded below for j = 0 and
/// above for j = breaks.len()), and the transfer function is linear on it.
#[derive(Debug, Clone)]
pub struct Intervals {
    pub breaks: Vec<f32>,
    pub gpu: Vec<IntervalGpu>,
}

impl Intervals {
    /// `tf` over scalars mapped as (s - origin) / scale (the mesh's
    /// `scalar_map`, as every scalar the device sees).
    pub fn new(tf: &TransferFunction, origin: f64, scale: f64) -> Result<Self> {
        ensure!(scale > 0.0 && scale.is_finite(), "transfer function '{}': scalar scale {scale} is not positive", tf.name);
        let map = |s: f64| (s - origin) / scale;
        // Distinct breaks in f32 (what the fragment stage compares with),
        // each with the first and last control-point scalar that rounds to it.
        let mut groups: Vec<(f32, f64, f64)> = Vec::new();
        for p in &tf.points {
            ensure!(p.scalar.is_finite(), "transfer function '{}': a control point's scalar is not finite", tf.name);
            let b = map(p.scalar) as f32;
            ensure!(b.is_finite(), "transfer function '{}': control point at {} is out of f32 range once mapped", tf.name, p.scalar);
            match groups.last_mut() {
                Some(g) if g.0 == b => g.2 = p.scalar,
                Some(g) if g.0 > b => anyhow::bail!("transfer function '{}': control points are not sorted by scalar", tf.name),
                _ => groups.push((b, p.scalar, p.scalar)),
            }
        }
        ensure!(
            groups.len() < MAX_INTERVALS,
            "transfer function '{}': {} distinct control points, more than adaptive transfer function sampling codes ({})",
            tf.name,
            groups.len(),
            MAX_INTERVALS - 1
        );
        let clamp = |v: f64| v.clamp(-TABLE_MAX, TABLE_MAX) as f32;
        let value = |(c, tau): ([f64; 3], f64)| [c[0], c[1], c[2], tau];
        let constant = |v: [f64; 4], at: f32| IntervalGpu { base: v.map(clamp), slope: [0.0; 4], bounds: [-UNBOUNDED, UNBOUNDED, at, 0.0] };
        let mut gpu = Vec::with_capacity(groups.len() + 1);
        // Below the first point: its value (`piece_at` is right-continuous,
        // so the constant below is the first point itself).
        gpu.push(constant(value(tf.piece_at(f64::NEG_INFINITY).eval(0.0)), 0.0));
        for w in groups.windows(2) {
            let ((b0, _, last0), (b1, first1, _)) = (w[0], w[1]);
            // Right limit at the lower break, left limit at the upper one.
            let piece = tf.piece_at(last0);
            let lower = value(piece.eval(last0));
            let upper = value(piece.eval(first1));
            let width = map(first1) - map(last0);
            let slope = std::array::from_fn(|k| if width > 0.0 { (upper[k] - lower[k]) / width } else { 0.0 });
            gpu.push(IntervalGpu { base: lower.map(clamp), slope: slope.map(clamp), bounds: [b0, b1, b0, 0.0] });
        }
        if let Some(&(b, _, last)) = groups.last() {
            let mut top = constant(value(tf.eval(last)), b);
            top.bounds[0] = b;
            gpu.push(top);
            gpu[0].bounds[1] = groups[0].0;
        }
        Ok(Intervals { breaks: groups.iter().map(|g| g.0).collect(), gpu })
    }

    /// The interval holding scalar `s` (lo <= s < hi).
    fn index_of(&self, s: f32) -> usize {
        self.breaks.partition_point(|&b| b <= s)
    }

    /// The intervals a cell with these scalars overlaps, [first, last]: the
    /// one holding the lowest scalar up to the one whose interior or upper
    /// bound holds the highest (a cell touching a break from below does not
    /// reach the interval above it).
    pub fn span(&self, scalars: &[f32; 4]) -> (u32, u32) {
        let lo = scalars.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = scalars.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let first = self.index_of(lo);
        let last = self.breaks.partition_point(|&b| b < hi).max(first);
        (first as u32, last as u32)
    }
}

fn create(inputs: MethodInputs) -> Result<Box<dyn RenderMethod>> {
    let crate::algo::method::SceneData::TetMesh { mesh, .. } = inputs.data else {
        anyhow::bail!("adaptive transfer function sampling renders tetrahedral meshes only");
    };
    let (origin, scale) = scalar_map(mesh);
    let intervals = Intervals::new(inputs.tf, origin, scale).with_context(|| format!("mesh '{}'", mesh.name))?;
    // The pieces depend on the scalars only: count them before allocating.
    let spans: Vec<(u32, u32)> = mesh
        .tets
        .par_iter()
        .map(|t| intervals.span(&t.map(|i| ((mesh.scalars[i as usize] - origin) / scale) as f32)))
        .collect();
    let pieces: u64 = spans.iter().map(|&(a, b)| u64::from(b - a) + 1).sum();
    // (Any number of pieces: they are drawn in runs whose indices fit a
    // u32, `balanced::split_records`.)
    let n = mesh.tets.len().max(1) as u64;
    let per_cell = |bytes_per_piece: u64| pieces.saturating_mul(bytes_per_piece).div_ceil(n) as usize;
    // The pieces' records are split at the device's limits (one run of
    // pieces per draw), so none must fit one allocation.
    // Host: f32 cells, spans, offsets and the packed pieces.
    let host = std::mem::size_of::<CellF32>() + std::mem::size_of::<(u32, u32)>() + std::mem::size_of::<usize>();
    let bytes = render::DeviceBytesPerCell {
        frame: 0,
        fixed: per_cell(((FLOATS_PER_PIECE + MAX_INDICES_PER_CELL) * 4) as u64),
        host: host + per_cell((FLOATS_PER_PIECE * 4) as u64),
    };
    let pieces = pieces as usize;
    render::CellProjection::create(inputs, bytes, move |ctx, mesh, tables, draw, counter| {
        Ok(Box::new(Atfs::new(ctx, mesh, tables, draw, intervals, spans, pieces, counter)?))
    })
}

pub struct Atfs {
    cells: Vec<CellF32>,
    intervals: Intervals,
    /// Per cell: the first and last interval it overlaps.
    spans: Vec<(u32, u32)>,
    pieces: usize,
    /// Per draw slot: the first piece of the cell drawn there (this frame).
    offsets: Vec<usize>,
    /// Cells and pieces the last `pack` wrote (`cull` may leave cells out).
    drawn: usize,
    drawn_pieces: usize,
    packed: Vec<f32>,
    /// The packed pieces in runs (one buffer holds at most
    /// maxMemoryAllocationSize bytes), one draw each.
    vertex_buffers: VertexChunks,
    indices: StaticIndices,
    _interval_buffer: Buffer,
    set: StorageBufferSet,
    pipeline: Arc<Pipeline>,
    pipeline_key: PipelineKey,
}

/// The order in which a cell's pieces `first..=last` are drawn (back to
/// front) for a view whose eye sees the cell's linear field at `s_eye`:
/// along every ray the scalar moves away from `s_eye`, so pieces on either
/// side of it are met nearest first; the piece holding `s_eye` (clamped to
/// the span) is met first on every ray through it and is drawn last. Rays
/// go one way only, so the two sides' relative order does not matter.
pub fn piece_order(first: u32, last: u32, holding_eye: u32, mut emit: impl FnMut(u32)) {
    let e = holding_eye.clamp(first, last);
    (first..e).for_each(&mut emit);
    (e + 1..=last).rev().for_each(&mut emit);
    emit(e);
}

fn piece_flags(j: u32, first: u32, last: u32) -> u32 {
    (if j == first { LOWEST } else { 0 }) | if j == last { HIGHEST } else { 0 }
}

impl Atfs {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        ctx: &Arc<Context>,
        mesh: &TetMesh,
        tables: &IntegrationTables,
        draw: DrawSettings,
        intervals: Intervals,
        spans: Vec<(u32, u32)>,
        pieces: usize,
        counter: &mut UploadCounter,
    ) -> VkResult<Self> {
        let cells = cells_f32(mesh);
        if spans.len() != cells.len() {
            return Err(VkError::Invalid(format!("atfs: {} spans for {} cells", spans.len(), cells.len())));
        }
        let usage = BufferUsage::STORAGE;
        let interval_buffer = upload_static(ctx, "atfs intervals", bytemuck::cast_slice(&intervals.gpu), usage, counter)?;
        let set = StorageBufferSet::new(ctx, "atfs intervals", &[&interval_buffer], Stages::VERTEX)?;
        let (indices, vertex_buffers) = super::balanced::split_records(ctx, "atfs", pieces, draw, counter)?;
        let (pipeline, pipeline_key) = build_pipeline(
            ctx,
            "cell_projection/atfs.vert",
            "cell_projection/atfs.frag",
            (FLOATS_PER_VERTEX * 4) as u32,
            &super::balanced::record_attributes(),
            draw.primitives.topology(),
            draw.primitives.primitive_restart(),
            tables,
            &draw,
            &[DescriptorSetDesc::storage_buffers(1, Stages::VERTEX)],
            &[],
        )?;
        Ok(Atfs {
            offsets: vec![0; cells.len()],
            drawn: cells.len(),
            drawn_pieces: pieces,
            packed: vec![0f32; pieces * FLOATS_PER_PIECE],
            cells,
            intervals,
            spans,
            pieces,
            vertex_buffers,
            indices,
            _interval_buffer: interval_buffer,
            set,
            pipeline,
            pipeline_key,
        })
    }

    /// The scalar the cell's linear field takes at the eye (orthographic:
    /// beyond either end, by the sign of the gradient along the view).
    fn scalar_at_eye(c: &CellF32, frame: &FrameSetup) -> f32 {
        let g = c.gradient;
        if frame.perspective {
            let (p, e) = (c.pos[0], frame.eye);
            c.scalar[0] + g[0] * (e[0] - p[0]) + g[1] * (e[1] - p[1]) + g[2] * (e[2] - p[2])
        } else {
            let v = frame.view_dir;
            if g[0] * v[0] + g[1] * v[1] + g[2] * v[2] < 0.0 {
                f32::INFINITY
            } else {
                f32::NEG_INFINITY
            }
        }
    }

    /// One cell's pieces, back to front, into `out`.
    fn write_cell(c: &CellF32, (first, last): (u32, u32), intervals: &Intervals, frame: &FrameSetup, out: &mut [f32]) {
        let mut rec = [0f32; FLOATS_PER_PIECE];
        cell_records(c, frame, &mut rec);
        let eye = intervals.index_of(Self::scalar_at_eye(c, frame)).min(u32::MAX as usize) as u32;
        let mut k = 0;
        piece_order(first, last, eye, |j| {
            let flags = piece_flags(j, first, last);
            let dst = &mut out[k * FLOATS_PER_PIECE..(k + 1) * FLOATS_PER_PIECE];
            dst.copy_from_slice(&rec);
            for i in 0..VERTICES_PER_CELL {
                // balanced's code (i and the exit mask) with this piece's.
                let code = &mut dst[i * FLOATS_PER_VERTEX + FLOATS_PER_VERTEX - 1];
                *code = (*code as u32 | flags << CODE_FLAGS_SHIFT | j << CODE_PIECE_SHIFT) as f32;
            }
            k += 1;
        });
    }
}

impl CellProjector for Atfs {
    fn cells(&self) -> usize {
        self.cells.len()
    }
    fn vertices_per_cell(&self) -> usize {
        VERTICES_PER_CELL
    }
    fn floats_per_cell(&self) -> usize {
        FLOATS_PER_PIECE
    }
    fn pieces(&self) -> Option<usize> {
        Some(self.pieces)
    }
    fn drawn(&self) -> usize {
        self.drawn
    }
    fn pieces_drawn(&self) -> usize {
        self.drawn_pieces
    }
    fn host_bytes(&self, memory: &mut HostMemory) {
        memory.vec("projector: f32 cells (CellF32)", &self.cells);
        memory.vec("projector: interval spans", &self.spans);
        memory.vec("projector: piece offsets", &self.offsets);
        memory.vec("projector: packed records", &self.packed);
    }

    fn pipeline_key(&self) -> &PipelineKey {
        &self.pipeline_key
    }
    fn device_chunks(&self) -> serde_json::Value {
        self.vertex_buffers.describe("pieces")
    }
    fn cap_pieces(&self, cell: usize, frame: &FrameSetup, emit: &mut dyn FnMut(u32)) {
        let (c, (first, last)) = (&self.cells[cell], self.spans[cell]);
        let eye = self.intervals.index_of(Self::scalar_at_eye(c, frame)).min(u32::MAX as usize) as u32;
        piece_order(first, last, eye, |j| emit(piece_flags(j, first, last) << CODE_FLAGS_SHIFT | j << CODE_PIECE_SHIFT));
    }
    fn pieces_set(&self) -> Option<&DescriptorSet> {
        Some(&self.set)
    }

    fn pack(&mut self, order: &[u32], frame: &FrameSetup) {
        // `cull` may leave cells out: only the given cells' pieces are
        // written, uploaded and drawn (a prefix of the static strips).
        let order = &order[..order.len().min(self.cells.len())];
        // Where each draw slot's pieces start (a prefix sum in draw order).
        let mut acc = 0usize;
        for (slot, &t) in order.iter().enumerate() {
            self.offsets[slot] = acc;
            let (a, b) = self.spans[t as usize];
            acc += (b - a) as usize + 1;
        }
        // Chunks of slots with the disjoint output ranges they fill.
        const CHUNK: usize = 4096;
        let mut outs = Vec::with_capacity(order.len().div_ceil(CHUNK));
        let mut rest = self.packed.as_mut_slice();
        for start in (0..order.len()).step_by(CHUNK) {
            let end = (start + CHUNK).min(order.len());
            let to = if end < order.len() { self.offsets[end] } else { acc };
            let (out, tail) = std::mem::take(&mut rest).split_at_mut((to - self.offsets[start]) * FLOATS_PER_PIECE);
            outs.push((start, end, out));
            rest = tail;
        }
        self.drawn = order.len();
        self.drawn_pieces = acc;
        let (cells, spans, intervals, offsets) = (&self.cells, &self.spans, &self.intervals, &self.offsets);
        outs.into_par_iter().for_each(|(start, end, out)| {
            let base = offsets[start];
            for slot in start..end {
                let from = (offsets[slot] - base) * FLOATS_PER_PIECE;
                let t = order[slot] as usize;
                Self::write_cell(&cells[t], spans[t], intervals, frame, &mut out[from..]);
            }
        });
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> VkResult<()> {
        self.vertex_buffers.write(&self.packed[..self.drawn_pieces * FLOATS_PER_PIECE], FLOATS_PER_PIECE, counter)
    }

    fn record_draw(&self, rec: &CommandRecorder, tables: &IntegrationTables, frame: &FrameSetup, counter: &mut UploadCounter) -> VkResult<()> {
        let sets: [&DescriptorSet; 2] = [&tables.set, &self.set];
        rec.bind_graphics(&self.pipeline, &sets)?;
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&frame.constants), counter);
        // One draw per run of pieces, in order (back to front across runs).
        for (buffer, pieces) in self.vertex_buffers.drawn(self.drawn_pieces) {
            rec.bind_vertex_buffer(buffer);
            self.indices.draw(rec, pieces.len());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::ControlPoint;

    fn tf(points: &[(f64, f64)]) -> TransferFunction {
        TransferFunction {
            name: "t".into(),
            points: points.iter().map(|&(scalar, tau)| ControlPoint { scalar, color: [tau; 3], attenuation: tau }).collect(),
        }
    }

    #[test]
    fn intervals_are_linear_pieces_with_steps_kept() {
        // A ramp 0 -> 4 over [0, 2], a step at 2 down to 1, flat to 3.
        let i = Intervals::new(&tf(&[(0.0, 0.0), (2.0, 4.0), (2.0, 1.0), (3.0, 1.0)]), 0.0, 4.0).unwrap();
        assert_eq!(i.breaks, vec![0.0, 0.5, 0.75]);
        assert_eq!(i.gpu.len(), 4);
        // Below the first point: constant 0; the ramp: 0 at 0, slope 4 per 0.5 mapped.
        assert_eq!(i.gpu[0].base[3], 0.0);
        assert_eq!(i.gpu[1].bounds[..3], [0.0, 0.5, 0.0]);
        assert_eq!((i.gpu[1].base[3], i.gpu[1].slope[3]), (0.0, 8.0));
        // After the step the value is the last point at 2 (right-continuous).
        assert_eq!((i.gpu[2].base[3], i.gpu[2].slope[3]), (1.0, 0.0));
        assert_eq!((i.gpu[3].base[3], i.gpu[3].bounds[0]), (1.0, 0.75));
        // Spans: a cell inside one interval, one across two breaks, one
        // touching a break from below, a constant cell exactly on a break.
        assert_eq!(i.span(&[0.1, 0.2, 0.3, 0.2]), (1, 1));
        assert_eq!(i.span(&[0.1, 0.6, 0.8, 0.2]), (1, 3));
        assert_eq!(i.span(&[0.1, 0.5, 0.3, 0.2]), (1, 1));
        assert_eq!(i.span(&[0.5; 4]), (2, 2));
        assert!(Intervals::new(&tf(&[(1.0, 0.0), (0.0, 1.0)]), 0.0, 1.0).is_err());
    }

    #[test]
    fn pieces_are_drawn_farthest_from_the_eye_first() {
        let order = |a, b, e| {
            let mut v = Vec::new();
            piece_order(a, b, e, |j| v.push(j));
            v
        };
        // The eye's scalar below the cell: rays go up, the highest piece is farthest.
        assert_eq!(order(2, 5, 0), vec![5, 4, 3, 2]);
        // Above: rays go down.
        assert_eq!(order(2, 5, 9), vec![2, 3, 4, 5]);
        // Inside: both sides before the piece holding the eye, which is drawn last.
        assert_eq!(order(2, 5, 3), vec![2, 5, 4, 3]);
        assert_eq!(order(4, 4, 0), vec![4]);
    }
}
