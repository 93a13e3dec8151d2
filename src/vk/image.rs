//! Images with their memory and their current layout, and samplers (texture
//! upload and readback, which record commands, are in `transfer`).
//!
//! One `Image` type covers the offscreen render target (RGBA32F; colour
//! attachment, storage image and sampled, so a compute pass can write the
//! final image or a later pass can read it) and sampled textures of one, two
//! or three dimensions (volumes in R8/R16/R32F, transfer-function tables in
//! RGBA32F, 2D integration tables in R32F/RG32F). Each image owns its
//! allocation and view and frees them on `Drop`.
//!
//! Layouts are tracked: every barrier recorded through `Image::barrier`
//! (`CommandRecorder::image_barrier`, `begin_rendering*`, readback, upload)
//! starts from the state the previous one left, so no caller has to remember
//! whether a render, a compute pass or a readback touched the image last.
//! The state is updated when the barrier is recorded; with one queue and
//! submissions in recording order that is the state the device will see (a
//! recorded but never submitted barrier would break this, so recorders are
//! always submitted or dropped with their images' users).
//!
//! Texture data is uploaded once through a staging buffer and counted as
//! static bytes at the copy (see `upload`).

use std::sync::{Arc, Mutex};

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::error::{Check, VkError, VkResult};
use super::format::{Format, DEPTH_FORMAT, TARGET_FORMAT};
use super::Context;

/// How many dimensions an image has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ImageDim {
    D1,
    D2,
    D3,
}

impl ImageDim {
    fn image_type(self) -> vk::ImageType {
        match self {
            ImageDim::D1 => vk::ImageType::TYPE_1D,
            ImageDim::D2 => vk::ImageType::TYPE_2D,
            ImageDim::D3 => vk::ImageType::TYPE_3D,
        }
    }
    fn view_type(self) -> vk::ImageViewType {
        match self {
            ImageDim::D1 => vk::ImageViewType::TYPE_1D,
            ImageDim::D2 => vk::ImageViewType::TYPE_2D,
            ImageDim::D3 => vk::ImageViewType::TYPE_3D,
        }
    }
}

/// A sampled image (or one read with imageLoad), as data. Texels are given
/// x fastest, then y, then z, tightly packed.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct TextureDesc {
    pub name: String,
    pub dim: ImageDim,
    pub width: u32,
    /// 1 for 1D images.
    pub height: u32,
    /// 1 for 1D and 2D images.
    pub depth: u32,
    pub format: Format,
    /// Read by shaders with imageLoad, as a storage image left in layout
    /// GENERAL after the upload (`ImageUse::ShaderLoad`), not sampled.
    pub loads: bool,
}

impl TextureDesc {
    pub fn d1(name: &str, width: u32, format: Format) -> Self {
        TextureDesc { name: name.into(), dim: ImageDim::D1, width, height: 1, depth: 1, format, loads: false }
    }
    pub fn d2(name: &str, width: u32, height: u32, format: Format) -> Self {
        TextureDesc { name: name.into(), dim: ImageDim::D2, width, height, depth: 1, format, loads: false }
    }
    pub fn d3(name: &str, [width, height, depth]: [u32; 3], format: Format) -> Self {
        TextureDesc { name: name.into(), dim: ImageDim::D3, width, height, depth, format, loads: false }
    }

    /// The same image, read with imageLoad instead of sampled.
    pub fn for_loads(mut self) -> Self {
        self.loads = true;
        self
    }

    /// Bytes of the whole image (checked; `None` on overflow).
    pub fn byte_size(&self) -> Option<u64> {
        self.format
            .texel_bytes()
            .checked_mul(self.width as u64)?
            .checked_mul(self.height as u64)?
            .checked_mul(self.depth as u64)
    }
}

