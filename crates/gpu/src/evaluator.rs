//! [`GpuDevice`]: the evaluation program made once on a [`GpuContext`], then any number of
//! batch evaluations (chunks planned, packed straight into their buffers, dispatched, read
//! back and scattered into place).

use super::context::{ErrorScope, GpuContext};
use super::fk::ForwardKinematics;
use super::layout::{self, ChunkPlan, ChunkTargets, GpuTrack, Params, PipelineKey};
use super::program;
use crate::error::{GpuError, JobError, MapError};
use quatcurve_eval::job::EvalJob;
use quatcurve_eval::output::{FloatOutput, Layout};
use quatcurve_eval::sampling::SampleTimes;
use quatcurve_shader as shader;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use wgpu::util::DeviceExt;

/// Largest binding of one chunk [`GpuDevice::evaluate`] streams on a hardware GPU (64 MiB):
/// small enough that the packed chunk stays a fraction of a large batch, large enough that a
/// dispatch's fixed cost is amortized.
pub const STREAM_CHUNK_BYTES: u64 = 64 << 20;

/// The same on a software adapter (8 MiB), whose device memory is host memory and whose
/// kernel runs on the host's cores. Measured on lavapipe, `bench --tracks 1000000 --samples
/// 10`: 64 -> 16 MiB took peak RSS from 3.03 to 2.74 GB and end to end from 2.4 to 3.3 M
/// samples/s, the 10,000 x 1,000 batch unchanged; since chunks are packed straight into their
/// buffers, 16 -> 8 MiB saves 45 MB more at the same speed.
pub const SOFTWARE_STREAM_CHUNK_BYTES: u64 = 8 << 20;

/// Host result of the GPU path (the float arrays every fast path returns).
pub type GpuOutput = FloatOutput;

/// A batch uploaded to the device by [`GpuDevice::prepare`].
pub struct PreparedBatch {
    plans: Vec<ChunkPlan>,
    chunks: Vec<PreparedChunk>,
    channels: usize,
    layout: Layout,
    times: SampleTimes,
}

impl PreparedBatch {
    /// Number of chunks (device bindings) the batch was split into.
    #[must_use]
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }
}

/// One chunk on the device, ready to dispatch (wgpu handles: clones share the objects).
#[derive(Clone)]
struct PreparedChunk {
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    /// The packed points, coefficients, knots and sample times.
    inputs: [wgpu::Buffer; 4],
    output: wgpu::Buffer,
    output_bytes: u64,
    groups: [u32; 2],
}

/// The evaluation program on one device: the WGSL module, its layouts, the pipelines
/// compiled so far (one per [`PipelineKey`], shared by every evaluator on the device) and the
/// polynomial table. Clones share everything.
#[derive(Clone)]
struct Program {
    module: wgpu::ShaderModule,
    bind_group_layout: wgpu::BindGroupLayout,
    /// The program's buffers by name (binding numbers read from the shader).
    resources: program::Resources,
    pipeline_layout: wgpu::PipelineLayout,
    pipelines: Arc<Mutex<HashMap<PipelineKey, wgpu::ComputePipeline>>>,
    workgroup_size: u32,
    /// [`layout::polynomial_table`], the same for every batch.
    polynomials: wgpu::Buffer,
}

impl Program {
    fn new(device: &wgpu::Device) -> Result<Self, GpuError> {
        let (naga_module, _) = shader::module()?;
        let workgroup_size = shader::workgroup_size(&naga_module)?;
        let scope = ErrorScope::push(device);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("quatcurve eval"),
            source: wgpu::ShaderSource::Wgsl(shader::source().into()),
        });
        let resources = program::Resources::of(&naga_module)?;
        let bind_group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("quatcurve eval"),
            entries: &resources.layout_entries(),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("quatcurve eval"),
            bind_group_layouts: &[Some(&bind_group_layout)],
            immediate_size: 0,
        });
        let table = layout::polynomial_table();
        let polynomials = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("quatcurve polynomials"),
            contents: bytemuck::cast_slice(&table),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        scope.pop()?;
        Ok(Self {
            module,
            bind_group_layout,
            resources,
            pipeline_layout,
            pipelines: Arc::default(),
            workgroup_size,
            polynomials,
        })
    }
}

