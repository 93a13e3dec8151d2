//! The centroid visibility sort on the device: a compute-shader LSD radix
//! sort (`shaders/cell_projection/sort_*.comp`) of the same keys the CPU's
//! `CentroidSort` sorts, into a device-local buffer of cell indices that a
//! draw reads in place. Per frame only the camera crosses (32 bytes of push
//! constants); the centroids are uploaded once.
//!
//! Keys: each cell's centroid depth (squared distance from the eye, or
//! distance along the view direction for orthographic views) in f32,
//! computed term by term as `CentroidSort::sort` computes it (no fused
//! multiply-adds), mapped by `radix::float_key` and inverted (farthest
//! first). The sort is stable, so ties stay in cell-index order: the order
//! equals the CPU's exactly (`tests/gpusort.rs`).
//!
//! Passes: one key dispatch, then per 4-bit digit (8 passes) a per-tile
//! histogram, a one-workgroup scan of the digit-major counts and a stable
//! scatter. Only shared memory and barriers are used, no subgroup
//! operations, so nothing depends on the subgroup size (4 or 8 on lavapipe).
//! Each invocation counts its keys' digits in registers (16 counters of 8
//! bits packed in a uvec4), not with shared atomics or a private array
//! indexed by the digit, both of which lavapipe runs lane by lane.
//! The pairs ping-pong between two buffer pairs; after an even number of
//! passes the order ends in `order`, where it started. Each pass has its
//! own descriptor set whose params buffer (static, uploaded once) holds the
//! digit's shift, so no per-pass constant crosses per frame.
//!
//! Synchronisation: a barrier orders the previous frame's draw (which read
//! `order`) and the previous sort before this frame's first write; one
//! compute-to-compute barrier separates every two dispatches; the last one
//! makes the order visible to the vertex stage (`record`). Timestamps
//! around the whole sort give its GPU time (`gpu_ms`).
//!
//! Centroids beyond one storage binding (8.4 M cells at lavapipe's 128 MiB)
//! come in several buffers at the device's limits (`algo::chunks`): bindings
//! 7-13, read by `centroid_at` in `radix_sort.glsl`. The keys, the
//! order and the counts stay one binding each (33.5 M cells at 128 MiB).

use std::sync::Arc;


use crate::algo::chunks::{self, ChunkLimits, MAX_CHUNKS};
use crate::scene::Camera;
use glam::{DVec3, Vec3};
use crate::vk::{
    upload_static, Buffer, BufferDesc, CommandRecorder, ComputePipelineKey, Context, DescriptorSetDesc,
    Pipeline, PipelineKey, ShaderKey, ShaderStage, StorageBufferSet, TimestampPool, UploadClass, UploadCounter, VkError,
    VkResult,
};
use crate::vk::{BufferUsage, Stages, TimestampAt};

/// Invocations per workgroup (the minimum every device supports is 128).
pub const WORKGROUP: u32 = 128;
/// Consecutive keys one invocation places in the scatter.
pub const ITEMS_PER_INVOCATION: u32 = 16;
/// Keys per histogram/scatter workgroup.
pub const TILE: u32 = WORKGROUP * ITEMS_PER_INVOCATION;
/// Bits per radix pass: 16 counters per invocation in the histogram's and
/// scatter's shared memory (8 KiB at 128 invocations, within the 16 KiB
/// every device has), packed 8 bits each in registers (so at most 255 keys
/// per invocation).
pub const RADIX_BITS: u32 = 4;
pub const PASSES: u32 = 32 / RADIX_BITS;
/// The camera as pushed per frame (`Camera` in `sort_keys.comp`).
pub const CAMERA_BYTES: usize = std::mem::size_of::<SortCamera>();

/// The sort's camera (`Camera` in `sort_keys.comp`; `tests/shader_interfaces.rs`
/// checks the two agree): the eye relative to the centroids' origin and the
/// view direction, in f32 as the CPU sort uses them; depth is the squared
/// distance for perspective views, along `dir` for orthographic ones.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SortCamera {
    pub eye: Vec3,
    /// 1 perspective, 0 orthographic.
    pub perspective: f32,
    pub dir: Vec3,
}

impl SortCamera {
    /// The same f64 -> f32 conversions as `CentroidSort::sort` for centroids
    /// relative to `origin` (and as `FrameSetup::new` for the eye).
    pub fn new(camera: &Camera, origin: [f64; 3]) -> Self {
        SortCamera {
            eye: (DVec3::from(camera.eye) - DVec3::from(origin)).as_vec3(),
            perspective: if camera.is_perspective() { 1.0 } else { 0.0 },
            dir: camera.forward().as_vec3(),
        }
    }

