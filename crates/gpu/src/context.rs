//! [`GpuContext`]: one wgpu device as quatcurve uses it, shared by the evaluator and forward
//! kinematics: the device and queue, the adapter, the limits chunks are planned by, whether
//! outputs map directly, the device-lost flag, and the calls every pass makes (error scopes,
//! dispatch grids, waiting, reading back).

use crate::error::{GpuError, MapError};
use std::sync::{Arc, Mutex};

/// A device and what quatcurve knows of it. Clones share the device (wgpu handles); a clone's
/// binding limit can be lowered on its own ([`GpuContext::with_binding_limit`]).
#[derive(Clone)]
pub struct GpuContext {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter_name: String,
    /// The driver and its version as the adapter reports them; empty when unknown.
    driver: String,
    /// The adapter rasterizes on the host's CPU (lavapipe, SwiftShader, WARP).
    software: bool,
    binding_limit: u64,
    max_groups_per_dim: u32,
    /// Outputs are mappable themselves (`MAPPABLE_PRIMARY_BUFFERS`): no staging copy.
    map_outputs: bool,
    lost: Arc<Mutex<Option<(wgpu::DeviceLostReason, String)>>>,
}

impl std::fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuContext")
            .field("adapter", &self.adapter_name)
            .field("software", &self.software)
            .field("binding_limit", &self.binding_limit)
            .finish_non_exhaustive()
    }
}

impl GpuContext {
    /// Picks the best adapter (high performance first; software adapters such as lavapipe
    /// count) and creates a device of its own, with every limit the adapter has.
    ///
    /// # Errors
    /// [`GpuError::NoAdapter`] when there is none, [`GpuError::Device`] when the device
    /// cannot be created.
    pub fn new() -> Result<Self, GpuError> {
        super::quietly(|| {
            pollster::block_on(async {
                let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
                let adapter = instance
                    .request_adapter(&wgpu::RequestAdapterOptions {
                        power_preference: wgpu::PowerPreference::HighPerformance,
                        ..wgpu::RequestAdapterOptions::default()
                    })
                    .await?;
                let info = adapter.get_info();
                // Where the GPU shares the host's memory (a CPU adapter such as lavapipe, or an
                // integrated GPU), outputs are mapped directly instead of copied to a staging
                // buffer first; on a discrete GPU that would make the kernel write over the bus.
                let unified = matches!(info.device_type, wgpu::DeviceType::Cpu | wgpu::DeviceType::IntegratedGpu);
                let mappable = wgpu::Features::MAPPABLE_PRIMARY_BUFFERS;
                let required_features =
                    if unified && adapter.features().contains(mappable) { mappable } else { wgpu::Features::empty() };
                let (device, queue) = adapter
                    .request_device(&wgpu::DeviceDescriptor {
                        label: Some("quatcurve"),
                        required_features,
                        required_limits: adapter.limits(),
                        ..wgpu::DeviceDescriptor::default()
                    })
                    .await?;
                // Errors outside our error scopes must not abort the process (wgpu's default).
                device.on_uncaptured_error(Arc::new(|e| eprintln!("quatcurve: uncaptured GPU error: {e}")));
                let name = format!("{} ({:?})", info.name, info.backend);
                Ok(Self {
                    software: info.device_type == wgpu::DeviceType::Cpu,
                    driver: format!("{} {}", info.driver, info.driver_info).trim().to_string(),
                    ..Self::with_device(device, queue, name)
                })
            })
        })
    }

    /// A context on an existing application's device and queue (its uncaptured-error handler
    /// is left alone: quatcurve reports through error scopes). If the device has
    /// `MAPPABLE_PRIMARY_BUFFERS` (meant for unified memory only), outputs are mapped directly.
    #[must_use]
    pub fn with_device(device: wgpu::Device, queue: wgpu::Queue, adapter_name: impl Into<String>) -> Self {
        let limits = device.limits();
        let lost = Arc::new(Mutex::new(None));
        let flag = lost.clone();
        device.set_device_lost_callback(move |reason, message| {
            *flag.lock().unwrap_or_else(|e| e.into_inner()) = Some((reason, message));
        });
        Self {
            map_outputs: device.features().contains(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS),
            binding_limit: limits.max_storage_buffer_binding_size.min(limits.max_buffer_size),
            max_groups_per_dim: limits.max_compute_workgroups_per_dimension,
            device,
            queue,
            adapter_name: adapter_name.into(),
            driver: String::new(),
            software: false,
            lost,
        }
    }

    /// The device.
    #[must_use]
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue passes are submitted to.
    #[must_use]
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The adapter's name, as the CLI reports it (`gpu: <name>`).
    #[must_use]
    pub fn adapter_name(&self) -> &str {
        &self.adapter_name
    }

    /// The driver and its version (`NVIDIA 550.54.15`, `llvmpipe Mesa 24.2.8`); empty for a
    /// device given to [`GpuContext::with_device`].
    #[must_use]
    pub fn driver(&self) -> &str {
        &self.driver
    }

    /// Whether the adapter is a software rasterizer running on the host's CPU (lavapipe).
    /// Unknown (false) for a device given to [`GpuContext::with_device`].
    #[must_use]
    pub fn is_software(&self) -> bool {
        self.software
    }

    /// The largest buffer binding used (bytes); work above it is split into chunks.
    #[must_use]
    pub fn binding_limit(&self) -> u64 {
        self.binding_limit
    }

