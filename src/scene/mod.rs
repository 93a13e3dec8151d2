//! What a frame shows: the camera and the transfer function, shared by every
//! method and by the CPU reference.

pub mod camera;
pub mod tf_file;
pub mod transfer_function;

pub use camera::{Camera, Projection};
pub use transfer_function::{effective_scalar_range, ControlPoint, TransferFunction};
