//! The Vulkan layer: every `unsafe` ash call of volbench lives under this
//! module. Code above it passes plain descriptions (`BufferDesc`,
//! `GraphicsPipelineDesc`) and gets owning wrappers whose `Drop` frees memory
//! and destroys handles. Errors are `VkError`, naming the failing call.

pub mod buffer;
pub mod commands;
pub mod context;
pub mod error;
pub mod image;
pub mod pipeline;
pub mod query;
pub mod shader;
pub mod upload;

pub use ash::vk as raw;
pub use buffer::{Buffer, BufferDesc, MemoryKind};
pub use commands::{upload_static, CommandRecorder, SubmitTiming};
pub use context::{list_devices, validation_requested, Context, ContextDesc, DeviceInfo};
pub use error::{VkError, VkResult};
pub use image::{Image, TARGET_FORMAT};
pub use pipeline::{Blend, GraphicsPipelineDesc, Pipeline, StorageBufferSet, VertexAttribute};
pub use query::{FrameQueries, PipelineStats};
pub use shader::{compile_glsl, ShaderModule, ShaderStage};
pub use upload::{UploadClass, UploadCounter};
