//! Headless device creation: an instance on Vulkan or GL, an adapter by power preference, a
//! device with explicitly requested limits and the optional features the renderer can use,
//! and error handlers that record errors into a shared slot instead of panicking.

use std::sync::{Arc, Mutex};

use super::GpuError;

/// The latest uncaptured error or device loss, shared with the device's callbacks so the
/// editor or CLI can show it. Cloning shares the slot.
#[derive(Debug, Clone, Default)]
pub struct ErrorSlot(Arc<Mutex<Option<GpuError>>>);

impl ErrorSlot {
    /// Records an error (the first one is kept until taken: later errors are usually
    /// consequences of it).
    pub fn record(&self, e: GpuError) {
        let mut slot = self
            .0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if slot.is_none() {
            log::error!("GPU: {e}");
            *slot = Some(e);
        }
    }

    /// Takes the recorded error, leaving the slot empty.
    #[must_use]
    pub fn take(&self) -> Option<GpuError> {
        self.0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .take()
    }

    /// Whether an error is waiting.
    #[must_use]
    pub fn is_set(&self) -> bool {
        self.0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .is_some()
    }
}

/// What the renderer may use on this device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Capabilities {
    /// 64-bit `atomicMin` on storage buffers (`SHADER_INT64_ATOMIC_MIN_MAX` + `SHADER_INT64`).
    pub int64_atomics: bool,
    /// Timestamp queries around passes (`TIMESTAMP_QUERY`).
    pub timestamps: bool,
}

impl Capabilities {
    /// From a device's enabled features.
    #[must_use]
    pub fn of(device: &wgpu::Device) -> Self {
        let f = device.features();
        Self {
            int64_atomics: f.contains(
                wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX,
            ),
            timestamps: f.contains(wgpu::Features::TIMESTAMP_QUERY),
        }
    }
}

/// A headless device with its adapter and error slot.
pub struct GpuContext {
    /// The adapter the device came from.
    pub adapter: wgpu::Adapter,
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Uncaptured errors and device loss land here.
    pub errors: ErrorSlot,
}

/// The optional features the renderer uses when the adapter has them.
#[must_use]
pub fn wanted_features() -> wgpu::Features {
    wgpu::Features::SHADER_INT64
        | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX
        | wgpu::Features::TIMESTAMP_QUERY
}

/// The limits to request: wgpu's defaults raised to what the adapter offers for the buffer
/// sizes, storage bindings and workgroup sizes the renderer relies on.
#[must_use]
pub fn wanted_limits(adapter: &wgpu::Adapter) -> wgpu::Limits {
    let a = adapter.limits();
    let base = wgpu::Limits::default().using_resolution(a.clone());
    wgpu::Limits {
        max_storage_buffer_binding_size: a.max_storage_buffer_binding_size,
        max_buffer_size: a.max_buffer_size,
        max_storage_buffers_per_shader_stage: a.max_storage_buffers_per_shader_stage,
        max_compute_workgroup_storage_size: a.max_compute_workgroup_storage_size,
        max_compute_invocations_per_workgroup: a.max_compute_invocations_per_workgroup,
        max_compute_workgroups_per_dimension: a.max_compute_workgroups_per_dimension,
        max_texture_dimension_2d: a.max_texture_dimension_2d,
        ..base
    }
}

impl GpuContext {
    /// Creates a headless device: Vulkan or GL backends, the adapter preferred by `power`
    /// (a software adapter such as lavapipe when it is the only one).
    ///
    /// # Errors
    /// [`GpuError::NoAdapter`] when no adapter is found, [`GpuError::RequestDevice`] when the
    /// device cannot be created.
    pub fn new_headless(power: wgpu::PowerPreference) -> Result<Self, GpuError> {
        Self::new_headless_with_binding_limit(power, None)
    }

    /// As [`GpuContext::new_headless`], with `max_storage_buffer_binding_size` requested at
    /// `binding_limit` bytes when that is below the adapter's (a lower limit is legal and makes
    /// wgpu validate every binding against it): how tests exercise scenes split across
    /// bindings without gigabytes of data.
    ///
    /// # Errors
    /// As [`GpuContext::new_headless`].
    pub fn new_headless_with_binding_limit(
        power: wgpu::PowerPreference,
        binding_limit: Option<u64>,
    ) -> Result<Self, GpuError> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if std::env::var_os("WGPU_BACKEND").is_none() {
            desc.backends = wgpu::Backends::VULKAN | wgpu::Backends::GL;
        }
        let instance = wgpu::Instance::new(desc);
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: power,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let mut limits = wanted_limits(&adapter);
        if let Some(l) = binding_limit {
            limits.max_storage_buffer_binding_size = limits.max_storage_buffer_binding_size.min(l);
        }
        let (device, queue) = request_device_with_limits(&adapter, limits)?;
        let errors = install_error_handlers(&device);
        Ok(Self {
            adapter,
            device,
            queue,
            errors,
        })
    }

    /// One line naming the adapter, driver and backend (for reports).
    #[must_use]
    pub fn describe(&self) -> String {
        let i = self.adapter.get_info();
        format!(
            "{} ({:?}, {:?}, driver {} {})",
            i.name, i.device_type, i.backend, i.driver, i.driver_info
        )
    }
}

/// Requests a device with [`wanted_limits`] and the subset of [`wanted_features`] the adapter
/// has.
///
/// # Errors
/// [`GpuError::RequestDevice`].
pub fn request_device(adapter: &wgpu::Adapter) -> Result<(wgpu::Device, wgpu::Queue), GpuError> {
    request_device_with_limits(adapter, wanted_limits(adapter))
}

fn request_device_with_limits(
    adapter: &wgpu::Adapter,
    limits: wgpu::Limits,
) -> Result<(wgpu::Device, wgpu::Queue), GpuError> {
    let features = adapter.features() & wanted_features();
    // 64-bit atomics are only usable with 64-bit integers in the shader.
    let features = if features
        .contains(wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX)
    {
        features
    } else {
        features - wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX
    };
    pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("thicket"),
        required_features: features,
        required_limits: limits,
        ..Default::default()
    }))
    .map_err(|e| GpuError::RequestDevice(e.to_string()))
}

/// Installs uncaptured-error and device-lost handlers that record into a new [`ErrorSlot`].
pub fn install_error_handlers(device: &wgpu::Device) -> ErrorSlot {
    let slot = ErrorSlot::default();
    let s = slot.clone();
    device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
        let err = match &e {
            wgpu::Error::OutOfMemory { .. } => GpuError::OutOfMemory(e.to_string()),
            _ => GpuError::Device(e.to_string()),
        };
        s.record(err);
    }));
    let s = slot.clone();
    device.set_device_lost_callback(move |reason, message| {
        // Dropping the device on purpose is not an error anyone needs to see.
        if reason != wgpu::DeviceLostReason::Destroyed {
            s.record(GpuError::DeviceLost(format!("{reason:?}: {message}")));
        }
    });
    slot
}