/// What an image is used for next; each maps to one layout and the stages
/// and accesses a barrier must cover.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ImageUse {
    /// Colour attachment of a dynamic-rendering pass (read and write, for blending).
    ColorAttachment,
    /// Storage image read and written by compute shaders (layout GENERAL).
    ComputeStorage,
    /// Sampled by any shader stage (fragment, compute, pre-rasterisation).
    Sampled,
    /// Read with imageLoad, never written, by any shader stage (layout
    /// GENERAL, as storage images are bound).
    ShaderLoad,
    /// Source of a copy (readback).
    TransferSrc,
    /// Destination of a copy (upload).
    TransferDst,
    /// Depth attachment of a dynamic-rendering pass (tested and written).
    DepthAttachment,
}

/// Layout, stages and accesses of the last recorded use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageState {
    pub layout: vk::ImageLayout,
    pub stages: vk::PipelineStageFlags2,
    pub access: vk::AccessFlags2,
}

impl ImageUse {
    pub fn state(self) -> ImageState {
        use vk::{AccessFlags2 as A, ImageLayout as L, PipelineStageFlags2 as S};
        let (layout, stages, access) = match self {
            ImageUse::ColorAttachment => (
                L::COLOR_ATTACHMENT_OPTIMAL,
                S::COLOR_ATTACHMENT_OUTPUT,
                A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE,
            ),
            ImageUse::ComputeStorage => {
                (L::GENERAL, S::COMPUTE_SHADER, A::SHADER_STORAGE_READ | A::SHADER_STORAGE_WRITE)
            }
            // PRE_RASTERIZATION_SHADERS covers vertex and geometry stages
            // without naming GEOMETRY_SHADER (invalid when the feature is off).
            ImageUse::Sampled => (
                L::SHADER_READ_ONLY_OPTIMAL,
                S::FRAGMENT_SHADER | S::COMPUTE_SHADER | S::PRE_RASTERIZATION_SHADERS,
                A::SHADER_SAMPLED_READ,
            ),
            ImageUse::ShaderLoad => (
                L::GENERAL,
                S::FRAGMENT_SHADER | S::COMPUTE_SHADER | S::PRE_RASTERIZATION_SHADERS,
                A::SHADER_STORAGE_READ,
            ),
            ImageUse::TransferSrc => (L::TRANSFER_SRC_OPTIMAL, S::COPY, A::TRANSFER_READ),
            ImageUse::TransferDst => (L::TRANSFER_DST_OPTIMAL, S::COPY, A::TRANSFER_WRITE),
            ImageUse::DepthAttachment => (
                L::DEPTH_ATTACHMENT_OPTIMAL,
                S::EARLY_FRAGMENT_TESTS | S::LATE_FRAGMENT_TESTS,
                A::DEPTH_STENCIL_ATTACHMENT_READ | A::DEPTH_STENCIL_ATTACHMENT_WRITE,
            ),
        };
        ImageState { layout, stages, access }
    }
}

const UNDEFINED_STATE: ImageState =
    ImageState { layout: vk::ImageLayout::UNDEFINED, stages: vk::PipelineStageFlags2::NONE, access: vk::AccessFlags2::NONE };

pub struct Image {
    pub raw: vk::Image,
    pub view: vk::ImageView,
    pub width: u32,
    pub height: u32,
    pub depth: u32,
    pub format: Format,
    pub dim: ImageDim,
    pub(crate) usage: vk::ImageUsageFlags,
    name: String,
    state: Mutex<ImageState>,
    /// `Some(r)`: as recorded so far, every pixel outside the inclusive
    /// bounds `r` is zero (`r` may be empty: x0 > x1), established only by
    /// `CommandRecorder::storage_target` (and kept, grown by the rectangle
    /// copied, by `CommandRecorder::copy_rect_to_image`); `None`: unknown.
    /// Any other barrier or transition into a state that may write the
    /// image resets it.
    zero_outside: Mutex<Option<[u32; 4]>>,
    allocation: Option<Allocation>,
    ctx: Arc<Context>,
}

