//! Projected tetrahedra in compute (beyond the papers; issue 24): the
//! balanced family's visibility-sorted cells, listed on the CPU per pixel
//! they cover (by the rasterizer's rule; each pixel's list keeps the
//! visibility order), and composited by one compute invocation per pixel
//! (workgroups of `TILE` pixels over the covered tiles), front to back, so
//! that a pixel stops once it is opaque (early termination). Per pixel and cell the
//! segment is balanced's: the pixel's ray is clipped by the tet's four
//! planes, and the barycentric weights where it enters give what the
//! rasterizer interpolates for balanced's entry face
//! (`shaders/cell_projection/pt_composite.comp`). The cells are stored once
//! on the device as `resident` stores them; per frame the pixel lists cross
//! (4 bytes per list entry, 4 per pixel start). No triangle reaches lavapipe's
//! serial vertex/setup/binning front end (PLATFORM.md): the compositing
//! dispatch runs on every core. A mesh whose cells one texel buffer cannot
//! hold has them in several (`algo::chunks`, as resident's), read through
//! `stored_cell.glsl`'s chunk bindings after the set's four.

use std::sync::Arc;
use std::time::Instant;

use rayon::prelude::*;

use super::balanced::VERTICES_PER_CELL;
use super::render;
use super::resident::{upload_cell_chunks, FLOATS_PER_STORED_CELL};
use super::{CellMaker, CellProjector, DrawSettings};
use crate::algo::tet_mesh::{FrameConstants, FrameSetup};
use crate::algo::chunks::{ensure_frame_texels, frame_texels, ChunkLimits, TexelChunks};
use crate::algo::integrate::IntegrationTables;
use crate::algo::method::{MethodInfo, MethodInputs, RenderMethod};
use crate::algo::host_memory::HostMemory;
use crate::mesh::TetMesh;
use crate::vk::{
    Buffer, BufferDesc, CommandRecorder, ComputePipelineKey, Context, DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc,
    Image, Pipeline, PipelineKey, ShaderKey, ShaderStage, TargetImageSet, TexelBuffer, TimestampPool, UploadClass, UploadCounter, VkError,
    VkResult,
};
use crate::vk::{Format, Stages, TimestampAt};

/// The compositing workgroup in pixels, one invocation each. llvmpipe runs
/// a workgroup as 8-lane vectors (AVX2) and executes both sides of a branch
/// under a mask; every entry of a pixel's list is a cell that covers it, so
/// a vector's lanes idle only where their lists differ in length, least
/// for a compact 4 x 2 block of neighbours.
pub const TILE: [u32; 2] = [4, 2];
/// Bytes per list entry: the cell (and `PLANE_TEST_BIT`).
pub const BYTES_PER_ENTRY: usize = 4;
/// Pixels a cell covers, for the memory estimate: about 36 on the oxygen
/// post at 512^2.
const PAIRS_PER_CELL: usize = 36;
/// Early termination: a pixel stops once its transmittance is below this.
/// What it leaves out is at most the transmittance times the premultiplied
/// colour and opacity behind, each at most 1 (colours in [0, 1]): at most
/// 1e-5 per channel, a third of the f32 error ppi and linear-exact show
/// against the f64 reference (3.1e-5, `render::accuracy_bound`) and a
/// tenth of the 1e-4 RMSE allowed against balanced.
pub const ERT_TRANSMITTANCE: f32 = 1e-5;
/// The compositing pass's device phase.
pub const COMPOSITE_PHASE: &str = "composite_gpu";
/// The CPU projection inside `pack`: each cell's snapped vertices.
pub const PROJECT_PHASE: &str = "project";
/// The CPU listing inside `pack`: each pixel's covering cells.
pub const BIN_PHASE: &str = "bin";

/// The registry entry.
pub const METHOD: MethodInfo = render::method_info(
    "pt-compute",
    "projected tetrahedra in compute: sorted cells listed per pixel on the CPU, each pixel composited front to back by one invocation with early termination",
    render::KNOWN_EXITS_OPTIONS,
    &[],
    create,
);

