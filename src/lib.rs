//! volbench: a Vulkan benchmark harness for GPU volume-rendering algorithms.
//!
//! Layers, dependencies pointing one way: `harness` (scenes, runs, reports) ->
//! `algo` (one module per method, with its shaders) -> `vk` (all `unsafe`
//! Vulkan). `mesh` and `scene` are plain data shared by all of them.

pub mod algo;
pub mod data_dir;
pub mod fsio;
pub mod harness;
pub mod mesh;
pub mod reference;
pub mod scene;
pub mod shaders;
pub mod terrain;
pub mod vk;
pub mod volume;
pub(crate) mod vtk_legacy;
pub(crate) mod vtk_xml;
