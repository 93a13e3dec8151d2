//! Descriptor sets described as data. A `DescriptorSetDesc` lists bindings
//! (kind and shader stages; binding numbers are the list positions
//! 0, 1, ...); it is `Hash + Eq`, so pipeline keys can contain it. A
//! `DescriptorSet` owns its layout and its own pool and destroys both on
//! `Drop`; the resources it points at are borrowed only while it is written,
//! so the caller keeps them alive as long as the set is used (the same rule
//! as for any Vulkan descriptor).
//!
//! Pipelines created from the same `DescriptorSetDesc` have identically
//! defined layouts, so a set made here binds to a pipeline whose layout was
//! made elsewhere (e.g. by the pipeline cache) from an equal description.
//!
//! Every resource is checked against its binding before anything is written
//! (kind, usage flags, range limits), so a mistake is an error naming the set
//! and the binding rather than a validation message or a device fault.

use std::ops::Deref;
use std::sync::Arc;

use ash::vk;

use super::buffer::{Buffer, TexelBuffer};
use super::error::{Check, VkError, VkResult};
use super::image::{Filter, Image, Sampler};
use super::types::{BufferUsage, Stages};
use super::{Context, DeviceInfo};

/// What a binding holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DescriptorKind {
    StorageBuffer,
    UniformBuffer,
    /// A sampled image with its sampler (`sampler1D/2D/3D` in GLSL).
    CombinedImageSampler,
    /// `image2D` etc., layout GENERAL.
    StorageImage,
    /// `samplerBuffer`.
    UniformTexelBuffer,
    /// `imageBuffer`.
    StorageTexelBuffer,
}

impl DescriptorKind {
    pub fn raw(self) -> vk::DescriptorType {
        match self {
            DescriptorKind::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
            DescriptorKind::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
            DescriptorKind::CombinedImageSampler => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
            DescriptorKind::StorageImage => vk::DescriptorType::STORAGE_IMAGE,
            DescriptorKind::UniformTexelBuffer => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
            DescriptorKind::StorageTexelBuffer => vk::DescriptorType::STORAGE_TEXEL_BUFFER,
        }
    }

    /// A stable small code for canonical serialisation (pipeline-key ids).
    pub(crate) fn code(self) -> u8 {
        match self {
            DescriptorKind::StorageBuffer => 0,
            DescriptorKind::UniformBuffer => 1,
            DescriptorKind::CombinedImageSampler => 2,
            DescriptorKind::StorageImage => 3,
            DescriptorKind::UniformTexelBuffer => 4,
            DescriptorKind::StorageTexelBuffer => 5,
        }
    }
}

/// One binding: its kind and the stages that see it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct DescriptorBinding {
    pub kind: DescriptorKind,
    pub stages: Stages,
}

/// The layout of one descriptor set: binding i is `bindings[i]`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash)]
pub struct DescriptorSetDesc {
    pub bindings: Vec<DescriptorBinding>,
}

impl DescriptorSetDesc {
    pub fn new(bindings: &[(DescriptorKind, Stages)]) -> Self {
        DescriptorSetDesc { bindings: bindings.iter().map(|&(kind, stages)| DescriptorBinding { kind, stages }).collect() }
    }

    /// `n` storage buffers seen by `stages` (what `StorageBufferSet` builds).
    pub fn storage_buffers(n: usize, stages: Stages) -> Self {
        DescriptorSetDesc { bindings: vec![DescriptorBinding { kind: DescriptorKind::StorageBuffer, stages }; n] }
    }

    /// Builder: append a binding.
    pub fn with(mut self, kind: DescriptorKind, stages: Stages) -> Self {
        self.bindings.push(DescriptorBinding { kind, stages });
        self
    }
}

/// The per-stage descriptor classes Vulkan limits: storage images (storage
/// texel buffers count as ones), sampled images (uniform texel buffers
/// too), storage buffers, uniform buffers.
const STAGE_CLASSES: [&str; 4] = ["storage images", "sampled images", "storage buffers", "uniform buffers"];

