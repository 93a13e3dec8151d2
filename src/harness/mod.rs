//! The harness: which datasets and transfer functions, how frames are run
//! and timed, sweeps over the method registry, and what results and images
//! are written. It drives `algo` through the registry (it never names a
//! method) and never calls Vulkan directly beyond creating the context.

pub mod ab;
pub mod child;
pub mod count;
pub mod datasets;
pub mod image;
pub mod pareto;
pub mod peers;
pub mod plots;
pub mod reference_cache;
pub mod report;
pub mod run;
pub mod scale;
pub mod serve;
pub mod stats;
pub mod stress;
pub mod suite;
pub mod sweep;
pub mod track;
