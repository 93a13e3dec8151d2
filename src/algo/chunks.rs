//! Per-cell device data split at the device's limits (issue 22 item 3). A
//! large mesh's arrays can be longer than one binding may see
//! (maxStorageBufferRange, maxTexelBufferElements) or than one allocation
//! may hold (maxMemoryAllocationSize): each such array is uploaded as
//! several buffers of whole elements ("chunks"), element `e` in chunk
//! `e / per_chunk` at `e % per_chunk`. Shaders see the chunks as separate
//! bindings (at most [`MAX_CHUNKS`], selected by the element's chunk:
//! `shaders/cell_projection/stored_cell.glsl`, `shaders/tet_raycast/walk.comp`,
//! `shaders/cell_projection/radix_sort.glsl`);
//! per-frame arrays read in draw order are instead drawn in several draws
//! ([`VertexChunks`]: balanced, VICP, ATFS).
//!
//! Test knob (docs/scaling.md, test only): `VOLBENCH_TEST_DEVICE_LIMIT_BYTES=N`
//! lowers the limits the chunked arrays are split at (the largest allocation
//! and storage range to N bytes, the texel count to N / 16), so a small mesh
//! is split as a large one is on a real device. It does not change what the
//! device accepts, nor any array that is not chunked.

use std::sync::Arc;

use crate::vk::{upload_static_streamed, Buffer, BufferDesc, Context, TexelBuffer, UploadClass, UploadCounter, VkError, VkResult};
use crate::vk::{BufferUsage, Format};

/// The test knob (see the module documentation).
pub const DEVICE_LIMIT_VAR: &str = crate::switches::TEST_DEVICE_LIMIT_BYTES;

/// Bindings a shader declares for one chunked array.
pub const MAX_CHUNKS: usize = 8;

/// The limits chunked arrays are split at: the device's, or lower under the
/// test knob.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChunkLimits {
    /// Bytes of one buffer (maxMemoryAllocationSize).
    pub allocation: u64,
    /// Bytes one storage-buffer binding sees (maxStorageBufferRange).
    pub storage_range: u64,
    /// Texels one texel-buffer view sees (maxTexelBufferElements).
    pub texel_elements: u64,
}

impl ChunkLimits {
    /// The device's limits, lowered by the test knob when it is set; a
    /// knob that is not a positive byte count is an error naming it.
    pub fn of(ctx: &Context) -> VkResult<Self> {
        let info = &ctx.info;
        let allocation = match info.max_memory_allocation_size {
            0 => u64::from(u32::MAX),
            m => m,
        };
        let device = ChunkLimits {
            allocation,
            storage_range: u64::from(info.max_storage_buffer_range),
            texel_elements: u64::from(info.max_texel_buffer_elements),
        };
        Ok(match crate::switches::int(DEVICE_LIMIT_VAR)? {
            None => device,
            Some(n) => device.lowered_to(n),
        })
    }

    /// These limits with none above `bytes` (texels: `bytes / 16`).
    pub fn lowered_to(self, bytes: u64) -> Self {
        ChunkLimits {
            allocation: self.allocation.min(bytes),
            storage_range: self.storage_range.min(bytes),
            texel_elements: self.texel_elements.min(bytes / 16).max(1),
        }
    }

    /// Elements of `elem_bytes` bytes (`texels` texels each) that one texel
    /// buffer may hold: within one allocation and one view.
    pub fn texel_chunk(&self, elem_bytes: u64, texels: u64) -> usize {
        let n = (self.allocation / elem_bytes.max(1)).min(self.texel_elements / texels.max(1));
        usize::try_from(n).unwrap_or(usize::MAX)
    }

    /// Elements of `elem_bytes` bytes that one storage-buffer binding may
    /// see (within one allocation too).
    pub fn storage_chunk(&self, elem_bytes: u64) -> usize {
        let n = self.allocation.min(self.storage_range) / elem_bytes.max(1);
        usize::try_from(n).unwrap_or(usize::MAX)
    }

    /// Elements of `elem_bytes` bytes that one buffer may hold.
    pub fn allocation_chunk(&self, elem_bytes: u64) -> usize {
        usize::try_from(self.allocation / elem_bytes.max(1)).unwrap_or(usize::MAX)
    }
}