impl DescriptorKind {
    fn stage_class(self) -> usize {
        match self {
            DescriptorKind::StorageImage | DescriptorKind::StorageTexelBuffer => 0,
            DescriptorKind::CombinedImageSampler | DescriptorKind::UniformTexelBuffer => 1,
            DescriptorKind::StorageBuffer => 2,
            DescriptorKind::UniformBuffer => 3,
        }
    }
}

/// Descriptors of each class (`STAGE_CLASSES`) that `stage` sees over all
/// of a pipeline's sets.
fn stage_counts(sets: &[DescriptorSetDesc], stage: Stages) -> [u32; 4] {
    let mut n = [0u32; 4];
    for b in sets.iter().flat_map(|s| &s.bindings).filter(|b| b.stages.intersects(stage)) {
        n[b.kind.stage_class()] += 1;
    }
    n
}

/// Refuses a pipeline whose sets give one stage more descriptors of a class
/// than the device's `maxPerStageDescriptor*` limit allows (a mesh split
/// over many texel buffers, `algo::chunks`, binds one per piece).
pub fn check_stage_limits(info: &DeviceInfo, pipeline: &str, sets: &[DescriptorSetDesc]) -> VkResult<()> {
    let limits = [
        info.max_per_stage_storage_images,
        info.max_per_stage_sampled_images,
        info.max_per_stage_storage_buffers,
        info.max_per_stage_uniform_buffers,
    ];
    for (stage_name, stage) in Stages::all().iter_names() {
        let counts = stage_counts(sets, stage);
        for (k, (&n, &max)) in counts.iter().zip(&limits).enumerate() {
            if n > max {
                return Err(VkError::Unsupported {
                    device: info.name.clone(),
                    what: format!("{n} {} in the {} stage of pipeline '{pipeline}' (the per-stage limit is {max})", STAGE_CLASSES[k], stage_name.to_lowercase()),
                });
            }
        }
    }
    Ok(())
}

/// A descriptor-set layout destroyed on drop (pipelines own the layouts
/// they were created with when the pipeline cache built them).
pub struct DescriptorSetLayout {
    pub raw: vk::DescriptorSetLayout,
    pub desc: DescriptorSetDesc,
    ctx: Arc<Context>,
}

impl DescriptorSetLayout {
    pub fn new(ctx: &Arc<Context>, desc: &DescriptorSetDesc) -> VkResult<Self> {
        let bindings: Vec<_> = desc
            .bindings
            .iter()
            .enumerate()
            .map(|(i, b)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(i as u32)
                    .descriptor_type(b.kind.raw())
                    .descriptor_count(1)
                    .stage_flags(b.stages.to_vk())
            })
            .collect();
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let raw = unsafe {
            ctx.device.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None)
        }
        .check("vkCreateDescriptorSetLayout")?;
        Ok(DescriptorSetLayout { raw, desc: desc.clone(), ctx: ctx.clone() })
    }
}

impl Drop for DescriptorSetLayout {
    fn drop(&mut self) {
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe { self.ctx.device.destroy_descriptor_set_layout(self.raw, None) };
    }
}

