//! Command buffers, submission and the safe recording wrappers the algorithms
//! use (rendering, binding, draws, compute dispatch, barriers, copies).
//!
//! One reusable command buffer + fence per `CommandRecorder`;
//! `submit_and_wait` blocks until the device is done, which is the whole
//! synchronisation model (one frame in flight).
//!
//! Never hang: every fence wait is bounded by `Context::fence_timeout` and a
//! time-out is a `VkError::Timeout` naming the recorder. A recorder tracks
//! whether a submission is pending, so one that was never submitted (or
//! whose submission failed) does not wait at all, in `wait` or in `Drop`. A
//! time-out marks the context hung: the recorder's command buffer and fence
//! are then leaked rather than destroyed while the device may still use them.
//!
//! Dispatches larger than `maxComputeWorkGroupCount` per dimension go
//! through `dispatch_groups`, which folds a linear group count into x*y(*z);
//! shaders recover the linear id with `shaders/common/dispatch.glsl` and skip
//! the few excess groups (see `fold_groups` for the rule).

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use ash::vk;

use super::buffer::{Buffer, TexelBuffer};
use super::descriptors::DescriptorSet;
use super::error::{Check, VkError, VkResult};
use super::image::{color_layers, Image, ImageDim, ImageUse};
use super::format::Format;
use super::pipeline::Pipeline;
use super::types::{BufferUsage, Stages};
use super::upload::{UploadClass, UploadCounter};
use super::Context;

/// Nothing recorded or the last submission has been waited for.
const IDLE: u8 = 0;
/// Between `begin` and `submit`.
const RECORDING: u8 = 1;
/// Submitted; the fence will signal.
const PENDING: u8 = 2;

pub struct CommandRecorder {
    pub raw: vk::CommandBuffer,
    fence: vk::Fence,
    name: String,
    state: AtomicU8,
    timeout: Duration,
    ctx: Arc<Context>,
}

/// Host wall time of one submission.
#[derive(Debug, Clone, Copy, Default)]
pub struct SubmitTiming {
    /// vkQueueSubmit itself.
    pub submit: Duration,
    /// Waiting on the fence after submitting.
    pub wait: Duration,
}