fn create(inputs: MethodInputs) -> anyhow::Result<Box<dyn RenderMethod>> {
    // Per frame: a list entry per pixel a cell covers, about 36 per cell on
    // the oxygen post at 512^2 (18.4 M pairs); stored: resident's cell.
    // Host: positions (48), footprints (at most 40) and the pixel lists.
    let bytes = render::DeviceBytesPerCell {
        frame: PAIRS_PER_CELL * BYTES_PER_ENTRY,
        fixed: FLOATS_PER_STORED_CELL * 4,
        host: 48 + std::mem::size_of::<Footprint>() + PAIRS_PER_CELL * BYTES_PER_ENTRY,
    };
    let stages = Stages::FRAGMENT | Stages::COMPUTE;
    render::CellProjection::create_for_stages(inputs, bytes, stages, |ctx, mesh, tables, draw, counter| {
        Ok(Box::new(PtCompute::new(ctx, mesh, tables, draw, counter)?))
    })
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

/// Sub-pixel bits of the snapped vertex positions: lavapipe's rasterizer
/// snaps to 1/256 pixel (`FIXED_ORDER` 8), and so does the coverage here,
/// so that a pixel is covered exactly when the rasterizer would cover it.
pub const SUBPIXEL_BITS: u32 = 8;
/// Rows of the image one CPU task lists pixels for.
pub const BAND_ROWS: u32 = 8;
/// Entries whose cell is not rasterized on the CPU (a vertex behind the eye
/// plane, or far off screen) carry this bit: the compositing pass decides
/// their coverage from the cell's planes, per pixel of the cell's box.
pub const PLANE_TEST_BIT: u32 = 1 << 31;
/// Vertices further than this many pixels off the image go the plane-test
/// way (keeps the fixed-point edge functions in range).
const GUARD_PIXELS: f32 = 8192.0;

/// Where a sorted cell lands on screen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Footprint {
    Off,
    /// Projected vertices in fixed point (pixel units << SUBPIXEL_BITS, y down
    /// as the rasterizer's framebuffer), the rows it may cover, and the faces
    /// (bit f: `FACES[f]`) seen edge-on, which cover no pixel (`edge_on_faces`).
    Raster { xy: [[i32; 2]; 4], rows: [u32; 2], edge_on: u8 },
    /// The pixel box (x0, y0, x1, y1 inclusive) of a cell the pass tests by planes.
    Planes([u32; 4]),
}

impl Footprint {
    /// The footprint of a cell with these clip-space vertices on an image
    /// of `size`; `min_w` is the eye plane (see `eye_plane_w`).
    pub fn of(clip: &[[f32; 4]; 4], min_w: f32, size: [u32; 2]) -> Footprint {
        let one = (1u32 << SUBPIXEL_BITS) as f32;
        let mut xy = [[0i32; 2]; 4];
        let mut raster = true;
        for (v, c) in xy.iter_mut().zip(clip) {
            if !(c[3] >= min_w && c[3] > 0.0) {
                raster = false;
                break;
            }
            // The viewport transform as the draw module does it: x / w, then scale and offset.
            let iw = 1.0 / c[3];
            for k in 0..2 {
                let half = size[k] as f32 * 0.5;
                let p = c[k] * iw * half + half;
                if !(p.abs() <= GUARD_PIXELS + size[k] as f32) {
                    raster = false;
                }
                v[k] = (p * one).round() as i32;
            }
        }
        if !raster {
            return pixel_box(clip, min_w, size).map_or(Footprint::Off, Footprint::Planes);
        }
        // Pixel i's centre is at (i + 1/2) << SUBPIXEL_BITS.
        let half = 1i32 << (SUBPIXEL_BITS - 1);
        let span = |k: usize| -> Option<[u32; 2]> {
            let lo = xy.iter().map(|v| v[k]).min().unwrap_or(0);
            let hi = xy.iter().map(|v| v[k]).max().unwrap_or(-1);
            let a = (lo - half).div_euclid(1 << SUBPIXEL_BITS);
            let b = (hi - half).div_euclid(1 << SUBPIXEL_BITS) + 1;
            let n = size[k] as i32;
            if b < 0 || a > n - 1 || lo > hi {
                return None;
            }
            Some([a.max(0) as u32, b.min(n - 1) as u32])
        };
        match (span(0), span(1)) {
            (Some(_), Some(rows)) => Footprint::Raster { xy, rows, edge_on: 0 },
            _ => Footprint::Off,
        }
    }

    /// This footprint with the faces in `mask()` (`edge_on_faces`) left out
    /// of the rasterization; `mask` runs only for a rasterized footprint.
    pub fn without_faces(self, mask: impl FnOnce() -> u8) -> Footprint {
        match self {
            Footprint::Raster { xy, rows, edge_on } => Footprint::Raster { xy, rows, edge_on: edge_on | mask() },
            other => other,
        }
    }

    fn rows(&self) -> Option<[u32; 2]> {
        match self {
            Footprint::Off => None,
            Footprint::Raster { rows, .. } => Some(*rows),
            Footprint::Planes(b) => Some([b[1], b[3]]),
        }
    }
}

/// The faces of a tet, consistently oriented (each edge of the tet runs one
/// way in one face and the other way in the other): projected, the faces
/// of positive area cover the tet's silhouette exactly once.
const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// A face is seen edge-on when the eye lies in its plane (perspective) or
/// the view direction does (orthographic) to within this sine of the angle:
/// the compositing pass's test for a ray in a cell's plane
/// (`pt_composite.comp`: |n . d| <= 1e-6 |n|), far above f32 rounding
/// (~1e-7) and far below a pixel (2.8e-3 rad at 256^2, 40 degrees).
pub const EDGE_ON_SINE: f64 = 1e-6;

