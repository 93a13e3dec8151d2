//! Instance, physical-device choice, logical device, the single queue, the
//! allocator and the validation-message log. One `Context` lives for a whole
//! run; every resource keeps an `Arc` to it so `Drop` order is always
//! resources first, then the device.
//!
//! Sync model: one queue, one frame at a time, the host waits on a fence after
//! each submission. That keeps timings honest (no overlap between frames) and
//! makes `Drop` of any resource safe after `wait_idle`. Fence waits are
//! bounded (`fence_timeout`, 60 s unless `VOLBENCH_FENCE_TIMEOUT_S` says
//! otherwise) so a hung device becomes an error, not a hang.
//!
//! Optional features (geometry shaders, pipeline statistics, f64 in shaders,
//! ...) are enabled when the device has them and recorded in
//! `DeviceInfo::features`, so the harness can skip a method whose features
//! are missing instead of failing at pipeline creation. Environment switches
//! are parsed strictly: a value we do not understand is an error naming the
//! variable, never silently "off".

use std::ffi::{c_void, CStr, CString};
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ash::{ext, vk};
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use serde::Serialize;

use super::error::{Check, VkError, VkResult};
use super::format::Format;
use super::image::Filter;

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// How to pick and set up the device.
#[derive(Debug, Clone, Default)]
pub struct ContextDesc {
    /// Index into the device list or a case-insensitive substring of the name.
    /// `None`: lavapipe if present, else the first device.
    pub device: Option<String>,
    /// Enable `VK_LAYER_KHRONOS_validation`; its warnings and errors are
    /// collected and turned into an error by [`Context::check_validation`].
    pub validation: bool,
}

impl ContextDesc {
    /// Device from `VOLBENCH_DEVICE`, validation from `VOLBENCH_VALIDATION`
    /// (see [`parse_env_flag`]); an unusable value is an error.
    pub fn from_env() -> VkResult<Self> {
        // A value that is not UTF-8 is an error, never "unset".
        for var in [DEVICE_VAR, VALIDATION_VAR] {
            if let Err(std::env::VarError::NotUnicode(v)) = std::env::var(var) {
                return Err(VkError::Env { var, value: v.to_string_lossy().into_owned(), expected: "a UTF-8 value".into() });
            }
        }
        Self::from_vars(&|name| std::env::var(name).ok())
    }

    /// `from_env` over any variable lookup (tests pass a map instead of
    /// mutating the process environment).
    pub fn from_vars(get: &dyn Fn(&str) -> Option<String>) -> VkResult<Self> {
        Ok(ContextDesc {
            device: get(DEVICE_VAR).filter(|s| !s.is_empty()),
            validation: match get(VALIDATION_VAR) {
                Some(v) => parse_env_flag(VALIDATION_VAR, &v)?,
                None => false,
            },
        })
    }
}

/// The variable that picks the device.
pub const DEVICE_VAR: &str = crate::switches::DEVICE;
/// The variable that turns the validation layer on.
pub const VALIDATION_VAR: &str = crate::switches::VALIDATION;
/// The variable that bounds every fence wait, in seconds.
pub const FENCE_TIMEOUT_VAR: &str = crate::switches::FENCE_TIMEOUT_S;
/// Fence waits give up after this long unless `VOLBENCH_FENCE_TIMEOUT_S` says
/// otherwise: far above any frame we draw, far below "forever".
pub const DEFAULT_FENCE_TIMEOUT: Duration = Duration::from_secs(60);

/// Whether `VOLBENCH_VALIDATION` asks for the validation layer (unset: no).
pub fn validation_requested() -> VkResult<bool> {
    Ok(crate::switches::flag(VALIDATION_VAR)?)
}

/// A boolean switch from the environment: 1/0, true/false, yes/no, on/off in
/// any case (surrounding blanks ignored); an empty value means off. Anything
/// else is an error naming `var` and the value (`crate::switches::parse`).
pub fn parse_env_flag(var: &'static str, value: &str) -> VkResult<bool> {
    Ok(crate::switches::parse(var, crate::switches::Kind::Flag, value)? == crate::switches::Value::Flag(true))
}

/// The fence time-out from `VOLBENCH_FENCE_TIMEOUT_S` (unset: 60 s).
pub fn fence_timeout_from_env() -> VkResult<Duration> {
    Ok(crate::switches::seconds(FENCE_TIMEOUT_VAR)?.map_or(DEFAULT_FENCE_TIMEOUT, Duration::from_secs_f64))
}

/// Seconds (fractions allowed) in (0, 86400]; anything else is an error.
pub fn parse_fence_timeout(value: &str) -> VkResult<Duration> {
    match crate::switches::parse_named(FENCE_TIMEOUT_VAR, value)? {
        crate::switches::Value::Seconds(s) => Ok(Duration::from_secs_f64(s)),
        _ => Err(VkError::Env { var: FENCE_TIMEOUT_VAR, value: value.to_string(), expected: "seconds".into() }),
    }
}

