//! The algorithms. Each owns its pipelines and buffers (through `crate::vk`)
//! and never writes files or decides what to measure: that is the harness.

pub mod cell_projection;
pub mod adaptive;
pub mod chunks;
pub mod host_memory;
pub mod integrate;
pub mod method;
pub mod pipelines;
pub mod psi;
pub mod raycast;
pub mod registry;
pub mod screen;
pub mod segment;
pub mod settings;
pub mod terrain;
pub mod tet_mesh;
pub mod tet_raycast;