/// The GPU device as quatcurve uses it: packed batches evaluated with the WGSL kernel, and
/// forward kinematics, mesh skinning and crowd playback on the same wgpu device
/// ([`GpuContext`]). Create once, reuse for every batch: it holds the context, its programs
/// and the buffers it reuses.
pub struct GpuDevice {
    context: GpuContext,
    program: Program,
    /// Forward kinematics on the same device, built on first use.
    fk: std::sync::OnceLock<ForwardKinematics>,
    /// The mesh-skinning program, built on first use (vertex textures).
    skinning: std::sync::OnceLock<super::MeshSkinning>,
    playback: std::sync::OnceLock<super::PosePalettes>,
    /// The last output buffer `evaluate` used, kept for the next chunk or call: a fresh
    /// buffer's memory is faulted in while the kernel writes it (on lavapipe that cost 15-20%
    /// of the kernel's time).
    spare_output: Mutex<Option<wgpu::Buffer>>,
    /// The last input buffers `evaluate` packed, where they are mappable
    /// ([`GpuContext::map_outputs`]): mapped again for the next chunk instead of created
    /// mapped, which wgpu zero-fills on one thread, page fault by page fault, before the
    /// packing overwrites every byte.
    spare_inputs: Mutex<Option<[wgpu::Buffer; 4]>>,
}

impl std::fmt::Debug for GpuDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuDevice").field("context", &self.context).finish_non_exhaustive()
    }
}

impl GpuDevice {
    /// An evaluator on a device of its own ([`GpuContext::new`]: the best adapter, high
    /// performance first; software adapters such as lavapipe count).
    ///
    /// # Errors
    /// [`GpuError::NoAdapter`] when there is none, [`GpuError::Device`] when the device
    /// cannot be created.
    pub fn new() -> Result<Self, GpuError> {
        Self::on(GpuContext::new()?)
    }

