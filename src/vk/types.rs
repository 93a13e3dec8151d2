//! The layer's own words for what the methods ask of Vulkan: shader stages,
//! buffer uses, primitive topology, culling and winding,
//! where a timestamp is taken (texel formats: `format`). Only the values volbench uses; each becomes
//! its ash value here (`to_vk`, crate-private), so nothing above `vk`
//! names ash. Barriers are the recorder's named dependencies
//! (`CommandRecorder::compute_to_graphics` and its siblings), not masks.

use ash::vk;
use bitflags::{bitflags, Flags};

/// The union of the Vulkan values paired with the flags `set` holds.
fn union_of<F: Flags + Copy, V: Copy + std::ops::BitOr<Output = V>>(set: F, empty: V, pairs: &[(F, V)]) -> V {
    pairs.iter().filter(|(ours, _)| set.contains(*ours)).fold(empty, |acc, &(_, theirs)| acc | theirs)
}

bitflags! {
    /// The shader stages a descriptor binding (or a barrier's shader side)
    /// reaches.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub struct Stages: u8 {
        const VERTEX = 1;
        const GEOMETRY = 1 << 1;
        const FRAGMENT = 1 << 2;
        const COMPUTE = 1 << 3;
    }
}

impl Stages {
    pub(crate) fn to_vk(self) -> vk::ShaderStageFlags {
        union_of(self, vk::ShaderStageFlags::empty(), &[
            (Stages::VERTEX, vk::ShaderStageFlags::VERTEX),
            (Stages::GEOMETRY, vk::ShaderStageFlags::GEOMETRY),
            (Stages::FRAGMENT, vk::ShaderStageFlags::FRAGMENT),
            (Stages::COMPUTE, vk::ShaderStageFlags::COMPUTE),
        ])
    }

    /// The pipeline stages these shaders run in (a barrier's shader side).
    pub(crate) fn pipeline_stages(self) -> vk::PipelineStageFlags2 {
        union_of(self, vk::PipelineStageFlags2::empty(), &[
            (Stages::VERTEX, vk::PipelineStageFlags2::VERTEX_SHADER),
            (Stages::GEOMETRY, vk::PipelineStageFlags2::GEOMETRY_SHADER),
            (Stages::FRAGMENT, vk::PipelineStageFlags2::FRAGMENT_SHADER),
            (Stages::COMPUTE, vk::PipelineStageFlags2::COMPUTE_SHADER),
        ])
    }
}

bitflags! {
    /// What a buffer is used for (its Vulkan usage flags).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub struct BufferUsage: u16 {
        /// Vertex input (`bind_vertex_buffer`).
        const VERTEX = 1;
        /// Index input (`bind_index_buffer_u32`).
        const INDEX = 1 << 1;
        /// A uniform buffer binding.
        const UNIFORM = 1 << 2;
        /// A storage buffer binding.
        const STORAGE = 1 << 3;
        /// A uniform texel buffer (`TexelBuffer`, read through a format).
        const UNIFORM_TEXEL = 1 << 4;
        /// A storage texel buffer.
        const STORAGE_TEXEL = 1 << 5;
        /// Indirect draw arguments.
        const INDIRECT = 1 << 6;
        /// The source of a copy (readback, staging).
        const TRANSFER_SRC = 1 << 7;
        /// The destination of a copy or fill.
        const TRANSFER_DST = 1 << 8;
    }
}

impl BufferUsage {
    pub(crate) fn to_vk(self) -> vk::BufferUsageFlags {
        union_of(self, vk::BufferUsageFlags::empty(), &[
            (BufferUsage::VERTEX, vk::BufferUsageFlags::VERTEX_BUFFER),
            (BufferUsage::INDEX, vk::BufferUsageFlags::INDEX_BUFFER),
            (BufferUsage::UNIFORM, vk::BufferUsageFlags::UNIFORM_BUFFER),
            (BufferUsage::STORAGE, vk::BufferUsageFlags::STORAGE_BUFFER),
            (BufferUsage::UNIFORM_TEXEL, vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER),
            (BufferUsage::STORAGE_TEXEL, vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER),
            (BufferUsage::INDIRECT, vk::BufferUsageFlags::INDIRECT_BUFFER),
            (BufferUsage::TRANSFER_SRC, vk::BufferUsageFlags::TRANSFER_SRC),
            (BufferUsage::TRANSFER_DST, vk::BufferUsageFlags::TRANSFER_DST),
        ])
    }
}

/// How vertices make primitives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Topology {
    PointList,
    TriangleList,
    TriangleStrip,
}

impl Topology {
    pub(crate) fn to_vk(self) -> vk::PrimitiveTopology {
        match self {
            Topology::PointList => vk::PrimitiveTopology::POINT_LIST,
            Topology::TriangleList => vk::PrimitiveTopology::TRIANGLE_LIST,
            Topology::TriangleStrip => vk::PrimitiveTopology::TRIANGLE_STRIP,
        }
    }
}

/// Which faces the rasteriser drops.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cull {
    None,
    Front,
    Back,
}

impl Cull {
    pub(crate) fn to_vk(self) -> vk::CullModeFlags {
        match self {
            Cull::None => vk::CullModeFlags::NONE,
            Cull::Front => vk::CullModeFlags::FRONT,
            Cull::Back => vk::CullModeFlags::BACK,
        }
    }
}

/// The winding (in framebuffer coordinates) of a front face.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Winding {
    Clockwise,
    CounterClockwise,
}

impl Winding {
    pub(crate) fn to_vk(self) -> vk::FrontFace {
        match self {
            Winding::Clockwise => vk::FrontFace::CLOCKWISE,
            Winding::CounterClockwise => vk::FrontFace::COUNTER_CLOCKWISE,
        }
    }
}

/// When a timestamp is written: at once (before the work recorded after
/// it starts), or once the work recorded before it finished its compute
/// or its graphics stages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimestampAt {
    Start,
    ComputeDone,
    GraphicsDone,
}

impl TimestampAt {
    pub(crate) fn to_vk(self) -> vk::PipelineStageFlags2 {
        match self {
            TimestampAt::Start => vk::PipelineStageFlags2::TOP_OF_PIPE,
            TimestampAt::ComputeDone => vk::PipelineStageFlags2::COMPUTE_SHADER,
            TimestampAt::GraphicsDone => vk::PipelineStageFlags2::ALL_GRAPHICS,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_flag_maps_to_its_own_vulkan_bit() {
        for s in Stages::all().iter() {
            assert_eq!(s.to_vk().as_raw().count_ones(), 1, "{s:?}");
            assert_eq!(s.pipeline_stages().as_raw().count_ones(), 1, "{s:?}");
        }
        assert_eq!(Stages::all().to_vk().as_raw().count_ones(), 4);
        for u in BufferUsage::all().iter() {
            assert_eq!(u.to_vk().as_raw().count_ones(), 1, "{u:?}");
        }
        assert_eq!(BufferUsage::all().to_vk().as_raw().count_ones(), BufferUsage::all().bits().count_ones());
        assert_eq!(
            (Stages::FRAGMENT | Stages::COMPUTE).to_vk(),
            vk::ShaderStageFlags::FRAGMENT | vk::ShaderStageFlags::COMPUTE
        );
    }
}
