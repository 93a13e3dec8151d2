//! Adaptive image-space refinement (issue 37; Levoy, "Volume rendering by
//! adaptive refinement", 1990), shared by the ray casters' `adaptive=TOL`
//! option: fewer rays than pixels where the image is smooth, every pixel
//! where it is not. All on the device, in seven compute passes
//! (shaders/common/adaptive.glsl, adaptive_decide.comp):
//!
//! 1. **cast, step 8**: a ray at every point of the 8-pixel lattice over
//!    the frame's rectangle (blocks of [`BLOCK`] = 16 pixels: their corners,
//!    centres and edge mid-points), rows of workgroups interleaved over the
//!    device's threads (`screen::interleaved_rows`);
//! 2. **decide, blocks of 16**: a block is filled, by the biquadratic
//!    through its nine rays, when its centre and four edge mid-points agree
//!    with the bilinear interpolation of its corners within TOL per
//!    premultiplied RGBA channel *and* the conservative structural test
//!    passes: the nine rays carry the same
//!    structural key (tet-raycast: boundary entries taken; the volume
//!    casters: the occupied bricks met) and, where the method projects one,
//!    no boundary silhouette edge reaches the block ([`Silhouettes`]);
//!    otherwise its four blocks of 8 are listed;
//! 3. **cast, step 4**: the points the decide pass listed (the centres and
//!    edge mid-points of the refined blocks' blocks of 8, each once, a
//!    block's together), an indirect dispatch over the list whose
//!    workgroups are interleaved over the device's threads like rows. Not a
//!    2D dispatch over the lattice: on llvmpipe an invocation that returns
//!    at once still runs the whole shader masked (docs/compute-speed.md),
//!    and not invocations per listed block: a point two blocks share would
//!    leave lanes idle;
//! 4. **decide, blocks of 8**, 5. **cast, step 2**, 6. **decide, blocks
//!    of 4**, 7. **cast, step 1**: the same rule over the listed blocks
//!    (indirect dispatches), each failing block listing its sub-blocks'
//!    points for the next cast, down to single pixels.
//!
//! The coarsest level is 16 pixels, not 8, and the fill biquadratic, not
//! bilinear: with bilinear fills blocks of 16 missed the image's curvature
//! (twice the error of blocks of 8 at the same TOL on post-small, more rays
//! at equal error); the biquadratic through the nine rays the test cast
//! anyway takes it, and on smooth images most blocks of 16 pass, so their
//! 4-lattice points are never cast (docs/methods.md has the figures).
//!
//! The passes write pixels (rays cast, blocks filled) to a buffer, rows of
//! the rectangle's width, copied into the target's rectangle after the last
//! pass ([`CommandRecorder::copy_rect_to_image`]): on llvmpipe an image
//! store costs a call per SIMD vector, and the fills are most pixels.
//!
//! Rays already cast are reused as the next level's corners; a pixel is
//! either cast or filled, and a ray cast later overwrites an interpolated
//! value (never the other way). The full-resolution image is what the run
//! measures against the f64 reference, as for every method.
//!
//! **Time per pass**: timestamps around the seven passes give each its
//! device time, reported as the phases [`PASS_PHASES`] (`time_ms.<name>`,
//! part of the frame's `gpu`). Counted instructions (`--count`) are not
//! split per pass: the passes run in one submission on lavapipe's queue
//! thread, and callgrind's dumps are taken at the host's phase boundaries,
//! which bracket the whole submission (`device`).
//!
//! **Counts** (device counters, deterministic): rays cast per pass, lattice
//! points past the rectangle (no ray), blocks filled per level, blocks
//! refined per level and why (silhouette, structure, colour), and the
//! covered pixels (alpha > 0) for rays per covered pixel.

use std::sync::Arc;

use anyhow::{bail, Result};
use serde_json::json;

use super::method::Work;
use super::screen;
use crate::vk::{
    Buffer, BufferDesc, BufferUsage, CommandRecorder, ComputePipelineKey, Context, DescriptorResource,
    DescriptorSet, DescriptorSetDesc, Image, MemoryKind, Pipeline, PipelineKey, ShaderKey, ShaderStage, Stages,
    TimestampAt, TimestampPool, UploadClass, UploadCounter,
};

/// Coarsest block side (pixels).
pub const BLOCK: u32 = 16;
/// The block sizes decided, coarsest first (a size's level is its index).
const SIZES: [u32; 3] = [16, 8, 4];
/// The first cast pass's step: the lattice of the coarsest blocks' corners,
/// centres and edge mid-points.
const LATTICE_STEP: u32 = BLOCK / 2;
/// Workgroup shape of every adaptive pass (the list passes run it as 64
/// invocations in a row).
pub const WORKGROUP: [u32; 2] = [8, 8];
/// Counter words (`A_*` in shaders/common/adaptive.glsl).
const COUNTER_WORDS: usize = 40;
/// Where the indirect arguments of the decide passes over the listed
/// blocks of 8 and 4 and of the three list casts begin (bytes; `A_ARGS_*`).
const ARGS_DECIDE: [u64; 2] = [0, 3 * 4];
const ARGS_CAST: [u64; 3] = [6 * 4, 9 * 4, 12 * 4];
/// The decide pass's push constants (`Decide` in
/// `shaders/common/adaptive_decide.comp`; `tests/shader_interfaces.rs`
/// checks the two agree).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DecidePush {
    /// The frame's rectangle, inclusive pixel bounds.
    pub rect: [u32; 4],
    /// 16, 8 or 4.
    pub block_size: u32,
    /// Size 16: rows of workgroups (`interleaved_row`); every size: the
    /// device's runs (`rows` of the cast passes' indirect dispatches).
    pub rows: u32,
    pub runs: u32,
    /// First word of this size's silhouette bits (`u32::MAX`: none).
    pub silhouettes: u32,
    /// Tolerance per premultiplied channel.
    pub tol: f32,
    /// First word of this size's straight-chord bits (`u32::MAX`: none;
    /// [`Silhouettes::straight`]).
    pub straight: u32,
}
/// List entries are 16-bit coordinates of blocks of 4.
const MAX_BLOCKS_PER_SIDE: u64 = 1 << 16;