/// Optional device features: what the device offers and we enable, recorded
/// with every result so a method needing a missing one can be skipped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize)]
pub struct DeviceFeatures {
    pub geometry_shader: bool,
    pub tessellation_shader: bool,
    pub pipeline_statistics_query: bool,
    pub shader_float64: bool,
    pub shader_int64: bool,
    pub shader_int16: bool,
    pub fragment_stores_and_atomics: bool,
    pub vertex_pipeline_stores_and_atomics: bool,
    /// Storage images declared without a format qualifier can be written.
    pub shader_storage_image_write_without_format: bool,
    /// Storage images of the extended formats (r8, r16, r16_snorm, ...) in
    /// shaders: an 8- or 16-bit volume read with imageLoad.
    pub shader_storage_image_extended_formats: bool,
    /// Primitives are not clipped at the near and far planes (depth clamped).
    pub depth_clamp: bool,
    /// Vertex shaders can write gl_ClipDistance (user clip planes).
    pub shader_clip_distance: bool,
}

impl DeviceFeatures {
    /// The names of the features `self` requires that `have` lacks (empty:
    /// the device can run it).
    pub fn missing_from(&self, have: &DeviceFeatures) -> Vec<&'static str> {
        let pairs = [
            (self.geometry_shader, have.geometry_shader, "geometryShader"),
            (self.tessellation_shader, have.tessellation_shader, "tessellationShader"),
            (self.pipeline_statistics_query, have.pipeline_statistics_query, "pipelineStatisticsQuery"),
            (self.shader_float64, have.shader_float64, "shaderFloat64"),
            (self.shader_int64, have.shader_int64, "shaderInt64"),
            (self.shader_int16, have.shader_int16, "shaderInt16"),
            (self.fragment_stores_and_atomics, have.fragment_stores_and_atomics, "fragmentStoresAndAtomics"),
            (
                self.vertex_pipeline_stores_and_atomics,
                have.vertex_pipeline_stores_and_atomics,
                "vertexPipelineStoresAndAtomics",
            ),
            (
                self.shader_storage_image_write_without_format,
                have.shader_storage_image_write_without_format,
                "shaderStorageImageWriteWithoutFormat",
            ),
            (
                self.shader_storage_image_extended_formats,
                have.shader_storage_image_extended_formats,
                "shaderStorageImageExtendedFormats",
            ),
            (self.depth_clamp, have.depth_clamp, "depthClamp"),
            (self.shader_clip_distance, have.shader_clip_distance, "shaderClipDistance"),
        ];
        pairs.iter().filter(|(need, has, _)| *need && !*has).map(|(_, _, n)| *n).collect()
    }

    fn of(f: &vk::PhysicalDeviceFeatures) -> Self {
        let b = |v: vk::Bool32| v == vk::TRUE;
        DeviceFeatures {
            geometry_shader: b(f.geometry_shader),
            tessellation_shader: b(f.tessellation_shader),
            pipeline_statistics_query: b(f.pipeline_statistics_query),
            shader_float64: b(f.shader_float64),
            shader_int64: b(f.shader_int64),
            shader_int16: b(f.shader_int16),
            fragment_stores_and_atomics: b(f.fragment_stores_and_atomics),
            vertex_pipeline_stores_and_atomics: b(f.vertex_pipeline_stores_and_atomics),
            shader_storage_image_write_without_format: b(f.shader_storage_image_write_without_format),
            shader_storage_image_extended_formats: b(f.shader_storage_image_extended_formats),
            depth_clamp: b(f.depth_clamp),
            shader_clip_distance: b(f.shader_clip_distance),
        }
    }

    fn to_vk(self) -> vk::PhysicalDeviceFeatures {
        vk::PhysicalDeviceFeatures::default()
            .geometry_shader(self.geometry_shader)
            .tessellation_shader(self.tessellation_shader)
            .pipeline_statistics_query(self.pipeline_statistics_query)
            .shader_float64(self.shader_float64)
            .shader_int64(self.shader_int64)
            .shader_int16(self.shader_int16)
            .fragment_stores_and_atomics(self.fragment_stores_and_atomics)
            .vertex_pipeline_stores_and_atomics(self.vertex_pipeline_stores_and_atomics)
            .shader_storage_image_write_without_format(self.shader_storage_image_write_without_format)
            .shader_storage_image_extended_formats(self.shader_storage_image_extended_formats)
            .depth_clamp(self.depth_clamp)
            .shader_clip_distance(self.shader_clip_distance)
    }
}

