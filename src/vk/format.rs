//! The texel formats the layer knows (`Format`: the ones volbench uses,
//! no more) and the formats it fixes (render target, depth): the lowest
//! piece of `vk`, read by buffers, images, pipelines and commands alike.

use ash::vk;

/// The offscreen render target's format (RGBA32F).
pub const TARGET_FORMAT: Format = Format::Rgba32Float;

/// The depth format of `Image::depth_target` (required by Vulkan for
/// depth attachments on every device).
pub const DEPTH_FORMAT: Format = Format::Depth32Float;

/// The texel formats of images, texel buffers, vertex attributes and
/// render targets: the ones volbench uses, no more.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    R8Unorm,
    R8Uint,
    /// Two bytes a texel (raycast's brick map with `coarse`).
    Rg8Uint,
    R16Unorm,
    R16Snorm,
    R16Sint,
    /// Four channels of the single-channel formats above (a volume's
    /// sample with its neighbours: raycast's `reads=quads`).
    Rgba8Unorm,
    Rgba16Unorm,
    Rgba16Snorm,
    R32Float,
    R32Uint,
    Rg32Float,
    Rgb32Float,
    Rgba32Float,
    Rgba32Uint,
    /// Depth only (`Image::depth_target`).
    Depth32Float,
}

impl Format {
    pub(crate) fn to_vk(self) -> vk::Format {
        match self {
            Format::R8Unorm => vk::Format::R8_UNORM,
            Format::R8Uint => vk::Format::R8_UINT,
            Format::Rg8Uint => vk::Format::R8G8_UINT,
            Format::R16Unorm => vk::Format::R16_UNORM,
            Format::R16Snorm => vk::Format::R16_SNORM,
            Format::R16Sint => vk::Format::R16_SINT,
            Format::Rgba8Unorm => vk::Format::R8G8B8A8_UNORM,
            Format::Rgba16Unorm => vk::Format::R16G16B16A16_UNORM,
            Format::Rgba16Snorm => vk::Format::R16G16B16A16_SNORM,
            Format::R32Float => vk::Format::R32_SFLOAT,
            Format::R32Uint => vk::Format::R32_UINT,
            Format::Rg32Float => vk::Format::R32G32_SFLOAT,
            Format::Rgb32Float => vk::Format::R32G32B32_SFLOAT,
            Format::Rgba32Float => vk::Format::R32G32B32A32_SFLOAT,
            Format::Rgba32Uint => vk::Format::R32G32B32A32_UINT,
            Format::Depth32Float => vk::Format::D32_SFLOAT,
        }
    }

    /// The format's GLSL image format qualifier (`layout(r8) image3D`) and
    /// whether it is one of the extended storage formats (SPIR-V's
    /// StorageImageExtendedFormats, the device feature
    /// shaderStorageImageExtendedFormats); `None` for a depth format.
    pub fn glsl_image_format(self) -> Option<(&'static str, bool)> {
        Some(match self {
            Format::R8Unorm => ("r8", true),
            Format::R8Uint => ("r8ui", true),
            Format::Rg8Uint => ("rg8ui", true),
            Format::R16Unorm => ("r16", true),
            Format::R16Snorm => ("r16_snorm", true),
            Format::R16Sint => ("r16i", true),
            Format::Rgba8Unorm => ("rgba8", false),
            Format::Rgba16Unorm => ("rgba16", true),
            Format::Rgba16Snorm => ("rgba16_snorm", true),
            Format::R32Float => ("r32f", false),
            Format::R32Uint => ("r32ui", false),
            Format::Rg32Float => ("rg32f", true),
            Format::Rgb32Float | Format::Depth32Float => return None,
            Format::Rgba32Float => ("rgba32f", false),
            Format::Rgba32Uint => ("rgba32ui", false),
        })
    }

    /// Bytes per texel.
    pub fn texel_bytes(self) -> u64 {
        match self {
            Format::R8Unorm | Format::R8Uint => 1,
            Format::R16Unorm | Format::R16Snorm | Format::R16Sint | Format::Rg8Uint => 2,
            Format::R32Float | Format::R32Uint | Format::Depth32Float | Format::Rgba8Unorm => 4,
            Format::Rg32Float | Format::Rgba16Unorm | Format::Rgba16Snorm => 8,
            Format::Rgb32Float => 12,
            Format::Rgba32Float | Format::Rgba32Uint => 16,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Format;

    /// The storage image formats every device supports: SPIR-V's `Shader`
    /// capability's (the spec's Image Format table); every other
    /// qualifier needs StorageImageExtendedFormats.
    const BASE: [&str; 13] =
        ["rgba32f", "rgba16f", "r32f", "rgba8", "rgba8_snorm", "rgba32i", "rgba16i", "rgba8i", "r32i", "rgba32ui", "rgba16ui", "rgba8ui", "r32ui"];

    #[test]
    fn extended_storage_formats_are_spirvs() {
        use Format::*;
        let all = [
            R8Unorm, R8Uint, Rg8Uint, R16Unorm, R16Snorm, R16Sint, Rgba8Unorm, Rgba16Unorm, Rgba16Snorm, R32Float, R32Uint, Rg32Float,
            Rgb32Float, Rgba32Float, Rgba32Uint, Depth32Float,
        ];
        for f in all {
            if let Some((name, extended)) = f.glsl_image_format() {
                assert_eq!(extended, !BASE.contains(&name), "{f:?} ({name})");
            }
        }
    }
}