/// Available host memory (MemAvailable, bytes), if /proc/meminfo says.
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The device memory a mesh's data is checked against before anything is
/// allocated, and what it is: the largest device-local heap, except on a
/// CPU device (lavapipe), whose "device memory" is the process's own memory
/// and whose advertised heap (2 GiB on lavapipe 22.3) is nominal: there
/// the host's available memory. Per-allocation and per-binding limits are
/// [`ChunkLimits`]'.
pub fn device_memory_bound(info: &crate::vk::DeviceInfo) -> (u64, &'static str) {
    if info.is_cpu() {
        if let Some(avail) = available_memory() {
            return (avail.max(info.device_local_heap_bytes), "the host's available memory (a CPU device's memory is the process's)");
        }
    }
    (info.device_local_heap_bytes, "the device's largest device-local heap")
}

/// Check, before anything is allocated, that `cells` cells fit: `device`
/// bytes each on the device ([`device_memory_bound`]) and `host` bytes each
/// that the method keeps on the host (against MemAvailable, measured after
/// the mesh is loaded). On a CPU device both come out of the process's
/// memory, so their sum is checked: a mesh too large for a method is a
/// clear error naming the memory, not an out-of-memory kill mid-build.
pub fn check_memory(info: &crate::vk::DeviceInfo, cells: usize, device: usize, host: usize) -> anyhow::Result<()> {
    use anyhow::Context as _;
    let (bound, what) = device_memory_bound(info);
    let available = available_memory();
    if info.is_cpu() && available.is_some() {
        return crate::mesh::check_fits(cells, device + host, bound).with_context(|| {
            format!("device and host memory together ({device} device + {host} host bytes per cell; {what})")
        });
    }
    crate::mesh::check_fits(cells, device, bound).with_context(|| format!("device memory ({what})"))?;
    match available {
        Some(avail) => crate::mesh::check_fits(cells, host, avail)
            .with_context(|| format!("host memory ({host} bytes per cell kept by the method; the host's available memory)")),
        None => Ok(()),
    }
}

/// `count` elements in pieces of at most `per_chunk`: the pieces' element
/// ranges, in order (one empty piece for no elements).
pub fn ranges(count: usize, per_chunk: usize) -> Vec<std::ops::Range<usize>> {
    let per = per_chunk.max(1);
    // No elements: one empty piece (so there is always a buffer to bind).
    (0..count.div_ceil(per).max(1)).map(|k| k * per..((k + 1) * per).min(count)).collect()
}

/// One array as texel buffers of whole elements.
pub struct TexelChunks {
    pub buffers: Vec<TexelBuffer>,
    /// Elements per buffer (all but the last are full).
    pub per_chunk: usize,
}

impl TexelChunks {
    /// Upload `count` elements of `elem_bytes` bytes (whole texels of
    /// `format`) into texel buffers of `per_chunk` elements (at most
    /// [`ChunkLimits::texel_chunk`]); `fill(first, bytes)` writes elements
    /// `first ..` into `bytes` (whole elements), chunk by chunk through the
    /// staging buffer. More than [`MAX_CHUNKS`] buffers is an error naming
    /// the array.
    #[allow(clippy::too_many_arguments)]
    pub fn upload(
        ctx: &Arc<Context>,
        name: &str,
        count: usize,
        elem_bytes: usize,
        format: Format,
        per_chunk: usize,
        counter: &mut UploadCounter,
        mut fill: impl FnMut(usize, &mut [u8]),
    ) -> VkResult<TexelChunks> {
        if per_chunk == 0 {
            return Err(VkError::Invalid(format!("{name}: one {elem_bytes}-byte element is larger than the device's limits")));
        }
        let pieces = ranges(count, per_chunk);
        if pieces.len() > MAX_CHUNKS {
            return Err(VkError::Invalid(format!(
                "{name}: {count} elements of {elem_bytes} bytes need {} buffers at the device's limits \
                 ({per_chunk} elements each), more than the {MAX_CHUNKS} bindings the shader declares",
                pieces.len()
            )));
        }
        // Read with imageLoad (integrate.rs says why not texelFetch).
        let usage = BufferUsage::STORAGE_TEXEL;
        let mut buffers = Vec::with_capacity(pieces.len());
        for (k, piece) in pieces.iter().enumerate() {
            // Empty arrays still get one element (zero-size buffers are invalid).
            let size = (piece.len().max(1) * elem_bytes) as u64;
            let label = if pieces.len() == 1 { name.to_string() } else { format!("{name} [{k}]") };
            let buffer = upload_static_streamed(ctx, &label, size, elem_bytes as u64, usage, counter, |offset, bytes| {
                if piece.is_empty() {
                    bytes.fill(0);
                } else {
                    fill(piece.start + offset as usize / elem_bytes, bytes);
                }
            })?;
            buffers.push(TexelBuffer::over(ctx, buffer, format)?);
        }
        Ok(TexelChunks { buffers, per_chunk })
    }