/// What results record about the device.
#[derive(Debug, Clone, Serialize)]
pub struct DeviceInfo {
    pub index: usize,
    pub name: String,
    pub device_type: String,
    pub driver_name: String,
    pub driver_info: String,
    pub api_version: String,
    pub vendor_id: u32,
    pub device_id: u32,
    pub timestamp_period_ns: f32,
    pub timestamp_valid_bits: u32,
    /// Same as `features.pipeline_statistics_query` (kept for old results).
    pub pipeline_statistics: bool,
    pub max_image_dimension_2d: u32,
    pub max_storage_buffer_range: u32,
    pub max_push_constants_size: u32,
    pub max_memory_allocation_size: u64,
    pub device_local_heap_bytes: u64,
    pub validation: bool,
    /// Optional features enabled on the device (all it supports).
    pub features: DeviceFeatures,
    pub max_image_dimension_1d: u32,
    pub max_image_dimension_3d: u32,
    pub max_uniform_buffer_range: u32,
    pub max_texel_buffer_elements: u32,
    pub max_color_attachments: u32,
    pub max_bound_descriptor_sets: u32,
    pub max_compute_work_group_count: [u32; 3],
    pub max_compute_work_group_size: [u32; 3],
    pub max_compute_work_group_invocations: u32,
    pub max_geometry_output_vertices: u32,
    /// All components (built-ins included) one geometry-shader invocation
    /// may emit over all its vertices.
    pub max_geometry_total_output_components: u32,
    /// Descriptors one shader stage may see, per class (every set of a
    /// pipeline together; checked when its layout is made).
    pub max_per_stage_storage_images: u32,
    pub max_per_stage_sampled_images: u32,
    pub max_per_stage_storage_buffers: u32,
    pub max_per_stage_uniform_buffers: u32,
    /// Invocations per subgroup (lavapipe: its SIMD width in 32-bit lanes).
    pub subgroup_size: u32,
    /// Compute shaders may use subgroup basic and arithmetic operations
    /// (subgroupAdd, subgroupElect, ...).
    pub compute_subgroup_arithmetic: bool,
}

impl DeviceInfo {
    /// A CPU device (lavapipe): its "device memory" is the process's own.
    pub fn is_cpu(&self) -> bool {
        self.device_type == format!("{:?}", vk::PhysicalDeviceType::CPU)
    }

    /// In how many contiguous runs the device shares out a compute
    /// dispatch's workgroups: on a CPU device (lavapipe) its compute
    /// thread pool gives each thread one run (`lp_cs_tpool`: the count
    /// divided by the threads), and it has `LP_NUM_THREADS` threads, else
    /// one per CPU, at most 32 (0: the caller's thread alone). 1 elsewhere:
    /// a GPU's scheduler hands out workgroups as its units free up.
    pub fn compute_runs(&self) -> u32 {
        if !self.is_cpu() {
            return 1;
        }
        let threads = match std::env::var("LP_NUM_THREADS").ok().and_then(|v| v.trim().parse::<u32>().ok()) {
            Some(n) => n,
            None => std::thread::available_parallelism().map_or(1, |n| n.get() as u32),
        };
        threads.clamp(1, 32)
    }
}

/// Messages the validation layer reported, shared with its callback.
#[derive(Default)]
pub struct ValidationLog {
    messages: Mutex<Vec<String>>,
}

