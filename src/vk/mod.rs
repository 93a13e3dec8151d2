//! The Vulkan layer: every `unsafe` ash call of volbench lives under this
//! module. Code above it passes plain descriptions (`BufferDesc`,
//! `TextureDesc`, `DescriptorSetDesc`, `GraphicsPipelineDesc`,
//! `ComputePipelineDesc`, `PipelineKey`) and gets owning wrappers whose `Drop`
//! frees memory and destroys handles. Errors are `VkError`, naming the
//! failing call or the rejected object.
//!
//! What is here: device and features (`context`), buffers and texel buffers
//! (`buffer`), images, samplers, texture upload and readback (`image`),
//! the fixed formats and texel sizes (`format`), host–image copies that
//! record commands (`transfer`), descriptor sets (`descriptors`), graphics and compute pipelines
//! (`pipeline`) and their cache (`pipeline_cache`), command recording with
//! bounded fence waits, dispatch and barriers (`commands`), timestamps and
//! statistics (`query`), a method's own timestamps (`timestamps`), shader compilation (`shader`), the byte
//! counters (`upload`) and valgrind's client requests for counted runs (`valgrind`).

// The one module where `unsafe` is allowed (denied elsewhere by
// `[lints.rust]` in Cargo.toml); every block says why it is sound.
#![allow(unsafe_code)]

pub mod buffer;
pub mod commands;
pub mod context;
pub mod descriptors;
pub mod error;
pub mod format;
pub mod image;
pub mod meter;
pub mod pipeline;
pub mod pipeline_cache;
pub mod query;
pub mod shader;
pub mod timestamps;
pub mod transfer;
pub mod upload;
pub mod valgrind;

pub use ash::vk as raw;
pub use buffer::{Buffer, BufferDesc, MemoryKind, TexelBuffer};
pub use commands::{fold_groups, upload_static, upload_static_streamed, upload_static_texels, STAGING_CHUNK_BYTES, STAGING_CHUNK_VAR, ColorAttachment, CommandRecorder, SubmitTiming};
pub use context::{
    fence_timeout_from_env, list_devices, parse_env_flag, parse_fence_timeout, validation_requested, Context, ContextDesc,
    DeviceFeatures, DeviceInfo, DEFAULT_FENCE_TIMEOUT, FENCE_TIMEOUT_VAR, VALIDATION_VAR,
};
pub use descriptors::{
    DescriptorBinding, DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc, DescriptorSetLayout,
    StorageBufferSet,
};
pub use error::{VkError, VkResult};
pub use format::{texel_bytes, TARGET_FORMAT};
pub use meter::MeteredAlloc;
pub use image::{Filter, Image, ImageDim, ImageState, ImageUse, Sampler, TextureDesc};
pub use transfer::{upload_texture, upload_texture_with, UPLOAD_SLAB_BYTES};
pub use pipeline::{Blend, ColorTarget, ComputePipelineDesc, GraphicsPipelineDesc, Pipeline, VertexAttribute};
pub use pipeline_cache::{
    fnv1a64, ComputePipelineKey, GraphicsPipelineKey, GraphicsState, PipelineCache, PipelineKey, ShaderKey,
};
pub use query::{FrameQueries, PipelineStats};
pub use shader::{compile_glsl, ShaderModule, ShaderStage};
pub use timestamps::TimestampPool;
pub use upload::{UploadClass, UploadCounter};