/// The device phases of the seven passes, in order (`RenderMethod::
/// after_frame`: each pass's GPU time from the timestamps around it).
pub const PASS_PHASES: [&str; 7] = [
    "adaptive_cast8_gpu",
    "adaptive_decide16_gpu",
    "adaptive_cast4_gpu",
    "adaptive_decide8_gpu",
    "adaptive_cast2_gpu",
    "adaptive_decide4_gpu",
    "adaptive_cast1_gpu",
];

/// The help text of every ray caster's `adaptive` option.
pub const HELP: &str = "adaptive image-space refinement: 0 = off (a ray per pixel); TOL > 0 = rays at the corners, \
    centres and edge mid-points of 16x16 blocks, a block filled (by the biquadratic through those nine rays) when they \
    agree with its corners' bilinear interpolation within TOL per premultiplied RGBA channel and a structural test passes, else refined to 8x8, 4x4, 2x2 \
    and single pixels (docs/methods.md, adaptive refinement)";

/// What adaptive refinement at `tol` (0: off) adds to a method's bound on
/// max |error| (the stress suite's): twice the tolerance. The test rays
/// agree with the bilinear interpolation within `tol` at the centre and
/// edge mid-points, where a block's bilinear error from smooth (quadratic)
/// variation is largest, and the biquadratic fill passes through them;
/// twice leaves room for the rest. A feature that
/// lies between the test rays of a block the structural test passes is not
/// bounded by this: such a case fails the stress suite (docs/stress.md).
pub fn bound(tol: f64) -> f64 {
    2.0 * tol.max(0.0)
}

/// Blocks of 16 across and down the inclusive pixel bounds `rect` (zero
/// for an empty one).
pub fn blocks(rect: [u32; 4]) -> [u32; 2] {
    if rect[0] > rect[2] || rect[1] > rect[3] {
        return [0, 0];
    }
    [(rect[2] - rect[0] + 1).div_ceil(BLOCK), (rect[3] - rect[1] + 1).div_ceil(BLOCK)]
}

/// Lattice points (samples) over an image of `size` at most.
fn lattice_points(size: [u32; 2]) -> u64 {
    let b = [u64::from(size[0].div_ceil(BLOCK)), u64::from(size[1].div_ceil(BLOCK))];
    (u64::from(BLOCK) * b[0] + 1) * (u64::from(BLOCK) * b[1] + 1)
}

/// The silhouette bits' layout over `n16` blocks of 16: the first word of
/// each size's bit rows ([`SIZES`] order), and the words of those rows (the
/// straight-chord rows follow them, as many again).
fn silhouette_layout(n16: u64) -> ([u32; 3], u64) {
    let mut offsets = [0u32; 3];
    let mut words = 0u64;
    for (l, size) in SIZES.iter().enumerate() {
        let k = u64::from(BLOCK / size);
        offsets[l] = words as u32;
        words += (n16 * k * k).div_ceil(32);
    }
    (offsets, words)
}

/// A block size's level, its index in [`SIZES`] (16: 0, 8: 1, 4: 2).
fn level(size: u32) -> usize {
    match size {
        16 => 0,
        8 => 1,
        _ => 2,
    }
}

/// Where boundary silhouettes could hide something between a block's test
/// rays, per block of 16, 8 and 4 of the frame's rectangle: bit rows over
/// each size's blocks, from [`Silhouettes::offsets`]; then the same rows
/// again from [`Silhouettes::straight`] for the blocks a single straight
/// chord crosses.
///
/// A block is marked when the silhouette segments reaching its closed
/// square (its corner rays included), padded by `pad` pixels, are not one
/// straight chord across it: two lines (crossing, parallel: a thin band
/// between them, such as a plate's rims seen edge-on), a bend, or an end
/// inside it (a thin spike, a corner). A single straight line across a
/// block is left to the colour test, which sees it: a line through the
/// square's interior has corners on both sides (a half-plane holding all
/// four holds the square), so an edge mid-point between corners of the two
/// sides, or the centre, is interpolated half-way across whatever the line
/// separates; where that jump exceeds 2 TOL the block refines, and where it
/// does not, interpolation is off by at most about the jump (the bound's
/// 2 TOL). Across a contour edge of a closed boundary the integral is even
/// continuous (the two crossings next to the edge meet there). The rays on
/// the chord's two sides take different numbers of boundary entries, so
/// such a block skips the structural key's test ([`Silhouettes::straight`]);
/// a block no silhouette reaches has one key throughout.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Silhouettes {
    pub words: Vec<u32>,
    /// The first word of each size's bits (16, 8, 4: [`SIZES`]).
    pub offsets: [u32; 3],
    /// Where the bits of the blocks crossed by one straight chord start
    /// (each size's from `straight + offsets[level]`).
    pub straight: u32,
    /// Blocks of 16, 8 and 4 marked.
    pub marked: [u64; 3],
    /// Blocks of 16 a silhouette reaches but leaves to the colour test (one
    /// straight line across).
    pub straight16: u64,
    /// Silhouette segments within the rectangle and their length (pixels).
    pub segments: u64,
    pub length_px: f64,
}

