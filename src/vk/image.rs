//! The offscreen render target (RGBA32F colour attachment) and its readback.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::buffer::{Buffer, BufferDesc};
use super::commands::CommandRecorder;
use super::error::{Check, VkError, VkResult};
use super::Context;

pub const TARGET_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

pub struct Image {
    pub raw: vk::Image,
    pub view: vk::ImageView,
    pub width: u32,
    pub height: u32,
    pub format: vk::Format,
    allocation: Option<Allocation>,
    ctx: Arc<Context>,
}

impl Image {
    /// A colour target that can also be copied out for readback.
    pub fn render_target(ctx: &Arc<Context>, name: &str, width: u32, height: u32) -> VkResult<Image> {
        let max = ctx.info.max_image_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(VkError::Unsupported {
                device: ctx.info.name.clone(),
                what: format!("a {width}x{height} render target (maxImageDimension2D is {max})"),
            });
        }
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(TARGET_FORMAT)
            .extent(vk::Extent3D { width, height, depth: 1 })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let raw = unsafe { ctx.device.create_image(&info, None) }.check("vkCreateImage")?;
        let requirements = unsafe { ctx.device.get_image_memory_requirements(raw) };
        let allocation = match ctx.allocator().allocate(&AllocationCreateDesc {
            name,
            requirements,
            location: MemoryLocation::GpuOnly,
            linear: false,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        }) {
            Ok(a) => a,
            Err(source) => {
                unsafe { ctx.device.destroy_image(raw, None) };
                return Err(VkError::Alloc { name: name.into(), source });
            }
        };
        let mut image = Image {
            raw,
            view: vk::ImageView::null(),
            width,
            height,
            format: TARGET_FORMAT,
            allocation: None,
            ctx: ctx.clone(),
        };
        unsafe { ctx.device.bind_image_memory(raw, allocation.memory(), allocation.offset()) }.check("vkBindImageMemory")?;
        image.allocation = Some(allocation);
        let view_info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(TARGET_FORMAT)
            .subresource_range(color_range());
        image.view = unsafe { ctx.device.create_image_view(&view_info, None) }.check("vkCreateImageView")?;
        ctx.set_name(raw, name);
        Ok(image)
    }

    /// Barrier moving the whole image between layouts.
    pub fn transition(
        &self,
        cmd: vk::CommandBuffer,
        from: (vk::ImageLayout, vk::PipelineStageFlags2, vk::AccessFlags2),
        to: (vk::ImageLayout, vk::PipelineStageFlags2, vk::AccessFlags2),
    ) {
        let barrier = [vk::ImageMemoryBarrier2::default()
            .src_stage_mask(from.1)
            .src_access_mask(from.2)
            .old_layout(from.0)
            .dst_stage_mask(to.1)
            .dst_access_mask(to.2)
            .new_layout(to.0)
            .image(self.raw)
            .subresource_range(color_range())];
        unsafe {
            self.ctx.device.cmd_pipeline_barrier2(cmd, &vk::DependencyInfo::default().image_memory_barriers(&barrier));
        }
    }

    /// Copy the image (left in COLOR_ATTACHMENT_OPTIMAL by a render) to the
    /// host as RGBA f32, row 0 at the top.
    pub fn read_rgba32f(&self, ctx: &Arc<Context>) -> VkResult<Vec<[f32; 4]>> {
        let bytes = self.width as u64 * self.height as u64 * 16;
        let buf = Buffer::new(ctx, BufferDesc::readback("target readback", bytes))?;
        let rec = CommandRecorder::new(ctx, "readback")?;
        let cmd = rec.begin()?;
        self.transition(
            cmd,
            (
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
                vk::AccessFlags2::COLOR_ATTACHMENT_WRITE,
            ),
            (vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::PipelineStageFlags2::COPY, vk::AccessFlags2::TRANSFER_READ),
        );
        let region = [vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers {
                aspect_mask: vk::ImageAspectFlags::COLOR,
                mip_level: 0,
                base_array_layer: 0,
                layer_count: 1,
            })
            .image_extent(vk::Extent3D { width: self.width, height: self.height, depth: 1 })];
        unsafe {
            ctx.device.cmd_copy_image_to_buffer(cmd, self.raw, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, buf.raw, &region);
        }
        let to_host = [vk::MemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::COPY)
            .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::HOST)
            .dst_access_mask(vk::AccessFlags2::HOST_READ)];
        unsafe { ctx.device.cmd_pipeline_barrier2(cmd, &vk::DependencyInfo::default().memory_barriers(&to_host)) };
        self.transition(
            cmd,
            (vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::PipelineStageFlags2::COPY, vk::AccessFlags2::TRANSFER_READ),
            (
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
                vk::AccessFlags2::COLOR_ATTACHMENT_WRITE,
            ),
        );
        rec.submit_and_wait()?;
        let data = buf.read()?;
        let f = |b: &[u8]| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]);
        Ok(data.chunks_exact(16).map(|c| [f(&c[0..4]), f(&c[4..8]), f(&c[8..12]), f(&c[12..16])]).collect())
    }
}

pub fn color_range() -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        unsafe {
            if self.view != vk::ImageView::null() {
                self.ctx.device.destroy_image_view(self.view, None);
            }
            self.ctx.device.destroy_image(self.raw, None);
        }
        if let Some(a) = self.allocation.take() {
            let _ = self.ctx.allocator().free(a);
        }
    }
}