impl CommandRecorder {
    pub fn new(ctx: &Arc<Context>, name: &str) -> VkResult<Self> {
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(ctx.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let raw = unsafe { ctx.device.allocate_command_buffers(&info) }.check("vkAllocateCommandBuffers")?[0];
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let fence = match unsafe { ctx.device.create_fence(&vk::FenceCreateInfo::default(), None) } {
            Ok(f) => f,
            Err(result) => {
                // SAFETY: `raw` was allocated just above from this pool, never
                // recorded or submitted, and is freed once (the recorder is not built).
                unsafe { ctx.device.free_command_buffers(ctx.command_pool, &[raw]) };
                return Err(VkError::Call { what: "vkCreateFence", result });
            }
        };
        ctx.set_name(raw, name);
        ctx.set_name(fence, name);
        Ok(CommandRecorder {
            raw,
            fence,
            name: name.to_string(),
            state: AtomicU8::new(IDLE),
            timeout: ctx.fence_timeout,
            ctx: ctx.clone(),
        })
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Bound this recorder's fence waits by `timeout` instead of the
    /// context's `fence_timeout`.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// Whether a submission is in flight (submitted, not yet waited for).
    pub fn is_pending(&self) -> bool {
        self.state.load(Ordering::SeqCst) == PENDING
    }

    /// Start recording. A submission still pending is waited for first
    /// (bounded): a command buffer must not be reset while in use.
    pub fn begin(&self) -> VkResult<vk::CommandBuffer> {
        self.wait()?;
        let d = &self.ctx.device;
        // SAFETY: the command buffer is this recorder's own, from a pool created
        // with RESET_COMMAND_BUFFER; no submission of it is pending (waited for
        // just above, and `wait` errs rather than return while one is), so it
        // may be reset and begun.
        unsafe {
            d.reset_command_buffer(self.raw, vk::CommandBufferResetFlags::empty()).check("vkResetCommandBuffer")?;
            let info = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            d.begin_command_buffer(self.raw, &info).check("vkBeginCommandBuffer")?;
        }
        self.state.store(RECORDING, Ordering::SeqCst);
        Ok(self.raw)
    }

    /// End recording, submit, and wait for completion.
    pub fn submit_and_wait(&self) -> VkResult<SubmitTiming> {
        let submit = self.submit()?;
        let wait = self.wait()?;
        Ok(SubmitTiming { submit, wait })
    }

    /// End recording and submit without waiting; returns the time
    /// vkQueueSubmit took. Call `wait` before recording again.
    pub fn submit(&self) -> VkResult<Duration> {
        if self.state.load(Ordering::SeqCst) != RECORDING {
            return Err(VkError::Invalid(format!("command recorder '{}': submit without begin", self.name)));
        }
        // Whatever happens below, nothing is pending unless the submit succeeds.
        self.state.store(IDLE, Ordering::SeqCst);
        let d = &self.ctx.device;
        // SAFETY: the command buffer is recording (checked above: state
        // RECORDING); the fence is this recorder's and not pending (a pending
        // state makes `begin` wait first), so it may be reset; the queue is
        // used by one thread at a time under the sync model of `context.rs`
        // (submissions come from the harness's thread; the type system does
        // not enforce it). Everything recorded is kept alive by its owner
        // until this submission is waited for.
        unsafe {
            d.end_command_buffer(self.raw).check("vkEndCommandBuffer")?;
            d.reset_fences(&[self.fence]).check("vkResetFences")?;
            let cmds = [self.raw];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            let t0 = Instant::now();
            d.queue_submit(self.ctx.queue, &submit, self.fence).check("vkQueueSubmit")?;
            self.state.store(PENDING, Ordering::SeqCst);
            Ok(t0.elapsed())
        }
    }

    /// Block until the last submission has finished; returns the time
    /// blocked. Returns at once when nothing is pending. Gives up after the
    /// time-out with `VkError::Timeout` (the submission stays pending).
    pub fn wait(&self) -> VkResult<Duration> {
        if self.state.load(Ordering::SeqCst) != PENDING {
            return Ok(Duration::ZERO);
        }
        if self.ctx.is_hung() {
            return Err(VkError::DeviceHung);
        }
        let t0 = Instant::now();
        let nanos = u64::try_from(self.timeout.as_nanos()).unwrap_or(u64::MAX);
        // SAFETY: the fence is this recorder's live fence on this device; waiting
        // needs no external synchronisation, and the wait is bounded.
        match unsafe { self.ctx.device.wait_for_fences(&[self.fence], true, nanos) } {
            Ok(()) => {
                self.state.store(IDLE, Ordering::SeqCst);
                Ok(t0.elapsed())
            }
            Err(vk::Result::TIMEOUT) => {
                self.ctx.mark_hung();
                Err(VkError::Timeout { recorder: self.name.clone(), seconds: self.timeout.as_secs_f64() })
            }
            Err(result) => {
                // Device lost or out of memory: the fence will never signal,
                // and objects of a lost device may be destroyed.
                self.state.store(IDLE, Ordering::SeqCst);
                Err(VkError::Call { what: "vkWaitForFences", result })
            }
        }
    }

    /// Record a buffer-to-buffer copy from host-visible `src` and count its
    /// bytes as crossing to the device. Sizes are checked as in
    /// [`Self::copy_buffer`].
    pub fn copy_to_device(
        &self,
        src: &Buffer,
        dst: &Buffer,
        bytes: u64,
        counter: &mut UploadCounter,
        class: UploadClass,
    ) -> VkResult<()> {
        self.copy_buffer(src, dst, bytes)?;
        counter.add_transfer(class, bytes);
        Ok(())
    }

    /// [`Self::copy_to_device`] of the first `bytes` of `src` into `dst` at
    /// `dst_offset` (a streamed upload's chunk).
    pub fn copy_to_device_at(
        &self,
        src: &Buffer,
        dst: &Buffer,
        dst_offset: u64,
        bytes: u64,
        counter: &mut UploadCounter,
        class: UploadClass,
    ) -> VkResult<()> {
        self.copy_region(src, dst, dst_offset, bytes)?;
        counter.add_transfer(class, bytes);
        Ok(())
    }

    /// Record a buffer-to-buffer copy of the first `bytes` of `src` to the
    /// start of `dst` that is not an upload (device to device, or device to
    /// a readback buffer): nothing is counted. `bytes` must be above zero
    /// and fit both buffers (else `VkError::Invalid`, naming them).
    pub fn copy_buffer(&self, src: &Buffer, dst: &Buffer, bytes: u64) -> VkResult<()> {
        self.copy_region(src, dst, 0, bytes)
    }

    /// The first `bytes` of `src` to `dst` at `dst_offset`, uncounted.
    fn copy_region(&self, src: &Buffer, dst: &Buffer, dst_offset: u64, bytes: u64) -> VkResult<()> {
        let fits_dst = dst_offset.checked_add(bytes).is_some_and(|end| end <= dst.size());
        if bytes == 0 || bytes > src.size() || !fits_dst {
            return Err(VkError::Invalid(format!(
                "copying {bytes} bytes from buffer '{}' ({} bytes) to '{}' ({} bytes) at offset {dst_offset}: {}",
                src.desc.name,
                src.size(),
                dst.desc.name,
                dst.size(),
                if bytes == 0 { "a copy needs at least one byte" } else { "more than a buffer holds" }
            )));
        }
        let region = [vk::BufferCopy { src_offset: 0, dst_offset, size: bytes }];
        // SAFETY: `self.raw` is recording (callers record between `begin`
        // and submit; the recorder owns the command buffer); both buffers are
        // live for the call (borrowed) and kept alive by their owners until
        // the submission is waited for; the region is within both (checked
        // above), as vkCmdCopyBuffer requires.
        unsafe { self.ctx.device.cmd_copy_buffer(self.raw, src.raw, dst.raw, &region) };
        Ok(())
    }

    /// Fill the whole buffer with the 32-bit `value` on the device (a
    /// transfer write; no bytes cross from the host). The buffer needs
    /// TRANSFER_DST usage (device-local buffers have it).
    pub fn fill_buffer(&self, dst: &Buffer, value: u32) {
        // vkCmdFillBuffer with WHOLE_SIZE rounds down to a multiple of 4.
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe { self.ctx.device.cmd_fill_buffer(self.raw, dst.raw, 0, vk::WHOLE_SIZE, value) };
    }

    /// Copy `count` layers (z slices of a 3D image, rows of a 2D one, the
    /// whole of a 1D one) from the start of `src` into `dst` from layer
    /// `first` on: a large upload goes through one small staging buffer.
    /// Parts may come in any order; the image's contents are kept (a fresh
    /// image's undefined state stays the barrier's source until written).
    pub fn copy_layers_to_image(&self, src: &Buffer, dst: &Image, first: u32, count: u32, counter: &mut UploadCounter) -> VkResult<()> {
        let (layers, offset, extent) = match dst.dim {
            ImageDim::D3 => (dst.depth, vk::Offset3D { x: 0, y: 0, z: first as i32 }, [dst.width, dst.height, count]),
            ImageDim::D2 => (dst.height, vk::Offset3D { x: 0, y: first as i32, z: 0 }, [dst.width, count, 1]),
            ImageDim::D1 => (1, vk::Offset3D::default(), [dst.width, 1, 1]),
        };
        let bytes = dst.byte_size() / u64::from(layers) * u64::from(count);
        if first.checked_add(count).is_none_or(|end| end > layers) || src.size() < bytes {
            return Err(VkError::Invalid(format!(
                "copy of layers {first}..+{count} into image '{}' ({layers} layers) from buffer '{}' of {} bytes",
                dst.name(),
                src.desc.name,
                src.size()
            )));
        }
        dst.barrier(self.raw, ImageUse::TransferDst, true);
        let region = [vk::BufferImageCopy::default()
            .image_subresource(color_layers())
            .image_offset(offset)
            .image_extent(vk::Extent3D { width: extent[0], height: extent[1], depth: extent[2] })];
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit; both handles are live and kept alive by their
        // owners until the submission is waited for; the region lies inside
        // the image (checked above) and the buffer holds its bytes.
        unsafe {
            self.ctx.device.cmd_copy_buffer_to_image(self.raw, src.raw, dst.raw, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &region)
        };
        counter.add_transfer(UploadClass::Static, bytes);
        Ok(())
    }
}

impl Drop for CommandRecorder {
    fn drop(&mut self) {
        // Waits only for a real submission, and only boundedly.
        if self.wait().is_err() && self.is_pending() {
            // Timed out: the device may still execute this command buffer
            // and signal this fence, so neither may be destroyed.
            return;
        }
        // SAFETY: no submission is pending (waited for above; a timed-out one
        // returns before this), so the fence and command buffer are unused;
        // both are this recorder's and are destroyed once, here.
        unsafe {
            self.ctx.device.destroy_fence(self.fence, None);
            self.ctx.device.free_command_buffers(self.ctx.command_pool, &[self.raw]);
        }
    }
}

/// Upload `data` once into a new device-local buffer through a staging buffer
/// (the path a discrete GPU needs for static data); counted as static bytes.
/// Streamed in chunks ([`upload_static_streamed`]).
pub fn upload_static(
    ctx: &Arc<Context>,
    name: &str,
    data: &[u8],
    usage: BufferUsage,
    counter: &mut UploadCounter,
) -> VkResult<Buffer> {
    upload_static_streamed(ctx, name, data.len() as u64, 16, usage, counter, |offset, chunk| {
        let start = offset as usize;
        chunk.copy_from_slice(&data[start..start + chunk.len()]);
    })
}

/// Largest staging buffer a static upload uses: the data is streamed
/// through it chunk by chunk, so the host memory an upload needs beside the
/// destination is bounded (on lavapipe, where device memory is host memory,
/// a whole-size staging copy doubled the peak resident set of large meshes).
pub const STAGING_CHUNK_BYTES: u64 = 64 << 20;

/// Test knob (docs/scaling.md): `VOLBENCH_TEST_STAGING_CHUNK_BYTES=N`
/// lowers the staging chunk to N bytes (rounded to the producer's element
/// size, at least one element), so that a small mesh crosses in many
/// chunks, as a large one does against the device's allocation limit.
/// Unset in real runs; a value that is not a byte count is an error (`crate::switches`).
pub const STAGING_CHUNK_VAR: &str = crate::switches::TEST_STAGING_CHUNK_BYTES;

/// Upload `size` bytes into a new device-local buffer, produced chunk by
/// chunk by `fill(offset, chunk)` (write bytes `offset .. offset +
/// chunk.len()` of the data into `chunk`), through one staging buffer of
/// at most [`STAGING_CHUNK_BYTES`] (and at most the device's largest
/// allocation) that is re-used for every chunk. Every chunk but the last is
/// a multiple of `granule` bytes (the producer's element size, a multiple
/// of 4), so no element is split. Counted as static bytes.
pub fn upload_static_streamed(
    ctx: &Arc<Context>,
    name: &str,
    size: u64,
    granule: u64,
    usage: BufferUsage,
    counter: &mut UploadCounter,
    mut fill: impl FnMut(u64, &mut [u8]),
) -> VkResult<Buffer> {
    use super::buffer::BufferDesc;
    let dst = Buffer::new(ctx, BufferDesc::device_local(name, size, usage))?;
    let max_alloc = match ctx.info.max_memory_allocation_size {
        0 => STAGING_CHUNK_BYTES,
        m => m,
    };
    let granule = granule.max(4);
    let limit = crate::switches::int(STAGING_CHUNK_VAR)?.unwrap_or(STAGING_CHUNK_BYTES);
    let chunk = (limit.min(STAGING_CHUNK_BYTES).min(max_alloc) / granule).max(1) * granule;
    let chunk = chunk.min(size.max(4));
    let mut staging = Buffer::new(ctx, BufferDesc::upload(&format!("{name} (staging)"), chunk, BufferUsage::TRANSFER_SRC))?;
    let rec = CommandRecorder::new(ctx, &format!("{name} upload"))?;
    let mut offset = 0;
    while offset < size {
        let len = chunk.min(size - offset);
        fill(offset, &mut staging.mapped_for_write()?[..len as usize]);
        rec.begin()?;
        rec.copy_to_device_at(&staging, &dst, offset, len, counter, UploadClass::Static)?;
        rec.memory_barrier(
            (vk::PipelineStageFlags2::COPY, vk::AccessFlags2::TRANSFER_WRITE),
            (vk::PipelineStageFlags2::ALL_COMMANDS, vk::AccessFlags2::MEMORY_READ),
        );
        rec.submit_and_wait()?;
        offset += len;
    }
    Ok(dst)
}

/// [`upload_static`] into a texel buffer of `format` texels, a uniform one
/// (`texelFetch` from a `samplerBuffer`) or a storage one (`imageLoad` from
/// an `imageBuffer`) as `usage` says, checked as `TexelBuffer::over` checks
/// it.
pub fn upload_static_texels(
    ctx: &Arc<Context>,
    name: &str,
    data: &[u8],
    format: Format,
    usage: BufferUsage,
    counter: &mut UploadCounter,
) -> VkResult<TexelBuffer> {
    let buffer = upload_static(ctx, name, data, usage, counter)?;
    TexelBuffer::over(ctx, buffer, format)
}

/// One colour attachment of a dynamic-rendering pass: cleared to `clear`, or
/// with `None` loaded (previous contents kept).
#[derive(Clone, Copy)]
pub struct ColorAttachment<'a> {
    pub image: &'a Image,
    pub clear: Option<[f32; 4]>,
}

/// Split `groups` workgroups into a grid `[x, y, z]` with every dimension
/// within `max` (maxComputeWorkGroupCount). The rule, which shaders rely on
/// (`shaders/common/dispatch.glsl`):
///
/// - z = ceil(n / (max_x * max_y)), then y = ceil(ceil(n / z) / max_x),
///   then x = ceil(ceil(n / z) / y); so n <= max_x gives `[n, 1, 1]`;
/// - a group's linear id is `(gid.z * num.y + gid.y) * num.x + gid.x`;
/// - x*y*z >= n, the excess is below y*z groups, and groups whose linear id
///   is >= n must do nothing.
///
/// `None` when n exceeds max_x*max_y*max_z. n = 0 gives `[0, 0, 0]`.
pub fn fold_groups(groups: u64, max: [u32; 3]) -> Option<[u32; 3]> {
    if groups == 0 {
        return Some([0, 0, 0]);
    }
    let [mx, my, mz] = max.map(|m| m.max(1) as u64);
    let div_ceil = |a: u64, b: u64| a.div_ceil(b);
    let plane = mx.checked_mul(my)?;
    let z = div_ceil(groups, plane);
    if z > mz {
        return None;
    }
    let per_z = div_ceil(groups, z);
    let y = div_ceil(per_z, mx);
    let x = div_ceil(per_z, y);
    debug_assert!(x <= mx && y <= my && x * y * z >= groups);
    Some([u32::try_from(x).ok()?, u32::try_from(y).ok()?, u32::try_from(z).ok()?])
}

/// Thin safe wrappers for the commands the algorithms record, so that no
/// algorithm needs `unsafe`. All take the recorder's own command buffer.
impl CommandRecorder {
    /// Start dynamic rendering into `target`, cleared to `clear` (the old
    /// contents are discarded).
    pub fn begin_rendering(&self, target: &Image, clear: [f32; 4]) {
        self.record_begin_rendering(&[ColorAttachment { image: target, clear: Some(clear) }]);
    }

