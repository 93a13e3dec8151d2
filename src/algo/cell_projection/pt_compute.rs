//! Projected tetrahedra in compute (beyond the papers; issue 24): the
//! balanced family's visibility-sorted cells, binned on the CPU into screen
//! tiles in sort order (each tile's list keeps the visibility order), and
//! each tile composited by one compute workgroup, front to back, so that a
//! pixel stops once it is opaque (early termination). Per pixel and cell the
//! segment is balanced's: the pixel's ray is clipped by the tet's four
//! planes, and the barycentric weights where it enters give what the
//! rasterizer interpolates for balanced's entry face
//! (`shaders/cell_projection/pt_composite.comp`). The cells are stored once
//! on the device as `resident` stores them; per frame the tile lists cross
//! (8 bytes per tile entry, 4 per tile). No triangle reaches lavapipe's
//! serial vertex/setup/binning front end (PLATFORM.md): the compositing
//! dispatch runs on every core.

use std::sync::Arc;
use std::time::Instant;

use ash::vk as raw;
use rayon::prelude::*;

use super::balanced::VERTICES_PER_CELL;
use super::render;
use super::resident::{upload_cells, FLOATS_PER_STORED_CELL};
use super::{cells_f32, CellProjector, DrawSettings, FrameConstants, FrameSetup};
use crate::algo::integrate::IntegrationTables;
use crate::algo::method::{MethodInfo, MethodInputs, RenderMethod};
use crate::mesh::{TetGeometry, TetMesh};
use crate::vk::{
    Buffer, BufferDesc, CommandRecorder, ComputePipelineKey, Context, DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc,
    Image, ImageUse, Pipeline, PipelineKey, ShaderKey, ShaderStage, TexelBuffer, TimestampPool, UploadClass, UploadCounter, VkError,
    VkResult,
};

/// A screen tile in pixels: one workgroup of TILE[0] x TILE[1]
/// invocations. llvmpipe runs a workgroup as 8-lane vectors (AVX2) and
/// executes both sides of a branch under a mask, so every tile entry costs
/// each of the tile's vectors the whole per-cell work whether or not its
/// pixels are covered: a tile of one vector (4 x 2) wastes the least
/// (docs/pt-compute.md: what was tried).
pub const TILE: [u32; 2] = [4, 2];
/// Bytes per tile entry: the cell and its pixel box inside the tile.
pub const BYTES_PER_ENTRY: usize = 8;
/// Early termination: a pixel stops once its transmittance is below this.
/// What it leaves out is at most the transmittance times the premultiplied
/// colour and opacity behind, each at most 1 (colours in [0, 1]): at most
/// 1e-5 per channel, a third of the f32 error ppi and linear-exact show
/// against the f64 reference (3.1e-5, `render::accuracy_bound`) and a
/// tenth of the 1e-4 RMSE allowed against balanced.
pub const ERT_TRANSMITTANCE: f32 = 1e-5;
/// The compositing pass's device phase.
pub const COMPOSITE_PHASE: &str = "composite_gpu";
/// The CPU binning inside `pack`.
pub const BIN_PHASE: &str = "bin";

/// The registry entry.
pub const METHOD: MethodInfo = render::method_info(
    "pt-compute",
    "projected tetrahedra in compute: sorted cells binned into screen tiles, each tile composited front to back by one workgroup with early termination",
    render::KNOWN_EXITS_OPTIONS,
    &[],
    create,
);

fn create(inputs: MethodInputs) -> anyhow::Result<Box<dyn RenderMethod>> {
    // Per frame: about two tile entries per cell at 512^2 (measured on the
    // shipped meshes, docs/pt-compute.md); stored: resident's cell.
    let bytes = render::DeviceBytesPerCell { frame: 2 * BYTES_PER_ENTRY, fixed: FLOATS_PER_STORED_CELL * 4 };
    let stages = raw::ShaderStageFlags::FRAGMENT | raw::ShaderStageFlags::COMPUTE;
    render::CellProjection::create_for_stages(inputs, bytes, stages, |ctx, mesh, geometry, tables, draw, counter| {
        Ok(Box::new(PtCompute::new(ctx, mesh, geometry, tables, draw, counter)?))
    })
}