/// What one binding points at, in binding order.
#[derive(Clone, Copy)]
pub enum DescriptorResource<'a> {
    StorageBuffer(&'a Buffer),
    UniformBuffer(&'a Buffer),
    /// Sampled in layout SHADER_READ_ONLY_OPTIMAL (`ImageUse::Sampled`).
    CombinedImageSampler(&'a Image, &'a Sampler),
    /// Accessed in layout GENERAL (`ImageUse::ComputeStorage`, `ImageUse::ShaderLoad`).
    StorageImage(&'a Image),
    UniformTexelBuffer(&'a TexelBuffer),
    StorageTexelBuffer(&'a TexelBuffer),
}

impl DescriptorResource<'_> {
    fn kind(&self) -> DescriptorKind {
        match self {
            DescriptorResource::StorageBuffer(_) => DescriptorKind::StorageBuffer,
            DescriptorResource::UniformBuffer(_) => DescriptorKind::UniformBuffer,
            DescriptorResource::CombinedImageSampler(..) => DescriptorKind::CombinedImageSampler,
            DescriptorResource::StorageImage(_) => DescriptorKind::StorageImage,
            DescriptorResource::UniformTexelBuffer(_) => DescriptorKind::UniformTexelBuffer,
            DescriptorResource::StorageTexelBuffer(_) => DescriptorKind::StorageTexelBuffer,
        }
    }
}

/// One descriptor set with its own layout and pool.
pub struct DescriptorSet {
    pub raw: vk::DescriptorSet,
    pub layout: vk::DescriptorSetLayout,
    pub desc: DescriptorSetDesc,
    name: String,
    pool: vk::DescriptorPool,
    /// Destroyed (as a field) after `Drop` has destroyed the pool.
    _layout: DescriptorSetLayout,
    ctx: Arc<Context>,
}

impl DescriptorSet {
    /// Create the set described by `desc` and point binding i at
    /// `resources[i]`.
    pub fn new(
        ctx: &Arc<Context>,
        name: &str,
        desc: &DescriptorSetDesc,
        resources: &[DescriptorResource],
    ) -> VkResult<DescriptorSet> {
        check_resources(ctx, name, desc, resources)?;
        let d = &ctx.device;
        let layout = DescriptorSetLayout::new(ctx, desc)?;
        let mut sizes: Vec<vk::DescriptorPoolSize> = Vec::new();
        for b in &desc.bindings {
            match sizes.iter_mut().find(|s| s.ty == b.kind.raw()) {
                Some(s) => s.descriptor_count += 1,
                None => sizes.push(vk::DescriptorPoolSize { ty: b.kind.raw(), descriptor_count: 1 }),
            }
        }
        if sizes.is_empty() {
            // A pool needs at least one size; an empty set still allocates.
            sizes.push(vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: 1 });
        }
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let pool = unsafe { d.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes), None) }
            .check("vkCreateDescriptorPool")?;
        // The set now owns layout and pool: an early return destroys both.
        let layouts = [layout.raw];
        let mut set = DescriptorSet {
            raw: vk::DescriptorSet::null(),
            layout: layout.raw,
            desc: desc.clone(),
            name: name.to_string(),
            pool,
            _layout: layout,
            ctx: ctx.clone(),
        };
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        set.raw = unsafe { d.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts)) }
            .check("vkAllocateDescriptorSets")?[0];
        set.write(resources);
        ctx.set_name(set.raw, name);
        ctx.set_name(set.pool, name);
        ctx.set_name(set.layout, name);
        Ok(set)
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Point the set's bindings at other resources (same kinds). The set
    /// must not be in use by a pending submission.
    pub fn update(&mut self, resources: &[DescriptorResource]) -> VkResult<()> {
        check_resources(&self.ctx, &self.name, &self.desc, resources)?;
        self.write(resources);
        Ok(())
    }

    fn write(&self, resources: &[DescriptorResource]) {
        let mut buffer_infos: Vec<[vk::DescriptorBufferInfo; 1]> = Vec::new();
        let mut image_infos: Vec<[vk::DescriptorImageInfo; 1]> = Vec::new();
        let mut views: Vec<[vk::BufferView; 1]> = Vec::new();
        // Fill the info arrays first: writes keep pointers into them.
        for r in resources {
            match *r {
                DescriptorResource::StorageBuffer(b) | DescriptorResource::UniformBuffer(b) => {
                    buffer_infos.push([vk::DescriptorBufferInfo { buffer: b.raw, offset: 0, range: vk::WHOLE_SIZE }])
                }
                DescriptorResource::CombinedImageSampler(i, s) => image_infos.push([vk::DescriptorImageInfo {
                    sampler: s.raw,
                    image_view: i.view,
                    image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                }]),
                DescriptorResource::StorageImage(i) => image_infos.push([vk::DescriptorImageInfo {
                    sampler: vk::Sampler::null(),
                    image_view: i.view,
                    image_layout: vk::ImageLayout::GENERAL,
                }]),
                DescriptorResource::UniformTexelBuffer(t) | DescriptorResource::StorageTexelBuffer(t) => views.push([t.view]),
            }
        }
        let (mut bi, mut ii, mut vi) = (0, 0, 0);
        let writes: Vec<vk::WriteDescriptorSet> = resources
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let w = vk::WriteDescriptorSet::default().dst_set(self.raw).dst_binding(i as u32).descriptor_type(r.kind().raw());
                match r {
                    DescriptorResource::StorageBuffer(_) | DescriptorResource::UniformBuffer(_) => {
                        bi += 1;
                        w.buffer_info(&buffer_infos[bi - 1])
                    }
                    DescriptorResource::CombinedImageSampler(..) | DescriptorResource::StorageImage(_) => {
                        ii += 1;
                        w.image_info(&image_infos[ii - 1])
                    }
                    DescriptorResource::UniformTexelBuffer(_) | DescriptorResource::StorageTexelBuffer(_) => {
                        vi += 1;
                        w.texel_buffer_view(&views[vi - 1])
                    }
                }
            })
            .collect();
        // SAFETY: the resources' kinds and count match the set's layout
        // (`check_resources`, run by `new` and `update` before this); each
        // write points into the info arrays above, which live for the call.
        // The set is not in use by a pending submission: new, or `update`'s
        // documented precondition (callers update between waited-for frames).
        unsafe { self.ctx.device.update_descriptor_sets(&writes, &[]) };
    }
}