/// Segments this close (pixels) to one line are on it: collinear pieces of
/// one straight contour edge, split by the mesh, differ only by rounding.
const COLLINEAR_PX: f64 = 1e-6;

impl Silhouettes {
    /// Marks `segments` (pixel coordinates, pixel x's centre at x) over the
    /// blocks of `rect`; a segment's part outside the rectangle's padded box
    /// is clipped away first, so the work is bounded by the rectangle.
    pub fn mark(rect: [u32; 4], segments: impl IntoIterator<Item = ([f64; 2], [f64; 2])>, pad: f64) -> Self {
        let nb = blocks(rect);
        let n16 = nb[0] as usize * nb[1] as usize;
        let (offsets, half) = silhouette_layout(n16 as u64);
        let half = half as usize;
        let mut s = Silhouettes { words: vec![0; 2 * half], offsets, straight: half as u32, ..Default::default() };
        if n16 == 0 {
            return s;
        }
        let o = [f64::from(rect[0]), f64::from(rect[1])];
        // The lattice box (blocks of 16 units), padded.
        let b = f64::from(BLOCK);
        let hi = [f64::from(nb[0]) * b, f64::from(nb[1]) * b];
        let clipped: Vec<([f64; 2], [f64; 2])> = segments
            .into_iter()
            .filter_map(|(a, b)| clip([a[0] - o[0], a[1] - o[1]], [b[0] - o[0], b[1] - o[1]], [-pad, -pad], [hi[0] + pad, hi[1] + pad]))
            .collect();
        s.segments = clipped.len() as u64;
        s.length_px = clipped.iter().map(|(a, b)| (b[0] - a[0]).hypot(b[1] - a[1])).sum();
        for (l, &size) in SIZES.iter().enumerate() {
            let k = (BLOCK / size) as usize;
            let n = [nb[0] as usize * k, nb[1] as usize * k];
            let (offset, size) = (offsets[l] as usize, f64::from(size));
            // The segments reaching each block's padded closed square.
            let mut reach: Vec<Vec<u32>> = vec![Vec::new(); n[0] * n[1]];
            for (i, (a, b)) in clipped.iter().enumerate() {
                for_each_block(*a, *b, size, pad, n, |x, y| reach[y * n[0] + x].push(i as u32));
            }
            let mut marked = 0u64;
            let mut straight = 0u64;
            for (bit, list) in reach.iter().enumerate() {
                if list.is_empty() {
                    continue;
                }
                let (x, y) = ((bit % n[0]) as f64 * size, (bit / n[0]) as f64 * size);
                if one_chord(&clipped, list, [x - pad, y - pad], [x + size + pad, y + size + pad]) {
                    straight += 1;
                    s.words[half + offset + bit / 32] |= 1 << (bit % 32);
                    continue;
                }
                marked += 1;
                s.words[offset + bit / 32] |= 1 << (bit % 32);
            }
            s.marked[l] = marked;
            if l == 0 {
                s.straight16 = straight;
            }
        }
        s
    }

    /// Whether block `(x, y)` of `size` (16, 8 or 4) is marked, for tests.
    pub fn is_marked(&self, rect: [u32; 4], size: u32, x: u32, y: u32) -> bool {
        self.bit(rect, size, x, y, 0)
    }

    /// Whether one straight chord crosses block `(x, y)` of `size`, for tests.
    pub fn is_straight(&self, rect: [u32; 4], size: u32, x: u32, y: u32) -> bool {
        self.bit(rect, size, x, y, self.straight)
    }

    fn bit(&self, rect: [u32; 4], size: u32, x: u32, y: u32, base: u32) -> bool {
        let nb = blocks(rect);
        let (w, off) = (nb[0] * (BLOCK / size), self.offsets[level(size)]);
        let bit = (y * w + x) as usize;
        self.words[(base + off) as usize + bit / 32] >> (bit % 32) & 1 == 1
    }
}

/// Calls `f(x, y)` for every block (squares of `size` on a grid of `n`
/// blocks from the origin) whose closed square padded by `pad` the segment
/// a-b reaches: per column of blocks, the segment's part within the
/// column's padded slab, and the blocks its y-range reaches.
fn for_each_block(a: [f64; 2], b: [f64; 2], size: f64, pad: f64, n: [usize; 2], mut f: impl FnMut(usize, usize)) {
    let first = |lo: f64| ((lo - pad) / size).ceil() - 1.0;
    let last = |hi: f64| ((hi + pad) / size).floor();
    let range = |lo: f64, hi: f64, count: usize| {
        let (l, h) = (first(lo).max(0.0), last(hi).min(count as f64 - 1.0));
        (l <= h).then_some((l as usize, h as usize))
    };
    let Some((x0, x1)) = range(a[0].min(b[0]), a[0].max(b[0]), n[0]) else { return };
    for x in x0..=x1 {
        let slab = [x as f64 * size - pad, (x + 1) as f64 * size + pad];
        let Some((p, q)) = clip(a, b, [slab[0], f64::NEG_INFINITY], [slab[1], f64::INFINITY]) else { continue };
        let Some((y0, y1)) = range(p[1].min(q[1]), p[1].max(q[1]), n[1]) else { continue };
        for y in y0..=y1 {
            f(x, y);
        }
    }
}