    /// Start dynamic rendering into `target` with the depth buffer `depth`
    /// (`Image::depth_target`), both cleared (colour to `clear`, depth to 1).
    pub fn begin_rendering_with_depth(&self, target: &Image, clear: [f32; 4], depth: &Image) -> VkResult<()> {
        if (depth.width, depth.height) != (target.width, target.height) || depth.format != super::format::DEPTH_FORMAT {
            return Err(VkError::Invalid(format!(
                "depth buffer '{}' ({}x{} {:?}) does not match target '{}' ({}x{})",
                depth.name(),
                depth.width,
                depth.height,
                depth.format,
                target.name(),
                target.width,
                target.height
            )));
        }
        depth.barrier(self.raw, ImageUse::DepthAttachment, false);
        let info = vk::RenderingAttachmentInfo::default()
            .image_view(depth.view)
            .image_layout(vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::DONT_CARE)
            .clear_value(vk::ClearValue { depth_stencil: vk::ClearDepthStencilValue { depth: 1.0, stencil: 0 } });
        self.record_begin_rendering_depth(&[ColorAttachment { image: target, clear: Some(clear) }], Some(&info));
        Ok(())
    }

    /// Start dynamic rendering into several colour attachments (locations
    /// 0, 1, ... in the order given); all must have the same size and be
    /// colour-attachment capable. Viewport and scissor cover the whole target.
    pub fn begin_rendering_targets(&self, targets: &[ColorAttachment]) -> VkResult<()> {
        let Some(first) = targets.first() else {
            return Err(VkError::Invalid(format!("recorder '{}': rendering without a colour attachment", self.name)));
        };
        let max = self.ctx.info.max_color_attachments as usize;
        if targets.len() > max {
            return Err(VkError::Unsupported {
                device: self.ctx.info.name.clone(),
                what: format!("{} colour attachments (maxColorAttachments is {max})", targets.len()),
            });
        }
        for t in targets {
            if (t.image.width, t.image.height, t.image.depth) != (first.image.width, first.image.height, 1) {
                return Err(VkError::Invalid(format!(
                    "colour attachments '{}' ({}x{}x{}) and '{}' ({}x{}) differ in size",
                    t.image.name(),
                    t.image.width,
                    t.image.height,
                    t.image.depth,
                    first.image.name(),
                    first.image.width,
                    first.image.height
                )));
            }
            if !t.image.usage.contains(vk::ImageUsageFlags::COLOR_ATTACHMENT) {
                return Err(VkError::Invalid(format!("image '{}' is not a colour attachment", t.image.name())));
            }
        }
        self.record_begin_rendering(targets);
        Ok(())
    }

