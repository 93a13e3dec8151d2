//! Graphics pipelines for dynamic rendering into the RGBA32F target, and the
//! storage-buffer descriptor sets they read. A pipeline is described by a
//! plain `GraphicsPipelineDesc`; the algorithms never touch raw create-infos.

use std::sync::Arc;

use ash::vk;

use super::buffer::Buffer;
use super::error::{Check, VkResult};
use super::image::TARGET_FORMAT;
use super::shader::ShaderModule;
use super::Context;

/// How fragments combine with the target.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Blend {
    /// Premultiplied "over", drawing back to front: dst = src + (1 - src.a) dst.
    PremultipliedOver,
    /// Overwrite.
    None,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct VertexAttribute {
    pub location: u32,
    pub format: vk::Format,
    pub offset: u32,
}

pub struct GraphicsPipelineDesc<'a> {
    pub name: &'a str,
    pub vertex: &'a ShaderModule,
    pub fragment: &'a ShaderModule,
    /// Bytes per vertex record; 0 for shaders that fetch nothing.
    pub vertex_stride: u32,
    pub attributes: &'a [VertexAttribute],
    pub topology: vk::PrimitiveTopology,
    pub primitive_restart: bool,
    pub cull: vk::CullModeFlags,
    pub front_face: vk::FrontFace,
    pub blend: Blend,
    pub push_constant_bytes: u32,
    pub descriptor_layout: Option<vk::DescriptorSetLayout>,
}

pub struct Pipeline {
    pub raw: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub push_stages: vk::ShaderStageFlags,
    ctx: Arc<Context>,
}

impl Pipeline {
    pub fn graphics(ctx: &Arc<Context>, desc: &GraphicsPipelineDesc) -> VkResult<Pipeline> {
        let d = &ctx.device;
        let push_stages = vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT;
        let ranges = [vk::PushConstantRange { stage_flags: push_stages, offset: 0, size: desc.push_constant_bytes }];
        let set_layouts: Vec<vk::DescriptorSetLayout> = desc.descriptor_layout.into_iter().collect();
        let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        if desc.push_constant_bytes > 0 {
            layout_info = layout_info.push_constant_ranges(&ranges);
        }
        let layout = unsafe { d.create_pipeline_layout(&layout_info, None) }.check("vkCreatePipelineLayout")?;

        let stages = [
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::VERTEX)
                .module(desc.vertex.raw)
                .name(c"main"),
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(desc.fragment.raw)
                .name(c"main"),
        ];
        let bindings = [vk::VertexInputBindingDescription {
            binding: 0,
            stride: desc.vertex_stride,
            input_rate: vk::VertexInputRate::VERTEX,
        }];
        let attributes: Vec<vk::VertexInputAttributeDescription> = desc
            .attributes
            .iter()
            .map(|a| vk::VertexInputAttributeDescription { location: a.location, binding: 0, format: a.format, offset: a.offset })
            .collect();
        let mut vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
        if desc.vertex_stride > 0 {
            vertex_input = vertex_input.vertex_binding_descriptions(&bindings).vertex_attribute_descriptions(&attributes);
        }
        let input_assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
            .topology(desc.topology)
            .primitive_restart_enable(desc.primitive_restart);
        let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(desc.cull)
            .front_face(desc.front_face)
            .line_width(1.0);
        let multisample =
            vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(vk::SampleCountFlags::TYPE_1);
        let attachment = match desc.blend {
            Blend::PremultipliedOver => vk::PipelineColorBlendAttachmentState::default()
                .blend_enable(true)
                .src_color_blend_factor(vk::BlendFactor::ONE)
                .dst_color_blend_factor(vk::BlendFactor::ONE_MINUS_SRC_ALPHA)
                .color_blend_op(vk::BlendOp::ADD)
                .src_alpha_blend_factor(vk::BlendFactor::ONE)
                .dst_alpha_blend_factor(vk::BlendFactor::ONE_MINUS_SRC_ALPHA)
                .alpha_blend_op(vk::BlendOp::ADD)
                .color_write_mask(vk::ColorComponentFlags::RGBA),
            Blend::None => vk::PipelineColorBlendAttachmentState::default().color_write_mask(vk::ColorComponentFlags::RGBA),
        };
        let attachments = [attachment];
        let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&attachments);
        let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
        let formats = [TARGET_FORMAT];
        let mut rendering = vk::PipelineRenderingCreateInfo::default().color_attachment_formats(&formats);
        let depth = vk::PipelineDepthStencilStateCreateInfo::default();
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
        let raw = match unsafe { d.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) } {
            Ok(p) => p[0],
            Err((_, result)) => {
                unsafe { d.destroy_pipeline_layout(layout, None) };
                return Err(super::VkError::Call { what: "vkCreateGraphicsPipelines", result });
            }
        };
        ctx.set_name(raw, desc.name);
        Ok(Pipeline { raw, layout, push_stages, ctx: ctx.clone() })
    }
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        unsafe {
            self.ctx.device.destroy_pipeline(self.raw, None);
            self.ctx.device.destroy_pipeline_layout(self.layout, None);
        }
    }
}

/// One descriptor set of read-only storage buffers at bindings 0..n.
pub struct StorageBufferSet {
    pub layout: vk::DescriptorSetLayout,
    pub set: vk::DescriptorSet,
    pool: vk::DescriptorPool,
    ctx: Arc<Context>,
}

impl StorageBufferSet {
    pub fn new(ctx: &Arc<Context>, name: &str, buffers: &[&Buffer], stages: vk::ShaderStageFlags) -> VkResult<Self> {
        let d = &ctx.device;
        let bindings: Vec<_> = (0..buffers.len() as u32)
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .descriptor_count(1)
                    .stage_flags(stages)
            })
            .collect();
        let layout = unsafe { d.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None) }
            .check("vkCreateDescriptorSetLayout")?;
        let sizes = [vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: buffers.len().max(1) as u32 }];
        let pool = match unsafe { d.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes), None) } {
            Ok(p) => p,
            Err(result) => {
                unsafe { d.destroy_descriptor_set_layout(layout, None) };
                return Err(super::VkError::Call { what: "vkCreateDescriptorPool", result });
            }
        };
        let me = |set| StorageBufferSet { layout, set, pool, ctx: ctx.clone() };
        let layouts = [layout];
        let set = match unsafe { d.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts)) } {
            Ok(s) => s[0],
            Err(result) => {
                drop(me(vk::DescriptorSet::null()));
                return Err(super::VkError::Call { what: "vkAllocateDescriptorSets", result });
            }
        };
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> =
            buffers.iter().map(|b| [vk::DescriptorBufferInfo { buffer: b.raw, offset: 0, range: vk::WHOLE_SIZE }]).collect();
        let writes: Vec<_> = infos
            .iter()
            .enumerate()
            .map(|(i, info)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(i as u32)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .buffer_info(info)
            })
            .collect();
        unsafe { d.update_descriptor_sets(&writes, &[]) };
        ctx.set_name(set, name);
        Ok(me(set))
    }
}

impl Drop for StorageBufferSet {
    fn drop(&mut self) {
        unsafe {
            self.ctx.device.destroy_descriptor_pool(self.pool, None);
            self.ctx.device.destroy_descriptor_set_layout(self.layout, None);
        }
    }
}