/// Whether the segments `list` of `all` lie on one line that they cover
/// wholly across the box [lo, hi] (no end, gap or second line in it).
fn one_chord(all: &[([f64; 2], [f64; 2])], list: &[u32], lo: [f64; 2], hi: [f64; 2]) -> bool {
    // The line of the longest segment (the best-conditioned direction).
    let longest = |&i: &u32| {
        let (a, b) = all[i as usize];
        (b[0] - a[0]).hypot(b[1] - a[1])
    };
    let Some(&base) = list.iter().max_by(|i, j| longest(i).total_cmp(&longest(j))) else { return false };
    let (p, q) = all[base as usize];
    let d = [q[0] - p[0], q[1] - p[1]];
    let len = d[0].hypot(d[1]);
    if !(len > COLLINEAR_PX) {
        return false;
    }
    let u = [d[0] / len, d[1] / len];
    // Signed distance from the line, and position along it (pixels).
    let off = |r: [f64; 2]| (r[0] - p[0]) * u[1] - (r[1] - p[1]) * u[0];
    let along = |r: [f64; 2]| (r[0] - p[0]) * u[0] + (r[1] - p[1]) * u[1];
    let mut pieces: Vec<(f64, f64)> = Vec::with_capacity(list.len());
    for &i in list {
        let (a, b) = all[i as usize];
        if off(a).abs() > COLLINEAR_PX || off(b).abs() > COLLINEAR_PX {
            return false;
        }
        let (s, t) = (along(a), along(b));
        pieces.push((s.min(t), s.max(t)));
    }
    // The whole line's chord across the box, in the same measure.
    let far = 4.0 * (hi[0] - lo[0] + hi[1] - lo[1]) + p[0].abs() + p[1].abs() + q[0].abs() + q[1].abs();
    let Some((c0, c1)) = clip([p[0] - u[0] * far, p[1] - u[1] * far], [p[0] + u[0] * far, p[1] + u[1] * far], lo, hi) else { return false };
    let (start, end) = { let (s, t) = (along(c0), along(c1)); (s.min(t), s.max(t)) };
    pieces.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut covered = start;
    for (s, t) in pieces {
        if s > covered + COLLINEAR_PX {
            return false;
        }
        covered = covered.max(t);
    }
    covered >= end - COLLINEAR_PX
}

/// Segment a-b clipped to the box [lo, hi] (Liang-Barsky), None when it
/// misses it.
fn clip(a: [f64; 2], b: [f64; 2], lo: [f64; 2], hi: [f64; 2]) -> Option<([f64; 2], [f64; 2])> {
    if !(a.iter().chain(&b).all(|v| v.is_finite())) {
        return None;
    }
    let d = [b[0] - a[0], b[1] - a[1]];
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..2 {
        for (p, q) in [(-d[k], a[k] - lo[k]), (d[k], hi[k] - a[k])] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
            }
        }
    }
    (t0 <= t1).then(|| ([a[0] + d[0] * t0, a[1] + d[1] * t0], [a[0] + d[0] * t1, a[1] + d[1] * t1]))
}

/// The adaptive passes' state: samples and keys per lattice point, the
/// block lists, the counters (with the indirect arguments), the silhouette
/// bits, and the decide pipeline.
pub struct Adaptive {
    pub tol: f64,
    /// Set of the cast passes (bindings 0-3 of shaders/common/adaptive.glsl;
    /// the decide pass's binding 4 too).
    pub desc: DescriptorSetDesc,
    set: DescriptorSet,
    keys: Buffer,
    counters: Buffer,
    silhouettes: Buffer,
    _samples: Buffer,
    _lists: Buffer,
    decide: Arc<Pipeline>,
    /// The frame's pixels (binding 5), copied into the target's rectangle
    /// after the passes.
    pixels: Buffer,
    size: [u32; 2],
    /// The frame's rectangle and silhouettes (None: the method projects none).
    rect: [u32; 4],
    sil: Option<Silhouettes>,
    uses_silhouettes: bool,
    /// Timestamps before the first pass and after each ([`PASS_PHASES`]);
    /// `timed`: the last recorded frame wrote them all.
    timestamps: TimestampPool,
    timed: bool,
    ctx: Arc<Context>,
}

