//! volbench: a Vulkan benchmark harness for GPU volume-rendering algorithms.
//!
//! Layers, dependencies pointing one way: `harness` (scenes, runs, reports) ->
//! `algo` (one module per method, with its shaders) -> `vk` (all `unsafe`
//! Vulkan). `mesh` and `scene` are plain data shared by all of them.

/// `eprintln!` for progress and warnings that never panics: a closed,
/// full or broken standard error loses the message, not the run (issue 21).
#[macro_export]
macro_rules! progress {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

pub mod algo;
pub mod bytes;
pub mod data_dir;
pub mod fsio;
pub mod harness;
pub mod mesh;
pub mod reference;
pub mod scene;
pub mod shaders;
pub mod switches;
pub mod terrain;
pub mod vk;
pub mod volume;
pub(crate) mod vtk_legacy;
pub(crate) mod vtk_xml;