fn check_resources(ctx: &Context, name: &str, desc: &DescriptorSetDesc, resources: &[DescriptorResource]) -> VkResult<()> {
    if resources.len() != desc.bindings.len() {
        return Err(VkError::Invalid(format!(
            "descriptor set '{name}': {} binding(s) described, {} resource(s) given",
            desc.bindings.len(),
            resources.len()
        )));
    }
    let info = &ctx.info;
    for (i, (b, r)) in desc.bindings.iter().zip(resources).enumerate() {
        let bad = |what: String| Err(VkError::Invalid(format!("descriptor set '{name}' binding {i}: {what}")));
        if b.kind != r.kind() {
            return bad(format!("described as {:?}, given a {:?}", b.kind, r.kind()));
        }
        match *r {
            DescriptorResource::StorageBuffer(buf) | DescriptorResource::UniformBuffer(buf) => {
                let (usage, max) = if b.kind == DescriptorKind::StorageBuffer {
                    (BufferUsage::STORAGE, info.max_storage_buffer_range)
                } else {
                    (BufferUsage::UNIFORM, info.max_uniform_buffer_range)
                };
                if !buf.desc.usage.contains(usage) {
                    return bad(format!("buffer '{}' lacks {usage:?} usage", buf.desc.name));
                }
                if buf.size() > max as u64 {
                    return bad(format!("buffer '{}' has {} bytes, more than the device's range limit {max}", buf.desc.name, buf.size()));
                }
            }
            DescriptorResource::CombinedImageSampler(img, sampler) => {
                if !img.is_sampled() {
                    return bad(format!("image '{}' is not sampled", img.name()));
                }
                if sampler.filter == Filter::Linear
                    && !ctx.can_sample(img.format, Filter::Linear)
                {
                    return bad(format!(
                        "image '{}' ({:?}) cannot be filtered linearly on this device; use a nearest sampler",
                        img.name(),
                        img.format
                    ));
                }
            }
            DescriptorResource::StorageImage(img) => {
                if !img.is_storage() {
                    return bad(format!("image '{}' lacks STORAGE usage", img.name()));
                }
            }
            DescriptorResource::UniformTexelBuffer(t) | DescriptorResource::StorageTexelBuffer(t) => {
                let usage = if b.kind == DescriptorKind::UniformTexelBuffer {
                    BufferUsage::UNIFORM_TEXEL
                } else {
                    BufferUsage::STORAGE_TEXEL
                };
                if !t.buffer.desc.usage.contains(usage) {
                    return bad(format!("texel buffer '{}' lacks {usage:?} usage", t.buffer.desc.name));
                }
            }
        }
    }
    Ok(())
}