/// Tile lists: tile k's entries are `entries[first[k]..first[k + 1]]`, in
/// the order the cells were given; an entry is (cell, box) with the cell's
/// pixel box inside the tile packed as x0 | y0 << 8 | x1 << 16 | y1 << 24
/// (inclusive).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Bins {
    pub tiles: [u32; 2],
    pub first: Vec<u32>,
    pub entries: Vec<[u32; 2]>,
}

/// The pixels (inclusive, clamped to the image) whose centres a cell with
/// these clip-space vertices can cover, one pixel of margin for rounding;
/// `None` off screen or wholly behind `min_w` (the eye plane the cell
/// pipelines clip at). The part of a cell in front of `min_w` is bounded by
/// its vertices there and its edges' crossings of w = min_w.
pub fn pixel_box(clip: &[[f32; 4]; 4], min_w: f32, size: [u32; 2]) -> Option<[u32; 4]> {
    let mut lo = [f32::INFINITY; 2];
    let mut hi = [f32::NEG_INFINITY; 2];
    let mut add = |p: [f32; 4]| {
        for k in 0..2 {
            let ndc = p[k] / p[3];
            lo[k] = lo[k].min(ndc);
            hi[k] = hi[k].max(ndc);
        }
    };
    for (i, a) in clip.iter().enumerate() {
        if a[3] >= min_w {
            add(*a);
        }
        for b in &clip[i + 1..] {
            if (a[3] - min_w) * (b[3] - min_w) < 0.0 {
                let f = (min_w - a[3]) / (b[3] - a[3]);
                add(std::array::from_fn(|k| a[k] + f * (b[k] - a[k])));
            }
        }
    }
    if lo.iter().chain(&hi).any(|v| v.is_nan()) {
        // Rounding gone wrong somewhere: the whole image, never a lost cell.
        return Some([0, 0, size[0] - 1, size[1] - 1]);
    }
    if lo[0] > hi[0] {
        return None;
    }
    // Pixel i's centre is at NDC 2 (i + 0.5) / n - 1.
    let range = |k: usize| -> Option<[u32; 2]> {
        let n = size[k] as f32;
        let a = ((lo[k] + 1.0) * 0.5 * n - 0.5).floor() - 1.0;
        let b = ((hi[k] + 1.0) * 0.5 * n - 0.5).ceil() + 1.0;
        if b < 0.0 || a > n - 1.0 {
            return None;
        }
        Some([a.max(0.0) as u32, b.min(n - 1.0) as u32])
    };
    let [x0, x1] = range(0)?;
    let [y0, y1] = range(1)?;
    Some([x0, y0, x1, y1])
}

impl Bins {
    /// Bin `boxes` (one per cell slot, `None`: not drawn) into tiles of
    /// `TILE` pixels, each tile's list in slot order; `cell_of(slot)` is the
    /// cell an entry names.
    pub fn build(boxes: &[Option<[u32; 4]>], cell_of: impl Fn(usize) -> u32, size: [u32; 2]) -> Bins {
        let tiles = [size[0].div_ceil(TILE[0]), size[1].div_ceil(TILE[1])];
        let n_tiles = (tiles[0] * tiles[1]) as usize;
        let tile_range = |b: &[u32; 4]| (b[0] / TILE[0], b[1] / TILE[1], b[2] / TILE[0], b[3] / TILE[1]);
        let mut first = vec![0u32; n_tiles + 1];
        for b in boxes.iter().flatten() {
            let (tx0, ty0, tx1, ty1) = tile_range(b);
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    first[(ty * tiles[0] + tx) as usize + 1] += 1;
                }
            }
        }
        for k in 0..n_tiles {
            first[k + 1] += first[k];
        }
        let mut cursor = first.clone();
        let mut entries = vec![[0u32; 2]; first[n_tiles] as usize];
        for (slot, b) in boxes.iter().enumerate() {
            let Some(b) = b else { continue };
            let (tx0, ty0, tx1, ty1) = tile_range(b);
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    let (ox, oy) = (tx * TILE[0], ty * TILE[1]);
                    let local = |v: u32, o: u32, k: usize| v.saturating_sub(o).min(TILE[k] - 1);
                    let packed = local(b[0], ox, 0) | local(b[1], oy, 1) << 8 | local(b[2], ox, 0) << 16 | local(b[3], oy, 1) << 24;
                    let k = (ty * tiles[0] + tx) as usize;
                    entries[cursor[k] as usize] = [cell_of(slot), packed];
                    cursor[k] += 1;
                }
            }
        }
        Bins { tiles, first, entries }
    }
}