impl Adaptive {
    /// State for images up to `width` x `height`; `silhouettes`: the method
    /// marks silhouettes per frame ([`Adaptive::set_silhouettes`]).
    pub fn new(ctx: &Arc<Context>, method: &str, tol: f64, width: u32, height: u32, silhouettes: bool) -> Result<Self> {
        if !(tol > 0.0 && tol.is_finite()) {
            bail!("{method}: adaptive tolerance {tol} must be above 0");
        }
        let size = [width, height];
        let nb = [u64::from(width.div_ceil(BLOCK)), u64::from(height.div_ceil(BLOCK))];
        // Blocks of 4 are listed by 16-bit coordinates: 4 per block of 16.
        if nb[0] * 4 > MAX_BLOCKS_PER_SIDE || nb[1] * 4 > MAX_BLOCKS_PER_SIDE {
            bail!("{method}: adaptive refinement takes images up to {} pixels a side, not {width}x{height}", MAX_BLOCKS_PER_SIDE * 4);
        }
        let points = lattice_points(size);
        let n16 = nb[0] * nb[1];
        // The longest dispatches: the blocks of 4, one invocation each in
        // a row of workgroups; a point list, rows of workgroups (padded to
        // the device's runs).
        let group = u64::from(WORKGROUP[0] * WORKGROUP[1]);
        let runs = u64::from(ctx.info.compute_runs());
        let most_groups = (16 * n16).div_ceil(group).max(points.div_ceil(group).div_ceil(runs) * runs);
        let max_xy = u64::from(ctx.info.max_compute_work_group_count[0].min(ctx.info.max_compute_work_group_count[1]));
        let range = u64::from(ctx.info.max_storage_buffer_range);
        // The blocks of 8 and of 4 (4 and 16 per block of 16), then three
        // point lists (adaptive_blocks_at, adaptive_points_at). The pixel
        // buffer (16 bytes a pixel) is no larger than the samples: the
        // lattice covers the image.
        let list_words = 20 * n16 + 3 * points;
        if most_groups > max_xy || points * 16 > range || list_words * 4 > range {
            bail!(
                "{method}: adaptive refinement of a {width}x{height} image needs {most_groups} workgroups in a row and {} bytes of samples; \
                 {} allows {max_xy} and {range}",
                points * 16,
                ctx.info.name
            );
        }
        let storage = BufferUsage::STORAGE;
        let samples = Buffer::new(ctx, BufferDesc::device_local(&format!("{method} adaptive samples"), points * 16, storage))?;
        let keys = Buffer::new(ctx, BufferDesc::device_local(&format!("{method} adaptive keys"), points * 4, storage))?;
        let lists = Buffer::new(ctx, BufferDesc::device_local(&format!("{method} adaptive lists"), list_words.max(1) * 4, storage))?;
        let counters = Buffer::new(
            ctx,
            BufferDesc {
                name: format!("{method} adaptive counters"),
                size: (COUNTER_WORDS * 4) as u64,
                usage: BufferUsage::STORAGE | BufferUsage::TRANSFER_DST | BufferUsage::INDIRECT,
                memory: MemoryKind::Readback,
            },
        )?;
        let sil_words = if silhouettes { (2 * silhouette_layout(n16).1).max(1) } else { 1 };
        let sil_buffer = Buffer::new(ctx, BufferDesc::upload(&format!("{method} adaptive silhouettes"), sil_words * 4, storage))?;
        let compute = Stages::COMPUTE;
        let pixels = Buffer::new(
            ctx,
            BufferDesc::device_local(&format!("{method} adaptive pixels"), u64::from(width) * u64::from(height) * 16, storage | BufferUsage::TRANSFER_SRC),
        )?;
        let desc = DescriptorSetDesc::storage_buffers(6, compute);
        let set = DescriptorSet::new(
            ctx,
            &format!("{method} adaptive"),
            &desc,
            &[
                DescriptorResource::StorageBuffer(&samples),
                DescriptorResource::StorageBuffer(&keys),
                DescriptorResource::StorageBuffer(&lists),
                DescriptorResource::StorageBuffer(&counters),
                DescriptorResource::StorageBuffer(&sil_buffer),
                DescriptorResource::StorageBuffer(&pixels),
            ],
        )?;
        let key = PipelineKey::Compute(ComputePipelineKey {
            shader: ShaderKey::new("common/adaptive_decide.comp", ShaderStage::Compute, &[]),
            push_constant_bytes: std::mem::size_of::<DecidePush>() as u32,
            sets: vec![desc.clone()],
        });
        let decide = super::pipelines::get(ctx, &key)?;
        Ok(Adaptive {
            tol,
            desc,
            set,
            keys,
            counters,
            silhouettes: sil_buffer,
            _samples: samples,
            _lists: lists,
            decide,
            pixels,
            size,
            rect: screen::NO_PIXELS,
            sil: None,
            uses_silhouettes: silhouettes,
            timestamps: TimestampPool::new(ctx, &format!("{method} adaptive timestamps"), PASS_PHASES.len() as u32 + 1)?,
            timed: false,
            ctx: ctx.clone(),
        })
    }

    /// The set the cast passes bind (at their `ADAPTIVE_SET`).
    pub fn set(&self) -> &DescriptorSet {
        &self.set
    }

    /// This frame's rectangle (inclusive pixel bounds within the image the
    /// state was made for).
    pub fn frame(&mut self, rect: [u32; 4], view_size: [u32; 2]) -> Result<()> {
        if view_size[0] > self.size[0] || view_size[1] > self.size[1] {
            bail!("adaptive refinement was set up for {}x{} pixels, not {}x{}", self.size[0], self.size[1], view_size[0], view_size[1]);
        }
        self.rect = rect;
        self.sil = None;
        Ok(())
    }

    /// This frame's silhouette marks ([`Silhouettes::mark`] over the
    /// frame's rectangle).
    pub fn set_silhouettes(&mut self, sil: Silhouettes) {
        self.sil = Some(sil);
    }

    pub fn upload(&mut self, counter: &mut UploadCounter) -> Result<()> {
        if let Some(s) = &self.sil {
            if !s.words.is_empty() {
                self.silhouettes.write(0, bytemuck::cast_slice(&s.words), counter, UploadClass::FrameCells)?;
            }
        }
        Ok(())
    }