    /// Upload a host array of `T` (whole texels of `format`) as
    /// [`TexelChunks::upload`] does.
    pub fn upload_slice<T: bytemuck::Pod>(
        ctx: &Arc<Context>,
        name: &str,
        data: &[T],
        format: Format,
        per_chunk: usize,
        counter: &mut UploadCounter,
    ) -> VkResult<TexelChunks> {
        let elem = std::mem::size_of::<T>();
        let bytes: &[u8] = bytemuck::cast_slice(data);
        Self::upload(ctx, name, data.len(), elem, format, per_chunk, counter, |first, out| {
            let start = first * elem;
            out.copy_from_slice(&bytes[start..start + out.len()]);
        })
    }

    /// Shader defines, when there is more than one buffer: `{prefix}_CHUNKS`
    /// (buffers) and `{prefix}_PER_CHUNK` (elements per buffer).
    pub fn defines(&self, prefix: &str) -> Vec<(String, String)> {
        if self.buffers.len() < 2 {
            return Vec::new();
        }
        vec![(format!("{prefix}_CHUNKS"), self.buffers.len().to_string()), (format!("{prefix}_PER_CHUNK"), self.per_chunk.to_string())]
    }
}

/// Per-frame vertex records in draw order, in host-visible vertex buffers
/// of at most `per_draw` elements each: drawn one draw per buffer, in
/// order, so back-to-front compositing is kept across the pieces.
pub struct VertexChunks {
    pub buffers: Vec<Buffer>,
    /// Elements per buffer (all but the last are full).
    pub per_draw: usize,
}

impl VertexChunks {
    /// Buffers for `count` elements of `elem_bytes` bytes, `per_draw` each
    /// (the caller's bound: [`ChunkLimits::allocation_chunk`] and whatever
    /// else one draw must fit, such as its index buffer).
    pub fn new(ctx: &Arc<Context>, name: &str, count: usize, elem_bytes: usize, per_draw: usize) -> VkResult<Self> {
        let per_draw = per_draw.max(1);
        let pieces = ranges(count, per_draw);
        let buffers = pieces
            .iter()
            .enumerate()
            .map(|(k, piece)| {
                let label = if pieces.len() == 1 { name.to_string() } else { format!("{name} [{k}]") };
                // Empty arrays still get one element (zero-size buffers are invalid).
                let bytes = (piece.len().max(1) * elem_bytes) as u64;
                Buffer::new(ctx, BufferDesc::upload(&label, bytes, BufferUsage::VERTEX))
            })
            .collect::<VkResult<Vec<_>>>()?;
        Ok(VertexChunks { buffers, per_draw })
    }

    /// The element ranges of the buffers holding the first `drawn`
    /// elements, in order (none for no elements).
    fn drawn_ranges(per_draw: usize, drawn: usize) -> impl Iterator<Item = std::ops::Range<usize>> {
        (0..).map(move |k| k * per_draw..drawn.min((k + 1) * per_draw)).take_while(|r| !r.is_empty())
    }

    /// The buffers holding the first `drawn` elements, each with its
    /// elements' range, in order (none for no elements).
    pub fn drawn_mut(&mut self, drawn: usize) -> impl Iterator<Item = (&mut Buffer, std::ops::Range<usize>)> {
        self.buffers.iter_mut().zip(Self::drawn_ranges(self.per_draw, drawn))
    }