pub struct Context {
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    debug: Option<(ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    debug_device: Option<ext::debug_utils::Device>,
    pub physical: vk::PhysicalDevice,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub command_pool: vk::CommandPool,
    pub info: DeviceInfo,
    /// How long any fence wait may block (see `FENCE_TIMEOUT_VAR`).
    pub fence_timeout: Duration,
    /// Set when a fence wait timed out: the device may still use memory, so
    /// wrappers leak instead of freeing and `Drop` does not wait forever.
    hung: AtomicBool,
    allocator: ManuallyDrop<Mutex<Allocator>>,
    validation_log: Arc<ValidationLog>,
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    let counts = severity.intersects(
        vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
    ) && kind.intersects(vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION);
    if counts && !data.is_null() && !user.is_null() {
        // SAFETY: `user` is the `ValidationLog` the Context keeps alive for as
        // long as the messenger exists; `data` is valid for this call.
        let log = unsafe { &*(user as *const ValidationLog) };
        // SAFETY: `data` is non-null (checked above) and valid for this call, as
        // the callback's contract says; the message is copied before returning.
        let msg = unsafe { (*data).message_as_c_str() }
            .map(|m| m.to_string_lossy().into_owned())
            .unwrap_or_default();
        if let Ok(mut m) = log.messages.lock() {
            m.push(format!("{severity:?}: {msg}"));
        }
    }
    vk::FALSE
}

fn api_version_string(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

fn device_name(props: &vk::PhysicalDeviceProperties) -> String {
    props.device_name_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default()
}

/// Everything `volbench info` lists, without creating a logical device.
pub fn list_devices() -> VkResult<Vec<(String, String)>> {
    // SAFETY: loading libvulkan runs its initialisers; the loader is the
    // system's, and the returned Entry keeps the library loaded while any
    // instance made from it lives (a local here; the Context holds both).
    let entry = unsafe { ash::Entry::load() }.map_err(|e| VkError::Loader(e.to_string()))?;
    let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_3);
    // SAFETY: the create info and the names it points to live for the call;
    // the instance is destroyed once, before this function returns.
    let instance = unsafe { entry.create_instance(&vk::InstanceCreateInfo::default().application_info(&app), None) }
        .map_err(|result| VkError::NoDriver { what: "vkCreateInstance", result })?;
    // SAFETY: queries of live instance/physical-device handles; output
    // structures are owned here, and any p_next chain points at locals that
    // outlive the call.
    let devices = unsafe { instance.enumerate_physical_devices() }.check("vkEnumeratePhysicalDevices");
    let out = devices.map(|ds| {
        ds.iter()
            .map(|&d| {
                // SAFETY: queries of live instance/physical-device handles; output
                // structures are owned here, and any p_next chain points at locals that
                // outlive the call.
                let p = unsafe { instance.get_physical_device_properties(d) };
                (device_name(&p), format!("{:?}", p.device_type))
            })
            .collect()
    });
    // SAFETY: the instance was created above, owns no live child object (only
    // queried) and is destroyed once.
    unsafe { instance.destroy_instance(None) };
    out
}

/// What `Context::create_device` makes: the physical device, the logical
/// device, its queue family and what results record about it.
type MadeDevice = (vk::PhysicalDevice, ash::Device, u32, DeviceInfo);

/// The instance-level objects a `Context` takes over once its device is made.
struct InstanceParts {
    entry: ash::Entry,
    instance: ash::Instance,
    debug: Option<(ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    validation_log: Arc<ValidationLog>,
}

/// An error unless the validation layer is installed.
fn check_validation_layer(entry: &ash::Entry) -> VkResult<()> {
    // SAFETY: queries of live instance/physical-device handles; output
    // structures are owned here, and any p_next chain points at locals that
    // outlive the call.
    let layers = unsafe { entry.enumerate_instance_layer_properties() }.check("vkEnumerateInstanceLayerProperties")?;
    let found = layers.iter().any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER));
    if !found {
        return Err(VkError::Unsupported {
            device: "instance".into(),
            what: "VK_LAYER_KHRONOS_validation (Debian: vulkan-validationlayers; run scripts/setup.sh)".into(),
        });
    }
    Ok(())
}

/// A Vulkan 1.3 instance, with the validation layer and debug utils when
/// `validation`.
fn create_instance(entry: &ash::Entry, validation: bool) -> VkResult<ash::Instance> {
    let app_name = CString::new("volbench").unwrap_or_default();
    let app = vk::ApplicationInfo::default()
        .application_name(&app_name)
        .application_version(1)
        .engine_name(&app_name)
        .api_version(vk::API_VERSION_1_3);
    let layer_ptrs = [VALIDATION_LAYER.as_ptr()];
    let ext_ptrs = [ext::debug_utils::NAME.as_ptr()];
    let mut ci = vk::InstanceCreateInfo::default().application_info(&app);
    if validation {
        ci = ci.enabled_layer_names(&layer_ptrs).enabled_extension_names(&ext_ptrs);
    }
    // SAFETY: the create info and the layer and extension names it points to
    // live for the call; the instance is destroyed by `Drop for Context`, or on
    // the error paths of `Context::new`.
    unsafe { entry.create_instance(&ci, None) }.map_err(|result| VkError::NoDriver { what: "vkCreateInstance", result })
}

/// The messenger that hands the validation layer's warnings and errors to
/// `log`. On failure the instance is destroyed.
fn create_messenger(
    entry: &ash::Entry,
    instance: &ash::Instance,
    log: &Arc<ValidationLog>,
) -> VkResult<(ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)> {
    let loader = ext::debug_utils::Instance::new(entry, instance);
    let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING)
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(debug_callback))
        .user_data(Arc::as_ptr(log) as *mut c_void);
    // SAFETY: `info` lives for the call; its user data is the `ValidationLog`
    // the Context keeps (an Arc) for as long as the messenger lives, so the
    // callback's pointer stays valid; the messenger is destroyed before the
    // instance (Drop for Context, or the error path below).
    let messenger = unsafe { loader.create_debug_utils_messenger(&info, None) };
    match messenger {
        Ok(m) => Ok((loader, m)),
        Err(result) => {
            // SAFETY: no child object of the instance exists (the messenger failed),
            // and the instance is destroyed once: nothing else owns it yet.
            unsafe { instance.destroy_instance(None) };
            Err(VkError::Call { what: "vkCreateDebugUtilsMessengerEXT", result })
        }
    }
}

/// A physical device's properties, name and driver, once it is known to
/// speak Vulkan 1.3.
struct Identity {
    props: vk::PhysicalDeviceProperties,
    name: String,
    driver_name: String,
    driver_info: String,
}

