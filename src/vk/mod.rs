//! The Vulkan layer: every `unsafe` ash call of volbench lives under this
//! module. Code above it passes plain descriptions (`BufferDesc`,
//! `TextureDesc`, `DescriptorSetDesc`, `GraphicsPipelineDesc`,
//! `ComputePipelineDesc`, `PipelineKey`) and gets owning wrappers whose `Drop`
//! frees memory and destroys handles. Errors are `VkError`, naming the
//! failing call or the rejected object.
//!
//! What is here: device and features (`context`), buffers and texel buffers
//! (`buffer`), images, samplers, texture upload and readback (`image`),
//! the formats it knows (`format`), its own words for stages, buffer
//! uses, topology, culling and winding (`types`: nothing above `vk` names ash), host–image copies that
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
pub mod types;
pub mod upload;
pub mod valgrind;

pub use buffer::{Buffer, BufferDesc, MemoryKind, TexelBuffer};
pub use commands::{fold_groups, upload_static, upload_static_streamed, upload_static_texels, STAGING_CHUNK_BYTES, STAGING_CHUNK_VAR, ColorAttachment, CommandRecorder, SubmitTiming};
pub use context::{
    fence_timeout_from_env, list_devices, parse_env_flag, parse_fence_timeout, validation_requested, Context, ContextDesc,
    DeviceFeatures, DeviceInfo, DEFAULT_FENCE_TIMEOUT, FENCE_TIMEOUT_VAR, VALIDATION_VAR,
};
pub use descriptors::{
    DescriptorBinding, DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc, DescriptorSetLayout,
    StorageBufferSet, TargetImageSet,
};
pub use error::{VkError, VkResult};
pub use format::{Format, TARGET_FORMAT};
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
pub use types::{BufferUsage, Cull, Stages, TimestampAt, Topology, Winding};
pub use upload::{UploadClass, UploadCounter};

#[cfg(test)]
mod tests {
    use std::path::Path;

    /// Where `ash` is named in `text`: `ash::` not inside a longer word
    /// (`hash::` is fine), or a `use ash` / `extern crate ash`.
    fn names_ash(text: &str) -> Option<usize> {
        let word = |c: char| c.is_alphanumeric() || c == '_';
        text.lines().position(|line| {
            let t = line.trim_start();
            if t.starts_with("//") {
                return false;
            }
            t.starts_with("use ash") || t.contains("extern crate ash") || line.match_indices("ash::").any(|(i, _)| !line[..i].ends_with(word))
        })
    }

    fn scan(dir: &Path, skip: &Path, found: &mut Vec<String>) {
        let Ok(entries) = std::fs::read_dir(dir) else { return };
        for e in entries.flatten() {
            let p = e.path();
            if p == skip {
                continue;
            }
            if p.is_dir() {
                scan(&p, skip, found);
            } else if p.extension().is_some_and(|x| x == "rs") {
                let text = std::fs::read_to_string(&p).unwrap_or_default();
                if let Some(line) = names_ash(&text) {
                    found.push(format!("{}:{}", p.display(), line + 1));
                }
            }
        }
    }

    /// The algorithms, the harness and the tests speak this layer's own
    /// types (`types`, `format`); only `src/vk` names ash.
    #[test]
    fn nothing_outside_the_vk_layer_names_ash() {
        assert_eq!(names_ash("use std::hash::Hash;\nlet x = 1;"), None);
        assert_eq!(names_ash("fn f() {}\nuse ash::vk as raw;"), Some(1));
        assert_eq!(names_ash("let s = ash::vk::Format::R8_UNORM;"), Some(0));
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut found = Vec::new();
        for dir in ["src", "tests", "benches", "fuzz"] {
            scan(&root.join(dir), &root.join("src/vk"), &mut found);
        }
        assert!(found.is_empty(), "ash named outside src/vk: {found:?}");
    }
}