/// The eye-plane clip of the cell pipelines as a clip-space w
/// (`eye_plane_distance` in common/clip.glsl: a ten-thousandth of the
/// longest cell edge, at most half the near distance), halved so that no
/// rounding of it loses a cell; 0 for orthographic views (no eye plane:
/// every w is 1).
fn eye_plane_w(frame: &FrameSetup) -> f32 {
    let c = &frame.constants;
    if !frame.perspective {
        return f32::NEG_INFINITY;
    }
    let row = |r: usize| [c.view_proj[0][r], c.view_proj[1][r], c.view_proj[2][r], c.view_proj[3][r]];
    let z = row(2);
    let (e, d) = (c.eye, c.view_dir);
    let near = -(z[0] * e[0] + z[1] * e[1] + z[2] * e[2] + z[3]) / (z[0] * d[0] + z[1] * d[1] + z[2] * d[2]);
    0.5 * (1e-4 * d[3]).min(0.5 * near)
}

pub struct PtCompute {
    /// Vertex positions (relative to the render origin) per cell.
    positions: Vec<[[f32; 3]; 4]>,
    drawn: usize,
    bins: Bins,
    boxes: Vec<Option<[u32; 4]>>,
    bin_ms: f64,
    /// An error of the last `pack` (a frame whose tile lists the device cannot hold), reported by `upload`.
    pack_error: Option<String>,
    _cells: TexelBuffer,
    first: TexelBuffer,
    entries: TexelBuffer,
    counters: Buffer,
    set: DescriptorSet,
    target_desc: DescriptorSetDesc,
    target_set: Option<(u64, DescriptorSet)>,
    constants: FrameConstants,
    /// The image size the last `pack` binned for.
    size: [u32; 2],
    pipeline: Arc<Pipeline>,
    pipeline_key: PipelineKey,
    timestamps: TimestampPool,
    ctx: Arc<Context>,
}

const COUNTER_WORDS: usize = 4;

fn set_desc() -> DescriptorSetDesc {
    let compute = raw::ShaderStageFlags::COMPUTE;
    DescriptorSetDesc::new(&[
        (DescriptorKind::UniformTexelBuffer, compute),
        (DescriptorKind::UniformTexelBuffer, compute),
        (DescriptorKind::UniformTexelBuffer, compute),
        (DescriptorKind::StorageBuffer, compute),
    ])
}

/// A host-visible uniform texel buffer of `texels` texels of `format`
/// (`texel_bytes` each), at least one.
fn frame_texels(ctx: &Arc<Context>, name: &str, texels: usize, texel_bytes: usize, format: raw::Format) -> VkResult<TexelBuffer> {
    let limit = ctx.info.max_texel_buffer_elements as usize;
    if texels > limit {
        return Err(VkError::Invalid(format!("{name}: {texels} texels, above the device's maxTexelBufferElements ({limit})")));
    }
    let desc = BufferDesc::upload(name, (texels.max(1) * texel_bytes) as u64, raw::BufferUsageFlags::UNIFORM_TEXEL_BUFFER);
    TexelBuffer::new(ctx, desc, format)
}