    /// This context with a lower binding limit (to exercise chunking in tests).
    #[must_use]
    pub fn with_binding_limit(mut self, bytes: u64) -> Self {
        self.binding_limit = self.binding_limit.min(bytes);
        self
    }

    /// Whether outputs can be mapped for reading themselves, without a staging copy.
    #[must_use]
    pub fn map_outputs(&self) -> bool {
        self.map_outputs
    }

    /// The compute program `source` (parsed and validated as `module`) with one bind group,
    /// at `entry`, on this device; the layout comes from the shader's own bindings.
    pub(super) fn compile(
        &self,
        label: &str,
        module: &naga::Module,
        source: &str,
        entry: &str,
    ) -> Result<super::program::Compiled, GpuError> {
        self.compile_specialized(label, module, source, entry, &[])
    }

    /// [`Self::compile`] with the shader's override constants set to `constants`.
    pub(super) fn compile_specialized(
        &self,
        label: &str,
        module: &naga::Module,
        source: &str,
        entry: &str,
        constants: &[(&str, f64)],
    ) -> Result<super::program::Compiled, GpuError> {
        use super::program::{Compiled, Resources};
        use quatcurve_shader::entry_workgroup_size;
        let device = &self.device;
        let workgroup_size = entry_workgroup_size(module, entry)?;
        let scope = ErrorScope::push(device);
        let resources = Resources::of(module)?;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &resources.layout_entries(),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
            cache: None,
        });
        scope.pop()?;
        Ok(Compiled { pipeline, layout, resources, workgroup_size })
    }

    /// The usage of a buffer a kernel writes and the host reads back.
    pub(super) fn output_usage(&self) -> wgpu::BufferUsages {
        let readable = if self.map_outputs { wgpu::BufferUsages::MAP_READ } else { wgpu::BufferUsages::empty() };
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | readable
    }

    /// The 2D grid of `groups` workgroups on this device ([`super::layout::grid`]).
    ///
    /// # Errors
    /// [`GpuError::Job`] when even the 2D grid cannot hold them.
    pub(super) fn grid(&self, groups: u64) -> Result<[u32; 2], GpuError> {
        super::layout::grid(groups, self.max_groups_per_dim)
    }

    /// The most workgroups a dispatch has in one dimension.
    pub(super) fn max_groups_per_dim(&self) -> u32 {
        self.max_groups_per_dim
    }

    /// Waits for every submitted pass; the device-lost flag after.
    ///
    /// # Errors
    /// [`GpuError::Device`], [`GpuError::DeviceLost`].
    pub(super) fn wait(&self) -> Result<(), GpuError> {
        self.device.poll(wgpu::PollType::wait_indefinitely())?;
        self.check_lost()
    }

    /// [`GpuError::DeviceLost`] once the device was lost.
    pub(super) fn check_lost(&self) -> Result<(), GpuError> {
        match self.lost.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
            Some((reason, message)) => Err(GpuError::DeviceLost { reason: *reason, message: message.clone() }),
            None => Ok(()),
        }
    }

    /// Maps the first `bytes` of `output` (directly where it is mappable, else through a
    /// staging copy) and hands its floats to `consume`, which copies them into place.
    pub(super) fn read_back(
        &self,
        output: &wgpu::Buffer,
        bytes: u64,
        consume: impl FnOnce(&[f32]),
    ) -> Result<(), GpuError> {
        if bytes == 0 {
            return Ok(());
        }
        let scope = ErrorScope::push(&self.device);
        let staging = if output.usage().contains(wgpu::BufferUsages::MAP_READ) {
            output.clone()
        } else {
            let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("quatcurve readback"),
                size: bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut encoder = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("quatcurve readback") });
            encoder.copy_buffer_to_buffer(output, 0, &staging, 0, bytes);
            self.queue.submit([encoder.finish()]);
            staging
        };
        let (sender, receiver) = std::sync::mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, ..bytes, move |r| {
            let _ = sender.send(r);
        });
        self.wait()?;
        scope.pop()?;
        match receiver.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(GpuError::Map { during: "reading results back", error: e.into() }),
            Err(_) => return Err(GpuError::Map { during: "reading results back", error: MapError::NeverRan }),
        }
        let view = staging
            .get_mapped_range(..bytes)
            .map_err(|e| GpuError::Map { during: "reading results back", error: e.into() })?;
        consume(bytemuck::cast_slice::<u8, f32>(&view));
        drop(view);
        staging.unmap();
        Ok(())
    }
}

/// Validation and out-of-memory scopes around a group of device calls.
pub(super) struct ErrorScope {
    // Declared in popping order: an early return drops the fields in this order, and wgpu
    // wants scopes popped in reverse order of pushing.
    memory: wgpu::ErrorScopeGuard,
    validation: wgpu::ErrorScopeGuard,
}

impl ErrorScope {
    pub(super) fn push(device: &wgpu::Device) -> Self {
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        Self { validation, memory }
    }

    pub(super) fn pop(self) -> Result<(), GpuError> {
        // Scopes pop in reverse order of pushing.
        let memory = pollster::block_on(self.memory.pop());
        let validation = pollster::block_on(self.validation.pop());
        match memory.or(validation) {
            Some(e) => Err(GpuError::Device(e)),
            None => Ok(()),
        }
    }
}