impl Identity {
    fn of(instance: &ash::Instance, physical: vk::PhysicalDevice) -> VkResult<Identity> {
        // SAFETY: queries of live instance/physical-device handles; output
        // structures are owned here, and any p_next chain points at locals that
        // outlive the call.
        let props = unsafe { instance.get_physical_device_properties(physical) };
        let name = device_name(&props);
        if props.api_version < vk::API_VERSION_1_3 {
            return Err(VkError::Unsupported {
                device: name,
                what: format!("Vulkan 1.3 (it reports {})", api_version_string(props.api_version)),
            });
        }
        let mut driver = vk::PhysicalDeviceDriverProperties::default();
        let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver);
        // SAFETY: queries of live instance/physical-device handles; output
        // structures are owned here, and any p_next chain points at locals that
        // outlive the call.
        unsafe { instance.get_physical_device_properties2(physical, &mut props2) };
        let driver_name = driver.driver_name_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();
        let driver_info = driver.driver_info_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();
        Ok(Identity { props, name, driver_name, driver_info })
    }
}

/// The first queue family with graphics (it has compute and transfer too),
/// and its timestamps' valid bits.
fn graphics_queue_family(instance: &ash::Instance, physical: vk::PhysicalDevice, name: &str) -> VkResult<(u32, u32)> {
    // SAFETY: queries of live instance/physical-device handles; output
    // structures are owned here, and any p_next chain points at locals that
    // outlive the call.
    let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
    let queue_family = families
        .iter()
        .position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
        .ok_or_else(|| VkError::Unsupported { device: name.to_string(), what: "a graphics queue".into() })?;
    Ok((queue_family as u32, families[queue_family].timestamp_valid_bits))
}

/// The optional features to enable (every one we know that the device has:
/// none costs anything unless a shader uses it) and whether it has
/// maintenance4; an error without dynamic rendering and synchronization2.
fn features_to_enable(instance: &ash::Instance, physical: vk::PhysicalDevice, name: &str) -> VkResult<(DeviceFeatures, bool)> {
    // SAFETY: queries of live instance/physical-device handles; output
    // structures are owned here, and any p_next chain points at locals that
    // outlive the call.
    let supported = unsafe { instance.get_physical_device_features(physical) };
    let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
    let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f13);
    // SAFETY: queries of live instance/physical-device handles; output
    // structures are owned here, and any p_next chain points at locals that
    // outlive the call.
    unsafe { instance.get_physical_device_features2(physical, &mut f2) };
    if f13.dynamic_rendering == vk::FALSE || f13.synchronization2 == vk::FALSE {
        return Err(VkError::Unsupported { device: name.to_string(), what: "dynamicRendering and synchronization2".into() });
    }
    Ok((DeviceFeatures::of(&supported), f13.maintenance4 == vk::TRUE))
}

/// The logical device: one queue of `queue_family`, the `enabled` features,
/// dynamic rendering, synchronization2 and (when present) maintenance4.
fn create_logical_device(
    instance: &ash::Instance,
    physical: vk::PhysicalDevice,
    queue_family: u32,
    enabled: DeviceFeatures,
    maintenance4: bool,
) -> VkResult<ash::Device> {
    let features = enabled.to_vk();
    let mut enable13 = vk::PhysicalDeviceVulkan13Features::default()
        .dynamic_rendering(true)
        .synchronization2(true)
        .maintenance4(maintenance4);
    let priorities = [1.0f32];
    let queue_info = [vk::DeviceQueueCreateInfo::default().queue_family_index(queue_family).queue_priorities(&priorities)];
    let dci = vk::DeviceCreateInfo::default()
        .queue_create_infos(&queue_info)
        .enabled_features(&features)
        .push_next(&mut enable13);
    // SAFETY: `dci` and what it points to (queue infos, priorities, the
    // feature chain, extension names) are locals that live for the call;
    // the device is destroyed once, by `Drop for Context`.
    unsafe { instance.create_device(physical, &dci, None) }.check("vkCreateDevice")
}

/// What `device_info` records beside the device's own properties and limits.
struct DeviceFacts {
    index: usize,
    identity: Identity,
    timestamp_valid_bits: u32,
    enabled: DeviceFeatures,
    validation: bool,
}