impl PtCompute {
    pub fn new(
        ctx: &Arc<Context>,
        mesh: &TetMesh,
        geometry: &TetGeometry,
        tables: &IntegrationTables,
        draw: DrawSettings,
        counter: &mut UploadCounter,
    ) -> VkResult<Self> {
        let cells = cells_f32(mesh, geometry);
        let n = cells.len();
        let cell_buffer = upload_cells(ctx, "pt-compute cells", mesh, &cells, counter)?;
        let first = frame_texels(ctx, "pt-compute tile starts", 1, 4, raw::Format::R32_UINT)?;
        let entries = frame_texels(ctx, "pt-compute tile entries", 2 * n, BYTES_PER_ENTRY, raw::Format::R32G32_UINT)?;
        let counters = Buffer::new(
            ctx,
            BufferDesc::upload(
                "pt-compute counters",
                (COUNTER_WORDS * 4) as u64,
                raw::BufferUsageFlags::STORAGE_BUFFER | raw::BufferUsageFlags::TRANSFER_DST,
            ),
        )?;
        let set = DescriptorSet::new(
            ctx,
            "pt-compute cells and tiles",
            &set_desc(),
            &[
                DescriptorResource::UniformTexelBuffer(&cell_buffer),
                DescriptorResource::UniformTexelBuffer(&first),
                DescriptorResource::UniformTexelBuffer(&entries),
                DescriptorResource::StorageBuffer(&counters),
            ],
        )?;
        let target_desc = DescriptorSetDesc::new(&[(DescriptorKind::StorageImage, raw::ShaderStageFlags::COMPUTE)]);
        let tile = TILE.map(|t| t.to_string());
        let ert = format!("{ERT_TRANSMITTANCE:e}");
        let defines: Vec<(&str, &str)> = draw
            .interpolation
            .defines()
            .iter()
            .copied()
            .chain(tables.integrator.define())
            .chain([("TILE_W", tile[0].as_str()), ("TILE_H", tile[1].as_str()), ("ERT_TRANSMITTANCE", ert.as_str())])
            .collect();
        let pipeline_key = PipelineKey::Compute(ComputePipelineKey {
            shader: ShaderKey::new("cell_projection/pt_composite.comp", ShaderStage::Compute, &defines),
            push_constant_bytes: std::mem::size_of::<FrameConstants>() as u32,
            sets: vec![tables.set.desc.clone(), set_desc(), target_desc.clone()],
        });
        let pipeline = crate::algo::pipelines::get(ctx, &pipeline_key)?;
        Ok(PtCompute {
            positions: cells.iter().map(|c| c.pos).collect(),
            drawn: n,
            bins: Bins::default(),
            boxes: Vec::new(),
            bin_ms: 0.0,
            pack_error: None,
            _cells: cell_buffer,
            first,
            entries,
            counters,
            set,
            target_desc,
            target_set: None,
            constants: bytemuck::Zeroable::zeroed(),
            size: [0, 0],
            pipeline,
            pipeline_key,
            timestamps: TimestampPool::new(ctx, "pt-compute timestamps", 2)?,
            ctx: ctx.clone(),
        })
    }

    /// The last frame's counters (`Counters` in pt_composite.comp).
    fn counters(&self) -> [u64; COUNTER_WORDS] {
        match self.counters.read() {
            Ok(b) if b.len() >= COUNTER_WORDS * 4 => {
                std::array::from_fn(|i| u32::from_ne_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]]) as u64)
            }
            _ => [0; COUNTER_WORDS],
        }
    }

    /// Grow a frame texel buffer to hold `texels` (by half again, so that
    /// growing frames do not reallocate every time); true when replaced.
    fn ensure(ctx: &Arc<Context>, buffer: &mut TexelBuffer, texels: usize, texel_bytes: usize, name: &str) -> VkResult<bool> {
        if buffer.texels as usize >= texels {
            return Ok(false);
        }
        let grown = (texels + texels / 2).min(ctx.info.max_texel_buffer_elements as usize).max(texels);
        *buffer = frame_texels(ctx, name, grown, texel_bytes, buffer.format)?;
        Ok(true)
    }
}

impl CellProjector for PtCompute {
    fn cells(&self) -> usize {
        self.positions.len()
    }
    fn vertices_per_cell(&self) -> usize {
        VERTICES_PER_CELL
    }
    /// Per frame a cell sends its tile entries (2 u32 each), about two.
    fn floats_per_cell(&self) -> usize {
        2 * BYTES_PER_ENTRY / 4
    }
    fn pipeline_key(&self) -> &PipelineKey {
        &self.pipeline_key
    }
    fn drawn(&self) -> usize {
        self.drawn
    }