    fn record_begin_rendering(&self, targets: &[ColorAttachment]) {
        self.record_begin_rendering_depth(targets, None);
    }

    fn record_begin_rendering_depth(&self, targets: &[ColorAttachment], depth: Option<&vk::RenderingAttachmentInfo>) {
        let (width, height) = targets.first().map(|t| (t.image.width, t.image.height)).unwrap_or((0, 0));
        let area = vk::Rect2D { offset: vk::Offset2D { x: 0, y: 0 }, extent: vk::Extent2D { width, height } };
        self.record_begin_rendering_area(targets, depth, area);
    }

    /// Begins rendering over `area` only: a cleared attachment is cleared
    /// there, and where `area` is not the whole target its contents outside
    /// are kept (the barrier keeps them).
    fn record_begin_rendering_area(&self, targets: &[ColorAttachment], depth: Option<&vk::RenderingAttachmentInfo>, area: vk::Rect2D) {
        let (width, height) = targets.first().map(|t| (t.image.width, t.image.height)).unwrap_or((0, 0));
        let whole = area.offset.x == 0 && area.offset.y == 0 && area.extent.width == width && area.extent.height == height;
        let attachments: Vec<vk::RenderingAttachmentInfo> = targets
            .iter()
            .map(|t| {
                t.image.barrier(self.raw, ImageUse::ColorAttachment, t.clear.is_none() || !whole);
                let info = vk::RenderingAttachmentInfo::default()
                    .image_view(t.image.view)
                    .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                    .store_op(vk::AttachmentStoreOp::STORE);
                match t.clear {
                    Some(c) => info
                        .load_op(vk::AttachmentLoadOp::CLEAR)
                        .clear_value(vk::ClearValue { color: vk::ClearColorValue { float32: c } }),
                    None => info.load_op(vk::AttachmentLoadOp::LOAD),
                }
            })
            .collect();
        let mut info = vk::RenderingInfo::default().render_area(area).layer_count(1).color_attachments(&attachments);
        if let Some(d) = depth {
            info = info.depth_attachment(d);
        }
        let viewport =
            [vk::Viewport { x: 0.0, y: 0.0, width: width as f32, height: height as f32, min_depth: 0.0, max_depth: 1.0 }];
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe {
            self.ctx.device.cmd_begin_rendering(self.raw, &info);
            self.ctx.device.cmd_set_viewport(self.raw, 0, &viewport);
            self.ctx.device.cmd_set_scissor(self.raw, 0, &[area]);
        }
    }

    /// Restrict the draws that follow in this rendering pass to the
    /// inclusive pixel bounds `rect` (`[x0, y0, x1, y1]`; x0 > x1 or
    /// y0 > y1: no pixel); `begin_rendering` resets it to the whole target.
    pub fn set_scissor(&self, rect: [u32; 4]) {
        let [x0, y0, x1, y1] = rect.map(|v| v.min(i32::MAX as u32 - 1));
        let area = vk::Rect2D {
            offset: vk::Offset2D { x: x0 as i32, y: y0 as i32 },
            extent: vk::Extent2D { width: (x1 + 1).saturating_sub(x0), height: (y1 + 1).saturating_sub(y0) },
        };
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); the offset and
        // extent are non-negative and their sums fit in an i32, as
        // vkCmdSetScissor requires.
        unsafe { self.ctx.device.cmd_set_scissor(self.raw, 0, &[area]) };
    }

