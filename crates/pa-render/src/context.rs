//! Headless device creation: instance from the environment, adapter choice, device and queue.
//!
//! The instance honours `WGPU_BACKEND` (e.g. `vulkan`, `gl`) and the other `WGPU_*` instance
//! variables; `WGPU_ADAPTER_NAME` picks an adapter by a case-insensitive substring of its name.
//! Otherwise adapters are ranked: hardware before software, Vulkan/Metal/DX12 before GL, and
//! the first one with the needed capabilities (storage buffers in the vertex stage, compute
//! shaders) wins.

use std::sync::Arc;

use crate::error::RenderError;

/// Number of storage buffers the vertex stage and the compute stage bind at once.
pub(crate) const STORAGE_BUFFERS_PER_STAGE: u32 = 5;

/// The device, its queue and what was learned about the adapter.
pub(crate) struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
}

impl GpuContext {
    pub fn new() -> Result<Self, RenderError> {
        let desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        let backends = desc.backends;
        let instance = wgpu::Instance::new(desc);
        let mut adapters = pollster::block_on(instance.enumerate_adapters(backends));
        if adapters.is_empty() {
            return Err(RenderError::NoAdapter {
                backends: format!("{backends:?}"),
            });
        }

        if let Ok(wanted) = std::env::var("WGPU_ADAPTER_NAME") {
            let wanted_lower = wanted.to_lowercase();
            let available = adapters
                .iter()
                .map(|a| describe(&a.get_info()))
                .collect::<Vec<_>>()
                .join(", ");
            adapters.retain(|a| a.get_info().name.to_lowercase().contains(&wanted_lower));
            if adapters.is_empty() {
                return Err(RenderError::AdapterNameNotFound { wanted, available });
            }
        }

        adapters.sort_by_key(|a| adapter_rank(&a.get_info()));
        let mut rejected = Vec::new();
        let mut chosen = None;
        for adapter in adapters {
            match missing_capabilities(&adapter) {
                None => {
                    chosen = Some(adapter);
                    break;
                }
                Some(missing) => {
                    rejected.push(format!("{} lacks {missing}", describe(&adapter.get_info())))
                }
            }
        }
        let Some(adapter) = chosen else {
            return Err(RenderError::UnsupportedAdapter {
                details: rejected.join("; "),
            });
        };
        for line in &rejected {
            log::info!("pa-render: skipped adapter: {line}");
        }

        let info = adapter.get_info();
        // Ask for everything the adapter offers (texture size, storage buffer size).
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("pa-render device"),
            required_features: wgpu::Features::empty(),
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| RenderError::RequestDevice {
            adapter: describe(&info),
            reason: e.to_string(),
        })?;
        // Errors are caught with error scopes around each operation; anything that escapes is
        // logged instead of panicking (wgpu's default handler panics).
        device.on_uncaptured_error(Arc::new(|e: wgpu::Error| {
            log::error!("pa-render: uncaptured wgpu error: {e}");
        }));
        log::info!("pa-render: using {}", describe(&info));
        Ok(Self {
            device,
            queue,
            info,
            limits,
        })
    }
}

/// "name (backend, device type, driver)" for logs and errors.
pub(crate) fn describe(info: &wgpu::AdapterInfo) -> String {
    let driver = if info.driver_info.is_empty() {
        info.driver.clone()
    } else {
        format!("{} {}", info.driver, info.driver_info)
    };
    format!(
        "{} ({:?}, {:?}, {})",
        info.name,
        info.backend,
        info.device_type,
        driver.trim()
    )
}

/// Sort key of adapters in order of preference (smaller first): hardware before software,
/// Vulkan/Metal/DX12 before GL. Shared with the preview window's adapter choice.
pub fn adapter_rank(info: &wgpu::AdapterInfo) -> (u8, u8) {
    let device = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    };
    let backend = match info.backend {
        wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12 => 0,
        wgpu::Backend::Gl => 1,
        _ => 2,
    };
    (device, backend)
}

/// None when the adapter can run pa-render, else what it lacks.
fn missing_capabilities(adapter: &wgpu::Adapter) -> Option<String> {
    let downlevel = adapter.get_downlevel_capabilities();
    let limits = adapter.limits();
    let mut missing = Vec::new();
    if !downlevel
        .flags
        .contains(wgpu::DownlevelFlags::VERTEX_STORAGE)
    {
        missing
            .push("storage buffers in vertex shaders (DownlevelFlags::VERTEX_STORAGE)".to_owned());
    }
    if !downlevel
        .flags
        .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS)
    {
        missing.push("compute shaders".to_owned());
    }
    if limits.max_storage_buffers_per_shader_stage < STORAGE_BUFFERS_PER_STAGE {
        missing.push(format!(
            "{} storage buffers per shader stage (has {})",
            STORAGE_BUFFERS_PER_STAGE, limits.max_storage_buffers_per_shader_stage
        ));
    }
    if limits.max_color_attachments < 2 {
        missing.push("two colour attachments".to_owned());
    }
    if missing.is_empty() {
        None
    } else {
        Some(missing.join(", "))
    }
}
