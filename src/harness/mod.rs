//! The harness: which meshes and transfer functions, how frames are run and
//! timed, and what results and images are written. It drives `algo` and never
//! calls Vulkan directly beyond creating the context.

pub mod datasets;
pub mod image;
pub mod pareto;
pub mod reference_cache;
pub mod report;
pub mod run;
pub mod stats;
pub mod stress;
