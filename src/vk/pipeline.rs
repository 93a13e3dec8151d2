//! Graphics and compute pipelines, described by plain structs
//! (`GraphicsPipelineDesc`, `ComputePipelineDesc`); the algorithms never touch
//! raw create-infos. Graphics pipelines render with dynamic rendering into
//! one or several colour attachments (a format and a blend per attachment;
//! the usual case is one RGBA32F target, `ColorTarget::rgba32f`), with an
//! optional geometry-shader stage (needs `DeviceFeatures::geometry_shader`).
//! Both kinds take any number of descriptor-set layouts (sets 0, 1, ...) and
//! one push-constant range visible to all their stages.
//!
//! A `Pipeline` owns its pipeline layout, and the set layouts too when the
//! pipeline cache made them (`pipeline_cache`); `Drop` destroys them.

use std::sync::Arc;

use ash::vk;

use super::descriptors::DescriptorSetLayout;
use super::error::{Check, VkError, VkResult};
use super::format::{Format, DEPTH_FORMAT, TARGET_FORMAT};
use super::shader::{ShaderModule, ShaderStage};
use super::types::{Cull, Stages, Topology, Winding};
use super::Context;

/// How fragments combine with the target.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Blend {
    /// Premultiplied "over", drawing back to front: dst = src + (1 - src.a) dst.
    PremultipliedOver,
    /// Overwrite.
    None,
    /// dst = src + dst on every channel (accumulation, counting).
    Additive,
}

impl Blend {
    pub(crate) fn code(self) -> u8 {
        match self {
            Blend::PremultipliedOver => 0,
            Blend::None => 1,
            Blend::Additive => 2,
        }
    }

    fn state(self) -> vk::PipelineColorBlendAttachmentState {
        let blended = |src: vk::BlendFactor, dst: vk::BlendFactor| {
            vk::PipelineColorBlendAttachmentState::default()
                .blend_enable(true)
                .src_color_blend_factor(src)
                .dst_color_blend_factor(dst)
                .color_blend_op(vk::BlendOp::ADD)
                .src_alpha_blend_factor(src)
                .dst_alpha_blend_factor(dst)
                .alpha_blend_op(vk::BlendOp::ADD)
                .color_write_mask(vk::ColorComponentFlags::RGBA)
        };
        match self {
            Blend::PremultipliedOver => blended(vk::BlendFactor::ONE, vk::BlendFactor::ONE_MINUS_SRC_ALPHA),
            Blend::Additive => blended(vk::BlendFactor::ONE, vk::BlendFactor::ONE),
            Blend::None => vk::PipelineColorBlendAttachmentState::default().color_write_mask(vk::ColorComponentFlags::RGBA),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct VertexAttribute {
    pub location: u32,
    pub format: Format,
    pub offset: u32,
}

/// One colour attachment of a graphics pipeline: its format and blend.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ColorTarget {
    pub format: Format,
    pub blend: Blend,
}

impl ColorTarget {
    /// The RGBA32F render target (`Image::render_target`).
    pub const fn rgba32f(blend: Blend) -> Self {
        ColorTarget { format: TARGET_FORMAT, blend }
    }
}

pub struct GraphicsPipelineDesc<'a> {
    pub name: &'a str,
    pub vertex: &'a ShaderModule,
    /// Optional geometry stage (needs the geometryShader feature).
    pub geometry: Option<&'a ShaderModule>,
    pub fragment: &'a ShaderModule,
    /// Bytes per vertex record; 0 for shaders that fetch nothing.
    pub vertex_stride: u32,
    pub attributes: &'a [VertexAttribute],
    pub topology: Topology,
    pub primitive_restart: bool,
    pub cull: Cull,
    pub front_face: Winding,
    /// Colour attachments at locations 0, 1, ...: usually
    /// `&[ColorTarget::rgba32f(blend)]`.
    pub targets: &'a [ColorTarget],
    /// Depth test (less) and write against a `DEPTH_FORMAT` attachment.
    pub depth_test: bool,
    /// No clipping at the near and far planes (the device's `depthClamp`).
    pub depth_clamp: bool,
    pub push_constant_bytes: u32,
    /// Set layouts for sets 0, 1, ... (e.g. `&[set.layout]`).
    pub descriptor_layouts: &'a [vk::DescriptorSetLayout],
}

pub struct ComputePipelineDesc<'a> {
    pub name: &'a str,
    pub shader: &'a ShaderModule,
    pub push_constant_bytes: u32,
    /// Set layouts for sets 0, 1, ...
    pub descriptor_layouts: &'a [vk::DescriptorSetLayout],
}