    fn pack(&mut self, order: &[u32], frame: &FrameSetup) {
        let t0 = Instant::now();
        self.drawn = order.len().min(self.positions.len());
        let order = &order[..self.drawn];
        let vp = frame.constants.view_proj;
        let min_w = eye_plane_w(frame);
        let size = frame.size;
        let positions = &self.positions;
        order
            .par_iter()
            .with_min_len(4096)
            .map(|&t| {
                let clip = positions[t as usize].map(|p| {
                    std::array::from_fn(|r| vp[0][r] * p[0] + vp[1][r] * p[1] + vp[2][r] * p[2] + vp[3][r])
                });
                pixel_box(&clip, min_w, size)
            })
            .collect_into_vec(&mut self.boxes);
        self.bins = Bins::build(&self.boxes, |slot| order[slot], size);
        self.constants = frame.constants;
        self.size = size;
        self.bin_ms = t0.elapsed().as_secs_f64() * 1e3;
    }

    fn pack_phases(&self) -> Vec<(&'static str, f64)> {
        vec![(BIN_PHASE, self.bin_ms)]
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> VkResult<()> {
        if let Some(e) = self.pack_error.take() {
            return Err(VkError::Invalid(e));
        }
        let ctx = self.ctx.clone();
        let grown_first = Self::ensure(&ctx, &mut self.first, self.bins.first.len(), 4, "pt-compute tile starts")?;
        let grown_entries = Self::ensure(&ctx, &mut self.entries, self.bins.entries.len(), BYTES_PER_ENTRY, "pt-compute tile entries")?;
        if grown_first || grown_entries {
            self.set.update(&[
                DescriptorResource::UniformTexelBuffer(&self._cells),
                DescriptorResource::UniformTexelBuffer(&self.first),
                DescriptorResource::UniformTexelBuffer(&self.entries),
                DescriptorResource::StorageBuffer(&self.counters),
            ])?;
        }
        self.first.buffer.write(0, bytemuck::cast_slice(&self.bins.first), counter, UploadClass::FrameCells)?;
        self.entries.buffer.write(0, bytemuck::cast_slice(&self.bins.entries), counter, UploadClass::FrameCells)
    }

    fn record_draw(&self, _rec: &CommandRecorder, _tables: &IntegrationTables, _frame: &FrameSetup, _counter: &mut UploadCounter) -> VkResult<()> {
        Err(VkError::Invalid("pt-compute composites in compute (record_composite); it has no draw".into()))
    }

    fn record_composite(
        &mut self,
        rec: &CommandRecorder,
        target: &Image,
        tables: &IntegrationTables,
        _frame: &FrameSetup,
        counter: &mut UploadCounter,
    ) -> VkResult<bool> {
        use raw::{AccessFlags2 as A, PipelineStageFlags2 as S};
        if [target.width, target.height] != self.size {
            return Err(VkError::Invalid(format!(
                "target '{}' is {}x{}, the tiles were binned for {}x{}",
                target.name(),
                target.width,
                target.height,
                self.size[0],
                self.size[1]
            )));
        }
        let id = raw::Handle::as_raw(target.raw);
        if self.target_set.as_ref().map(|(t, _)| *t) != Some(id) {
            let set = DescriptorSet::new(&self.ctx, "pt-compute target", &self.target_desc, &[DescriptorResource::StorageImage(target)])?;
            self.target_set = Some((id, set));
        }
        let Some((_, target_set)) = &self.target_set else {
            return Err(VkError::Invalid("pt-compute: no target set".into()));
        };
        self.timestamps.reset(rec);
        rec.fill_buffer(&self.counters, 0);
        rec.memory_barrier(
            (S::HOST | S::CLEAR | S::COPY, A::HOST_WRITE | A::TRANSFER_WRITE),
            (S::COMPUTE_SHADER, A::SHADER_READ | A::SHADER_STORAGE_READ | A::SHADER_STORAGE_WRITE),
        );
        rec.image_barrier_discard(target, ImageUse::ComputeStorage);
        self.timestamps.write(rec, 0, S::TOP_OF_PIPE)?;
        rec.bind_compute(&self.pipeline, &[&tables.set, &self.set, target_set])?;
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&self.constants), counter);
        rec.dispatch([self.bins.tiles[0], self.bins.tiles[1], 1])?;
        self.timestamps.write(rec, 1, S::COMPUTE_SHADER)?;
        rec.compute_to_host();
        Ok(true)
    }

    fn device_phases(&self) -> VkResult<Vec<(&'static str, f64)>> {
        Ok(vec![(COMPOSITE_PHASE, self.timestamps.elapsed_ms(0, 1)?)])
    }

    fn work_counts(&self) -> Vec<(&'static str, u64)> {
        let c = self.counters();
        vec![
            ("cells_binned", self.boxes.iter().flatten().count() as u64),
            ("tile_entries", self.bins.entries.len() as u64),
            ("tiles", self.bins.first.len().saturating_sub(1) as u64),
            ("pixels_integrated", c[0] | (c[1] << 32)),
            ("pixels_covered", c[3]),
            ("pixels_terminated_early", c[2]),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algo::method::DEVICE_PHASE_SUFFIX;

    #[test]
    fn composite_phase_is_a_device_phase() {
        assert!(COMPOSITE_PHASE.ends_with(DEVICE_PHASE_SUFFIX));
    }

    /// Every tile's list keeps the given order; entries name the cell and
    /// its box inside the tile.
    #[test]
    fn bins_keep_order_and_boxes() {
        let [tw, th] = TILE;
        let size = [3 * tw - 1, 2 * th];
        let boxes = vec![Some([0, 0, size[0] - 1, size[1] - 1]), None, Some([tw + 1, 1, tw + 1, 1]), Some([1, th, 2 * tw, th])];
        let b = Bins::build(&boxes, |slot| 100 + slot as u32, size);
        assert_eq!(b.tiles, [3, 2]);
        let tile = |k: usize| &b.entries[b.first[k] as usize..b.first[k + 1] as usize];
        let cells = |k: usize| tile(k).iter().map(|e| e[0]).collect::<Vec<_>>();
        assert_eq!(cells(0), vec![100]);
        assert_eq!(cells(1), vec![100, 102]);
        assert_eq!(cells(2), vec![100]);
        assert_eq!(cells(3), vec![100, 103]);
        assert_eq!(cells(5), vec![100, 103]);
        // Cell 102's box (tw + 1, 1) is (1, 1)-(1, 1) in tile 1.
        assert_eq!(tile(1)[1][1], 1 | 1 << 8 | 1 << 16 | 1 << 24);
        // Cell 103's box from x = 1 in tile 3, to the tile's end; in tile 5 up to x = 0.
        assert_eq!(tile(3)[1][1], 1 | (tw - 1) << 16);
        assert_eq!(tile(5)[1][1], 0);
        assert_eq!(b.entries.len(), 6 + 1 + 3);
    }

    #[test]
    fn pixel_box_covers_the_projection_and_clips_at_the_eye_plane() {
        // A triangle-ish cell in NDC [-0.5, 0.5] on a 100x100 image.
        let v = |x: f32, y: f32, w: f32| [x * w, y * w, 0.5, w];
        let clip = [v(-0.5, -0.5, 1.0), v(0.5, -0.5, 1.0), v(0.0, 0.5, 1.0), v(0.0, 0.0, 2.0)];
        let b = pixel_box(&clip, 0.01, [100, 100]).unwrap();
        assert!(b[0] <= 24 && b[2] >= 74 && b[1] <= 24 && b[3] >= 74, "{b:?}");
        assert!(b[0] >= 22 && b[2] <= 76, "{b:?}");
        // Wholly behind the eye plane: nothing.
        let behind = clip.map(|p| [p[0], p[1], p[2], -1.0]);
        assert_eq!(pixel_box(&behind, 0.01, [100, 100]), None);
        // Off screen.
        let off = [v(2.0, 2.0, 1.0), v(3.0, 2.0, 1.0), v(2.0, 3.0, 1.0), v(2.5, 2.5, 1.0)];
        assert_eq!(pixel_box(&off, 0.01, [100, 100]), None);
        // Straddling: bounded by the crossing with w = min_w.
        let straddle = [v(0.0, 0.0, 1.0), [0.1, 0.0, 0.0, -1.0], v(0.1, 0.1, 1.0), v(0.0, 0.1, 1.0)];
        let b = pixel_box(&straddle, 0.01, [100, 100]).unwrap();
        assert_eq!((b[2], b[3]), (99, 99));
    }
}
