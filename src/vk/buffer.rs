//! Buffers with their memory, and texel buffers (a buffer with a typed view,
//! `samplerBuffer` / `imageBuffer` in GLSL). Each `Buffer` owns its
//! allocation and frees it on `Drop` (we wait idle between runs, so no frame
//! can still use it; after a fence time-out it leaks instead). A
//! `TexelBuffer` owns its buffer and view and destroys the view first.
//! Host writes that the device will read go through `write`, which counts
//! them (see `upload`).

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::error::{Check, VkError, VkResult};
use super::format::Format;
use super::types::BufferUsage;
use super::upload::{UploadClass, UploadCounter};
use super::Context;

/// Where a buffer's memory lives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MemoryKind {
    /// Host-visible, written by the CPU and read by the device.
    Upload,
    /// Device-local; filled by transfer commands.
    DeviceLocal,
    /// Host-visible, written by the device and read back by the CPU.
    Readback,
}

#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct BufferDesc {
    pub name: String,
    pub size: u64,
    pub usage: BufferUsage,
    pub memory: MemoryKind,
}

impl BufferDesc {
    pub fn upload(name: &str, size: u64, usage: BufferUsage) -> Self {
        BufferDesc { name: name.into(), size, usage, memory: MemoryKind::Upload }
    }
    pub fn device_local(name: &str, size: u64, usage: BufferUsage) -> Self {
        BufferDesc { name: name.into(), size, usage: usage | BufferUsage::TRANSFER_DST, memory: MemoryKind::DeviceLocal }
    }
    pub fn readback(name: &str, size: u64) -> Self {
        BufferDesc { name: name.into(), size, usage: BufferUsage::TRANSFER_DST, memory: MemoryKind::Readback }
    }
    /// `words` u32 counters a shader adds to and the host reads after the
    /// frame: a storage buffer the device clears (a fill) and the host maps.
    pub fn counters(name: &str, words: usize) -> Self {
        BufferDesc {
            name: name.into(),
            size: (words * 4) as u64,
            usage: BufferUsage::STORAGE | BufferUsage::TRANSFER_DST,
            memory: MemoryKind::Readback,
        }
    }
}

pub struct Buffer {
    pub raw: vk::Buffer,
    pub desc: BufferDesc,
    allocation: Option<Allocation>,
    ctx: Arc<Context>,
}

impl Buffer {
    pub fn new(ctx: &Arc<Context>, desc: BufferDesc) -> VkResult<Buffer> {
        let size = desc.size.max(4);
        if size > ctx.info.max_memory_allocation_size && ctx.info.max_memory_allocation_size > 0 {
            return Err(VkError::Unsupported {
                device: ctx.info.name.clone(),
                what: format!(
                    "a {} byte allocation for {} (maxMemoryAllocationSize is {})",
                    size, desc.name, ctx.info.max_memory_allocation_size
                ),
            });
        }
        let info = vk::BufferCreateInfo::default().size(size).usage(desc.usage.to_vk()).sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let raw = unsafe { ctx.device.create_buffer(&info, None) }.check("vkCreateBuffer")?;
        // SAFETY: the handle was created on this device just above and is live.
        let requirements = unsafe { ctx.device.get_buffer_memory_requirements(raw) };
        let location = match desc.memory {
            MemoryKind::Upload => MemoryLocation::CpuToGpu,
            MemoryKind::DeviceLocal => MemoryLocation::GpuOnly,
            MemoryKind::Readback => MemoryLocation::GpuToCpu,
        };
        let allocation = ctx.allocate(&AllocationCreateDesc {
            name: &desc.name,
            requirements,
            location,
            linear: true,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        });
        let allocation = match allocation {
            Ok(a) => a,
            Err(source) => {
                // SAFETY: the handle was created just above, was never used or
                // submitted, and is destroyed once here, on the error path (the wrapper
                // that would own it is not built).
                unsafe { ctx.device.destroy_buffer(raw, None) };
                return Err(VkError::Alloc { name: desc.name.clone(), source });
            }
        };
        // SAFETY: the handle is live and unbound; the allocation was made by
        // this device's allocator for its memory requirements, is owned by the
        // same wrapper and freed only when the handle is no longer used (Drop,
        // or the error path below; Vulkan allows freeing memory still bound
        // to a handle that is then only destroyed).
        let bound = unsafe { ctx.device.bind_buffer_memory(raw, allocation.memory(), allocation.offset()) };
        if let Err(result) = bound {
            ctx.free(allocation);
            // SAFETY: the handle was created just above, was never used or
            // submitted, and is destroyed once here, on the error path (the wrapper
            // that would own it is not built).
            unsafe { ctx.device.destroy_buffer(raw, None) };
            return Err(VkError::Call { what: "vkBindBufferMemory", result });
        }
        ctx.set_name(raw, &desc.name);
        Ok(Buffer { raw, desc, allocation: Some(allocation), ctx: ctx.clone() })
    }

    pub fn size(&self) -> u64 {
        self.desc.size
    }

    fn mapped_mut(&mut self) -> VkResult<&mut [u8]> {
        let name = self.desc.name.clone();
        let size = self.desc.size as usize;
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .map(|s| &mut s[..size])
            .ok_or(VkError::Unsupported { device: name, what: "host-mapped memory".into() })
    }

    /// Bytes the device wrote (readback buffers).
    pub fn read(&self) -> VkResult<&[u8]> {
        let size = self.desc.size as usize;
        self.allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .map(|s| &s[..size])
            .ok_or(VkError::Unsupported { device: self.desc.name.clone(), what: "host-mapped memory".into() })
    }