pub struct Pipeline {
    pub raw: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub push_stages: Stages,
    pub bind_point: vk::PipelineBindPoint,
    /// Number of descriptor sets the layout expects.
    pub set_count: u32,
    pub name: String,
    /// Set layouts this pipeline owns (made by the pipeline cache); dropped
    /// after the pipeline layout.
    owned_layouts: Vec<DescriptorSetLayout>,
    ctx: Arc<Context>,
}

fn check_stage(name: &str, module: &ShaderModule, want: ShaderStage) -> VkResult<()> {
    if module.stage == want {
        Ok(())
    } else {
        Err(VkError::Invalid(format!("pipeline '{name}': a {:?} module given as its {want:?} shader", module.stage)))
    }
}

/// The pipeline layout shared by both kinds, after checking the limits.
fn create_layout(
    ctx: &Context,
    name: &str,
    push_stages: Stages,
    push_constant_bytes: u32,
    set_layouts: &[vk::DescriptorSetLayout],
) -> VkResult<vk::PipelineLayout> {
    let info = &ctx.info;
    if !push_constant_bytes.is_multiple_of(4) || push_constant_bytes > info.max_push_constants_size {
        return Err(VkError::Invalid(format!(
            "pipeline '{name}': {push_constant_bytes} bytes of push constants (a multiple of 4, at most {})",
            info.max_push_constants_size
        )));
    }
    if set_layouts.len() > info.max_bound_descriptor_sets as usize {
        return Err(VkError::Unsupported {
            device: info.name.clone(),
            what: format!("{} descriptor sets in pipeline '{name}' (maxBoundDescriptorSets is {})", set_layouts.len(), info.max_bound_descriptor_sets),
        });
    }
    let ranges = [vk::PushConstantRange { stage_flags: push_stages.to_vk(), offset: 0, size: push_constant_bytes }];
    let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(set_layouts);
    if push_constant_bytes > 0 {
        layout_info = layout_info.push_constant_ranges(&ranges);
    }
    // SAFETY: the create info and everything it points to live for the
    // call; the device outlives the handle (the owner holds the Context in
    // an Arc) and the handle is destroyed once, by its owner's Drop or the
    // error path below.
    unsafe { ctx.device.create_pipeline_layout(&layout_info, None) }.check("vkCreatePipelineLayout")
}

/// A graphics description's stages are the kinds they are given as, the
/// device has what it asks for (geometry shaders, its colour targets).
fn check_graphics(ctx: &Context, desc: &GraphicsPipelineDesc) -> VkResult<()> {
    check_stage(desc.name, desc.vertex, ShaderStage::Vertex)?;
    check_stage(desc.name, desc.fragment, ShaderStage::Fragment)?;
    if let Some(g) = desc.geometry {
        check_stage(desc.name, g, ShaderStage::Geometry)?;
        if !ctx.info.features.geometry_shader {
            return Err(VkError::Unsupported {
                device: ctx.info.name.clone(),
                what: format!("geometry shaders (pipeline '{}')", desc.name),
            });
        }
    }
    if desc.targets.is_empty() || desc.targets.len() > ctx.info.max_color_attachments as usize {
        return Err(VkError::Invalid(format!(
            "pipeline '{}': {} colour targets (1 to {})",
            desc.name,
            desc.targets.len(),
            ctx.info.max_color_attachments
        )));
    }
    Ok(())
}