impl Image {
    /// The RGBA32F target: colour attachment, copy source for readback, copy
    /// destination (passes that write their pixels to a buffer) and, where
    /// the device allows it for the format, storage image (a compute pass
    /// writes the final image) and sampled image (a later pass reads it).
    pub fn render_target(ctx: &Arc<Context>, name: &str, width: u32, height: u32) -> VkResult<Image> {
        let max = ctx.info.max_image_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(VkError::Unsupported {
                device: ctx.info.name.clone(),
                what: format!("a {width}x{height} render target (maxImageDimension2D is {max})"),
            });
        }
        let mut usage = vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
        if ctx.format_supports(TARGET_FORMAT, vk::FormatFeatureFlags::STORAGE_IMAGE) {
            usage |= vk::ImageUsageFlags::STORAGE;
        }
        if ctx.format_supports(TARGET_FORMAT, vk::FormatFeatureFlags::SAMPLED_IMAGE) {
            usage |= vk::ImageUsageFlags::SAMPLED;
        }
        Self::create(ctx, name, ImageDim::D2, [width, height, 1], TARGET_FORMAT, usage)
    }

    /// A 32-bit float depth buffer (`DEPTH_FORMAT`) for a `width`x`height` target.
    pub fn depth_target(ctx: &Arc<Context>, name: &str, width: u32, height: u32) -> VkResult<Image> {
        Self::create(ctx, name, ImageDim::D2, [width, height, 1], DEPTH_FORMAT, vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT)
    }

    /// An empty sampled image (contents undefined until uploaded or written).
    pub fn texture(ctx: &Arc<Context>, desc: &TextureDesc) -> VkResult<Image> {
        let mut usage = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::TRANSFER_SRC;
        let mut features = vk::FormatFeatureFlags::SAMPLED_IMAGE | vk::FormatFeatureFlags::TRANSFER_DST;
        if desc.loads {
            usage |= vk::ImageUsageFlags::STORAGE;
            features |= vk::FormatFeatureFlags::STORAGE_IMAGE;
        }
        if !ctx.format_supports(desc.format, features) {
            return Err(VkError::Unsupported {
                device: ctx.info.name.clone(),
                what: format!("format {:?} with {:?} for image '{}'", desc.format, features, desc.name),
            });
        }
        let extent = match desc.dim {
            ImageDim::D1 => [desc.width, 1, 1],
            ImageDim::D2 => [desc.width, desc.height, 1],
            ImageDim::D3 => [desc.width, desc.height, desc.depth],
        };
        if extent != [desc.width, desc.height, desc.depth] {
            return Err(VkError::Invalid(format!(
                "image '{}': a {:?} image must have height/depth 1 beyond its dimensions, got {}x{}x{}",
                desc.name, desc.dim, desc.width, desc.height, desc.depth
            )));
        }
        Self::create(ctx, &desc.name, desc.dim, extent, desc.format, usage)
    }

    fn create(
        ctx: &Arc<Context>,
        name: &str,
        dim: ImageDim,
        [width, height, depth]: [u32; 3],
        format: Format,
        usage: vk::ImageUsageFlags,
    ) -> VkResult<Image> {
        let info = &ctx.info;
        let max = match dim {
            ImageDim::D1 => info.max_image_dimension_1d,
            ImageDim::D2 => info.max_image_dimension_2d,
            ImageDim::D3 => info.max_image_dimension_3d,
        };
        let limits = ctx.image_format_limits(format.to_vk(), dim.image_type(), usage);
        let fits = |l: &vk::ImageFormatProperties| {
            let bytes = format
                .texel_bytes()
                .checked_mul(width as u64)
                .and_then(|b| b.checked_mul(height as u64))
                .and_then(|b| b.checked_mul(depth as u64));
            width <= l.max_extent.width
                && height <= l.max_extent.height
                && depth <= l.max_extent.depth
                && bytes.is_some_and(|b| b <= l.max_resource_size)
        };
        if width == 0 || height == 0 || depth == 0 || width.max(height).max(depth) > max || !limits.as_ref().is_some_and(fits) {
            return Err(VkError::Unsupported {
                device: info.name.clone(),
                what: format!(
                    "a {width}x{height}x{depth} {dim:?} image '{name}' of {format:?} with usage {usage:?} (max dimension {max}, format limits {:?})",
                    limits.map(|l| l.max_extent)
                ),
            });
        }
        let ci = vk::ImageCreateInfo::default()
            .image_type(dim.image_type())
            .format(format.to_vk())
            .extent(vk::Extent3D { width, height, depth })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let raw = unsafe { ctx.device.create_image(&ci, None) }.check("vkCreateImage")?;
        // From here the image owns `raw`: an early return drops it (and frees
        // what exists so far).
        let mut image = Image {
            raw,
            view: vk::ImageView::null(),
            width,
            height,
            depth,
            format,
            dim,
            usage,
            name: name.to_string(),
            state: Mutex::new(UNDEFINED_STATE),
            zero_outside: Mutex::new(None),
            allocation: None,
            ctx: ctx.clone(),
        };
        // SAFETY: the handle was created on this device just above and is live.
        let requirements = unsafe { ctx.device.get_image_memory_requirements(raw) };
        let allocation = ctx
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location: MemoryLocation::GpuOnly,
                linear: false,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|source| VkError::Alloc { name: name.into(), source })?;
        // SAFETY: the handle is live and unbound; the allocation was made by
        // this device's allocator for its memory requirements, is owned by the
        // same wrapper and freed only when the handle is no longer used (Drop,
        // or the error path below; Vulkan allows freeing memory still bound
        // to a handle that is then only destroyed).
        let bound = unsafe { ctx.device.bind_image_memory(raw, allocation.memory(), allocation.offset()) };
        image.allocation = Some(allocation);
        bound.check("vkBindImageMemory")?;
        let view_info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(dim.view_type())
            .format(format.to_vk())
            .subresource_range(range_of(format));
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        image.view = unsafe { ctx.device.create_image_view(&view_info, None) }.check("vkCreateImageView")?;
        ctx.set_name(raw, name);
        ctx.set_name(image.view, name);
        Ok(image)
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Whether shaders may sample the image (a render target is sampled
    /// only where the device allows it for the target format).
    pub fn is_sampled(&self) -> bool {
        self.usage.contains(vk::ImageUsageFlags::SAMPLED)
    }

    /// Whether compute shaders may write the image as a storage image.
    pub fn is_storage(&self) -> bool {
        self.usage.contains(vk::ImageUsageFlags::STORAGE)
    }

    /// A number naming this image while it lives (its handle): a method
    /// keeps a descriptor set per target and rebuilds it when this changes.
    pub fn id(&self) -> u64 {
        vk::Handle::as_raw(self.raw)
    }

    /// Bytes of the whole image.
    pub fn byte_size(&self) -> u64 {
        // Checked at creation (it fitted maxResourceSize).
        self.format.texel_bytes() * self.width as u64 * self.height as u64 * self.depth as u64
    }

    /// The last recorded use.
    pub fn state(&self) -> ImageState {
        *self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Record a barrier from the last recorded use to `to`. With `keep`
    /// false the old contents are discarded (layout UNDEFINED as source),
    /// which is what a pass that overwrites every texel wants.
    pub fn barrier(&self, cmd: vk::CommandBuffer, to: ImageUse, keep: bool) {
        if !keep || !matches!(to, ImageUse::Sampled | ImageUse::ShaderLoad | ImageUse::TransferSrc) {
            self.set_zero_outside(None);
        }
        let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        let mut from = *state;
        if !keep {
            from.layout = vk::ImageLayout::UNDEFINED;
        }
        let to = to.state();
        self.record_barrier(cmd, from, to);
        *state = to;
    }

    /// Barrier moving the whole image between explicit states, given as
    /// (layout, stages, accesses); the tracked state becomes `to`.
    pub fn transition(
        &self,
        cmd: vk::CommandBuffer,
        from: (vk::ImageLayout, vk::PipelineStageFlags2, vk::AccessFlags2),
        to: (vk::ImageLayout, vk::PipelineStageFlags2, vk::AccessFlags2),
    ) {
        let to = ImageState { layout: to.0, stages: to.1, access: to.2 };
        self.set_zero_outside(None);
        self.record_barrier(cmd, ImageState { layout: from.0, stages: from.1, access: from.2 }, to);
        *self.state.lock().unwrap_or_else(|p| p.into_inner()) = to;
    }

    /// The rectangle outside which the image is known to be zero, as
    /// recorded so far (`None`: unknown; the field's note says when).
    pub fn zero_outside(&self) -> Option<[u32; 4]> {
        *self.zero_outside.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub(crate) fn set_zero_outside(&self, rect: Option<[u32; 4]>) {
        *self.zero_outside.lock().unwrap_or_else(|p| p.into_inner()) = rect;
    }

    fn record_barrier(&self, cmd: vk::CommandBuffer, from: ImageState, to: ImageState) {
        let barrier = [vk::ImageMemoryBarrier2::default()
            .src_stage_mask(from.stages)
            .src_access_mask(from.access)
            .old_layout(from.layout)
            .dst_stage_mask(to.stages)
            .dst_access_mask(to.access)
            .new_layout(to.layout)
            .image(self.raw)
            .subresource_range(range_of(self.format))];
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe {
            self.ctx.device.cmd_pipeline_barrier2(cmd, &vk::DependencyInfo::default().image_memory_barriers(&barrier));
        }
    }

}

/// The whole image: the depth aspect for the depth format, else colour.
fn range_of(format: Format) -> vk::ImageSubresourceRange {
    let aspect_mask = if format == DEPTH_FORMAT { vk::ImageAspectFlags::DEPTH } else { vk::ImageAspectFlags::COLOR };
    vk::ImageSubresourceRange { aspect_mask, ..color_range() }
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

pub(crate) fn color_layers() -> vk::ImageSubresourceLayers {
    vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: 0, layer_count: 1 }
}

impl Drop for Image {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            // The device may still write this memory: leak rather than free.
            return;
        }
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe {
            if self.view != vk::ImageView::null() {
                self.ctx.device.destroy_image_view(self.view, None);
            }
            self.ctx.device.destroy_image(self.raw, None);
        }
        if let Some(a) = self.allocation.take() {
            self.ctx.free(a);
        }
    }
}

