//! Instance, physical-device choice, logical device, the single queue, the
//! allocator and the validation-message log. One `Context` lives for a whole
//! run; every resource keeps an `Arc` to it so `Drop` order is always
//! resources first, then the device.
//!
//! Sync model: one queue, one frame at a time, the host waits on a fence after
//! each submission. That keeps timings honest (no overlap between frames) and
//! makes `Drop` of any resource safe after `wait_idle`.

use std::ffi::{c_void, CStr, CString};
use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex};

use ash::{ext, vk};
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use serde::Serialize;

use super::error::{Check, VkError, VkResult};

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
    /// Device from `VOLBENCH_DEVICE`, validation from `VOLBENCH_VALIDATION=1`.
    pub fn from_env() -> Self {
        ContextDesc {
            device: std::env::var("VOLBENCH_DEVICE").ok().filter(|s| !s.is_empty()),
            validation: validation_requested(),
        }
    }
}

pub fn validation_requested() -> bool {
    std::env::var("VOLBENCH_VALIDATION").is_ok_and(|v| v == "1" || v.eq_ignore_ascii_case("true"))
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
    pub pipeline_statistics: bool,
    pub max_image_dimension_2d: u32,
    pub max_storage_buffer_range: u32,
    pub max_push_constants_size: u32,
    pub max_memory_allocation_size: u64,
    pub device_local_heap_bytes: u64,
    pub validation: bool,
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
    let entry = unsafe { ash::Entry::load() }.map_err(|e| VkError::Loader(e.to_string()))?;
    let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_3);
    let instance = unsafe { entry.create_instance(&vk::InstanceCreateInfo::default().application_info(&app), None) }
        .map_err(|result| VkError::NoDriver { what: "vkCreateInstance", result })?;
    let devices = unsafe { instance.enumerate_physical_devices() }.check("vkEnumeratePhysicalDevices");
    let out = devices.map(|ds| {
        ds.iter()
            .map(|&d| {
                let p = unsafe { instance.get_physical_device_properties(d) };
                (device_name(&p), format!("{:?}", p.device_type))
            })
            .collect()
    });
    unsafe { instance.destroy_instance(None) };
    out
}