    /// Embeds in an existing wgpu application: uses its device and queue
    /// ([`GpuContext::with_device`]).
    ///
    /// # Errors
    /// [`GpuError::Device`] when the shader or pipelines cannot be created on that device.
    pub fn with_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        adapter_name: impl Into<String>,
    ) -> Result<Self, GpuError> {
        Self::on(GpuContext::with_device(device, queue, adapter_name))
    }

    /// An evaluator on `context`'s device.
    ///
    /// # Errors
    /// [`GpuError::Device`] when the shader or pipelines cannot be created on that device.
    pub fn on(context: GpuContext) -> Result<Self, GpuError> {
        let program = Program::new(context.device())?;
        Ok(Self {
            context,
            program,
            fk: std::sync::OnceLock::new(),
            skinning: std::sync::OnceLock::new(),
            playback: std::sync::OnceLock::new(),
            spare_output: Mutex::new(None),
            spare_inputs: Mutex::new(None),
        })
    }

    /// The device this evaluator runs on.
    #[must_use]
    pub fn context(&self) -> &GpuContext {
        &self.context
    }

    /// The adapter's name, as the CLI reports it (`gpu: <name>`).
    #[must_use]
    pub fn adapter_name(&self) -> &str {
        self.context.adapter_name()
    }

    /// Whether the adapter is a software rasterizer running on the host's CPU (lavapipe):
    /// `--device auto` then prefers the fast CPU path, which is many times faster on the same
    /// cores. Unknown (false) for a device given to [`GpuDevice::with_device`].
    #[must_use]
    pub fn is_software(&self) -> bool {
        self.context.is_software()
    }

    /// The device, for creating buffers that [`GpuDevice::evaluate_into`] fills.
    #[must_use]
    pub fn device(&self) -> &wgpu::Device {
        self.context.device()
    }

    /// The queue the evaluator submits to.
    #[must_use]
    pub fn queue(&self) -> &wgpu::Queue {
        self.context.queue()
    }

    /// The largest buffer binding used (bytes); batches above it are split into chunks.
    #[must_use]
    pub fn binding_limit(&self) -> u64 {
        self.context.binding_limit()
    }

    /// Another evaluator on this one's device: the device, queue, program and compiled
    /// pipelines are shared (no second device), the reused buffers and the binding limit are
    /// its own. For a host that wants evaluators with different limits, and for tests that run
    /// beside each other on one device.
    #[must_use]
    pub fn share_device(&self) -> Self {
        Self {
            context: self.context.clone(),
            program: self.program.clone(),
            fk: std::sync::OnceLock::new(),
            skinning: std::sync::OnceLock::new(),
            playback: std::sync::OnceLock::new(),
            spare_output: Mutex::new(None),
            spare_inputs: Mutex::new(None),
        }
    }

    /// Model matrices by forward kinematics on this evaluator's device
    /// ([`ForwardKinematics::run`]; its program is built on first use).
    ///
    /// # Errors
    /// As [`ForwardKinematics::run`], and [`GpuError::Device`] when the program cannot be built.
    pub fn forward_kinematics(
        &self,
        parents: &[Option<usize>],
        order: &[usize],
        local: &[f32],
    ) -> Result<Vec<f32>, GpuError> {
        built(&self.fk, || ForwardKinematics::new(&self.context))?.run(parents, order, local)
    }

    /// Crowd playback's palettes on this evaluator's device ([`super::PosePalettes::run`]:
    /// blend, forward kinematics and palettes in one submission; built on first use).
    ///
    /// # Errors
    /// As [`super::PosePalettes::run`], and [`GpuError::Device`] when the program cannot be
    /// built.
    pub fn play_palettes(
        &self,
        parents: &[Option<usize>],
        order: &[usize],
        poses: &[f32],
        weights: &[f32],
        skin: Option<quatcurve_eval::skeleton::PaletteSkin<'_>>,
    ) -> Result<Vec<f32>, GpuError> {
        built(&self.playback, || super::PosePalettes::new(&self.context))?.run(parents, order, poses, weights, skin)
    }

    /// `curves` uploaded for playback on this evaluator's device ([`super::CurvePalettes`]).
    ///
    /// # Errors
    /// As [`super::CurvePalettes::new`].
    pub fn curve_palettes(
        &self,
        curves: &quatcurve_eval::skeleton::PoseCurves<'_>,
    ) -> Result<super::CurvePalettes, GpuError> {
        super::CurvePalettes::new(&self.context, curves)
    }

    /// A mesh primitive skinned at every frame of `matrices` on this evaluator's device
    /// ([`super::MeshSkinning::run`]; its program is built on first use).
    ///
    /// # Errors
    /// As [`super::MeshSkinning::run`], and [`GpuError::Device`] when the program cannot be built.
    pub fn skin_mesh(
        &self,
        mesh: &super::skinning::BindMesh,
        joints: usize,
        matrices: &[f32],
    ) -> Result<Vec<f32>, GpuError> {
        built(&self.skinning, || super::MeshSkinning::new(&self.context))?.run(mesh, joints, matrices)
    }

    /// Largest binding of one chunk [`GpuDevice::evaluate`] and [`GpuDevice::prepare`]
    /// stream: [`STREAM_CHUNK_BYTES`], or [`SOFTWARE_STREAM_CHUNK_BYTES`] on a software adapter.
    #[must_use]
    pub fn stream_chunk_bytes(&self) -> u64 {
        if self.context.is_software() {
            SOFTWARE_STREAM_CHUNK_BYTES
        } else {
            STREAM_CHUNK_BYTES
        }
    }

    /// Lowers the binding limit used for chunking, e.g. to exercise chunking in tests.
    #[must_use]
    pub fn with_binding_limit(mut self, bytes: u64) -> Self {
        self.context = self.context.with_binding_limit(bytes);
        self
    }

    /// Evaluates every track at its sample times and reads the result back. Chunks of at most
    /// [`STREAM_CHUNK_BYTES`] per binding are packed, uploaded, run and read one at a time, so
    /// host and device memory hold one chunk beside the batch and the output; the output
    /// buffer is kept for reuse by the next chunk and the next call
    /// ([`GpuDevice::release_buffers`] frees it).
    ///
    /// # Errors
    /// [`GpuError::Pack`] for a batch the kernel cannot take, [`GpuError::Job`] for
    /// mismatched inputs, device errors as [`GpuError::Device`] or [`GpuError::DeviceLost`].
    pub fn evaluate(&self, job: &EvalJob<'_>) -> Result<GpuOutput, GpuError> {
        let EvalJob { times, options, .. } = *job;
        let channels = options.row().channels();
        let FloatOutput { mut data, .. } = FloatOutput::zeroed(times.total(), channels);
        for plan in &self.plan(job, channels, self.context.binding_limit().min(self.stream_chunk_bytes()))? {
            let prepared = self.upload(plan, job, channels, None)?;
            self.submit(&prepared)?;
            // The readback copy is queued behind the dispatch: one wait covers both.
            self.context.read_back(&prepared.output, prepared.output_bytes, |local| {
                scatter(local, plan, times, options.layout, channels, &mut data)
            })?;
            *self.spare_output.lock().unwrap_or_else(|e| e.into_inner()) = Some(prepared.output);
            if self.context.map_outputs() {
                *self.spare_inputs.lock().unwrap_or_else(|e| e.into_inner()) = Some(prepared.inputs);
            }
        }
        Ok(GpuOutput { channels, data })
    }

    /// Frees the buffers kept for reuse by [`GpuDevice::evaluate`].
    pub fn release_buffers(&self) {
        self.spare_output.lock().unwrap_or_else(|e| e.into_inner()).take();
        self.spare_inputs.lock().unwrap_or_else(|e| e.into_inner()).take();
    }

    /// Uploads a batch once for repeated dispatches (benchmarks, or re-evaluation after the
    /// output was consumed). Holds every chunk on the device.
    ///
    /// # Errors
    /// As [`GpuDevice::evaluate`].
    pub fn prepare(&self, job: &EvalJob<'_>) -> Result<PreparedBatch, GpuError> {
        let EvalJob { times, options, .. } = *job;
        let channels = options.row().channels();
        // The chunks `evaluate` streams, so a dispatch-only figure times the same dispatches.
        let plans = self.plan(job, channels, self.context.binding_limit().min(self.stream_chunk_bytes()))?;
        let chunks = plans.iter().map(|plan| self.upload(plan, job, channels, None)).collect::<Result<_, _>>()?;
        Ok(PreparedBatch { plans, chunks, channels, layout: options.layout, times: times.clone() })
    }

    /// Runs a prepared batch's kernels and waits for them (no transfers).
    ///
    /// # Errors
    /// Device errors.
    pub fn dispatch(&self, prepared: &PreparedBatch) -> Result<(), GpuError> {
        for chunk in &prepared.chunks {
            self.submit(chunk)?;
        }
        self.context.wait()
    }

    /// Reads a prepared batch's outputs back, in the requested layout.
    ///
    /// # Errors
    /// Device errors.
    pub fn read(&self, prepared: &PreparedBatch) -> Result<GpuOutput, GpuError> {
        let channels = prepared.channels;
        let FloatOutput { mut data, .. } = FloatOutput::zeroed(prepared.times.total(), channels);
        for (plan, chunk) in prepared.plans.iter().zip(&prepared.chunks) {
            self.context.read_back(&chunk.output, chunk.output_bytes, |local| {
                scatter(local, plan, &prepared.times, prepared.layout, channels, &mut data)
            })?;
        }
        Ok(GpuOutput { channels, data })
    }

    /// Evaluates into a caller's buffer (usage `STORAGE`) without reading back, for engines
    /// that consume the samples on the GPU. The buffer receives `samples x channels` f32 in
    /// the requested layout, starting at offset 0.
    ///
    /// # Errors
    /// As [`GpuDevice::evaluate`], and [`GpuError::Job`] when the buffer is too small or
    /// the batch needs more than one binding (evaluate it in parts, or use `evaluate`).
    pub fn evaluate_into(&self, job: &EvalJob<'_>, target: &wgpu::Buffer) -> Result<(), GpuError> {
        let EvalJob { times, options, .. } = *job;
        let channels = options.row().channels();
        let needed = (times.total() * channels * 4) as u64;
        if target.size() < needed {
            return Err(JobError::TargetTooSmall { has: target.size(), needs: needed }.into());
        }
        let chunks = self.plan(job, channels, self.context.binding_limit())?;
        if chunks.len() != 1 {
            let (bindings, limit) = (chunks.len(), self.context.binding_limit());
            return Err(
                JobError::Bindings { what: "the batch's tracks", bindings, limit, pass: "evaluate_into" }.into()
            );
        }
        let prepared = self.upload(&chunks[0], job, channels, Some(target))?;
        self.submit(&prepared)?;
        self.context.wait()
    }

    /// Validates the job and plans its chunks, every binding within `limit` bytes.
    fn plan(&self, job: &EvalJob<'_>, channels: usize, limit: u64) -> Result<Vec<ChunkPlan>, GpuError> {
        job.validate()?;
        layout::plan_chunks(job.batch, job.times, channels, limit).map_err(GpuError::Pack)
    }

    /// Runs the write-only roofline kernel over a prepared batch's chunks and waits: the same
    /// dispatches and output bytes as [`GpuDevice::dispatch`], no math. Its rate is the
    /// device's own ceiling for this output (`bench`'s `roofline_samples_per_s`).
    ///
    /// # Errors
    /// Device errors.
    pub fn roofline(&self, prepared: &PreparedBatch) -> Result<(), GpuError> {
        let scope = ErrorScope::push(self.context.device());
        let pipeline = self.context.device().create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("quatcurve roofline"),
            layout: Some(&self.program.pipeline_layout),
            module: &self.program.module,
            entry_point: Some(shader::ROOFLINE_ENTRY_POINT),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            cache: None,
        });
        scope.pop()?;
        for chunk in &prepared.chunks {
            self.submit(&PreparedChunk { pipeline: pipeline.clone(), ..chunk.clone() })?;
        }
        self.context.wait()
    }

    fn pipeline(&self, key: PipelineKey) -> Result<wgpu::ComputePipeline, GpuError> {
        let mut cache = self.program.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = cache.get(&key) {
            return Ok(p.clone());
        }
        let scope = ErrorScope::push(self.context.device());
        let constants = key.constants();
        let pipeline = self.context.device().create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("quatcurve eval"),
            layout: Some(&self.program.pipeline_layout),
            module: &self.program.module,
            entry_point: Some(shader::ENTRY_POINT),
            compilation_options: wgpu::PipelineCompilationOptions { constants: &constants, ..Default::default() },
            cache: None,
        });
        scope.pop()?;
        cache.insert(key, pipeline.clone());
        Ok(pipeline)
    }

    /// Creates a chunk's buffers, packs its tracks straight into them ([`layout::pack`]), and
    /// makes its bind group and pipeline; output into `target` when given.
    fn upload(
        &self,
        plan: &ChunkPlan,
        job: &EvalJob<'_>,
        channels: usize,
        target: Option<&wgpu::Buffer>,
    ) -> Result<PreparedChunk, GpuError> {
        self.context.check_lost()?;
        let options = &job.options;
        let [groups_x, groups_y] =
            self.context.grid((plan.samples as u64).div_ceil(u64::from(self.program.workgroup_size)))?;
        let scope = ErrorScope::push(self.context.device());
        // Mapped at creation and written in place; where buffers the kernel reads can be
        // mapped themselves (`MAPPABLE_PRIMARY_BUFFERS`, unified memory), without a staging copy.
        let storage = wgpu::BufferUsages::STORAGE;
        let writable = storage
            | if self.context.map_outputs() { wgpu::BufferUsages::MAP_WRITE } else { wgpu::BufferUsages::empty() };
        // Bindings may not be empty.
        let bytes = plan.binding_bytes(channels);
        let sizes = [bytes[1], bytes[2], bytes[3], bytes[4]].map(|b| b.max(16));
        let packed = match self.reuse_inputs(&sizes)? {
            Some(buffers) => buffers,
            None => {
                let labels = ["points", "coefs", "knots", "times"];
                std::array::from_fn(|i| {
                    self.context.device().create_buffer(&wgpu::BufferDescriptor {
                        label: Some(labels[i]),
                        size: sizes[i],
                        usage: writable,
                        mapped_at_creation: true,
                    })
                })
            }
        };
        let tracks = {
            let [p, c, k, t] = std::array::from_fn(|i| {
                packed[i]
                    .get_mapped_range_mut(..sizes[i])
                    .map_err(|e| GpuError::Map { during: "writing the packed batch", error: e.into() })
            });
            let (mut p, mut c, mut k, mut t) = (p?, c?, k?, t?);
            layout::pack(
                plan,
                job.batch,
                job.times,
                ChunkTargets { points: p.slice(..), coefs: c.slice(..), knots: k.slice(..), times: t.slice(..) },
            )
        };
        packed.iter().for_each(wgpu::Buffer::unmap);
        let pipeline = self.pipeline(PipelineKey::for_chunk(&tracks, options))?;
        let params = Params {
            sample_count: plan.samples as u32,
            track_count: tracks.len() as u32,
            channels: channels as u32,
            frame_major: u32::from(options.layout == Layout::Frame),
            groups_x,
            ..Params::default()
        };
        let init = |label: &str, contents: &[u8], usage: wgpu::BufferUsages| {
            // Bindings may not be empty: pad to 16 bytes (a copy only for tiny contents).
            let padded;
            let contents = if contents.len() >= 16 {
                contents
            } else {
                padded = [contents, &[0u8; 16][contents.len()..]].concat();
                &padded
            };
            self.context.device().create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let [points, coefs, knots, times] = packed.clone();
        let inputs = [
            init("params", bytemuck::bytes_of(&params), wgpu::BufferUsages::UNIFORM),
            init("tracks", bytemuck::cast_slice::<GpuTrack, u8>(&tracks), storage),
            points,
            coefs,
            knots,
            times,
        ];
        let output_bytes = bytes[5];
        let spare = if target.is_none() {
            self.spare_output.lock().unwrap_or_else(|e| e.into_inner()).take().filter(|b| b.size() >= output_bytes)
        } else {
            None
        };
        let output = match (target, spare) {
            (Some(buffer), _) => buffer.clone(),
            (None, Some(buffer)) => buffer,
            (None, None) => self.context.device().create_buffer(&wgpu::BufferDescriptor {
                label: Some("quatcurve output"),
                size: output_bytes.max(16),
                usage: self.context.output_usage(),
                mapped_at_creation: false,
            }),
        };
        // Bound by the shader's variable names, which are also the buffers' labels.
        let names = ["params", "tracks", "points", "coefs", "knots", "times"];
        let buffers = names.iter().zip(&inputs).chain([(&"out", &output), (&"poly", &self.program.polynomials)]);
        let entries = buffers
            .map(|(name, buffer)| {
                Ok(wgpu::BindGroupEntry {
                    binding: self.program.resources.binding(name)?,
                    resource: buffer.as_entire_binding(),
                })
            })
            .collect::<Result<Vec<_>, GpuError>>()?;
        let bind_group = self.context.device().create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("quatcurve eval"),
            layout: &self.program.bind_group_layout,
            entries: &entries,
        });
        scope.pop()?;
        Ok(PreparedChunk { pipeline, bind_group, inputs: packed, output, output_bytes, groups: [groups_x, groups_y] })
    }

    /// The input buffers the last chunk of [`GpuDevice::evaluate`] packed, mapped for
    /// writing again, when it kept them and each holds `sizes` bytes; else `None`.
    fn reuse_inputs(&self, sizes: &[u64; 4]) -> Result<Option<[wgpu::Buffer; 4]>, GpuError> {
        let spare = self.spare_inputs.lock().unwrap_or_else(|e| e.into_inner()).take();
        let Some(buffers) = spare.filter(|buffers| buffers.iter().zip(sizes).all(|(b, &size)| b.size() >= size)) else {
            return Ok(None);
        };
        let (sender, receiver) = std::sync::mpsc::channel();
        for (buffer, &size) in buffers.iter().zip(sizes) {
            let sender = sender.clone();
            buffer.map_async(wgpu::MapMode::Write, ..size, move |r| {
                let _ = sender.send(r);
            });
        }
        drop(sender);
        self.context.wait()?;
        // Another thread's poll may run the callbacks: wait for each (a callback dropped
        // unrun drops its sender, which ends the wait).
        for _ in &buffers {
            match receiver.recv() {
                Ok(Ok(())) => {}
                Ok(Err(e)) => return Err(GpuError::Map { during: "mapping the input buffers", error: e.into() }),
                Err(_) => return Err(GpuError::Map { during: "mapping the input buffers", error: MapError::NeverRan }),
            }
        }
        Ok(Some(buffers))
    }

    /// Records and submits one chunk's dispatch.
    fn submit(&self, chunk: &PreparedChunk) -> Result<(), GpuError> {
        let scope = ErrorScope::push(self.context.device());
        let mut encoder = self
            .context
            .device()
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("quatcurve eval") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("quatcurve eval"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&chunk.pipeline);
            pass.set_bind_group(0, &chunk.bind_group, &[]);
            pass.dispatch_workgroups(chunk.groups[0], chunk.groups[1], 1);
        }
        self.context.queue().submit([encoder.finish()]);
        scope.pop()
    }
}

