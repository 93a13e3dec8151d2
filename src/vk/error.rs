//! The one error type of the Vulkan layer: every failing call says what it was
//! doing. Layers above add context (scene, file) with `anyhow::Context`.

use ash::vk;

#[derive(Debug, thiserror::Error)]
pub enum VkError {
    #[error("cannot load the Vulkan loader (libvulkan.so.1): {0}; install it with scripts/setup.sh (Debian: libvulkan1 mesa-vulkan-drivers)")]
    Loader(String),
    #[error("{what} failed: {result:?}")]
    Call { what: &'static str, result: vk::Result },
    #[error("no Vulkan driver found ({what} returned {result:?}); install Mesa's lavapipe (Debian: mesa-vulkan-drivers) with scripts/setup.sh")]
    NoDriver { what: &'static str, result: vk::Result },
    #[error("no Vulkan device matches '{wanted}'; available: {available}")]
    NoDevice { wanted: String, available: String },
    #[error("device '{device}' lacks {what}")]
    Unsupported { device: String, what: String },
    #[error("allocating memory for {name}: {source}")]
    Alloc {
        name: String,
        #[source]
        source: gpu_allocator::AllocationError,
    },
    #[error("{0}")]
    Shader(String),
    #[error("the validation layer reported {count} message(s); first: {first}")]
    Validation { count: usize, first: String },
}

pub type VkResult<T> = Result<T, VkError>;

/// Attach a description of the call to a raw `vk::Result`.
pub(crate) trait Check<T> {
    fn check(self, what: &'static str) -> VkResult<T>;
}

impl<T> Check<T> for Result<T, vk::Result> {
    fn check(self, what: &'static str) -> VkResult<T> {
        self.map_err(|result| VkError::Call { what, result })
    }
}
