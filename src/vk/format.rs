//! The formats the layer fixes (render target, depth) and the texel sizes
//! of the formats it handles: the lowest piece of `vk`, read by buffers,
//! images, pipelines and commands alike.

use ash::vk;

/// The offscreen render target's format (RGBA32F).
pub const TARGET_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

/// The depth format of `Image::depth_target` (required by Vulkan for
/// depth attachments on every device).
pub const DEPTH_FORMAT: vk::Format = vk::Format::D32_SFLOAT;

/// Bytes per texel of the formats images here may have; `None` for formats
/// this layer does not handle (creating such an image is an error).
pub fn texel_bytes(format: vk::Format) -> Option<u64> {
    Some(match format {
        vk::Format::R8_UNORM | vk::Format::R8_SNORM | vk::Format::R8_UINT | vk::Format::R8_SINT => 1,
        vk::Format::R16_UNORM
        | vk::Format::R16_SNORM
        | vk::Format::R16_UINT
        | vk::Format::R16_SINT
        | vk::Format::R16_SFLOAT => 2,
        vk::Format::R32_SFLOAT | vk::Format::R32_UINT | vk::Format::R32_SINT | vk::Format::R8G8B8A8_UNORM | vk::Format::D32_SFLOAT => 4,
        vk::Format::R32G32_SFLOAT | vk::Format::R32G32_UINT | vk::Format::R16G16B16A16_SFLOAT => 8,
        vk::Format::R32G32B32A32_SFLOAT | vk::Format::R32G32B32A32_UINT => 16,
        _ => return None,
    })
}