/// The shader stages of a graphics description, in pipeline order.
fn graphics_stages(desc: &GraphicsPipelineDesc) -> Vec<vk::PipelineShaderStageCreateInfo<'static>> {
    let stage = |flag, module: &ShaderModule| vk::PipelineShaderStageCreateInfo::default().stage(flag).module(module.raw).name(c"main");
    let mut stages = vec![stage(vk::ShaderStageFlags::VERTEX, desc.vertex)];
    if let Some(g) = desc.geometry {
        stages.push(stage(vk::ShaderStageFlags::GEOMETRY, g));
    }
    stages.push(stage(vk::ShaderStageFlags::FRAGMENT, desc.fragment));
    stages
}

/// The vertex input of a graphics description: binding 0 with its
/// attributes, none for shaders that fetch nothing (stride 0). Held here so
/// that the create info may point into it.
struct VertexInput {
    bindings: [vk::VertexInputBindingDescription; 1],
    attributes: Vec<vk::VertexInputAttributeDescription>,
    used: bool,
}

impl VertexInput {
    fn of(desc: &GraphicsPipelineDesc) -> VertexInput {
        let bindings = [vk::VertexInputBindingDescription { binding: 0, stride: desc.vertex_stride, input_rate: vk::VertexInputRate::VERTEX }];
        let attributes = desc
            .attributes
            .iter()
            .map(|a| vk::VertexInputAttributeDescription { location: a.location, binding: 0, format: a.format.to_vk(), offset: a.offset })
            .collect();
        VertexInput { bindings, attributes, used: desc.vertex_stride > 0 }
    }

    fn info(&self) -> vk::PipelineVertexInputStateCreateInfo<'_> {
        let info = vk::PipelineVertexInputStateCreateInfo::default();
        if self.used {
            info.vertex_binding_descriptions(&self.bindings).vertex_attribute_descriptions(&self.attributes)
        } else {
            info
        }
    }
}

/// The graphics pipeline of `desc` with `layout`: its fixed-function state
/// (viewport and scissor dynamic), dynamic rendering into its targets.
fn create_graphics_pipeline(ctx: &Context, desc: &GraphicsPipelineDesc, layout: vk::PipelineLayout, cache: vk::PipelineCache) -> VkResult<vk::Pipeline> {
    let stages = graphics_stages(desc);
    let vertex = VertexInput::of(desc);
    let vertex_input = vertex.info();
    let input_assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
        .topology(desc.topology.to_vk())
        .primitive_restart_enable(desc.primitive_restart);
    let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
    let raster = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(desc.cull.to_vk())
        .front_face(desc.front_face.to_vk())
        .depth_clamp_enable(desc.depth_clamp)
        .line_width(1.0);
    let multisample = vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(vk::SampleCountFlags::TYPE_1);
    let attachments: Vec<_> = desc.targets.iter().map(|t| t.blend.state()).collect();
    let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&attachments);
    let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
    let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
    let formats: Vec<vk::Format> = desc.targets.iter().map(|t| t.format.to_vk()).collect();
    let mut rendering = vk::PipelineRenderingCreateInfo::default().color_attachment_formats(&formats);
    let mut depth = vk::PipelineDepthStencilStateCreateInfo::default();
    if desc.depth_test {
        rendering = rendering.depth_attachment_format(DEPTH_FORMAT.to_vk());
        depth = depth.depth_test_enable(true).depth_write_enable(true).depth_compare_op(vk::CompareOp::LESS);
    }
    let info = vk::GraphicsPipelineCreateInfo::default()
        .stages(&stages)
        .vertex_input_state(&vertex_input)
        .input_assembly_state(&input_assembly)
        .viewport_state(&viewport)
        .rasterization_state(&raster)
        .multisample_state(&multisample)
        .depth_stencil_state(&depth)
        .color_blend_state(&blend)
        .dynamic_state(&dynamic)
        .layout(layout)
        .push_next(&mut rendering);
    // SAFETY: the create info and everything it points to live for the
    // call; the device outlives the handle (the owner holds the Context in
    // an Arc) and the handle is destroyed once, by its owner's Drop (the
    // caller's `Pipeline` holds it and the layout).
    match unsafe { ctx.device.create_graphics_pipelines(cache, &[info], None) } {
        Ok(p) => Ok(p[0]),
        Err((_, result)) => Err(VkError::Call { what: "vkCreateGraphicsPipelines", result }),
    }
}