/// What results record about the device: its identity, limits, memory and
/// subgroup properties, the features enabled.
fn device_info(instance: &ash::Instance, physical: vk::PhysicalDevice, facts: DeviceFacts) -> DeviceInfo {
    let DeviceFacts { index, identity, timestamp_valid_bits, enabled, validation } = facts;
    let Identity { props, name, driver_name, driver_info } = identity;
    // SAFETY: queries of live instance/physical-device handles; output
    // structures are owned here, and any p_next chain points at locals that
    // outlive the call.
    let mem = unsafe { instance.get_physical_device_memory_properties(physical) };
    let device_local_heap_bytes = mem.memory_heaps[..mem.memory_heap_count as usize]
        .iter()
        .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
        .map(|h| h.size)
        .max()
        .unwrap_or(0);
    let mut m3 = vk::PhysicalDeviceMaintenance3Properties::default();
    let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
    let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut m3).push_next(&mut subgroup);
    // SAFETY: queries of live instance/physical-device handles; output
    // structures are owned here, and any p_next chain points at locals that
    // outlive the call.
    unsafe { instance.get_physical_device_properties2(physical, &mut p2) };

    let limits = &props.limits;
    DeviceInfo {
        index,
        name,
        device_type: format!("{:?}", props.device_type),
        driver_name,
        driver_info,
        api_version: api_version_string(props.api_version),
        vendor_id: props.vendor_id,
        device_id: props.device_id,
        timestamp_period_ns: props.limits.timestamp_period,
        timestamp_valid_bits,
        pipeline_statistics: enabled.pipeline_statistics_query,
        max_image_dimension_2d: props.limits.max_image_dimension2_d,
        max_storage_buffer_range: props.limits.max_storage_buffer_range,
        max_push_constants_size: props.limits.max_push_constants_size,
        max_memory_allocation_size: m3.max_memory_allocation_size,
        device_local_heap_bytes,
        validation,
        features: enabled,
        max_image_dimension_1d: limits.max_image_dimension1_d,
        max_image_dimension_3d: limits.max_image_dimension3_d,
        max_uniform_buffer_range: limits.max_uniform_buffer_range,
        max_texel_buffer_elements: limits.max_texel_buffer_elements,
        max_color_attachments: limits.max_color_attachments,
        max_bound_descriptor_sets: limits.max_bound_descriptor_sets,
        max_compute_work_group_count: limits.max_compute_work_group_count,
        max_compute_work_group_size: limits.max_compute_work_group_size,
        max_compute_work_group_invocations: limits.max_compute_work_group_invocations,
        max_geometry_output_vertices: limits.max_geometry_output_vertices,
        max_geometry_total_output_components: limits.max_geometry_total_output_components,
        max_per_stage_storage_images: limits.max_per_stage_descriptor_storage_images,
        max_per_stage_sampled_images: limits.max_per_stage_descriptor_sampled_images,
        max_per_stage_storage_buffers: limits.max_per_stage_descriptor_storage_buffers,
        max_per_stage_uniform_buffers: limits.max_per_stage_descriptor_uniform_buffers,
        subgroup_size: subgroup.subgroup_size,
        compute_subgroup_arithmetic: subgroup.supported_stages.contains(vk::ShaderStageFlags::COMPUTE)
            && subgroup.supported_operations.contains(vk::SubgroupFeatureFlags::BASIC | vk::SubgroupFeatureFlags::ARITHMETIC),
    }
}

impl Context {
    pub fn new(desc: &ContextDesc) -> VkResult<Arc<Context>> {
        // SAFETY: loading the system loader; failure is an Err, not a crash.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| VkError::Loader(e.to_string()))?;

        let fence_timeout = fence_timeout_from_env()?;
        let validation = desc.validation;
        if validation {
            check_validation_layer(&entry)?;
        }
        let instance = create_instance(&entry, validation)?;
        let validation_log = Arc::new(ValidationLog::default());
        let debug = if validation { Some(create_messenger(&entry, &instance, &validation_log)?) } else { None };

        // From here on, a failure must destroy what exists: build the rest in a
        // helper and clean up on error.
        match Self::create_device(&instance, desc, validation) {
            Ok(made) => {
                let instance_parts = InstanceParts { entry, instance, debug, validation_log };
                Self::with_device(instance_parts, made, fence_timeout)
            }
            Err(e) => {
                // SAFETY: the device was not made (or was destroyed by
                // `create_device`'s own error path), so the messenger and the
                // instance have no other user; each is destroyed once, the
                // messenger first.
                unsafe {
                    if let Some((loader, m)) = &debug {
                        loader.destroy_debug_utils_messenger(*m, None);
                    }
                    instance.destroy_instance(None);
                }
                Err(e)
            }
        }
    }