    /// Records the seven passes. `bind(rec, set, step, rows, counter)`
    /// readies one cast pass: its pipeline bound with `set` (this state's)
    /// at its `ADAPTIVE_SET`, its push constants naming `step` (8, 4, 2,
    /// or 1) and, for step 8, `rows`: the rows of workgroups over the
    /// 8-lattice ([`Adaptive::lattice_groups`], before interleaving); the
    /// dispatch is recorded here.
    pub fn record(
        &mut self,
        rec: &CommandRecorder,
        target: &Image,
        counter: &mut UploadCounter,
        mut bind: impl FnMut(&CommandRecorder, &DescriptorSet, u32, u32, &mut UploadCounter) -> Result<()>,
    ) -> Result<()> {
        self.timed = false;
        self.timestamps.reset(rec);
        rec.fill_buffer(&self.keys, 0);
        rec.fill_buffer(&self.counters, 0);
        rec.transfer_to_storage(Stages::COMPUTE);
        let nb = blocks(self.rect);
        if nb[0] == 0 || nb[1] == 0 {
            rec.compute_to_host();
            return Ok(());
        }
        let runs = self.ctx.info.compute_runs();
        let lattice = Adaptive::lattice_groups(self.rect);
        self.timestamps.write(rec, 0, TimestampAt::Start)?;
        bind(rec, &self.set, LATTICE_STEP, lattice[1], counter)?;
        rec.dispatch([lattice[0], screen::interleaved_rows(lattice[1], runs), 1])?;
        self.timestamps.write(rec, 1, TimestampAt::ComputeDone)?;
        rec.compute_to_indirect();
        let push = |block_size: u32, rows: u32| {
            let (sil, straight) = match (&self.sil, self.uses_silhouettes) {
                (Some(s), true) => (s.offsets[level(block_size)], s.straight + s.offsets[level(block_size)]),
                _ => (u32::MAX, u32::MAX),
            };
            DecidePush { rect: self.rect, block_size, rows, runs, silhouettes: sil, tol: self.tol as f32, straight }
        };
        let mut stamp = 2;
        for (l, &size) in SIZES.iter().enumerate() {
            // Decide the blocks of `size` (the coarsest: all of them, a 2D
            // dispatch; the others: the listed ones), then cast the points
            // they listed, at a step of a quarter of the size.
            rec.bind_compute(&self.decide, &[&self.set])?;
            if l == 0 {
                let rows = nb[1].div_ceil(WORKGROUP[1]);
                rec.push_constants(&self.decide, bytemuck::bytes_of(&push(size, rows)), counter);
                rec.dispatch([nb[0].div_ceil(WORKGROUP[0]), screen::interleaved_rows(rows, runs), 1])?;
            } else {
                rec.push_constants(&self.decide, bytemuck::bytes_of(&push(size, 0)), counter);
                rec.dispatch_indirect(&self.counters, ARGS_DECIDE[l - 1])?;
            }
            self.timestamps.write(rec, stamp, TimestampAt::ComputeDone)?;
            rec.compute_to_indirect();
            bind(rec, &self.set, size / 4, 0, counter)?;
            rec.dispatch_indirect(&self.counters, ARGS_CAST[l])?;
            self.timestamps.write(rec, stamp + 1, TimestampAt::ComputeDone)?;
            stamp += 2;
            if l + 1 < SIZES.len() {
                rec.compute_to_indirect();
            }
        }
        rec.copy_rect_to_image(&self.pixels, target, self.rect)?;
        rec.compute_to_host();
        self.timed = true;
        Ok(())
    }

    /// A frame recorded without the passes (the method cast every pixel):
    /// no pass times for it.
    pub fn skipped(&mut self) {
        self.timed = false;
    }

    /// The last recorded frame's device time per pass ([`PASS_PHASES`]),
    /// after its fence: empty when it ran no passes or the queue has no
    /// timestamps.
    pub fn device_phases(&self) -> Result<Vec<(&'static str, f64)>> {
        if !self.timed || self.ctx.info.timestamp_valid_bits == 0 {
            return Ok(Vec::new());
        }
        // One read of the eight timestamps (each read costs the `finish`
        // phase's counted instructions some thousands, varying).
        let t = self.timestamps.all_ms()?;
        Ok(PASS_PHASES.iter().enumerate().map(|(i, name)| (*name, t[i + 1] - t[i])).collect())
    }

    /// The step-8 cast pass's grid: workgroups across, rows of workgroups
    /// (before interleaving) over the 8-lattice of `rect`.
    pub fn lattice_groups(rect: [u32; 4]) -> [u32; 2] {
        let nb = blocks(rect);
        if nb[0] == 0 || nb[1] == 0 {
            return [0, 0];
        }
        [(2 * nb[0] + 1).div_ceil(WORKGROUP[0]), (2 * nb[1] + 1).div_ceil(WORKGROUP[1])]
    }

    fn counts(&self) -> Counts {
        let c: [u64; COUNTER_WORDS] = self.counters.read_counters();
        let three = |at: usize| [c[at], c[at + 1], c[at + 2]];
        Counts {
            rays: [c[21], c[22], c[23], c[24]],
            filled: three(25),
            silhouette: three(28),
            structure: three(31),
            colour: three(34),
            covered: c[37] + c[38],
            padding: c[39],
            listed: three(15),
        }
    }

    /// Rays cast this frame (all passes).
    pub fn rays_cast(&self) -> u64 {
        self.counts().rays.iter().sum()
    }

    /// The frame's counts added to a method's.
    pub fn work(&self, w: Work) -> Work {
        let c = self.counts();
        let sil = self.sil.as_ref().map_or(0, |s| s.marked[0]);
        let mut w = w
            .with("adaptive_rays_cast", c.rays.iter().sum())
            .with("adaptive_rays_step8", c.rays[0])
            .with("adaptive_rays_step4", c.rays[1])
            .with("adaptive_rays_step2", c.rays[2])
            .with("adaptive_rays_step1", c.rays[3])
            .with("adaptive_covered_pixels", c.covered);
        for (l, [filled, silhouette, structure, colour]) in BLOCK_COUNTS.into_iter().enumerate() {
            w = w.with(filled, c.filled[l]).with(silhouette, c.silhouette[l]).with(structure, c.structure[l]).with(colour, c.colour[l]);
        }
        w.with("adaptive_blocks2_cast", c.listed[2]).with("adaptive_blocks16_silhouette_marked", sil)
    }