    /// The same camera from a frame's setup (its eye is relative to the
    /// mesh's render origin, which the centroids must be relative to).
    pub fn from_frame(frame: &super::FrameSetup) -> Self {
        SortCamera { eye: frame.eye.into(), perspective: if frame.perspective { 1.0 } else { 0.0 }, dir: frame.view_dir.into() }
    }
}

/// One radix pass's parameters (`Params` in `radix_sort.glsl`, a static
/// buffer per pass; `tests/shader_interfaces.rs` checks the two agree).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PassParams {
    /// Keys.
    pub n: u32,
    /// Workgroups of [`TILE`] keys.
    pub groups: u32,
    /// The pass's digit: `(key >> shift) & (RADIX - 1)`.
    pub shift: u32,
}

/// How the centroids are split: buffers, and centroids per buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct CentroidChunks {
    buffers: usize,
    per_chunk: usize,
}

/// The pipelines' defines: the constants above, set in one place, and the
/// centroids' split when there is one.
fn defines(centroids: CentroidChunks) -> Vec<(&'static str, String)> {
    let mut d = vec![("WG", WORKGROUP.to_string()), ("ITEMS", ITEMS_PER_INVOCATION.to_string()), ("RADIX_BITS", RADIX_BITS.to_string())];
    if centroids.buffers > 1 {
        d.push(("CENTROID_CHUNKS", centroids.buffers.to_string()));
        d.push(("CENTROID_PER_CHUNK", centroids.per_chunk.to_string()));
    }
    d
}

/// Bindings 0-6 (`radix_sort.glsl`) and, split, the centroids' seven
/// further bindings.
fn set_desc(centroids: CentroidChunks) -> DescriptorSetDesc {
    let bindings = if centroids.buffers > 1 { 6 + MAX_CHUNKS } else { 7 };
    DescriptorSetDesc::storage_buffers(bindings, Stages::COMPUTE)
}

fn pipeline(ctx: &Arc<Context>, shader: &str, push_constant_bytes: u32, centroids: CentroidChunks) -> VkResult<Arc<Pipeline>> {
    let d = defines(centroids);
    let d: Vec<(&str, &str)> = d.iter().map(|(k, v)| (*k, v.as_str())).collect();
    let key = PipelineKey::Compute(ComputePipelineKey {
        shader: ShaderKey::new(shader, ShaderStage::Compute, &d),
        push_constant_bytes,
        sets: vec![set_desc(centroids)],
    });
    crate::algo::pipelines::get(ctx, &key)
}

/// Bytes on the device per cell: centroid (vec4), two key and two value
/// buffers; the counts add 16 u32 per `TILE` cells.
pub const DEVICE_BYTES_PER_CELL: usize = 16 + 4 * 4;

pub struct DeviceCentroidSort {
    n: u32,
    groups: u32,
    pipelines: Pipeline4,
    /// One set per pass (pass 0's also serves the key dispatch).
    sets: Vec<StorageBufferSet>,
    timestamps: TimestampPool,
    /// The sorted cell indices after `record` (farthest first).
    order: Buffer,
    _params: Vec<Buffer>,
    centroids: Vec<Buffer>,
    centroid_chunks: CentroidChunks,
    _buffers: [Buffer; 4],
}

/// The four kernels.
struct Pipeline4 {
    keys: Arc<Pipeline>,
    histogram: Arc<Pipeline>,
    scan: Arc<Pipeline>,
    scatter: Arc<Pipeline>,
}