    pub fn end_rendering(&self) {
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe { self.ctx.device.cmd_end_rendering(self.raw) };
    }

    /// Bind a graphics pipeline and (optionally) one descriptor set at set 0.
    pub fn bind_pipeline(&self, pipeline: &Pipeline, set: Option<&DescriptorSet>) {
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe {
            self.ctx.device.cmd_bind_pipeline(self.raw, vk::PipelineBindPoint::GRAPHICS, pipeline.raw);
            if let Some(s) = set {
                self.ctx.device.cmd_bind_descriptor_sets(
                    self.raw,
                    vk::PipelineBindPoint::GRAPHICS,
                    pipeline.layout,
                    0,
                    &[s.raw],
                    &[],
                );
            }
        }
    }

    /// Bind a graphics pipeline with its descriptor sets at sets 0, 1, ...
    pub fn bind_graphics(&self, pipeline: &Pipeline, sets: &[&DescriptorSet]) -> VkResult<()> {
        self.bind(vk::PipelineBindPoint::GRAPHICS, pipeline, sets)
    }

    /// Bind a compute pipeline with its descriptor sets at sets 0, 1, ...
    pub fn bind_compute(&self, pipeline: &Pipeline, sets: &[&DescriptorSet]) -> VkResult<()> {
        self.bind(vk::PipelineBindPoint::COMPUTE, pipeline, sets)
    }

    fn bind(&self, point: vk::PipelineBindPoint, pipeline: &Pipeline, sets: &[&DescriptorSet]) -> VkResult<()> {
        if pipeline.bind_point != point {
            return Err(VkError::Invalid(format!(
                "pipeline '{}' is a {:?} pipeline, bound as {point:?}",
                pipeline.name, pipeline.bind_point
            )));
        }
        if sets.len() != pipeline.set_count as usize {
            return Err(VkError::Invalid(format!(
                "pipeline '{}' has {} descriptor set layout(s), {} set(s) bound",
                pipeline.name,
                pipeline.set_count,
                sets.len()
            )));
        }
        let raw: Vec<vk::DescriptorSet> = sets.iter().map(|s| s.raw).collect();
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe {
            self.ctx.device.cmd_bind_pipeline(self.raw, point, pipeline.raw);
            if !raw.is_empty() {
                self.ctx.device.cmd_bind_descriptor_sets(self.raw, point, pipeline.layout, 0, &raw, &[]);
            }
        }
        Ok(())
    }

    /// Push constants (recorded into the command buffer, so they cross to
    /// the device with it: counted as per-frame constants).
    pub fn push_constants(&self, pipeline: &Pipeline, data: &[u8], counter: &mut UploadCounter) {
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        // The bytes are the caller's; a range beyond the layout's push-constant
        // range is a validation error (GPU tests run with the layer on).
        unsafe { self.ctx.device.cmd_push_constants(self.raw, pipeline.layout, pipeline.push_stages.to_vk(), 0, data) };
        counter.add_direct(UploadClass::FrameConstants, data.len() as u64);
    }

    pub fn bind_vertex_buffer(&self, buffer: &Buffer) {
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe { self.ctx.device.cmd_bind_vertex_buffers(self.raw, 0, &[buffer.raw], &[0]) };
    }

    pub fn bind_index_buffer_u32(&self, buffer: &Buffer) {
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe { self.ctx.device.cmd_bind_index_buffer(self.raw, buffer.raw, 0, vk::IndexType::UINT32) };
    }

    pub fn draw(&self, vertices: u32) {
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        // Counts and offsets are the caller's: one beyond the bound buffers
        // is a validation error, and every GPU test runs with the layer on.
        unsafe { self.ctx.device.cmd_draw(self.raw, vertices, 1, 0, 0) };
    }

    pub fn draw_indexed(&self, indices: u32) {
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        // Counts and offsets are the caller's: one beyond the bound buffers
        // is a validation error, and every GPU test runs with the layer on.
        unsafe { self.ctx.device.cmd_draw_indexed(self.raw, indices, 1, 0, 0, 0) };
    }

    /// Draw `count` indices starting at index `first` of the bound buffer.
    pub fn draw_indexed_range(&self, first: u32, count: u32) {
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        // Counts and offsets are the caller's: one beyond the bound buffers
        // is a validation error, and every GPU test runs with the layer on.
        unsafe { self.ctx.device.cmd_draw_indexed(self.raw, count, 1, first, 0, 0) };
    }

    /// One indexed draw whose arguments (`VkDrawIndexedIndirectCommand`,
    /// 20 bytes) the device reads from `args` at `offset` (e.g. written by
    /// a compute pass).
    pub fn draw_indexed_indirect(&self, args: &Buffer, offset: u64) -> VkResult<()> {
        if !offset.is_multiple_of(4) || offset.checked_add(20).is_none_or(|end| end > args.size()) {
            return Err(VkError::Invalid(format!(
                "indirect draw arguments at byte {offset} of buffer '{}' ({} bytes)",
                args.desc.name,
                args.size()
            )));
        }
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        // The indirect record fits `args` (checked above).
        unsafe { self.ctx.device.cmd_draw_indexed_indirect(self.raw, args.raw, offset, 1, 20) };
        Ok(())
    }

    /// Dispatch the bound compute pipeline with the group counts
    /// (`VkDispatchIndirectCommand`, 12 bytes) the device reads from `args`
    /// at `offset` (written by an earlier compute pass: `compute_to_indirect`
    /// between them). The counts must be within maxComputeWorkGroupCount; the
    /// writer bounds them.
    pub fn dispatch_indirect(&self, args: &Buffer, offset: u64) -> VkResult<()> {
        if !offset.is_multiple_of(4) || offset.checked_add(12).is_none_or(|end| end > args.size()) || !args.desc.usage.contains(BufferUsage::INDIRECT) {
            return Err(VkError::Invalid(format!(
                "indirect dispatch arguments at byte {offset} of buffer '{}' ({} bytes, indirect use {})",
                args.desc.name,
                args.size(),
                args.desc.usage.contains(BufferUsage::INDIRECT)
            )));
        }
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        // The indirect record fits `args`, made for indirect use (checked above).
        unsafe { self.ctx.device.cmd_dispatch_indirect(self.raw, args.raw, offset) };
        Ok(())
    }