/// Copies a chunk's local output into its place in the whole output.
fn scatter(local: &[f32], chunk: &ChunkPlan, times: &SampleTimes, layout: Layout, channels: usize, data: &mut [f32]) {
    match layout {
        Layout::Track => {
            // In parallel blocks: one thread alone copies a few GB/s, a third of the kernel's
            // time for a large output on lavapipe.
            use rayon::prelude::*;
            const COPY_BLOCK: usize = 1 << 20;
            let start = (times.offsets()[chunk.first_track] + chunk.sample_base) * channels;
            let (to, from) = (&mut data[start..start + chunk.samples * channels], &local[..chunk.samples * channels]);
            to.par_chunks_mut(COPY_BLOCK)
                .zip(from.par_chunks(COPY_BLOCK))
                .for_each(|(to, from)| to.copy_from_slice(from));
        }
        Layout::Frame => {
            // Local rows are [frame][chunk track]; global rows are [frame][track].
            let n = chunk.tracks;
            let frames = chunk.samples.checked_div(n).unwrap_or(0);
            for j in 0..frames {
                let src = j * n * channels;
                let dst = layout.slot(times, chunk.first_track, chunk.sample_base + j) * channels;
                data[dst..dst + n * channels].copy_from_slice(&local[src..src + n * channels]);
            }
        }
    }
}

/// The program in `cell`, built by `build` on first use (a failed build is not kept, so the
/// next call tries again).
fn built<T>(cell: &std::sync::OnceLock<T>, build: impl FnOnce() -> Result<T, GpuError>) -> Result<&T, GpuError> {
    match cell.get() {
        Some(program) => Ok(program),
        None => {
            let program = build()?;
            Ok(cell.get_or_init(|| program))
        }
    }
}
