//! Command buffers and submission. One reusable command buffer + fence per
//! `CommandRecorder`; `submit_and_wait` blocks until the device is done, which
//! is the whole synchronisation model (one frame in flight).

use std::sync::Arc;
use std::time::{Duration, Instant};

use ash::vk;

use super::buffer::Buffer;
use super::error::{Check, VkResult};
use super::upload::{UploadClass, UploadCounter};
use super::Context;

pub struct CommandRecorder {
    pub raw: vk::CommandBuffer,
    fence: vk::Fence,
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
        let raw = unsafe { ctx.device.allocate_command_buffers(&info) }.check("vkAllocateCommandBuffers")?[0];
        let fence = match unsafe { ctx.device.create_fence(&vk::FenceCreateInfo::default(), None) } {
            Ok(f) => f,
            Err(result) => {
                unsafe { ctx.device.free_command_buffers(ctx.command_pool, &[raw]) };
                return Err(super::VkError::Call { what: "vkCreateFence", result });
            }
        };
        ctx.set_name(raw, name);
        Ok(CommandRecorder { raw, fence, ctx: ctx.clone() })
    }

    pub fn begin(&self) -> VkResult<vk::CommandBuffer> {
        let d = &self.ctx.device;
        unsafe {
            d.reset_command_buffer(self.raw, vk::CommandBufferResetFlags::empty()).check("vkResetCommandBuffer")?;
            let info = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            d.begin_command_buffer(self.raw, &info).check("vkBeginCommandBuffer")?;
        }
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
        let d = &self.ctx.device;
        unsafe {
            d.end_command_buffer(self.raw).check("vkEndCommandBuffer")?;
            d.reset_fences(&[self.fence]).check("vkResetFences")?;
            let cmds = [self.raw];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            let t0 = Instant::now();
            d.queue_submit(self.ctx.queue, &submit, self.fence).check("vkQueueSubmit")?;
            Ok(t0.elapsed())
        }
    }

    /// Block until the last submission has finished; returns the time blocked.
    pub fn wait(&self) -> VkResult<Duration> {
        let t0 = Instant::now();
        unsafe { self.ctx.device.wait_for_fences(&[self.fence], true, u64::MAX) }.check("vkWaitForFences")?;
        Ok(t0.elapsed())
    }

    /// Record a buffer-to-buffer copy from host-visible `src` and count its
    /// bytes as crossing to the device.
    pub fn copy_to_device(
        &self,
        src: &Buffer,
        dst: &Buffer,
        bytes: u64,
        counter: &mut UploadCounter,
        class: UploadClass,
    ) {
        let region = [vk::BufferCopy { src_offset: 0, dst_offset: 0, size: bytes }];
        unsafe { self.ctx.device.cmd_copy_buffer(self.raw, src.raw, dst.raw, &region) };
        counter.add_transfer(class, bytes);
    }
}

impl Drop for CommandRecorder {
    fn drop(&mut self) {
        unsafe {
            let _ = self.ctx.device.wait_for_fences(&[self.fence], true, u64::MAX);
            self.ctx.device.destroy_fence(self.fence, None);
            self.ctx.device.free_command_buffers(self.ctx.command_pool, &[self.raw]);
        }
    }
}

/// Upload `data` once into a new device-local buffer through a staging buffer
/// (the path a discrete GPU needs for static data); counted as static bytes.
pub fn upload_static(
    ctx: &Arc<Context>,
    name: &str,
    data: &[u8],
    usage: vk::BufferUsageFlags,
    counter: &mut UploadCounter,
) -> VkResult<Buffer> {
    use super::buffer::BufferDesc;
    let size = data.len() as u64;
    let mut staging = Buffer::new(ctx, BufferDesc::upload(&format!("{name} (staging)"), size, vk::BufferUsageFlags::TRANSFER_SRC))?;
    staging.write_staging(0, data)?;
    let dst = Buffer::new(ctx, BufferDesc::device_local(name, size, usage))?;
    let rec = CommandRecorder::new(ctx, &format!("{name} upload"))?;
    rec.begin()?;
    rec.copy_to_device(&staging, &dst, size, counter, UploadClass::Static);
    let barrier = [vk::MemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::COPY)
        .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
        .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .dst_access_mask(vk::AccessFlags2::MEMORY_READ)];
    unsafe {
        ctx.device.cmd_pipeline_barrier2(rec.raw, &vk::DependencyInfo::default().memory_barriers(&barrier));
    }
    rec.submit_and_wait()?;
    Ok(dst)
}