impl DeviceCentroidSort {
    /// Upload `centroids` (relative to the origin the cameras given to
    /// `record` are relative to; see `SortCamera::new`) once and build the
    /// buffers and pipelines. `name` names the buffers.
    pub fn new(ctx: &Arc<Context>, name: &str, centroids: &[[f32; 3]], counter: &mut UploadCounter) -> VkResult<Self> {
        let len = centroids.len();
        // Every index (up to the last tile's end) must fit a u32.
        let n = u32::try_from(len)
            .ok()
            .filter(|&n| n <= u32::MAX - TILE)
            .ok_or_else(|| VkError::Invalid(format!("{name}: {len} cells are more than the device sort indexes (u32)")))?;
        let groups = n.div_ceil(TILE);
        // The keys, values and counts are one binding each.
        let limit = u64::from(ctx.info.max_storage_buffer_range);
        let key_bytes = len as u64 * 4;
        let count_bytes = u64::from(groups) * (1 << RADIX_BITS) * 4;
        if key_bytes.max(count_bytes) > limit {
            return Err(VkError::Invalid(format!(
                "{name}: {len} cells need a {key_bytes}-byte key buffer, above the device's \
                 maxStorageBufferRange ({limit} bytes)"
            )));
        }
        // The centroids (16 bytes each) in as many bindings as the limits need.
        let per_chunk = ChunkLimits::of(ctx)?.storage_chunk(16);
        let pieces = chunks::ranges(len, per_chunk);
        if per_chunk == 0 || pieces.len() > MAX_CHUNKS {
            return Err(VkError::Invalid(format!(
                "{name} centroids: {len} cells need {} storage buffers at the device's limits ({per_chunk} centroids each), \
                 more than the {MAX_CHUNKS} bindings the shader declares",
                pieces.len()
            )));
        }
        let centroid_chunks = CentroidChunks { buffers: pieces.len(), per_chunk };
        let storage = BufferUsage::STORAGE;
        let padded: Vec<[f32; 4]> = centroids.iter().map(|c| [c[0], c[1], c[2], 0.0]).collect();
        let centroid_buffers = pieces
            .iter()
            .enumerate()
            .map(|(k, piece)| {
                let label = if pieces.len() == 1 { format!("{name} centroids") } else { format!("{name} centroids [{k}]") };
                // An empty mesh still gets one (zero) centroid: zero-size buffers are invalid.
                let data: &[[f32; 4]] = if piece.is_empty() { &[[0.0; 4]] } else { &padded[piece.clone()] };
                upload_static(ctx, &label, bytemuck::cast_slice(data), storage, counter)
            })
            .collect::<VkResult<Vec<_>>>()?;
        let pair_bytes = (len.max(1) * 4) as u64;
        let local = |what: &str, usage| Buffer::new(ctx, BufferDesc::device_local(&format!("{name} {what}"), pair_bytes, usage));
        // The order is read by the draw and, in tests, copied back.
        let order = local("order", storage | BufferUsage::TRANSFER_SRC)?;
        let keys_a = local("keys A", storage)?;
        let keys_b = local("keys B", storage)?;
        let vals_b = local("order B", storage)?;
        let counts = Buffer::new(ctx, BufferDesc::device_local(&format!("{name} digit counts"), count_bytes.max(4), storage))?;
        let mut params = Vec::with_capacity(PASSES as usize);
        for pass in 0..PASSES {
            let pass_params = PassParams { n, groups, shift: pass * RADIX_BITS };
            let mut b = Buffer::new(ctx, BufferDesc::upload(&format!("{name} pass {pass} params"), std::mem::size_of::<PassParams>() as u64, storage))?;
            b.write(0, bytemuck::bytes_of(&pass_params), counter, UploadClass::Static)?;
            params.push(b);
        }
        let mut sets = Vec::with_capacity(PASSES as usize);
        for (pass, p) in params.iter().enumerate() {
            // Even passes read A (`keys_a`, `order`) and write B, odd ones back.
            let (src, dst) = if pass % 2 == 0 { ([&keys_a, &order], [&keys_b, &vals_b]) } else { ([&keys_b, &vals_b], [&keys_a, &order]) };
            let mut buffers = vec![p, &centroid_buffers[0], src[0], src[1], dst[0], dst[1], &counts];
            if let (Some(last), true) = (centroid_buffers.last(), centroid_buffers.len() > 1) {
                // Chunks 1.., the last repeated in the bindings no chunk uses.
                buffers.extend(&centroid_buffers[1..]);
                buffers.resize(6 + MAX_CHUNKS, last);
            }
            sets.push(StorageBufferSet::new(ctx, &format!("{name} pass {pass}"), &buffers, Stages::COMPUTE)?);
        }
        let pipelines = Pipeline4 {
            keys: pipeline(ctx, "cell_projection/sort_keys.comp", CAMERA_BYTES as u32, centroid_chunks)?,
            histogram: pipeline(ctx, "cell_projection/sort_histogram.comp", 0, centroid_chunks)?,
            scan: pipeline(ctx, "cell_projection/sort_scan.comp", 0, centroid_chunks)?,
            scatter: pipeline(ctx, "cell_projection/sort_scatter.comp", 0, centroid_chunks)?,
        };
        let timestamps = TimestampPool::new(ctx, &format!("{name} timestamps"), 2)?;
        Ok(DeviceCentroidSort {
            n,
            groups,
            pipelines,
            sets,
            timestamps,
            order,
            _params: params,
            centroids: centroid_buffers,
            centroid_chunks,
            _buffers: [keys_a, keys_b, vals_b, counts],
        })
    }

