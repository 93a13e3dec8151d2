//! The one error type of the Vulkan layer: every failing call says what it was
//! doing, every rejected description names the object and the problem, a
//! bounded wait that ran out names its recorder. Layers above add context
//! (scene, file) with `anyhow::Context`.

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
    /// An environment variable holds a value we cannot use.
    #[error("environment variable {var}={value:?} is not valid: expected {expected}")]
    Env { var: &'static str, value: String, expected: String },
    /// A bounded fence wait ran out: the device may be hung.
    #[error("waiting for command recorder '{recorder}' timed out after {seconds} s (VOLBENCH_FENCE_TIMEOUT_S); the device may be hung")]
    Timeout { recorder: String, seconds: f64 },
    /// After a time-out nothing waits on the device again.
    #[error("an earlier submission did not finish in time; the device is treated as hung and not waited for again")]
    DeviceHung,
    /// A description or a set of resources that does not fit together
    /// (wrong descriptor kind, sizes, missing usage); names the object.
    #[error("{0}")]
    Invalid(String),
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

/// A switch's bad value (`crate::switches`) as the environment error.
impl From<crate::switches::BadValue> for VkError {
    fn from(e: crate::switches::BadValue) -> Self {
        VkError::Env { var: e.var, value: e.value, expected: e.expected }
    }
}