/// Thin safe wrappers for the commands the algorithms record, so that no
/// algorithm needs `unsafe`. All take the recorder's own command buffer.
impl CommandRecorder {
    /// Start dynamic rendering into `target`, cleared to `clear`. The image
    /// goes from UNDEFINED (contents discarded) to COLOR_ATTACHMENT_OPTIMAL.
    pub fn begin_rendering(&self, target: &super::Image, clear: [f32; 4]) {
        target.transition(
            self.raw,
            (vk::ImageLayout::UNDEFINED, vk::PipelineStageFlags2::TOP_OF_PIPE, vk::AccessFlags2::NONE),
            (
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
                vk::AccessFlags2::COLOR_ATTACHMENT_WRITE | vk::AccessFlags2::COLOR_ATTACHMENT_READ,
            ),
        );
        let attachments = [vk::RenderingAttachmentInfo::default()
            .image_view(target.view)
            .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .clear_value(vk::ClearValue { color: vk::ClearColorValue { float32: clear } })];
        let area = vk::Rect2D { offset: vk::Offset2D { x: 0, y: 0 }, extent: vk::Extent2D { width: target.width, height: target.height } };
        let info = vk::RenderingInfo::default().render_area(area).layer_count(1).color_attachments(&attachments);
        let viewport = [vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: target.width as f32,
            height: target.height as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        }];
        unsafe {
            self.ctx.device.cmd_begin_rendering(self.raw, &info);
            self.ctx.device.cmd_set_viewport(self.raw, 0, &viewport);
            self.ctx.device.cmd_set_scissor(self.raw, 0, &[area]);
        }
    }

    pub fn end_rendering(&self) {
        unsafe { self.ctx.device.cmd_end_rendering(self.raw) };
    }

    pub fn bind_pipeline(&self, pipeline: &super::Pipeline, set: Option<&super::StorageBufferSet>) {
        unsafe {
            self.ctx.device.cmd_bind_pipeline(self.raw, vk::PipelineBindPoint::GRAPHICS, pipeline.raw);
            if let Some(s) = set {
                self.ctx.device.cmd_bind_descriptor_sets(
                    self.raw,
                    vk::PipelineBindPoint::GRAPHICS,
                    pipeline.layout,
                    0,
                    &[s.set],
                    &[],
                );
            }
        }
    }

    /// Push constants (recorded into the command buffer, so they cross to
    /// the device with it: counted as per-frame constants).
    pub fn push_constants(&self, pipeline: &super::Pipeline, data: &[u8], counter: &mut UploadCounter) {
        unsafe { self.ctx.device.cmd_push_constants(self.raw, pipeline.layout, pipeline.push_stages, 0, data) };
        counter.add_direct(UploadClass::FrameConstants, data.len() as u64);
    }

    pub fn bind_vertex_buffer(&self, buffer: &Buffer) {
        unsafe { self.ctx.device.cmd_bind_vertex_buffers(self.raw, 0, &[buffer.raw], &[0]) };
    }

    pub fn bind_index_buffer_u32(&self, buffer: &Buffer) {
        unsafe { self.ctx.device.cmd_bind_index_buffer(self.raw, buffer.raw, 0, vk::IndexType::UINT32) };
    }

    pub fn draw(&self, vertices: u32) {
        unsafe { self.ctx.device.cmd_draw(self.raw, vertices, 1, 0, 0) };
    }

    pub fn draw_indexed(&self, indices: u32) {
        unsafe { self.ctx.device.cmd_draw_indexed(self.raw, indices, 1, 0, 0, 0) };
    }

    /// Make host writes to mapped buffers visible to vertex input and shaders
    /// (required by the spec even for coherent memory written before submit).
    pub fn host_to_device_barrier(&self) {
        let barrier = [vk::MemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::HOST)
            .src_access_mask(vk::AccessFlags2::HOST_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::VERTEX_INPUT | vk::PipelineStageFlags2::ALL_GRAPHICS)
            .dst_access_mask(vk::AccessFlags2::VERTEX_ATTRIBUTE_READ | vk::AccessFlags2::SHADER_STORAGE_READ)];
        unsafe { self.ctx.device.cmd_pipeline_barrier2(self.raw, &vk::DependencyInfo::default().memory_barriers(&barrier)) };
    }
}