    /// The frame's figures for a method's details.
    pub fn details(&self, rect_pixels: u64) -> serde_json::Value {
        let c = self.counts();
        let rays: u64 = c.rays.iter().sum();
        let per = |n: u64, of: u64| if of > 0 { n as f64 / of as f64 } else { 0.0 };
        let per_size = |v: [u64; 3]| json!({ "16": v[0], "8": v[1], "4": v[2] });
        let refined = |l: usize| json!({ "silhouette": c.silhouette[l], "structure": c.structure[l], "colour": c.colour[l] });
        json!({
            "tolerance": self.tol,
            "block": BLOCK,
            "silhouettes": self.uses_silhouettes,
            "rays_cast": rays,
            "rays_per_pass": { "step8": c.rays[0], "step4": c.rays[1], "step2": c.rays[2], "step1": c.rays[3] },
            "rays_per_rect_pixel": per(rays, rect_pixels),
            "covered_pixels": c.covered,
            "rays_per_covered_pixel": per(rays, c.covered),
            "lattice_padding_points": c.padding,
            "blocks_filled": per_size(c.filled),
            "blocks_refined": { "16": refined(0), "8": refined(1), "4": refined(2) },
            "blocks_listed": { "8": c.listed[0], "4": c.listed[1], "2": c.listed[2] },
            "silhouette": self.sil.as_ref().map(|s| json!({
                "segments": s.segments,
                "length_px": s.length_px,
                "blocks_marked": per_size(s.marked),
                "blocks16_straight": s.straight16,
            })),
        })
    }
}

/// The work counts of each block size ([`SIZES`]): filled, refined for a
/// silhouette, for the structure, for the colour.
const BLOCK_COUNTS: [[&str; 4]; 3] = [
    ["adaptive_blocks16_filled", "adaptive_blocks16_refined_silhouette", "adaptive_blocks16_refined_structure", "adaptive_blocks16_refined_colour"],
    ["adaptive_blocks8_filled", "adaptive_blocks8_refined_silhouette", "adaptive_blocks8_refined_structure", "adaptive_blocks8_refined_colour"],
    ["adaptive_blocks4_filled", "adaptive_blocks4_refined_silhouette", "adaptive_blocks4_refined_structure", "adaptive_blocks4_refined_colour"],
];

/// The counter words read back, per level (blocks of 16, 8, 4; rays per
/// cast step 8, 4, 2, 1).
struct Counts {
    rays: [u64; 4],
    filled: [u64; 3],
    silhouette: [u64; 3],
    structure: [u64; 3],
    colour: [u64; 3],
    covered: u64,
    padding: u64,
    /// Blocks listed: of 8, of 4, and blocks of 2 cast.
    listed: [u64; 3],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_cover_the_rectangle() {
        assert_eq!(blocks([0, 0, 63, 31]), [4, 2]);
        assert_eq!(blocks([3, 5, 3, 5]), [1, 1]);
        assert_eq!(blocks([10, 0, 27, 16]), [2, 2]);
        assert_eq!(blocks(screen::NO_PIXELS), [0, 0]);
        assert_eq!(Adaptive::lattice_groups([0, 0, 63, 31]), [2, 1]);
        assert_eq!(Adaptive::lattice_groups([0, 0, 511, 511]), [9, 9]);
        assert_eq!(Adaptive::lattice_groups(screen::NO_PIXELS), [0, 0]);
    }

    /// The marked blocks of `size` as (x, y), for comparing.
    fn marked(s: &Silhouettes, rect: [u32; 4], size: u32) -> Vec<(u32, u32)> {
        let nb = blocks(rect);
        let k = BLOCK / size;
        let mut out = Vec::new();
        for y in 0..nb[1] * k {
            for x in 0..nb[0] * k {
                if s.is_marked(rect, size, x, y) {
                    out.push((x, y));
                }
            }
        }
        out
    }