/// The faces of a tet (bit f: `FACES[f]`) seen edge-on from `eye` (a point
/// under perspective) or along `view_dir` (orthographic): vertices, eye and
/// direction in the same frame. Projected, such a face is a segment, but
/// snapping its vertices to the sub-pixel grid can leave it a sliver of
/// positive area: the cell behind it would then cover the centres on the
/// segment through it while the cell in front covers them too, and both
/// would integrate the whole chord the ray runs along the face (stress case
/// `eye-on-plane`, one pixel at 256^2: 5.9e-2). Left out, the centres go
/// to the one neighbour whose other faces cover them.
pub fn edge_on_faces(v: &[[f32; 3]; 4], eye: [f32; 3], view_dir: [f32; 3], perspective: bool) -> u8 {
    let p = v.map(|q| q.map(f64::from));
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let e = eye.map(f64::from);
    // Squared distances from the eye (or the view direction's), once per vertex.
    let d = view_dir.map(f64::from);
    let reach: [f64; 4] = if perspective { p.map(|q| dot(sub(q, e), sub(q, e))) } else { [dot(d, d); 4] };
    let mut mask = 0u8;
    for (f, face) in FACES.iter().enumerate() {
        let [a, b, c] = face.map(|i| p[i]);
        let (u, w) = (sub(b, a), sub(c, a));
        let n = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
        // The sine of the angle between the plane and the direction from the
        // eye to its farthest vertex (or the view direction), compared squared.
        let along = if perspective { dot(n, sub(a, e)) } else { dot(n, d) };
        let length2 = face.iter().map(|&i| reach[i]).fold(0.0, f64::max);
        if along * along <= EDGE_ON_SINE * EDGE_ON_SINE * dot(n, n) * length2 {
            mask |= 1 << f;
        }
    }
    mask
}

/// Calls `f(x, y)` for every pixel in rows [row0, row1] whose centre the
/// tet's projection covers, by the rasterizer's rule: exact edge functions
/// on the snapped vertices, a centre on an edge belongs to the triangle the
/// edge is a top or left edge of. A face shared by two cells is the same
/// edges from the same snapped points, so the two agree on every pixel.
/// Faces in `edge_on` (`edge_on_faces`) cover nothing.
fn rasterize(xy: &[[i32; 2]; 4], edge_on: u8, row0: u32, row1: u32, width: u32, mut f: impl FnMut(u32, u32)) {
    let half = 1i64 << (SUBPIXEL_BITS - 1);
    let unit = 1i64 << SUBPIXEL_BITS;
    for (index, face) in FACES.into_iter().enumerate() {
        let p = face.map(|i| [xy[i][0] as i64, xy[i][1] as i64]);
        let area = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]);
        if area <= 0 || edge_on & (1 << index) != 0 {
            continue;
        }
        // Edge (a, b): E(q) = (b - a) x (q - a), positive inside; its
        // gradient (-(b.y - a.y), b.x - a.x) points inward; a top edge
        // (interior below, y down) or a left edge (interior right) keeps
        // centres on it.
        let edges = [0usize, 1, 2].map(|i| {
            let (a, b) = (p[i], p[(i + 1) % 3]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let top_left = -dy > 0 || (dy == 0 && dx > 0);
            (a, dx, dy, if top_left { 0 } else { 1 })
        });
        let lo = |k: usize| p.iter().map(|v| v[k]).min().unwrap_or(0);
        let hi = |k: usize| p.iter().map(|v| v[k]).max().unwrap_or(-1);
        let first = |v: i64| (v - half + unit - 1).div_euclid(unit);
        let last = |v: i64| (v - half).div_euclid(unit);
        let x0 = first(lo(0)).max(0);
        let x1 = last(hi(0)).min(width as i64 - 1);
        let y0 = first(lo(1)).max(row0 as i64);
        let y1 = last(hi(1)).min(row1 as i64);
        for y in y0..=y1 {
            let qy = y * unit + half;
            let qx0 = x0 * unit + half;
            // E at the row's first centre, and its step per pixel.
            let mut e = edges.map(|(a, dx, dy, bias)| (dx * (qy - a[1]) - dy * (qx0 - a[0]) - bias, -dy * unit));
            for x in x0..=x1 {
                if e.iter().all(|(v, _)| *v >= 0) {
                    f(x as u32, y as u32);
                }
                for (v, step) in &mut e {
                    *v += *step;
                }
            }
        }
    }
}

/// Per pixel (row-major) the cells covering it, in the order the cells were
/// given: pixel i's are `cells[first[i]..first[i + 1]]`, an entry being the
/// cell, with `PLANE_TEST_BIT` set where the pass tests coverage itself.
/// Built in bands of `BAND_ROWS` rows, one task each; `band_cells[b]`
/// holds band b's entries, which follow each other in `first`'s order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PixelLists {
    pub size: [u32; 2],
    pub first: Vec<u32>,
    pub band_cells: Vec<Vec<u32>>,
}