    /// Dispatch a `[x, y, z]` grid of workgroups of the bound compute
    /// pipeline; each dimension must be within maxComputeWorkGroupCount.
    pub fn dispatch(&self, groups: [u32; 3]) -> VkResult<()> {
        let max = self.ctx.info.max_compute_work_group_count;
        if groups.iter().zip(max).any(|(&g, m)| g > m) {
            return Err(VkError::Unsupported {
                device: self.ctx.info.name.clone(),
                what: format!("a dispatch of {groups:?} workgroups (maxComputeWorkGroupCount is {max:?}; use dispatch_groups)"),
            });
        }
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        // The group counts are within the device's limits (checked above).
        unsafe { self.ctx.device.cmd_dispatch(self.raw, groups[0], groups[1], groups[2]) };
        Ok(())
    }

    /// Dispatch the workgroups `base .. base + groups` (per dimension): the
    /// shader's `gl_WorkGroupID` starts at `base`, so a pass over part of an
    /// image needs no offset of its own. Every compute pipeline here is made
    /// with `DISPATCH_BASE` (pipeline.rs).
    pub fn dispatch_base(&self, base: [u32; 3], groups: [u32; 3]) -> VkResult<()> {
        let max = self.ctx.info.max_compute_work_group_count;
        if (0..3).any(|k| base[k] >= max[k] || groups[k] > max[k] - base[k]) {
            return Err(VkError::Unsupported {
                device: self.ctx.info.name.clone(),
                what: format!("a dispatch of {groups:?} workgroups from {base:?} (maxComputeWorkGroupCount is {max:?})"),
            });
        }
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for. Base and counts are within the device's
        // limits (checked above); the bound pipeline allows a base.
        unsafe { self.ctx.device.cmd_dispatch_base(self.raw, base[0], base[1], base[2], groups[0], groups[1], groups[2]) };
        Ok(())
    }

    /// Dispatch `groups` workgroups however many that is, folded into a grid
    /// by [`fold_groups`]; returns the grid. The shader must compute its
    /// linear group id with `linear_workgroup_id()` from
    /// `shaders/common/dispatch.glsl` and return when it is >= `groups`.
    pub fn dispatch_groups(&self, groups: u64) -> VkResult<[u32; 3]> {
        let max = self.ctx.info.max_compute_work_group_count;
        let grid = fold_groups(groups, max).ok_or_else(|| VkError::Unsupported {
            device: self.ctx.info.name.clone(),
            what: format!("{groups} workgroups in one dispatch (at most {max:?} per dimension)"),
        })?;
        if groups > 0 {
            self.dispatch(grid)?;
        }
        Ok(grid)
    }

    /// A memory barrier between two (stages, accesses) scopes.
    /// One memory dependency (the named ones below are what callers use).
    fn memory_barrier(
        &self,
        src: (vk::PipelineStageFlags2, vk::AccessFlags2),
        dst: (vk::PipelineStageFlags2, vk::AccessFlags2),
    ) {
        let barrier = [vk::MemoryBarrier2::default()
            .src_stage_mask(src.0)
            .src_access_mask(src.1)
            .dst_stage_mask(dst.0)
            .dst_access_mask(dst.1)];
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe { self.ctx.device.cmd_pipeline_barrier2(self.raw, &vk::DependencyInfo::default().memory_barriers(&barrier)) };
    }

    /// Make host writes to mapped buffers visible to vertex input and shaders
    /// (required by the spec even for coherent memory written before submit).
    pub fn host_to_device_barrier(&self) {
        self.memory_barrier(
            (vk::PipelineStageFlags2::HOST, vk::AccessFlags2::HOST_WRITE),
            (
                vk::PipelineStageFlags2::VERTEX_INPUT | vk::PipelineStageFlags2::ALL_GRAPHICS,
                vk::AccessFlags2::VERTEX_ATTRIBUTE_READ | vk::AccessFlags2::SHADER_STORAGE_READ,
            ),
        );
    }

    /// Compute-shader writes (buffers, texel buffers) before a copy reads them.
    pub fn compute_to_transfer(&self) {
        self.memory_barrier(
            (vk::PipelineStageFlags2::COMPUTE_SHADER, vk::AccessFlags2::SHADER_STORAGE_WRITE),
            (vk::PipelineStageFlags2::COPY, vk::AccessFlags2::TRANSFER_READ),
        );
    }

    /// Compute-shader writes before any graphics stage reads them: fragment
    /// and pre-rasterisation shaders (storage, uniform, sampled reads),
    /// vertex/index fetch and indirect draws.
    pub fn compute_to_graphics(&self) {
        use vk::{AccessFlags2 as A, PipelineStageFlags2 as S};
        self.memory_barrier(
            (S::COMPUTE_SHADER, A::SHADER_STORAGE_WRITE),
            (
                S::FRAGMENT_SHADER | S::PRE_RASTERIZATION_SHADERS | S::VERTEX_INPUT | S::DRAW_INDIRECT,
                A::SHADER_READ | A::VERTEX_ATTRIBUTE_READ | A::INDEX_READ | A::INDIRECT_COMMAND_READ,
            ),
        );
    }

    /// Alias of [`compute_to_graphics`](Self::compute_to_graphics) under the
    /// name of its most common case.
    pub fn compute_to_fragment(&self) {
        self.compute_to_graphics();
    }

    /// Copies (uploads) before compute shaders read or overwrite the data.
    pub fn transfer_to_compute(&self) {
        self.memory_barrier(
            (vk::PipelineStageFlags2::COPY, vk::AccessFlags2::TRANSFER_WRITE),
            (vk::PipelineStageFlags2::COMPUTE_SHADER, vk::AccessFlags2::SHADER_READ | vk::AccessFlags2::SHADER_STORAGE_WRITE),
        );
    }

    /// One compute pass's writes before the next one reads or writes.
    pub fn compute_to_compute(&self) {
        self.memory_barrier(
            (vk::PipelineStageFlags2::COMPUTE_SHADER, vk::AccessFlags2::SHADER_STORAGE_WRITE),
            (vk::PipelineStageFlags2::COMPUTE_SHADER, vk::AccessFlags2::SHADER_READ | vk::AccessFlags2::SHADER_STORAGE_WRITE),
        );
    }