    #[test]
    fn silhouettes_mark_ends_bends_and_second_lines_not_straight_chords() {
        // At two rectangle sizes, from (1, 1): pixel coordinates relative to
        // the rectangle are the absolute ones minus 1.
        for rect in [[1u32, 1, 40, 30], [1, 1, 200, 100]] {
            let nb = blocks(rect);
            // A horizontal segment at relative y = 9.5 from x = 1 to 17.5:
            // its ends lie in blocks of 4 (0, 2) and (4, 2), of 8 (0, 1)
            // and (2, 1), and of 16 (0, 0) and (1, 0); the blocks between
            // are crossed by one straight chord and left to the colour test.
            let s = Silhouettes::mark(rect, [([2.0, 10.5], [18.5, 10.5])], 0.01);
            assert_eq!(marked(&s, rect, 4), [(0, 2), (4, 2)], "{rect:?}");
            assert_eq!(marked(&s, rect, 8), [(0, 1), (2, 1)], "{rect:?}");
            assert_eq!(marked(&s, rect, 16), [(0, 0), (1, 0)], "{rect:?}");
            assert_eq!((s.marked, s.straight16, s.segments), ([2, 2, 2], 0, 1));
            assert!((1..4).all(|x| s.is_straight(rect, 4, x, 2)) && s.is_straight(rect, 8, 1, 1));
            assert!(!s.is_straight(rect, 4, 0, 2) && !s.is_straight(rect, 8, 0, 1) && !s.is_straight(rect, 4, 1, 1));
            assert!((s.length_px - 16.5).abs() < 1e-12);
            // The same line split into collinear pieces at x = 6 and 13: the
            // same marks (a split is no end).
            let pieces = [([2.0, 10.5], [7.0, 10.5]), ([7.0, 10.5], [14.0, 10.5]), ([14.0, 10.5], [18.5, 10.5])];
            let split = Silhouettes::mark(rect, pieces, 0.01);
            assert_eq!((marked(&split, rect, 4), marked(&split, rect, 8)), (marked(&s, rect, 4), marked(&s, rect, 8)));
            // A line across the whole rectangle and beyond: nothing marked,
            // every block of 8 on its way straight; work bounded by the clip.
            let s = Silhouettes::mark(rect, [([-1e9, 10.5], [1e9, 10.5])], 0.01);
            assert_eq!(s.marked, [0, 0, 0]);
            assert_eq!(s.straight16, u64::from(nb[0]));
            // Two parallel lines 1.5 pixels apart (a thin band between
            // them): every block both reach is marked.
            let band = [([-1e9, 10.5], [1e9, 10.5]), ([-1e9, 12.0], [1e9, 12.0])];
            let s = Silhouettes::mark(rect, band, 0.01);
            assert_eq!(marked(&s, rect, 4), (0..4 * nb[0]).map(|x| (x, 2)).collect::<Vec<_>>());
            assert_eq!(s.marked, [1, 2, 4].map(|k| k * u64::from(nb[0])));
            // A bend: two pieces meeting at relative (9, 9.5) at an angle:
            // marked where the vertex is (block of 4 (2, 2), both blocks of
            // 4 and 8 whose closed squares hold x = 8 or the vertex), not
            // along the straight parts away from it.
            let bend = [([-1e9, 10.5], [10.0, 10.5]), ([10.0, 10.5], [1e9, 10.5 + 1e-3 * (1e9 - 10.0)])];
            let s = Silhouettes::mark(rect, bend, 0.01);
            assert_eq!(marked(&s, rect, 4), [(2, 2)], "{rect:?}");
            assert_eq!(marked(&s, rect, 8), [(1, 1)], "{rect:?}");
            assert_eq!(marked(&s, rect, 16), [(0, 0)], "{rect:?}");
            // On a block edge (relative y = 8), a short segment: its ends
            // mark the blocks of 4 on both sides.
            let s = Silhouettes::mark(rect, [([2.0, 9.0], [3.0, 9.0])], 0.01);
            assert!(s.is_marked(rect, 4, 0, 1) && s.is_marked(rect, 4, 0, 2));
            // A point (an edge seen end-on) alone: marked.
            let s = Silhouettes::mark(rect, [([5.5, 5.5], [5.5, 5.5])], 0.01);
            assert_eq!(marked(&s, rect, 4), [(1, 1)]);
            // Far outside: nothing; not finite: nothing.
            let s = Silhouettes::mark(rect, [([-500.0, -500.0], [-400.0, -450.0]), ([f64::NAN, 0.0], [3.0, 3.0])], 0.01);
            assert_eq!((s.marked, s.segments), ([0, 0, 0], 0));
            assert!(s.words.iter().all(|&w| w == 0));
            // A diagonal across everything: straight wherever it goes.
            let s = Silhouettes::mark(rect, [([-1e9, -1e9], [1e9, 1e9])], 0.01);
            assert_eq!(s.marked, [0, 0, 0]);
            assert!(s.straight16 >= u64::from(nb[0].min(nb[1])));
            // Two lines crossing at relative (20, 15): the blocks holding the
            // crossing are marked.
            let x = [([-1e9, -1e9 + 15.0 - 20.0], [1e9, 1e9 + 15.0 - 20.0]), ([20.0 - 1e9, 15.0 + 1e9], [20.0 + 1e9, 15.0 - 1e9])];
            let s = Silhouettes::mark(rect, x.map(|(a, b)| ([a[0] + 1.0, a[1] + 1.0], [b[0] + 1.0, b[1] + 1.0])), 0.01);
            assert!(s.is_marked(rect, 8, 2, 1) && s.is_marked(rect, 4, 5, 3) && s.is_marked(rect, 4, 4, 3));
        }
    }

    #[test]
    fn blocks_reached_by_a_segment_are_those_its_square_test_finds() {
        // for_each_block against the plain test of every block (the
        // segment clipped to each padded closed square).
        let n = [12usize, 9];
        for (a, b) in [([0.3, 0.2], [40.7, 33.1]), ([5.0, 30.0], [5.0, 2.0]), ([47.9, 0.0], [0.0, 35.9]), ([8.0, 8.0], [16.0, 8.0]), ([3.0, 3.0], [3.0, 3.0])] {
            for (size, pad) in [(4.0, 0.01), (8.0, 0.5)] {
                let mut got = Vec::new();
                for_each_block(a, b, size, pad, n, |x, y| got.push((x, y)));
                got.sort_unstable();
                let mut want = Vec::new();
                for x in 0..n[0] {
                    for y in 0..n[1] {
                        let lo = [x as f64 * size - pad, y as f64 * size - pad];
                        if clip(a, b, lo, [lo[0] + size + 2.0 * pad, lo[1] + size + 2.0 * pad]).is_some() {
                            want.push((x, y));
                        }
                    }
                }
                assert_eq!(got, want, "{a:?} {b:?} size {size}");
            }
        }
    }

    #[test]
    fn clip_keeps_the_inside_part() {
        assert_eq!(clip([-1.0, 0.5], [2.0, 0.5], [0.0, 0.0], [1.0, 1.0]), Some(([0.0, 0.5], [1.0, 0.5])));
        assert_eq!(clip([-1.0, 2.0], [2.0, 2.0], [0.0, 0.0], [1.0, 1.0]), None);
        assert_eq!(clip([0.5, 0.5], [0.5, 0.5], [0.0, 0.0], [1.0, 1.0]), Some(([0.5, 0.5], [0.5, 0.5])));
    }
}