    /// The context around a device just made: its queue, command pool and
    /// allocator.
    fn with_device(parts: InstanceParts, (physical, device, queue_family, info): MadeDevice, fence_timeout: Duration) -> VkResult<Arc<Context>> {
        let InstanceParts { entry, instance, debug, validation_log } = parts;
        // SAFETY: the device was created with one queue of `queue_family`.
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: `pool_info` lives for the call; the pool is destroyed by `Drop
        // for Context` before the device. (On the error path the device and
        // instance leak: no unsoundness, the process reports the error.)
        let command_pool = unsafe { device.create_command_pool(&pool_info, None) }.check("vkCreateCommandPool")?;
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .map_err(|source| VkError::Alloc { name: "allocator".into(), source })?;
        let debug_device = info.validation.then(|| ext::debug_utils::Device::new(&instance, &device));
        Ok(Arc::new(Context {
            entry,
            instance,
            debug,
            debug_device,
            physical,
            device,
            queue,
            queue_family,
            command_pool,
            info,
            fence_timeout,
            hung: AtomicBool::new(false),
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            validation_log,
        }))
    }

    fn pick_physical(instance: &ash::Instance, wanted: Option<&str>) -> VkResult<(usize, vk::PhysicalDevice)> {
        // SAFETY: queries of live instance/physical-device handles; output
        // structures are owned here, and any p_next chain points at locals that
        // outlive the call.
        let devices = unsafe { instance.enumerate_physical_devices() }.check("vkEnumeratePhysicalDevices")?;
        let names: Vec<String> = devices
            .iter()
            // SAFETY: queries of live instance/physical-device handles; output
            // structures are owned here, and any p_next chain points at locals that
            // outlive the call.
            .map(|&d| device_name(&unsafe { instance.get_physical_device_properties(d) }))
            .collect();
        let available = || {
            if names.is_empty() {
                "none (no Vulkan driver installed?)".to_string()
            } else {
                names.iter().enumerate().map(|(i, n)| format!("[{i}] {n}")).collect::<Vec<_>>().join(", ")
            }
        };
        let found = match wanted {
            Some(w) => match w.parse::<usize>() {
                Ok(i) if i < devices.len() => Some(i),
                Ok(_) => None,
                Err(_) => names.iter().position(|n| n.to_lowercase().contains(&w.to_lowercase())),
            },
            None => names
                .iter()
                .position(|n| n.contains("llvmpipe") || n.contains("lavapipe"))
                .or(if devices.is_empty() { None } else { Some(0) }),
        };
        match found {
            Some(i) => Ok((i, devices[i])),
            None => Err(VkError::NoDevice {
                wanted: wanted.unwrap_or("any (default: lavapipe)").to_string(),
                available: available(),
            }),
        }
    }

    fn create_device(instance: &ash::Instance, desc: &ContextDesc, validation: bool) -> VkResult<MadeDevice> {
        let (index, physical) = Self::pick_physical(instance, desc.device.as_deref())?;
        let identity = Identity::of(instance, physical)?;
        let (queue_family, timestamp_valid_bits) = graphics_queue_family(instance, physical, &identity.name)?;
        let (enabled, maintenance4) = features_to_enable(instance, physical, &identity.name)?;
        let device = create_logical_device(instance, physical, queue_family, enabled, maintenance4)?;
        let info = device_info(instance, physical, DeviceFacts { index, identity, timestamp_valid_bits, enabled, validation });
        Ok((physical, device, queue_family, info))
    }

    fn allocator(&self) -> std::sync::MutexGuard<'_, Allocator> {
        // A poisoned lock only means another thread panicked mid-allocation;
        // the allocator's state is still consistent for freeing.
        self.allocator.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Device memory for a buffer or image, counted (`vk::meter`).
    pub(crate) fn allocate(
        &self,
        desc: &gpu_allocator::vulkan::AllocationCreateDesc<'_>,
    ) -> gpu_allocator::Result<gpu_allocator::vulkan::Allocation> {
        let a = self.allocator().allocate(desc)?;
        super::meter::device_allocated(a.size());
        Ok(a)
    }

    /// Gives back what [`Context::allocate`] gave.
    pub(crate) fn free(&self, a: gpu_allocator::vulkan::Allocation) {
        super::meter::device_freed(a.size());
        let _ = self.allocator().free(a);
    }

    /// Give a Vulkan object a debug name (visible in validation messages).
    pub fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(d) = &self.debug_device {
            if let Ok(c) = CString::new(name) {
                let info = vk::DebugUtilsObjectNameInfoEXT::default().object_handle(handle).object_name(&c);
                // Naming is best-effort diagnostics; a failure changes nothing.
                // SAFETY: the name is a NUL-terminated CString living for the call and
                // the object handle is live on this device.
                let _ = unsafe { d.set_debug_utils_object_name(&info) };
            }
        }
    }

    /// Whether `format` has all of `features` on this device. Image features
    /// (sampled, linear filter, storage image, colour attachment, transfer)
    /// are checked for optimal tiling, the tiling every image here uses;
    /// buffer features (uniform/storage texel buffer, vertex buffer) against
    /// the format's buffer features. E.g. a volume that is to be sampled with
    /// trilinear filtering needs `SAMPLED_IMAGE | SAMPLED_IMAGE_FILTER_LINEAR`
    /// (`can_sample` with `Filter::Linear`).
    pub(crate) fn format_supports(&self, format: Format, features: vk::FormatFeatureFlags) -> bool {
        // SAFETY: queries of live instance/physical-device handles; output
        // structures are owned here, and any p_next chain points at locals that
        // outlive the call.
        let props = unsafe { self.instance.get_physical_device_format_properties(self.physical, format.to_vk()) };
        let buffer_bits = vk::FormatFeatureFlags::UNIFORM_TEXEL_BUFFER
            | vk::FormatFeatureFlags::STORAGE_TEXEL_BUFFER
            | vk::FormatFeatureFlags::STORAGE_TEXEL_BUFFER_ATOMIC
            | vk::FormatFeatureFlags::VERTEX_BUFFER;
        let want_buffer = features & buffer_bits;
        let want_image = features & !buffer_bits;
        props.buffer_features.contains(want_buffer) && props.optimal_tiling_features.contains(want_image)
    }