impl PixelLists {
    /// Lists for `footprints` (one per cell slot in sort order);
    /// `cell_of(slot)` is the cell an entry names. Deterministic.
    pub fn build(footprints: &[Footprint], cell_of: impl Fn(usize) -> u32 + Sync, size: [u32; 2]) -> PixelLists {
        let bands = size[1].div_ceil(BAND_ROWS) as usize;
        // Each band's slots, in slot order (count, prefix sum, fill).
        let mut band_first = vec![0usize; bands + 1];
        for rows in footprints.iter().filter_map(Footprint::rows) {
            for b in rows[0] / BAND_ROWS..=rows[1] / BAND_ROWS {
                band_first[b as usize + 1] += 1;
            }
        }
        for b in 0..bands {
            band_first[b + 1] += band_first[b];
        }
        let mut cursor = band_first.clone();
        let mut band_slots = vec![0u32; band_first[bands]];
        for (slot, rows) in footprints.iter().enumerate().filter_map(|(s, f)| Some((s, f.rows()?))) {
            for b in rows[0] / BAND_ROWS..=rows[1] / BAND_ROWS {
                band_slots[cursor[b as usize]] = slot as u32;
                cursor[b as usize] += 1;
            }
        }
        let width = size[0];
        let per_band: Vec<(Vec<u32>, Vec<u32>)> = (0..bands)
            .into_par_iter()
            .map(|b| {
                let row0 = b as u32 * BAND_ROWS;
                let row1 = (row0 + BAND_ROWS).min(size[1]) - 1;
                let pixels = ((row1 - row0 + 1) * width) as usize;
                let mut pairs: Vec<[u32; 2]> = Vec::new();
                for &slot in &band_slots[band_first[b]..band_first[b + 1]] {
                    let cell = cell_of(slot as usize);
                    match &footprints[slot as usize] {
                        Footprint::Off => {}
                        Footprint::Raster { xy, edge_on, .. } => {
                            rasterize(xy, *edge_on, row0, row1, width, |x, y| pairs.push([(y - row0) * width + x, cell]));
                        }
                        Footprint::Planes(bx) => {
                            for y in bx[1].max(row0)..=bx[3].min(row1) {
                                for x in bx[0]..=bx[2] {
                                    pairs.push([(y - row0) * width + x, cell | PLANE_TEST_BIT]);
                                }
                            }
                        }
                    }
                }
                // Stable counting sort by pixel: each pixel's cells stay in slot order.
                let mut start = vec![0u32; pixels + 1];
                for p in &pairs {
                    start[p[0] as usize + 1] += 1;
                }
                let counts = start[1..].to_vec();
                for i in 0..pixels {
                    start[i + 1] += start[i];
                }
                let mut cells = vec![0u32; pairs.len()];
                for p in &pairs {
                    let i = &mut start[p[0] as usize];
                    cells[*i as usize] = p[1];
                    *i += 1;
                }
                (counts, cells)
            })
            .collect();
        let mut first = Vec::with_capacity((size[0] * size[1]) as usize + 1);
        let mut total = 0u32;
        first.push(0);
        let mut band_cells = Vec::with_capacity(bands);
        for (counts, cells) in per_band {
            for c in counts {
                total = total.saturating_add(c);
                first.push(total);
            }
            band_cells.push(cells);
        }
        PixelLists { size, first, band_cells }
    }

    /// The tiles (`TILE` pixels each) around every pixel with a non-empty
    /// list: [x0, y0, x1, y1] in tiles, inclusive; none when no list has an
    /// entry.
    pub fn covered_tiles(&self) -> Option<[u32; 4]> {
        let [w, h] = self.size.map(|v| v as usize);
        let mut lo = [usize::MAX; 2];
        let mut hi = [0usize; 2];
        for y in 0..h {
            let row = &self.first[y * w..=(y + 1) * w];
            let Some(x0) = row.windows(2).position(|p| p[1] > p[0]) else { continue };
            let x1 = row.windows(2).rposition(|p| p[1] > p[0]).unwrap_or(x0);
            lo = [lo[0].min(x0), lo[1].min(y)];
            hi = [hi[0].max(x1), y];
        }
        (lo[1] <= hi[1]).then(|| {
            let t = TILE.map(|v| v as usize);
            [lo[0] / t[0], lo[1] / t[1], hi[0] / t[0], hi[1] / t[1]].map(|v| v as u32)
        })
    }

    /// Entries in all.
    pub fn entries(&self) -> usize {
        self.band_cells.iter().map(Vec::len).sum()
    }