impl Drop for DescriptorSet {
    fn drop(&mut self) {
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe { self.ctx.device.destroy_descriptor_pool(self.pool, None) };
    }
}

/// A compute pass's storage-image target as a one-binding set: made for the
/// first target and made again only when the target is another image
/// (`Image::id`), so a pass that draws into the same image every frame
/// writes no descriptor per frame.
pub struct TargetImageSet {
    name: String,
    /// The binding, for the pipeline's layout.
    pub desc: DescriptorSetDesc,
    current: Option<(u64, DescriptorSet)>,
}

impl TargetImageSet {
    pub fn new(name: &str, stages: Stages) -> Self {
        TargetImageSet {
            name: name.to_string(),
            desc: DescriptorSetDesc::new(&[(DescriptorKind::StorageImage, stages)]),
            current: None,
        }
    }

    /// The set pointing at `target`. Replacing the set of an earlier target
    /// requires that no pending submission still uses it (owners wait for
    /// their recorders before recording again: the sync model of
    /// `context.rs`).
    pub fn for_target(&mut self, ctx: &Arc<Context>, target: &Image) -> VkResult<&DescriptorSet> {
        let id = target.id();
        if self.current.as_ref().is_none_or(|(t, _)| *t != id) {
            let set = DescriptorSet::new(ctx, &self.name, &self.desc, &[DescriptorResource::StorageImage(target)])?;
            self.current = Some((id, set));
        }
        self.current.as_ref().map(|(_, s)| s).ok_or_else(|| VkError::Invalid(format!("{}: no set for the target", self.name)))
    }
}

/// One descriptor set of read-only storage buffers at bindings 0..n: a thin
/// constructor over `DescriptorSet` (derefs to it, so `.layout` and
/// `bind_pipeline(.., Some(&set))` work as before).
pub struct StorageBufferSet(DescriptorSet);

impl StorageBufferSet {
    pub fn new(ctx: &Arc<Context>, name: &str, buffers: &[&Buffer], stages: Stages) -> VkResult<Self> {
        let desc = DescriptorSetDesc::storage_buffers(buffers.len(), stages);
        let resources: Vec<DescriptorResource> = buffers.iter().map(|b| DescriptorResource::StorageBuffer(b)).collect();
        DescriptorSet::new(ctx, name, &desc, &resources).map(StorageBufferSet)
    }
}

impl Deref for StorageBufferSet {
    type Target = DescriptorSet;
    fn deref(&self) -> &DescriptorSet {
        &self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_counts_add_every_set_a_stage_sees_by_class() {
        let c = Stages::COMPUTE;
        let f = Stages::FRAGMENT;
        let sets = [
            DescriptorSetDesc::new(&[(DescriptorKind::StorageTexelBuffer, c | f), (DescriptorKind::UniformTexelBuffer, c)]),
            DescriptorSetDesc::new(&[(DescriptorKind::StorageImage, c), (DescriptorKind::StorageBuffer, c), (DescriptorKind::UniformBuffer, f)]),
            DescriptorSetDesc::new(&[(DescriptorKind::CombinedImageSampler, f), (DescriptorKind::StorageTexelBuffer, c)]),
        ];
        assert_eq!(stage_counts(&sets, c), [3, 1, 1, 0]);
        assert_eq!(stage_counts(&sets, f), [1, 1, 0, 1]);
        assert_eq!(stage_counts(&sets, Stages::VERTEX), [0; 4]);
    }
}