    /// Whether images of `format` can be sampled with `filter` on this
    /// device (optimal tiling).
    pub fn can_sample(&self, format: Format, filter: Filter) -> bool {
        let mut features = vk::FormatFeatureFlags::SAMPLED_IMAGE;
        if filter == Filter::Linear {
            features |= vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR;
        }
        self.format_supports(format, features)
    }

    /// Whether shaders may read images of `format` with imageLoad (as a
    /// storage image declared with its format qualifier).
    pub fn can_load(&self, format: Format) -> bool {
        let Some((_, extended)) = format.glsl_image_format() else { return false };
        self.format_supports(format, vk::FormatFeatureFlags::STORAGE_IMAGE) && (!extended || self.info.features.shader_storage_image_extended_formats)
    }

    /// The largest extent (and layers, max resource size) an optimal-tiling
    /// image of this type, format and usage may have, or `None` when the
    /// combination is not supported at all.
    pub(crate) fn image_format_limits(
        &self,
        format: vk::Format,
        ty: vk::ImageType,
        usage: vk::ImageUsageFlags,
    ) -> Option<vk::ImageFormatProperties> {
        // SAFETY: queries of live instance/physical-device handles; output
        // structures are owned here, and any p_next chain points at locals that
        // outlive the call.
        unsafe {
            self.instance.get_physical_device_image_format_properties(
                self.physical,
                format,
                ty,
                vk::ImageTiling::OPTIMAL,
                usage,
                vk::ImageCreateFlags::empty(),
            )
        }
        .ok()
    }

    /// Record that a submission did not finish within `fence_timeout`.
    pub(crate) fn mark_hung(&self) {
        self.hung.store(true, Ordering::SeqCst);
    }

    /// Whether some submission timed out (see `mark_hung`).
    pub fn is_hung(&self) -> bool {
        self.hung.load(Ordering::SeqCst)
    }

    /// Wait for the device to be idle; refused (instead of waiting forever)
    /// once a submission has timed out.
    pub fn wait_idle(&self) -> VkResult<()> {
        if self.is_hung() {
            return Err(VkError::DeviceHung);
        }
        // SAFETY: the device is live (self); vkDeviceWaitIdle needs its queues
        // externally synchronised, which the sync model (module documentation:
        // one queue, used from one thread at a time) provides.
        unsafe { self.device.device_wait_idle() }.check("vkDeviceWaitIdle")
    }

    /// Validation messages so far (empty when validation is off).
    pub fn validation_messages(&self) -> Vec<String> {
        self.validation_log.messages.lock().map(|m| m.clone()).unwrap_or_default()
    }

    /// Turn any validation message into an error: a message is a failure.
    pub fn check_validation(&self) -> VkResult<()> {
        let msgs = self.validation_messages();
        match msgs.first() {
            None => Ok(()),
            Some(first) => Err(VkError::Validation { count: msgs.len(), first: first.clone() }),
        }
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        if self.is_hung() {
            // vkDeviceWaitIdle could block forever and destroying a busy
            // device is undefined: leak it; the process is about to report
            // the time-out anyway.
            return;
        }
        // SAFETY: every resource holds an Arc of the Context, so none is left
        // when this runs; after the idle wait no submission is pending (a hung
        // device returned above). Children go before parents, each once: pool,
        // allocator (its memory), device, messenger, instance.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_command_pool(self.command_pool, None);
            ManuallyDrop::drop(&mut self.allocator);
            self.device.destroy_device(None);
            if let Some((loader, m)) = &self.debug {
                loader.destroy_debug_utils_messenger(*m, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The validation plumbing itself: an invalid call must be caught and
    /// turned into an error, or "no validation message" would mean nothing.
    #[test]
    fn validation_messages_become_errors() {
        let ctx = Context::new(&ContextDesc { device: None, validation: true }).expect("a Vulkan device");
        assert!(ctx.check_validation().is_ok());
        // A buffer of size 0 violates VUID-VkBufferCreateInfo-size-00912.
        let info = vk::BufferCreateInfo::default().size(0).usage(vk::BufferUsageFlags::VERTEX_BUFFER);
        // SAFETY: test code on live handles of the test's own device, used
        // and destroyed within this test.
        if let Ok(b) = unsafe { ctx.device.create_buffer(&info, None) } {
            // SAFETY: `b` was just created and never used; destroyed once.
            unsafe { ctx.device.destroy_buffer(b, None) };
        }
        let err = ctx.check_validation().expect_err("the validation layer must report the zero-sized buffer");
        assert!(err.to_string().contains("00912") || err.to_string().contains("size"), "{err}");
    }
}