impl Context {
    pub fn new(desc: &ContextDesc) -> VkResult<Arc<Context>> {
        // SAFETY: loading the system loader; failure is an Err, not a crash.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| VkError::Loader(e.to_string()))?;

        let validation = desc.validation;
        if validation {
            let layers = unsafe { entry.enumerate_instance_layer_properties() }.check("vkEnumerateInstanceLayerProperties")?;
            let found = layers.iter().any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER));
            if !found {
                return Err(VkError::Unsupported {
                    device: "instance".into(),
                    what: "VK_LAYER_KHRONOS_validation (Debian: vulkan-validationlayers; run scripts/setup.sh)".into(),
                });
            }
        }

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
        let instance = unsafe { entry.create_instance(&ci, None) }
            .map_err(|result| VkError::NoDriver { what: "vkCreateInstance", result })?;

        let validation_log = Arc::new(ValidationLog::default());
        let debug = if validation {
            let loader = ext::debug_utils::Instance::new(&entry, &instance);
            let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
                .message_severity(
                    vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
                )
                .message_type(
                    vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                        | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                        | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
                )
                .pfn_user_callback(Some(debug_callback))
                .user_data(Arc::as_ptr(&validation_log) as *mut c_void);
            let messenger = unsafe { loader.create_debug_utils_messenger(&info, None) };
            match messenger {
                Ok(m) => Some((loader, m)),
                Err(result) => {
                    unsafe { instance.destroy_instance(None) };
                    return Err(VkError::Call { what: "vkCreateDebugUtilsMessengerEXT", result });
                }
            }
        } else {
            None
        };

        // From here on, a failure must destroy what exists: build the rest in a
        // helper and clean up on error.
        match Self::create_device(&entry, &instance, desc, validation) {
            Ok((physical, device, queue_family, info)) => {
                let queue = unsafe { device.get_device_queue(queue_family, 0) };
                let pool_info = vk::CommandPoolCreateInfo::default()
                    .queue_family_index(queue_family)
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
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
                let debug_device = validation.then(|| ext::debug_utils::Device::new(&instance, &device));
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
                    allocator: ManuallyDrop::new(Mutex::new(allocator)),
                    validation_log,
                }))
            }
            Err(e) => {
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

    fn pick_physical(instance: &ash::Instance, wanted: Option<&str>) -> VkResult<(usize, vk::PhysicalDevice)> {
        let devices = unsafe { instance.enumerate_physical_devices() }.check("vkEnumeratePhysicalDevices")?;
        let names: Vec<String> = devices
            .iter()
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

    fn create_device(
        entry: &ash::Entry,
        instance: &ash::Instance,
        desc: &ContextDesc,
        validation: bool,
    ) -> VkResult<(vk::PhysicalDevice, ash::Device, u32, DeviceInfo)> {
        let _ = entry;
        let (index, physical) = Self::pick_physical(instance, desc.device.as_deref())?;
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
        unsafe { instance.get_physical_device_properties2(physical, &mut props2) };
        let driver_name = driver.driver_name_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();
        let driver_info = driver.driver_info_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();

        let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
        let queue_family = families
            .iter()
            .position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
            .ok_or_else(|| VkError::Unsupported { device: name.clone(), what: "a graphics queue".into() })?
            as u32;
        let timestamp_valid_bits = families[queue_family as usize].timestamp_valid_bits;

        let supported = unsafe { instance.get_physical_device_features(physical) };
        let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
        let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f13);
        unsafe { instance.get_physical_device_features2(physical, &mut f2) };
        if f13.dynamic_rendering == vk::FALSE || f13.synchronization2 == vk::FALSE {
            return Err(VkError::Unsupported { device: name, what: "dynamicRendering and synchronization2".into() });
        }
        let maintenance4 = f13.maintenance4;
        let pipeline_statistics = supported.pipeline_statistics_query == vk::TRUE;

        let features = vk::PhysicalDeviceFeatures::default()
            .pipeline_statistics_query(pipeline_statistics)
            .fragment_stores_and_atomics(supported.fragment_stores_and_atomics == vk::TRUE)
            .geometry_shader(supported.geometry_shader == vk::TRUE)
            .shader_float64(supported.shader_float64 == vk::TRUE);
        let mut enable13 = vk::PhysicalDeviceVulkan13Features::default()
            .dynamic_rendering(true)
            .synchronization2(true)
            .maintenance4(maintenance4 == vk::TRUE);
        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default().queue_family_index(queue_family).queue_priorities(&priorities)];
        let dci = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_features(&features)
            .push_next(&mut enable13);
        let device = unsafe { instance.create_device(physical, &dci, None) }.check("vkCreateDevice")?;

        let mem = unsafe { instance.get_physical_device_memory_properties(physical) };
        let device_local_heap_bytes = mem.memory_heaps[..mem.memory_heap_count as usize]
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .max()
            .unwrap_or(0);
        let mut m3 = vk::PhysicalDeviceMaintenance3Properties::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut m3);
        unsafe { instance.get_physical_device_properties2(physical, &mut p2) };

        let info = DeviceInfo {
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
            pipeline_statistics,
            max_image_dimension_2d: props.limits.max_image_dimension2_d,
            max_storage_buffer_range: props.limits.max_storage_buffer_range,
            max_push_constants_size: props.limits.max_push_constants_size,
            max_memory_allocation_size: m3.max_memory_allocation_size,
            device_local_heap_bytes,
            validation,
        };
        Ok((physical, device, queue_family, info))
    }

    pub(crate) fn allocator(&self) -> std::sync::MutexGuard<'_, Allocator> {
        // A poisoned lock only means another thread panicked mid-allocation;
        // the allocator's state is still consistent for freeing.
        self.allocator.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Give a Vulkan object a debug name (visible in validation messages).
    pub fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(d) = &self.debug_device {
            if let Ok(c) = CString::new(name) {
                let info = vk::DebugUtilsObjectNameInfoEXT::default().object_handle(handle).object_name(&c);
                // Naming is best-effort diagnostics; a failure changes nothing.
                let _ = unsafe { d.set_debug_utils_object_name(&info) };
            }
        }
    }

    pub fn wait_idle(&self) -> VkResult<()> {
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
        if let Ok(b) = unsafe { ctx.device.create_buffer(&info, None) } {
            unsafe { ctx.device.destroy_buffer(b, None) };
        }
        let err = ctx.check_validation().expect_err("the validation layer must report the zero-sized buffer");
        assert!(err.to_string().contains("00912") || err.to_string().contains("size"), "{err}");
    }
}
