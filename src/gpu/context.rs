//! The GPU: adapter and device, with wgpu's failures turned into clear errors.
//!
//! `gpu` accepts any adapter, software ones included (lavapipe), so the GPU code runs on every
//! machine and in CI; `auto` takes a hardware adapter when there is one and otherwise falls back
//! to the CPU solver with a warning.

use crate::error::{Error, Result};

/// The features that time a frame's stages on the GPU.
const STAGE_TIMESTAMPS: wgpu::Features =
    wgpu::Features::TIMESTAMP_QUERY.union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES);

/// Storage buffers one kernel binds (shaders/common.wgsl group 0, the residual group and the
/// group of particle collisions, attachments and characters' shells).
pub const STORAGE_BUFFERS_NEEDED: u32 = 28;

/// A device and queue with what the report says about them (cloning shares them).
#[derive(Clone)]
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter: wgpu::AdapterInfo,
}

/// Whether the machine shows any GPU device at all (Linux: a `/dev/nvidia<N>` or a
/// `/dev/dri/renderD*` node; elsewhere assumed). `auto` asks this before opening Vulkan, because
/// opening it on a machine without a GPU costs time and makes Mesa print Wayland complaints.
pub fn hardware_present() -> bool {
    if !cfg!(target_os = "linux") {
        return true;
    }
    let nodes = |dir: &str, prefix: &str| {
        std::fs::read_dir(dir).is_ok_and(|entries| {
            entries.filter_map(|e| e.ok()).any(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                name.starts_with(prefix)
                    && name[prefix.len()..]
                        .chars()
                        .next()
                        .is_some_and(|c| c.is_ascii_digit())
            })
        })
    };
    nodes("/dev", "nvidia") || nodes("/dev/dri", "renderD")
}

impl GpuContext {
    /// Opens the best adapter: a hardware one when `hardware_only`, else any (software included).
    pub fn new(hardware_only: bool) -> Result<GpuContext> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let rank = |a: &wgpu::Adapter| match a.get_info().device_type {
            wgpu::DeviceType::DiscreteGpu => 0,
            wgpu::DeviceType::IntegratedGpu => 1,
            wgpu::DeviceType::VirtualGpu => 2,
            wgpu::DeviceType::Other => 3,
            wgpu::DeviceType::Cpu => 4,
        };
        let adapter = adapters
            .into_iter()
            .filter(|a| !hardware_only || rank(a) <= 2)
            .min_by_key(rank)
            .ok_or_else(|| Error::Gpu {
                reason: if hardware_only {
                    "no hardware GPU adapter found".into()
                } else {
                    "no GPU adapter found (install mesa-vulkan-drivers for the software one)".into()
                },
            })?;
        let info = adapter.get_info();
        let limits = adapter.limits();
        if limits.max_storage_buffers_per_shader_stage < STORAGE_BUFFERS_NEEDED {
            return Err(Error::Gpu {
                reason: format!(
                    "{} allows {} storage buffers per kernel; drape needs {STORAGE_BUFFERS_NEEDED}",
                    info.name, limits.max_storage_buffers_per_shader_stage
                ),
            });
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("drape"),
            // Timestamps between a frame's stages, where the adapter has them (`stages_ms`).
            required_features: adapter.features() & STAGE_TIMESTAMPS,
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| Error::Gpu {
            reason: format!("{}: cannot open the device: {e}", info.name),
        })?;
        Ok(GpuContext {
            device,
            queue,
            adapter: info,
        })
    }

    /// True when the device can time the stages of a frame (timestamps inside a pass).
    pub fn timestamps(&self) -> bool {
        self.device.features().contains(STAGE_TIMESTAMPS)
    }

    /// "name (type)" for messages and reports.
    pub fn describe(&self) -> String {
        format!("{} ({:?})", self.adapter.name, self.adapter.device_type)
    }
}