/// How a sampler filters between texels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Filter {
    /// Linear (trilinear for 3D images); needs SAMPLED_IMAGE_FILTER_LINEAR.
    Linear,
    /// Nearest texel (integer formats, or exact texel values).
    Nearest,
}

/// A sampler with clamp-to-edge addressing, normalised coordinates, one mip
/// level and no anisotropy: texel i's centre is at (i + 0.5) / size.
pub struct Sampler {
    pub raw: vk::Sampler,
    pub filter: Filter,
    ctx: Arc<Context>,
}

impl Sampler {
    pub fn new(ctx: &Arc<Context>, name: &str, filter: Filter) -> VkResult<Sampler> {
        let f = match filter {
            Filter::Linear => vk::Filter::LINEAR,
            Filter::Nearest => vk::Filter::NEAREST,
        };
        let clamp = vk::SamplerAddressMode::CLAMP_TO_EDGE;
        let info = vk::SamplerCreateInfo::default()
            .mag_filter(f)
            .min_filter(f)
            .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
            .address_mode_u(clamp)
            .address_mode_v(clamp)
            .address_mode_w(clamp)
            .min_lod(0.0)
            .max_lod(0.0)
            .unnormalized_coordinates(false);
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let raw = unsafe { ctx.device.create_sampler(&info, None) }.check("vkCreateSampler")?;
        ctx.set_name(raw, name);
        Ok(Sampler { raw, filter, ctx: ctx.clone() })
    }

    pub fn linear_clamp(ctx: &Arc<Context>, name: &str) -> VkResult<Sampler> {
        Self::new(ctx, name, Filter::Linear)
    }

    pub fn nearest_clamp(ctx: &Arc<Context>, name: &str) -> VkResult<Sampler> {
        Self::new(ctx, name, Filter::Nearest)
    }
}

impl Drop for Sampler {
    fn drop(&mut self) {
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe { self.ctx.device.destroy_sampler(self.raw, None) };
    }
}