    /// Lane iterations of the compositing pass without early termination:
    /// a workgroup's vector runs its longest list, so every lane pays for
    /// it. Entries over this is the share of lanes doing work.
    pub fn lane_slots(&self) -> u64 {
        let [w, h] = self.size;
        let len = |x: u32, y: u32| (self.first[(y * w + x) as usize + 1] - self.first[(y * w + x) as usize]) as u64;
        let mut slots = 0;
        for ty in (0..h).step_by(TILE[1] as usize) {
            for tx in (0..w).step_by(TILE[0] as usize) {
                let longest = (ty..(ty + TILE[1]).min(h)).flat_map(|y| (tx..(tx + TILE[0]).min(w)).map(move |x| (x, y))).map(|(x, y)| len(x, y)).max();
                slots += longest.unwrap_or(0) * (TILE[0] * TILE[1]) as u64;
            }
        }
        slots
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
    0.5 * (1e-4 * c.max_segment).min(0.5 * near)
}

pub struct PtCompute {
    /// Vertex positions (relative to the render origin) per cell.
    positions: Vec<[[f32; 3]; 4]>,
    drawn: usize,
    lists: PixelLists,
    /// The tiles the compositing pass runs over this frame
    /// (`PixelLists::covered_tiles`).
    covered: Option<[u32; 4]>,
    footprints: Vec<Footprint>,
    project_ms: f64,
    bin_ms: f64,
    /// An error of the last `pack` (a frame whose tile lists the device cannot hold), reported by `upload`.
    pack_error: Option<String>,
    cells: TexelChunks,
    first: TexelBuffer,
    entries: TexelBuffer,
    counters: Buffer,
    set: DescriptorSet,
    target_set: TargetImageSet,
    constants: FrameConstants,
    /// The image size the last `pack` binned for.
    size: [u32; 2],
    pipeline: Arc<Pipeline>,
    pipeline_key: PipelineKey,
    timestamps: TimestampPool,
    ctx: Arc<Context>,
}

const COUNTER_WORDS: usize = 4;

/// Binding of the cells' second texel buffer (`CELL_CHUNK_BINDING` in
/// stored_cell.glsl), after the set's cells, starts, lists and counters.
const CELL_CHUNK_BINDING: usize = 4;

/// The cells and tiles set, with `cell_chunks - 1` more cell bindings.
fn set_desc(cell_chunks: usize) -> DescriptorSetDesc {
    let compute = Stages::COMPUTE;
    let mut desc = DescriptorSetDesc::new(&[
        (DescriptorKind::StorageTexelBuffer, compute),
        (DescriptorKind::StorageTexelBuffer, compute),
        (DescriptorKind::StorageTexelBuffer, compute),
        (DescriptorKind::StorageBuffer, compute),
    ]);
    for _ in 1..cell_chunks {
        desc = desc.with(DescriptorKind::StorageTexelBuffer, compute);
    }
    desc
}

/// The resources of `set_desc`, in its order.
fn set_resources<'a>(cells: &'a TexelChunks, first: &'a TexelBuffer, entries: &'a TexelBuffer, counters: &'a Buffer) -> Vec<DescriptorResource<'a>> {
    let mut resources = vec![
        DescriptorResource::StorageTexelBuffer(&cells.buffers[0]),
        DescriptorResource::StorageTexelBuffer(first),
        DescriptorResource::StorageTexelBuffer(entries),
        DescriptorResource::StorageBuffer(counters),
    ];
    resources.extend(cells.buffers[1..].iter().map(DescriptorResource::StorageTexelBuffer));
    resources
}

impl PtCompute {
    pub fn new(
        ctx: &Arc<Context>,
        mesh: &TetMesh,
        tables: &IntegrationTables,
        draw: DrawSettings,
        counter: &mut UploadCounter,
    ) -> VkResult<Self> {
        // Only the positions are kept (degenerate cells collapsed as the
        // stored cells are): no whole-mesh array of f32 cells on the host.
        let maker = CellMaker::new(mesh);
        let positions: Vec<[[f32; 3]; 4]> = (0..mesh.tets.len()).into_par_iter().map(|t| maker.cell(mesh, t).pos).collect();
        let n = positions.len();
        let cells = upload_cell_chunks(ctx, "pt-compute cells", mesh, &ChunkLimits::of(ctx)?, counter)?;
        let first = frame_texels(ctx, "pt-compute pixel starts", 1, 4, Format::R32Uint)?;
        // A first guess at the lists (they grow with the frame's entries).
        let guess = (8 * n).min(ctx.info.max_texel_buffer_elements as usize);
        let entries = frame_texels(ctx, "pt-compute pixel lists", guess, BYTES_PER_ENTRY, Format::R32Uint)?;
        let counters = Buffer::new(ctx, BufferDesc::counters("pt-compute counters", COUNTER_WORDS))?;
        let set = DescriptorSet::new(
            ctx,
            "pt-compute cells and tiles",
            &set_desc(cells.buffers.len()),
            &set_resources(&cells, &first, &entries, &counters),
        )?;
        let target_set = TargetImageSet::new("pt-compute target", Stages::COMPUTE);
        let tile = TILE.map(|t| t.to_string());
        let ert = format!("{ERT_TRANSMITTANCE:e}");
        let chunked = cells.defines("CELL");
        let chunk_binding = (!chunked.is_empty()).then(|| CELL_CHUNK_BINDING.to_string());
        let defines: Vec<(&str, &str)> = draw
            .defines()
            .into_iter()
            .chain([("TILE_W", tile[0].as_str()), ("TILE_H", tile[1].as_str()), ("ERT_TRANSMITTANCE", ert.as_str())])
            .chain(chunked.iter().map(|(k, v)| (k.as_str(), v.as_str())))
            .chain(chunk_binding.iter().map(|b| ("CELL_CHUNK_BINDING", b.as_str())))
            .collect();
        let pipeline_key = PipelineKey::Compute(ComputePipelineKey {
            shader: ShaderKey::new("cell_projection/pt_composite.comp", ShaderStage::Compute, &defines),
            push_constant_bytes: std::mem::size_of::<FrameConstants>() as u32,
            sets: vec![tables.set.desc.clone(), set_desc(cells.buffers.len()), target_set.desc.clone()],
        });
        let pipeline = crate::algo::pipelines::get(ctx, &pipeline_key)?;
        Ok(PtCompute {
            positions,
            drawn: n,
            lists: PixelLists::default(),
            covered: None,
            footprints: Vec::new(),
            project_ms: 0.0,
            bin_ms: 0.0,
            pack_error: None,
            cells,
            first,
            entries,
            counters,
            set,
            target_set,
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
        self.counters.read_counters()
    }

}

impl CellProjector for PtCompute {
    fn host_bytes(&self, memory: &mut HostMemory) {
        memory.vec("projector: cell positions", &self.positions);
        memory.vec("projector: footprints", &self.footprints);
        memory.vec("projector: pixel list starts", &self.lists.first);
        memory.add("projector: pixel lists", self.lists.band_cells.iter().map(crate::algo::host_memory::vec_bytes).sum());
    }

    fn cells(&self) -> usize {
        self.positions.len()
    }
    fn device_chunks(&self) -> serde_json::Value {
        serde_json::json!({ "cell_buffers": self.cells.buffers.len(), "cells_per_buffer": self.cells.per_chunk })
    }
    fn vertices_per_cell(&self) -> usize {
        VERTICES_PER_CELL
    }
    /// Per frame a cell sends a list entry (one u32) per pixel it covers.
    fn floats_per_cell(&self) -> usize {
        PAIRS_PER_CELL * BYTES_PER_ENTRY / 4
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
        let c = &frame.constants;
        let (eye, view_dir) = ([c.eye[0], c.eye[1], c.eye[2]], [c.view_dir[0], c.view_dir[1], c.view_dir[2]]);
        order
            .par_iter()
            .with_min_len(4096)
            .map(|&t| {
                let v = &positions[t as usize];
                let clip = v.map(|p| {
                    std::array::from_fn(|r| vp[0][r] * p[0] + vp[1][r] * p[1] + vp[2][r] * p[2] + vp[3][r])
                });
                Footprint::of(&clip, min_w, size).without_faces(|| edge_on_faces(v, eye, view_dir, frame.perspective))
            })
            .collect_into_vec(&mut self.footprints);
        let t1 = Instant::now();
        self.project_ms = (t1 - t0).as_secs_f64() * 1e3;
        self.lists = PixelLists::build(&self.footprints, |slot| order[slot], size);
        self.covered = self.lists.covered_tiles();
        let limit = self.ctx.info.max_texel_buffer_elements as usize;
        self.pack_error = (self.lists.entries() >= limit.min(u32::MAX as usize)).then(|| {
            format!("pt-compute: {} (pixel, cell) pairs this frame, above the device's maxTexelBufferElements ({limit}); use a smaller image", self.lists.entries())
        });
        self.constants = frame.constants;
        self.size = size;
        self.bin_ms = t1.elapsed().as_secs_f64() * 1e3;
    }

    fn pack_phases(&self) -> Vec<(&'static str, f64)> {
        vec![(PROJECT_PHASE, self.project_ms), (BIN_PHASE, self.bin_ms)]
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> VkResult<()> {
        if let Some(e) = self.pack_error.take() {
            return Err(VkError::Invalid(e));
        }
        let ctx = self.ctx.clone();
        let grown_first = ensure_frame_texels(&ctx, &mut self.first, self.lists.first.len(), 4, "pt-compute pixel starts")?;
        let grown_entries = ensure_frame_texels(&ctx, &mut self.entries, self.lists.entries(), BYTES_PER_ENTRY, "pt-compute pixel lists")?;
        if grown_first || grown_entries {
            self.set.update(&set_resources(&self.cells, &self.first, &self.entries, &self.counters))?;
        }
        self.first.buffer.write(0, bytemuck::cast_slice(&self.lists.first), counter, UploadClass::FrameCells)?;
        let mut offset = 0;
        for cells in &self.lists.band_cells {
            self.entries.buffer.write(offset, bytemuck::cast_slice(cells), counter, UploadClass::FrameCells)?;
            offset += cells.len() * BYTES_PER_ENTRY;
        }
        Ok(())
    }

    fn record_composite(
        &mut self,
        rec: &CommandRecorder,
        target: &Image,
        tables: &IntegrationTables,
        _frame: &FrameSetup,
        counter: &mut UploadCounter,
    ) -> VkResult<bool> {
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
        let (base, groups) = self.dispatched();
        let target_set = self.target_set.for_target(&self.ctx, target)?;
        self.timestamps.reset(rec);
        rec.fill_buffer(&self.counters, 0);
        rec.uploads_to_compute();
        // Only the tiles around the covered pixels run the pass: on llvmpipe
        // a workgroup with nothing to do still runs the whole shader masked
        // (docs/compute-speed.md, "What llvmpipe does"). The rest is cleared.
        rec.storage_target(target, crate::algo::screen::pixels_of_groups(base, groups, TILE, self.size));
        self.timestamps.write(rec, 0, TimestampAt::Start)?;
        rec.bind_compute(&self.pipeline, &[&tables.set, &self.set, target_set])?;
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&self.constants), counter);
        rec.dispatch_base(base, groups)?;
        self.timestamps.write(rec, 1, TimestampAt::ComputeDone)?;
        rec.compute_to_host();
        Ok(true)
    }

    fn device_phases(&self) -> VkResult<Vec<(&'static str, f64)>> {
        Ok(vec![(COMPOSITE_PHASE, self.timestamps.elapsed_ms(0, 1)?)])
    }

    fn work_counts(&self) -> Vec<(&'static str, u64)> {
        let c = self.counters();
        let (_, groups) = self.dispatched();
        vec![
            ("cells_binned", self.footprints.iter().filter(|f| **f != Footprint::Off).count() as u64),
            ("cells_plane_tested", self.footprints.iter().filter(|f| matches!(f, Footprint::Planes(_))).count() as u64),
            ("pixel_cell_pairs", self.lists.entries() as u64),
            ("lane_slots", self.lists.lane_slots()),
            ("pixels_integrated", c[0] | (c[1] << 32)),
            ("pixels_covered", c[3]),
            ("pixels_terminated_early", c[2]),
            ("tiles_dispatched", groups[0] as u64 * groups[1] as u64),
        ]
    }
}

impl PtCompute {
    /// The compositing pass's workgroups this frame: (first, count), the
    /// tiles of `covered` (none when nothing is covered).
    fn dispatched(&self) -> ([u32; 3], [u32; 3]) {
        match self.covered {
            Some([x0, y0, x1, y1]) => ([x0, y0, 0], [x1 - x0 + 1, y1 - y0 + 1, 1]),
            None => ([0; 3], [0, 0, 1]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algo::method::DEVICE_PHASE_SUFFIX;

    /// The dispatch covers the tiles around every listed pixel and no more.
    #[test]
    fn covered_tiles_hold_every_listed_pixel() {
        let lists_with = |size: [u32; 2], pixels: &[(u32, u32)]| {
            let mut first = vec![0u32];
            for y in 0..size[1] {
                for x in 0..size[0] {
                    let n = pixels.iter().filter(|&&p| p == (x, y)).count() as u32;
                    first.push(first.last().unwrap() + n);
                }
            }
            let entries = *first.last().unwrap() as usize;
            PixelLists { size, first, band_cells: vec![vec![0; entries]] }
        };
        assert_eq!(lists_with([16, 8], &[]).covered_tiles(), None);
        assert_eq!(lists_with([16, 8], &[(5, 3), (10, 6)]).covered_tiles(), Some([1, 1, 2, 3]));
        assert_eq!(lists_with([16, 8], &[(0, 0), (15, 7), (15, 7)]).covered_tiles(), Some([0, 0, 3, 3]));
        // A partial last tile (size not a multiple of TILE).
        assert_eq!(lists_with([17, 9], &[(16, 8)]).covered_tiles(), Some([4, 4, 4, 4]));
        // The tiles hold the pixels, at two image sizes.
        for size in [[16u32, 8u32], [33, 21]] {
            let px = [(3, 1), (size[0] - 2, size[1] / 2)];
            let [x0, y0, x1, y1] = lists_with(size, &px).covered_tiles().unwrap();
            for (x, y) in px {
                assert!((x0 * TILE[0]..(x1 + 1) * TILE[0]).contains(&x) && (y0 * TILE[1]..(y1 + 1) * TILE[1]).contains(&y));
            }
        }
    }

    #[test]
    fn composite_phase_is_a_device_phase() {
        assert!(COMPOSITE_PHASE.ends_with(DEVICE_PHASE_SUFFIX));
    }

    /// Two cells sharing a face seen edge-on whose snapped projection is a
    /// sliver 1/256 pixel wide, to the right of the line through the centres
    /// of column 8 (as `eye-on-plane` at 256x256): through the sliver the
    /// left cell covered column 8, which the right cell covers too. With the
    /// face left out each centre is covered once.
    #[test]
    fn a_face_seen_edge_on_covers_no_pixel() {
        let px = |x: f64, y: f64| [(x * 256.0) as i32, (y * 256.0) as i32];
        let (v1, v2, v3) = (px(8.5, 1.0), [px(8.5, 8.0)[0] + 1, px(8.5, 8.0)[1]], px(8.5, 15.0));
        // The shared face runs one way in each cell (FACES[3] = opposite vertex 3).
        let left = [v1, v2, v3, px(2.0, 8.0)];
        let right = [v1, v3, v2, px(14.0, 8.0)];
        let coverage = |edge_on: u8| {
            let mut n = vec![0u32; 256];
            for xy in [left, right] {
                rasterize(&xy, edge_on, 0, 15, 16, |x, y| n[(y * 16 + x) as usize] += 1);
            }
            n
        };
        let twice = coverage(0).iter().filter(|&&c| c == 2).count();
        assert!(twice > 0, "the sliver double-covers column 8");
        let once = coverage(1 << 3);
        for y in 0..16u32 {
            for x in 0..16u32 {
                assert!(once[(y * 16 + x) as usize] <= 1, "pixel {x},{y}: {}", once[(y * 16 + x) as usize]);
                if x == 8 && (2..=14).contains(&y) {
                    assert_eq!(once[(y * 16 + x) as usize], 1, "pixel {x},{y}");
                }
            }
        }
        // Which faces: the eye in a face's plane, perspective; a face along
        // the view direction, orthographic; none of a generic tet.
        let tet = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        // FACES[3] = vertices 0, 2, 1: the plane z = 0.
        assert_eq!(edge_on_faces(&tet, [3.0, 2.0, 0.0], [0.0; 3], true), 1 << 3);
        assert_eq!(edge_on_faces(&tet, [3.0, 2.0, 1e-3], [0.0; 3], true), 0);
        assert_eq!(edge_on_faces(&tet, [0.0; 3], [1.0, 1.0, 0.0], false), 1 << 3);
        assert_eq!(edge_on_faces(&tet, [5.0, 4.0, 3.0], [0.0; 3], true), 0);
    }

    /// A grid of two cells sharing a face, seen along it: every pixel centre
    /// of their joint square covered by exactly one of them, in the order
    /// given; a cell behind the eye plane is listed for the plane test.
    #[test]
    fn lists_partition_shared_faces_and_keep_order() {
        let size = [16, 16];
        // Two tets in the plane z = 0.5 (orthographic): a square split along
        // its diagonal, each with a fourth vertex above its own triangle.
        let v = |x: f32, y: f32| [x, y, 0.5, 1.0];
        let a = [v(-1.0, -1.0), v(1.0, -1.0), v(1.0, 1.0), v(0.5, -0.5)];
        let b = [v(-1.0, -1.0), v(1.0, 1.0), v(-1.0, 1.0), v(-0.5, 0.5)];
        let c = [v(-1.0, -1.0), v(1.0, -1.0), v(1.0, 1.0), v(0.5, -0.5)];
        let fp: Vec<Footprint> = [a, b, c].iter().map(|clip| Footprint::of(clip, f32::NEG_INFINITY, size)).collect();
        let lists = PixelLists::build(&fp, |slot| 10 + slot as u32, size);
        assert_eq!(lists.first.len(), 257);
        let all: Vec<u32> = lists.band_cells.concat();
        for i in 0..256 {
            let cells = &all[lists.first[i] as usize..lists.first[i + 1] as usize];
            let (x, y) = (i % 16, i / 16);
            // a (slot 0) and b (slot 1) partition the square; c (slot 2) repeats a, after it.
            let in_a = cells.contains(&10);
            assert!(in_a != cells.contains(&11), "pixel {x},{y}: {cells:?}");
            assert_eq!(cells.contains(&12), in_a, "pixel {x},{y}: {cells:?}");
            if in_a {
                assert_eq!(cells, &[10, 12][..]);
            }
        }
        // Behind the eye plane: every pixel of its box, marked for the plane test.
        let straddle = [v(0.0, 0.0), [0.1, 0.0, 0.0, -1.0], v(0.1, 0.1), v(0.0, 0.1)];
        let fp = [Footprint::of(&straddle, 0.01, size)];
        assert!(matches!(fp[0], Footprint::Planes(_)));
        let lists = PixelLists::build(&fp, |_| 7, size);
        assert!(lists.entries() > 0 && lists.band_cells.concat().iter().all(|&e| e == 7 | PLANE_TEST_BIT));
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