    pub fn len(&self) -> usize {
        self.n as usize
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The centroids' storage buffers (more than one beyond one binding's
    /// range), and the centroids in each but the last.
    pub fn centroid_buffers(&self) -> (usize, usize) {
        debug_assert_eq!(self.centroids.len(), self.centroid_chunks.buffers);
        (self.centroid_chunks.buffers, self.centroid_chunks.per_chunk)
    }

    /// The device-local buffer of sorted cell indices (u32, farthest first)
    /// that `record` writes.
    pub fn order(&self) -> &Buffer {
        &self.order
    }

    /// Record the sort for `camera` (outside a render pass); the camera's
    /// push constants are counted in `counter`. Ends with the order visible
    /// to the graphics stages and to copies.
    pub fn record(&self, rec: &CommandRecorder, camera: &SortCamera, counter: &mut UploadCounter) -> VkResult<()> {
        // The previous frame's draw read `order`, its sort wrote every buffer.
        rec.consumers_to_compute();
        self.timestamps.reset(rec);
        self.timestamps.write(rec, 0, TimestampAt::Start)?;
        if self.n > 0 {
            let p = &self.pipelines;
            rec.bind_compute(&p.keys, &[&self.sets[0]])?;
            rec.push_constants(&p.keys, bytemuck::bytes_of(camera), counter);
            rec.dispatch_groups(u64::from(self.n.div_ceil(WORKGROUP)))?;
            for set in &self.sets {
                rec.compute_to_compute();
                rec.bind_compute(&p.histogram, &[set])?;
                rec.dispatch_groups(u64::from(self.groups))?;
                rec.compute_to_compute();
                rec.bind_compute(&p.scan, &[set])?;
                rec.dispatch([1, 1, 1])?;
                rec.compute_to_compute();
                rec.bind_compute(&p.scatter, &[set])?;
                rec.dispatch_groups(u64::from(self.groups))?;
            }
        }
        self.timestamps.write(rec, 1, TimestampAt::ComputeDone)?;
        rec.compute_to_consumers();
        Ok(())
    }

    /// GPU milliseconds the last recorded sort took (after its submission
    /// has been waited for).
    pub fn gpu_ms(&self) -> VkResult<f64> {
        self.timestamps.elapsed_ms(0, 1)
    }

    /// Copy the order back to the host (tests; after the sort's submission
    /// has been waited for).
    pub fn read_order(&self, ctx: &Arc<Context>) -> VkResult<Vec<u32>> {
        let bytes = u64::from(self.n) * 4;
        let readback = Buffer::new(ctx, BufferDesc::readback("device sort order readback", bytes.max(4)))?;
        let rec = CommandRecorder::new(ctx, "device sort order readback")?;
        rec.begin()?;
        if bytes > 0 {
            rec.copy_buffer(&self.order, &readback, bytes)?;
        }
        rec.transfer_to_host();
        rec.submit_and_wait()?;
        let data = readback.read()?;
        Ok(bytemuck::pod_collect_to_vec(&data[..bytes as usize]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_passes_cover_a_u32_key_and_end_where_they_started() {
        assert_eq!(PASSES * RADIX_BITS, 32);
        assert_eq!(PASSES % 2, 0, "the order must end in the buffer the keys started in");
        const { assert!(RADIX_BITS == 4 && ITEMS_PER_INVOCATION <= 255, "the packed counters (radix_sort.glsl)") };
        // The scatter's shared memory: RADIX counters per invocation plus the bases.
        let shared = ((1 << RADIX_BITS) * WORKGROUP + (1 << RADIX_BITS)) * 4;
        assert!(shared <= 16 * 1024, "{shared} bytes of shared memory");
    }

    #[test]
    fn the_sort_camera_is_the_frame_setup_camera() {
        use crate::algo::tet_mesh::{ExitTolerances, FrameSetup, Interpolation};
        use crate::mesh::Bounds;
        use crate::scene::Projection;
        let b = Bounds { min: [0.0; 3], max: [1.0, 2.0, 3.0] };
        for projection in [Projection::Perspective { fovy_deg: 30.0 }, Projection::Orthographic { height: 1.0 }] {
            let cam = Camera::orbit(&b, 0.7, projection);
            let frame = FrameSetup::for_camera(&cam, b.diagonal(), Interpolation::Exact, &ExitTolerances::default());
            assert_eq!(SortCamera::from_frame(&frame), SortCamera::new(&cam, [0.0; 3]));
        }
    }
}