impl Pipeline {
    pub fn graphics(ctx: &Arc<Context>, desc: &GraphicsPipelineDesc) -> VkResult<Pipeline> {
        Self::graphics_in(ctx, desc, vk::PipelineCache::null(), Vec::new())
    }

    pub fn compute(ctx: &Arc<Context>, desc: &ComputePipelineDesc) -> VkResult<Pipeline> {
        Self::compute_in(ctx, desc, vk::PipelineCache::null(), Vec::new())
    }

    /// `graphics` with a VkPipelineCache and set layouts to own.
    pub(crate) fn graphics_in(
        ctx: &Arc<Context>,
        desc: &GraphicsPipelineDesc,
        cache: vk::PipelineCache,
        owned_layouts: Vec<DescriptorSetLayout>,
    ) -> VkResult<Pipeline> {
        check_graphics(ctx, desc)?;
        let mut push_stages = Stages::VERTEX | Stages::FRAGMENT;
        if desc.geometry.is_some() {
            push_stages |= Stages::GEOMETRY;
        }
        let layout = create_layout(ctx, desc.name, push_stages, desc.push_constant_bytes, desc.descriptor_layouts)?;
        // From here the pipeline value owns `layout`: early returns drop it.
        let mut pipeline = Pipeline {
            raw: vk::Pipeline::null(),
            layout,
            push_stages,
            bind_point: vk::PipelineBindPoint::GRAPHICS,
            set_count: desc.descriptor_layouts.len() as u32,
            name: desc.name.to_string(),
            owned_layouts,
            ctx: ctx.clone(),
        };
        pipeline.raw = create_graphics_pipeline(ctx, desc, layout, cache)?;
        ctx.set_name(pipeline.raw, desc.name);
        Ok(pipeline)
    }

    /// `compute` with a VkPipelineCache and set layouts to own.
    pub(crate) fn compute_in(
        ctx: &Arc<Context>,
        desc: &ComputePipelineDesc,
        cache: vk::PipelineCache,
        owned_layouts: Vec<DescriptorSetLayout>,
    ) -> VkResult<Pipeline> {
        check_stage(desc.name, desc.shader, ShaderStage::Compute)?;
        let push_stages = Stages::COMPUTE;
        let layout = create_layout(ctx, desc.name, push_stages, desc.push_constant_bytes, desc.descriptor_layouts)?;
        let mut pipeline = Pipeline {
            raw: vk::Pipeline::null(),
            layout,
            push_stages,
            bind_point: vk::PipelineBindPoint::COMPUTE,
            set_count: desc.descriptor_layouts.len() as u32,
            name: desc.name.to_string(),
            owned_layouts,
            ctx: ctx.clone(),
        };
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(desc.shader.raw)
            .name(c"main");
        // DISPATCH_BASE: any compute pass may be dispatched over part of
        // its grid (CommandRecorder::dispatch_base).
        let info = vk::ComputePipelineCreateInfo::default().flags(vk::PipelineCreateFlags::DISPATCH_BASE).stage(stage).layout(layout);
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        pipeline.raw = match unsafe { ctx.device.create_compute_pipelines(cache, &[info], None) } {
            Ok(p) => p[0],
            Err((_, result)) => return Err(VkError::Call { what: "vkCreateComputePipelines", result }),
        };
        ctx.set_name(pipeline.raw, desc.name);
        Ok(pipeline)
    }

    /// The descriptor-set layouts this pipeline owns (cache-made pipelines).
    pub fn owned_set_layouts(&self) -> &[DescriptorSetLayout] {
        &self.owned_layouts
    }
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe {
            if self.raw != vk::Pipeline::null() {
                self.ctx.device.destroy_pipeline(self.raw, None);
            }
            self.ctx.device.destroy_pipeline_layout(self.layout, None);
        }
        // `owned_layouts` drop after this, once the pipeline layout is gone.
    }
}