    /// The first `N` u32 words of a counters buffer (`BufferDesc::counters`)
    /// as the host reads them after the frame, widened to u64; all zero
    /// when the buffer is not mapped or shorter.
    pub fn read_counters<const N: usize>(&self) -> [u64; N] {
        match self.read() {
            Ok(b) if b.len() >= N * 4 => std::array::from_fn(|i| u32::from_ne_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]]) as u64),
            _ => [0; N],
        }
    }

    /// Copy `data` into this host-visible buffer at `offset` and count it as
    /// bytes crossing to the device (the device reads this memory in place).
    pub fn write(&mut self, offset: usize, data: &[u8], counter: &mut UploadCounter, class: UploadClass) -> VkResult<()> {
        self.write_uncounted(offset, data)?;
        counter.add_direct(class, data.len() as u64);
        Ok(())
    }

    /// Fill a staging buffer: the bytes cross later, when a transfer command
    /// copies them (and are counted there).
    pub fn write_staging(&mut self, offset: usize, data: &[u8]) -> VkResult<()> {
        self.write_uncounted(offset, data)
    }

    fn write_uncounted(&mut self, offset: usize, data: &[u8]) -> VkResult<()> {
        let name = self.desc.name.clone();
        let dst = self.mapped_mut()?;
        let end = offset.checked_add(data.len()).filter(|&e| e <= dst.len()).ok_or(VkError::Unsupported {
            device: name,
            what: format!("room for {} bytes at offset {} (size {})", data.len(), offset, dst.len()),
        })?;
        dst[offset..end].copy_from_slice(data);
        Ok(())
    }

    /// Direct mutable access to the mapped memory, for writers that fill it
    /// in place; the caller counts what it wrote with `UploadCounter::add_direct`.
    pub fn mapped_for_write(&mut self) -> VkResult<&mut [u8]> {
        self.mapped_mut()
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            // The device may still access this memory: leak rather than free.
            return;
        }
        if let Some(a) = self.allocation.take() {
            self.ctx.free(a);
        }
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe { self.ctx.device.destroy_buffer(self.raw, None) };
    }
}

/// A buffer seen through a typed view: a uniform texel buffer (read with
/// filtering-free `texelFetch`) and/or a storage texel buffer (`imageLoad`,
/// `imageStore`), as the buffer's usage says. The view covers the whole
/// buffer, whose size must be a whole number of texels.
pub struct TexelBuffer {
    pub buffer: Buffer,
    pub view: vk::BufferView,
    pub format: Format,
    /// Number of texels the view covers.
    pub texels: u64,
}

impl TexelBuffer {
    /// `desc.usage` must include UNIFORM_TEXEL and/or STORAGE_TEXEL; the format must support them as buffer features.
    pub fn new(ctx: &Arc<Context>, desc: BufferDesc, format: Format) -> VkResult<TexelBuffer> {
        Self::check(ctx, &desc, format)?;
        Self::over(ctx, Buffer::new(ctx, desc)?, format)
    }

    /// A view of `format` texels over all of an existing buffer (e.g. one
    /// `upload_static` filled in device-local memory), checked as `new`
    /// checks its description.
    pub fn over(ctx: &Arc<Context>, buffer: Buffer, format: Format) -> VkResult<TexelBuffer> {
        let texels = Self::check(ctx, &buffer.desc, format)?;
        let info = vk::BufferViewCreateInfo::default().buffer(buffer.raw).format(format.to_vk()).offset(0).range(buffer.size());
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let view = unsafe { ctx.device.create_buffer_view(&info, None) }.check("vkCreateBufferView")?;
        ctx.set_name(view, &buffer.desc.name);
        Ok(TexelBuffer { buffer, view, format, texels })
    }

    /// Usage, format features, whole texels and the device's element limit;
    /// the number of texels.
    fn check(ctx: &Context, desc: &BufferDesc, format: Format) -> VkResult<u64> {
        let texel = format.texel_bytes();
        let mut features = vk::FormatFeatureFlags::empty();
        if desc.usage.contains(BufferUsage::UNIFORM_TEXEL) {
            features |= vk::FormatFeatureFlags::UNIFORM_TEXEL_BUFFER;
        }
        if desc.usage.contains(BufferUsage::STORAGE_TEXEL) {
            features |= vk::FormatFeatureFlags::STORAGE_TEXEL_BUFFER;
        }
        if features.is_empty() {
            return Err(VkError::Invalid(format!(
                "texel buffer '{}': usage {:?} has neither UNIFORM_TEXEL nor STORAGE_TEXEL",
                desc.name, desc.usage
            )));
        }
        if !ctx.format_supports(format, features) {
            return Err(VkError::Unsupported {
                device: ctx.info.name.clone(),
                what: format!("{format:?} as {features:?} for texel buffer '{}'", desc.name),
            });
        }
        if desc.size == 0 || !desc.size.is_multiple_of(texel) {
            return Err(VkError::Invalid(format!(
                "texel buffer '{}': {} bytes is not a whole, non-zero number of {texel}-byte texels",
                desc.name, desc.size
            )));
        }
        let texels = desc.size / texel;
        let max = ctx.info.max_texel_buffer_elements as u64;
        if texels > max {
            return Err(VkError::Unsupported {
                device: ctx.info.name.clone(),
                what: format!("{texels} texels in texel buffer '{}' (maxTexelBufferElements is {max})", desc.name),
            });
        }
        Ok(texels)
    }
}

impl Drop for TexelBuffer {
    fn drop(&mut self) {
        // The view goes before its buffer (a field, dropped after this).
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe { self.buffer.ctx.device.destroy_buffer_view(self.view, None) };
    }
}