    /// [`VertexChunks::drawn_mut`], to record the draws.
    pub fn drawn(&self, drawn: usize) -> impl Iterator<Item = (&Buffer, std::ops::Range<usize>)> {
        self.buffers.iter().zip(Self::drawn_ranges(self.per_draw, drawn))
    }

    /// Write the first `packed.len() / elem_floats` elements (`elem_floats`
    /// floats each) into the buffers.
    pub fn write(&mut self, packed: &[f32], elem_floats: usize, counter: &mut UploadCounter) -> VkResult<()> {
        let drawn = packed.len() / elem_floats.max(1);
        for (buffer, r) in self.drawn_mut(drawn) {
            let part = &packed[r.start * elem_floats..r.end * elem_floats];
            buffer.write(0, bytemuck::cast_slice(part), counter, UploadClass::FrameCells)?;
        }
        Ok(())
    }

    /// The split for `details.device_chunks`: draws and `{unit}_per_draw`.
    pub fn describe(&self, unit: &str) -> serde_json::Value {
        serde_json::json!({ "draws": self.buffers.len(), format!("{unit}_per_draw"): self.per_draw })
    }
}

/// A host-visible storage texel buffer (read with imageLoad) written every
/// frame (pt-compute's pixel lists, tet-raycast's tile lists), of `texels`
/// texels of `format` (`texel_bytes` each), at least one. Refused past
/// maxTexelBufferElements.
pub fn frame_texels(ctx: &Arc<Context>, name: &str, texels: usize, texel_bytes: usize, format: Format) -> VkResult<TexelBuffer> {
    let limit = ctx.info.max_texel_buffer_elements as usize;
    if texels > limit {
        return Err(VkError::Invalid(format!("{name}: {texels} texels, above the device's maxTexelBufferElements ({limit})")));
    }
    let desc = BufferDesc::upload(name, (texels.max(1) * texel_bytes) as u64, BufferUsage::STORAGE_TEXEL);
    TexelBuffer::new(ctx, desc, format)
}

/// Grows a [`frame_texels`] buffer to hold `texels` (by half again, so that
/// growing frames do not reallocate every time); true when it was replaced
/// (descriptor sets that name it must be updated).
pub fn ensure_frame_texels(ctx: &Arc<Context>, buffer: &mut TexelBuffer, texels: usize, texel_bytes: usize, name: &str) -> VkResult<bool> {
    if buffer.texels as usize >= texels {
        return Ok(false);
    }
    let grown = (texels + texels / 2).min(ctx.info.max_texel_buffer_elements as usize).max(texels);
    *buffer = frame_texels(ctx, name, grown, texel_bytes, buffer.format)?;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_cover_every_element_once_in_order() {
        assert_eq!(ranges(0, 5), vec![0..0]);
        assert_eq!(ranges(5, 5), vec![0..5]);
        assert_eq!(ranges(11, 5), vec![0..5, 5..10, 10..11]);
        assert_eq!(ranges(3, 0), vec![0..1, 1..2, 2..3]);
    }

    #[test]
    fn chunk_sizes_respect_every_limit() {
        let l = ChunkLimits { allocation: 1 << 31, storage_range: 1 << 27, texel_elements: 1 << 27 };
        // resident's stored cells: 144 bytes, 9 texels; the allocation binds first.
        assert_eq!(l.texel_chunk(144, 9), (1usize << 31) / 144);
        // tet-raycast's cells: 16 bytes, 1 texel; the view's texel count binds.
        assert_eq!(l.texel_chunk(16, 1), 1 << 27);
        assert_eq!(l.storage_chunk(4), 1 << 25);
        assert_eq!(l.allocation_chunk(112), (1usize << 31) / 112);
        let t = l.lowered_to(4096);
        assert_eq!((t.allocation, t.storage_range, t.texel_elements), (4096, 4096, 256));
        assert_eq!(t.texel_chunk(144, 9), 28);
        // 33 M tets at lavapipe's limits: resident's cells take 3 buffers.
        assert_eq!(ranges(32_856_000, l.texel_chunk(144, 9)).len(), 3);
    }
}