    /// One compute pass's writes before the next one reads or writes them
    /// and before an indirect dispatch reads its group counts from them.
    pub fn compute_to_indirect(&self) {
        use vk::{AccessFlags2 as A, PipelineStageFlags2 as S};
        self.memory_barrier(
            (S::COMPUTE_SHADER, A::SHADER_STORAGE_WRITE),
            (S::COMPUTE_SHADER | S::DRAW_INDIRECT, A::SHADER_READ | A::SHADER_STORAGE_WRITE | A::INDIRECT_COMMAND_READ),
        );
    }

    /// Compute-shader writes into host-visible memory before the host reads
    /// it (after the fence).
    pub fn compute_to_host(&self) {
        self.storage_to_host(Stages::COMPUTE);
    }

    /// Copies into host-visible memory before the host reads it.
    pub fn transfer_to_host(&self) {
        self.memory_barrier(
            (vk::PipelineStageFlags2::COPY, vk::AccessFlags2::TRANSFER_WRITE),
            (vk::PipelineStageFlags2::HOST, vk::AccessFlags2::HOST_READ),
        );
    }

    /// Clears and copies (`fill_buffer`, uploads) before shaders of
    /// `stages` read or write the same storage buffers.
    pub fn transfer_to_storage(&self, stages: Stages) {
        use vk::{AccessFlags2 as A, PipelineStageFlags2 as S};
        self.memory_barrier(
            (S::CLEAR | S::COPY, A::TRANSFER_WRITE),
            (stages.pipeline_stages(), A::SHADER_STORAGE_READ | A::SHADER_STORAGE_WRITE),
        );
    }

    /// This frame's host writes (mapped buffers), clears and copies before
    /// compute shaders read them (any way) or write storage.
    pub fn uploads_to_compute(&self) {
        use vk::{AccessFlags2 as A, PipelineStageFlags2 as S};
        self.memory_barrier(
            (S::HOST | S::CLEAR | S::COPY, A::HOST_WRITE | A::TRANSFER_WRITE),
            (S::COMPUTE_SHADER, A::SHADER_READ | A::SHADER_STORAGE_READ | A::SHADER_STORAGE_WRITE),
        );
    }

    /// Storage writes of shaders in `stages` into host-visible memory before
    /// the host reads it (after the fence).
    pub fn storage_to_host(&self, stages: Stages) {
        self.memory_barrier(
            (stages.pipeline_stages(), vk::AccessFlags2::SHADER_STORAGE_WRITE),
            (vk::PipelineStageFlags2::HOST, vk::AccessFlags2::HOST_READ),
        );
    }

    /// An earlier indexed indirect draw fetched indices and arguments that
    /// compute shaders now rewrite (write after read), reading them too.
    pub fn draw_fetch_to_compute(&self) {
        use vk::{AccessFlags2 as A, PipelineStageFlags2 as S};
        self.memory_barrier(
            (S::INDEX_INPUT | S::DRAW_INDIRECT, A::INDEX_READ | A::INDIRECT_COMMAND_READ),
            (S::COMPUTE_SHADER, A::SHADER_STORAGE_WRITE | A::SHADER_STORAGE_READ),
        );
    }

    /// Earlier vertex-stage shaders, compute shaders and copies read (or
    /// wrote) storage that compute shaders now read and rewrite: a pass
    /// that recomputes, each frame, data the previous frame consumed.
    pub fn consumers_to_compute(&self) {
        use vk::{AccessFlags2 as A, PipelineStageFlags2 as S};
        let rw = A::SHADER_STORAGE_READ | A::SHADER_STORAGE_WRITE;
        self.memory_barrier((S::PRE_RASTERIZATION_SHADERS | S::COMPUTE_SHADER | S::COPY, rw | A::TRANSFER_READ), (S::COMPUTE_SHADER, rw));
    }

    /// Compute-shader storage writes before vertex-stage shaders, compute
    /// shaders or copies read them (the other half of
    /// [`consumers_to_compute`](Self::consumers_to_compute)).
    pub fn compute_to_consumers(&self) {
        use vk::{AccessFlags2 as A, PipelineStageFlags2 as S};
        self.memory_barrier(
            (S::COMPUTE_SHADER, A::SHADER_STORAGE_WRITE),
            (S::PRE_RASTERIZATION_SHADERS | S::COMPUTE_SHADER | S::COPY, A::SHADER_STORAGE_READ | A::TRANSFER_READ),
        );
    }

    /// An earlier draw read vertex attributes from storage that compute
    /// shaders now rewrite (write after read: a per-frame expansion into
    /// vertex records).
    pub fn vertex_input_to_compute(&self) {
        use vk::{AccessFlags2 as A, PipelineStageFlags2 as S};
        self.memory_barrier((S::VERTEX_ATTRIBUTE_INPUT, A::VERTEX_ATTRIBUTE_READ), (S::COMPUTE_SHADER, A::SHADER_STORAGE_WRITE));
    }

    /// Compute-shader storage writes before a draw reads them as vertex
    /// attributes (the other half of
    /// [`vertex_input_to_compute`](Self::vertex_input_to_compute)).
    pub fn compute_to_vertex_input(&self) {
        use vk::{AccessFlags2 as A, PipelineStageFlags2 as S};
        self.memory_barrier((S::COMPUTE_SHADER, A::SHADER_STORAGE_WRITE), (S::VERTEX_ATTRIBUTE_INPUT, A::VERTEX_ATTRIBUTE_READ));
    }

    /// Move `image` to its next use, keeping its contents (layout
    /// transitions and hazards handled from the image's tracked state).
    pub fn image_barrier(&self, image: &Image, to: ImageUse) {
        image.barrier(self.raw, to, true);
    }

    /// Like `image_barrier`, discarding the contents (for a pass that
    /// overwrites every texel).
    pub fn image_barrier_discard(&self, image: &Image, to: ImageUse) {
        image.barrier(self.raw, to, false);
    }

