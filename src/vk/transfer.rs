//! Copies between the host and images, which record and submit commands:
//! texture upload through a staging buffer, readback of a whole image.
//! (Apart from `image` so that images do not depend on command recording.)

use std::sync::Arc;

use ash::vk;

use super::buffer::{Buffer, BufferDesc};
use super::commands::CommandRecorder;
use super::error::{VkError, VkResult};
use super::format::TARGET_FORMAT;
use super::image::{color_layers, Image, ImageDim, ImageUse, TextureDesc};
use super::upload::UploadCounter;
use super::Context;

impl Image {
    /// Copy the whole image to the host: texels x fastest, then y (row 0 at
    /// the top for a render target), then z, tightly packed.
    pub fn read_bytes(&self, ctx: &Arc<Context>) -> VkResult<Vec<u8>> {
        if !self.usage.contains(vk::ImageUsageFlags::TRANSFER_SRC) {
            return Err(VkError::Invalid(format!("image '{}' cannot be read back (no TRANSFER_SRC usage)", self.name())));
        }
        let buf = Buffer::new(ctx, BufferDesc::readback(&format!("{} readback", self.name()), self.byte_size()))?;
        let rec = CommandRecorder::new(ctx, &format!("{} readback", self.name()))?;
        let cmd = rec.begin()?;
        self.barrier(cmd, ImageUse::TransferSrc, true);
        let region = [vk::BufferImageCopy::default()
            .image_subresource(color_layers())
            .image_extent(vk::Extent3D { width: self.width, height: self.height, depth: self.depth })];
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe {
            ctx.device.cmd_copy_image_to_buffer(cmd, self.raw, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, buf.raw, &region);
        }
        rec.transfer_to_host();
        rec.submit_and_wait()?;
        Ok(buf.read()?.to_vec())
    }

    /// The image (RGBA32F) as RGBA f32, row 0 at the top; works after a
    /// render, a compute write or an upload (the layout is tracked).
    pub fn read_rgba32f(&self, ctx: &Arc<Context>) -> VkResult<Vec<[f32; 4]>> {
        if self.format != TARGET_FORMAT {
            return Err(VkError::Invalid(format!("image '{}' is {:?}, not RGBA32F", self.name(), self.format)));
        }
        let data = self.read_bytes(ctx)?;
        let f = |b: &[u8]| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]);
        Ok(data.chunks_exact(16).map(|c| [f(&c[0..4]), f(&c[4..8]), f(&c[8..12]), f(&c[12..16])]).collect())
    }
}

/// Create a sampled image and fill it with `data` through a staging buffer;
/// the bytes are counted as static at the copy. The image is left ready to
/// sample (`ImageUse::Sampled`), or to load from (`ImageUse::ShaderLoad`)
/// for `desc.loads`, by any later submission.
pub fn upload_texture(ctx: &Arc<Context>, desc: &TextureDesc, data: &[u8], counter: &mut UploadCounter) -> VkResult<Image> {
    let expected = texture_bytes(desc)?;
    if data.len() as u64 != expected {
        return Err(VkError::Invalid(format!(
            "image '{}': {} bytes given, {}x{}x{} texels of {:?} need {expected}",
            desc.name,
            data.len(),
            desc.width,
            desc.height,
            desc.depth,
            desc.format
        )));
    }
    upload_texture_with(ctx, desc, counter, &mut |offset, dst| dst.copy_from_slice(&data[offset..offset + dst.len()]))
}

/// Staging room a texture upload takes (at least one layer): a texture
/// goes up in slabs of whole layers, so that uploading a volume costs the
/// image and this much, never a second copy of the volume.
pub const UPLOAD_SLAB_BYTES: u64 = 8 << 20;

/// Uploads a texture whose bytes `fill(offset, dst)` writes into `dst`
/// (the texture's bytes from `offset` on, `dst.len()` of them), slab by
/// slab through one staging buffer of about [`UPLOAD_SLAB_BYTES`]: a
/// converted texture (floats from bytes) is never held whole on the host.
pub fn upload_texture_with(
    ctx: &Arc<Context>,
    desc: &TextureDesc,
    counter: &mut UploadCounter,
    fill: &mut dyn FnMut(usize, &mut [u8]),
) -> VkResult<Image> {
    let expected = texture_bytes(desc)?;
    let layers = match desc.dim {
        ImageDim::D3 => desc.depth,
        ImageDim::D2 => desc.height,
        ImageDim::D1 => 1,
    }
    .max(1);
    let layer_bytes = expected / u64::from(layers);
    let per_slab = (UPLOAD_SLAB_BYTES / layer_bytes.max(1)).clamp(1, u64::from(layers)) as u32;
    let image = Image::texture(ctx, desc)?;
    let mut staging = Buffer::new(
        ctx,
        BufferDesc::upload(&format!("{} (staging)", desc.name), u64::from(per_slab) * layer_bytes, super::types::BufferUsage::TRANSFER_SRC),
    )?;
    // Last slab first: a caller whose `fill` gives back its source's tail
    // as it goes (a volume's samples, `Samples::truncate`) frees each slab
    // as the image gets it, so source and image together stay one copy.
    let mut end = layers;
    while end > 0 {
        let first = end - ((end - 1) % per_slab + 1);
        let count = end - first;
        let len = (u64::from(count) * layer_bytes) as usize;
        fill((u64::from(first) * layer_bytes) as usize, &mut staging.mapped_for_write()?[..len]);
        let rec = CommandRecorder::new(ctx, &format!("{} upload", desc.name))?;
        rec.begin()?;
        rec.copy_layers_to_image(&staging, &image, first, count, counter)?;
        if first == 0 {
            rec.image_barrier(&image, if desc.loads { ImageUse::ShaderLoad } else { ImageUse::Sampled });
        }
        rec.submit_and_wait()?;
        end = first;
    }
    Ok(image)
}

fn texture_bytes(desc: &TextureDesc) -> VkResult<u64> {
    desc.byte_size().filter(|&n| n > 0).ok_or_else(|| {
        VkError::Invalid(format!(
            "image '{}': {}x{}x{} texels of {:?} overflow, are empty or the format is not supported",
            desc.name, desc.width, desc.height, desc.depth, desc.format
        ))
    })
}