    /// Copy the pixels `rect` (inclusive bounds, non-empty, within the
    /// image) of the 2D image `dst` from `src`, which holds them row after
    /// row (rows of the rectangle's width, texels of `dst`'s format) from
    /// its start, after the compute writes that filled it. What the image
    /// knows of where it may be nonzero ([`Image::zero_outside`]) grows by
    /// `rect` instead of being forgotten: a frame whose passes write their
    /// pixels to a buffer keeps [`CommandRecorder::storage_target`]'s
    /// partial clear.
    pub fn copy_rect_to_image(&self, src: &Buffer, dst: &Image, rect: [u32; 4]) -> VkResult<()> {
        let [x0, y0, x1, y1] = rect;
        let fits = dst.dim == ImageDim::D2 && x0 <= x1 && y0 <= y1 && x1 < dst.width && y1 < dst.height;
        let (w, h) = (x1.wrapping_sub(x0).wrapping_add(1), y1.wrapping_sub(y0).wrapping_add(1));
        let bytes = u64::from(w) * u64::from(h) * dst.format.texel_bytes();
        if !fits || src.size() < bytes {
            return Err(VkError::Invalid(format!(
                "copy of pixels {rect:?} into image '{}' ({}x{}) from buffer '{}' of {} bytes",
                dst.name(),
                dst.width,
                dst.height,
                src.desc.name,
                src.size()
            )));
        }
        self.compute_to_transfer();
        let known = dst.zero_outside();
        dst.barrier(self.raw, ImageUse::TransferDst, true);
        dst.set_zero_outside(known.map(|k| [k[0].min(x0), k[1].min(y0), k[2].max(x1), k[3].max(y1)]));
        let region = [vk::BufferImageCopy::default()
            .buffer_row_length(w)
            .buffer_image_height(h)
            .image_subresource(color_layers())
            .image_offset(vk::Offset3D { x: x0 as i32, y: y0 as i32, z: 0 })
            .image_extent(vk::Extent3D { width: w, height: h, depth: 1 })];
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit; both handles are live and kept alive by their
        // owners until the submission is waited for; the region lies inside
        // the image and the buffer holds its bytes (checked above).
        unsafe {
            self.ctx.device.cmd_copy_buffer_to_image(self.raw, src.raw, dst.raw, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &region)
        };
        Ok(())
    }

    /// Make `target` ready for a compute pass's image stores into the
    /// pixels `written` (inclusive bounds `[x0, y0, x1, y1]`, empty when
    /// x0 > x1 or y0 > y1): the pass may write fewer, never others. Once it
    /// has run, every pixel outside `written` is zero. When `written` is
    /// the whole image the old contents are discarded; otherwise an empty
    /// rendering pass clears what may be nonzero: the rectangle the last
    /// call gave for this image when nothing has written it since
    /// ([`Image::zero_outside`]: a frame's clear then covers the last
    /// frame's pixels, not the image), else the whole image.
    pub fn storage_target(&self, target: &Image, written: [u32; 4]) {
        let (w, h) = (target.width, target.height);
        let full = [0, 0, w.saturating_sub(1), h.saturating_sub(1)];
        if written[0] == 0 && written[1] == 0 && written[2] >= full[2] && written[3] >= full[3] {
            self.image_barrier_discard(target, ImageUse::ComputeStorage);
            target.set_zero_outside(Some(full));
            return;
        }
        let [x0, y0, x1, y1] = target.zero_outside().unwrap_or(full);
        let (x1, y1) = (x1.min(full[2]), y1.min(full[3]));
        if x0 <= x1 && y0 <= y1 {
            let area = vk::Rect2D {
                offset: vk::Offset2D { x: x0 as i32, y: y0 as i32 },
                extent: vk::Extent2D { width: x1 - x0 + 1, height: y1 - y0 + 1 },
            };
            self.record_begin_rendering_area(&[ColorAttachment { image: target, clear: Some([0.0; 4]) }], None, area);
            self.end_rendering();
        }
        self.image_barrier(target, ImageUse::ComputeStorage);
        target.set_zero_outside(Some(written));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fold_groups_follows_the_documented_rule() {
        let max = [65_535, 65_535, 65_535];
        assert_eq!(fold_groups(0, max), Some([0, 0, 0]));
        assert_eq!(fold_groups(1, max), Some([1, 1, 1]));
        assert_eq!(fold_groups(65_535, max), Some([65_535, 1, 1]));
        assert_eq!(fold_groups(65_536, max), Some([32_768, 2, 1]));
        assert_eq!(fold_groups(100_001, max), Some([50_001, 2, 1]));
        // Beyond one plane of x*y groups, z takes over.
        let big = 65_535u64 * 65_535 + 1;
        let [x, y, z] = fold_groups(big, max).unwrap();
        assert_eq!(z, 2);
        assert!((x as u64) * (y as u64) * (z as u64) >= big);
        assert_eq!(fold_groups(65_535u64.pow(3) + 1, max), None);
        // Small limits: every n fits, the excess stays below y*z groups.
        for n in 1..2_000u64 {
            let [x, y, z] = fold_groups(n, [7, 5, 100]).unwrap();
            let (x, y, z) = (x as u64, y as u64, z as u64);
            assert!(x <= 7 && y <= 5 && z <= 100, "{n}: {x} {y} {z}");
            assert!(x * y * z >= n && x * y * z - n < y * z, "{n}: {x} {y} {z}");
        }
    }

    /// A submission that never finishes (it waits on an event the host has
    /// not set) must time out with an error naming the recorder; once the
    /// event is set the context is marked hung, so nothing waits again.
    #[test]
    fn a_fence_wait_times_out_with_the_recorder_name() {
        let ctx = Context::new(&super::super::ContextDesc { device: None, validation: false }).expect("a Vulkan device");
        // SAFETY: test code on live handles of the test's own device, used
        // and destroyed within this test.
        let event = unsafe { ctx.device.create_event(&vk::EventCreateInfo::default(), None) }.expect("event");
        let mut rec = CommandRecorder::new(&ctx, "stuck on an event").expect("recorder");
        rec.set_timeout(Duration::from_millis(200));
        let cmd = rec.begin().expect("begin");
        // SAFETY: test code on live handles of the test's own device, used
        // and destroyed within this test.
        unsafe {
            ctx.device.cmd_wait_events(
                cmd,
                &[event],
                vk::PipelineStageFlags::HOST,
                vk::PipelineStageFlags::TOP_OF_PIPE,
                &[],
                &[],
                &[],
            );
        }
        rec.submit().expect("submit");
        let err = rec.wait().expect_err("the wait must time out");
        assert!(matches!(err, VkError::Timeout { .. }), "{err}");
        assert!(err.to_string().contains("stuck on an event"), "{err}");
        assert!(ctx.is_hung());
        // Let the device finish so the test process does not keep a busy
        // queue thread; the recorder and context leak by design.
        // SAFETY: test code on live handles of the test's own device, used
        // and destroyed within this test.
        unsafe { ctx.device.set_event(event).expect("set event") };
        assert!(matches!(rec.wait(), Err(VkError::DeviceHung)));
    }
}
