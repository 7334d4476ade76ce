//! Forward kinematics on the GPU for bake's model textures (`shaders/fk.wgsl`), the twin of
//! [`quatcurve_eval::skeleton::forward_kinematics`]: local rows `[frames, joints, 10]` in, 3x4 model rows
//! `[frames, joints, 12]` out. One dispatch per level of the hierarchy, all levels of a chunk
//! of frames in one pass; frames are split into chunks that fit a storage binding.

use super::context::{ErrorScope, GpuContext};
use super::program::Compiled;
use crate::error::{GpuError, JobError};
use quatcurve_eval::output::{LOCAL_CHANNELS, MATRIX_CHANNELS};
use quatcurve_shader as shader;
use wgpu::util::DeviceExt;

/// Host twin of WGSL's `FkLevel` (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FkLevel {
    /// First entry of this level in the joints-by-level list.
    pub first: u32,
    /// Joints at this level.
    pub count: u32,
    /// Frames in the chunk.
    pub frames: u32,
    /// Joints per frame.
    pub joints: u32,
    /// Invocations per row of the dispatch grid.
    pub row: u32,
    /// Padding to 32 bytes.
    pub pad: [u32; 3],
}

impl FkLevel {
    /// The level whose joints are entries `start..end` of the joints-by-level list, over
    /// `frames` frames of `joints` joints, `row` invocations per row of the grid.
    #[must_use]
    pub fn new([start, end]: [u32; 2], frames: usize, joints: usize, row: u32) -> Self {
        Self { first: start, count: end - start, frames: frames as u32, joints: joints as u32, row, pad: [0; 3] }
    }
}

/// Joint indices grouped by depth (roots first) and where each depth starts, from `parents`
/// and an order with every parent before its children.
///
/// # Errors
/// [`GpuError::Job`] when `order` puts a joint before its parent or misses one.
pub fn levels(parents: &[Option<usize>], order: &[usize]) -> Result<(Vec<u32>, Vec<u32>), GpuError> {
    let n = parents.len();
    let mut depth = vec![usize::MAX; n];
    for &j in order {
        depth[j] = match parents.get(j).copied().flatten() {
            None => 0,
            Some(p) if p < n && depth[p] != usize::MAX => depth[p] + 1,
            Some(parent) => return Err(JobError::ParentAfterChild { joint: j, parent }.into()),
        };
    }
    if depth.contains(&usize::MAX) {
        return Err(JobError::OrderIncomplete.into());
    }
    let deepest = depth.iter().copied().max().unwrap_or(0);
    let mut joints = Vec::with_capacity(n);
    let mut starts = Vec::with_capacity(deepest + 2);
    for level in 0..=deepest {
        starts.push(joints.len() as u32);
        joints.extend((0..n).filter(|&j| depth[j] == level).map(|j| j as u32));
    }
    starts.push(joints.len() as u32);
    Ok((joints, starts))
}

/// The forward-kinematics program on one device.
pub struct ForwardKinematics {
    context: GpuContext,
    program: Compiled,
}

impl std::fmt::Debug for ForwardKinematics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ForwardKinematics").field("context", &self.context).finish_non_exhaustive()
    }
}

impl ForwardKinematics {
    /// The program compiled on `context`'s device.
    ///
    /// # Errors
    /// [`GpuError::Shader`] or [`GpuError::Device`] when it cannot be built.
    pub fn new(context: &GpuContext) -> Result<Self, GpuError> {
        let (module, _) = shader::fk_module()?;
        let program = context.compile("quatcurve fk", &module, &shader::fk_source(), shader::FK_ENTRY_POINT)?;
        Ok(Self { context: context.clone(), program })
    }

    /// Model matrices of every joint and frame from local rows (see the module docs):
    /// `parents[j]` is joint `j`'s parent, `order` lists parents before children
    /// (`Animation::parents_first` in `quatcurve::anim`). Computed in f32 (the CPU twin composes
    /// in f64).
    ///
    /// # Errors
    /// [`GpuError::Job`] for mismatched inputs or a frame larger than a binding; device errors.
    pub fn run(&self, parents: &[Option<usize>], order: &[usize], local: &[f32]) -> Result<Vec<f32>, GpuError> {
        let joints = parents.len();
        if joints == 0 || local.len() % (joints * LOCAL_CHANNELS) != 0 {
            let whole = format!("whole frames of {joints} joints");
            return Err(JobError::NotWhole { what: "local floats", len: local.len(), whole }.into());
        }
        let frames = local.len() / (joints * LOCAL_CHANNELS);
        let frame_bytes = (joints * MATRIX_CHANNELS * 4) as u64;
        if frame_bytes > self.context.binding_limit() {
            let what = format!("one frame of {joints} joints");
            return Err(JobError::OverBinding { what, bytes: frame_bytes, limit: self.context.binding_limit() }.into());
        }
        let (by_level, starts) = levels(parents, order)?;
        let parents: Vec<i32> = parents.iter().map(|p| p.map_or(-1, |p| p as i32)).collect();
        let scope = ErrorScope::push(self.context.device());
        let init = |label: &str, contents: &[u8], usage: wgpu::BufferUsages| {
            self.context.device().create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let parents_buffer = init("quatcurve fk parents", bytemuck::cast_slice(&parents), wgpu::BufferUsages::STORAGE);
        let levels_buffer = init("quatcurve fk levels", bytemuck::cast_slice(&by_level), wgpu::BufferUsages::STORAGE);
        scope.pop()?;
        let mut model = vec![0.0f32; frames * joints * MATRIX_CHANNELS];
        let per_chunk = ((self.context.binding_limit() / frame_bytes) as usize).clamp(1, frames);
        for first in (0..frames).step_by(per_chunk) {
            let count = per_chunk.min(frames - first);
            let rows = &local[first * joints * LOCAL_CHANNELS..(first + count) * joints * LOCAL_CHANNELS];
            let out = &mut model[first * joints * MATRIX_CHANNELS..(first + count) * joints * MATRIX_CHANNELS];
            self.chunk(&parents_buffer, &levels_buffer, &starts, joints, rows, out)?;
        }
        Ok(model)
    }

    /// One chunk of whole frames: upload, one dispatch per level, read back into `out`.
    #[allow(clippy::too_many_arguments)]
    fn chunk(
        &self,
        parents: &wgpu::Buffer,
        levels: &wgpu::Buffer,
        starts: &[u32],
        joints: usize,
        rows: &[f32],
        out: &mut [f32],
    ) -> Result<(), GpuError> {
        let fk = &self.program;
        let frames = rows.len() / (joints * LOCAL_CHANNELS);
        let scope = ErrorScope::push(self.context.device());
        let local = self.context.device().create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("quatcurve fk local"),
            contents: bytemuck::cast_slice(rows),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let bytes = (out.len() * 4) as u64;
        let model = self.context.device().create_buffer(&wgpu::BufferDescriptor {
            label: Some("quatcurve fk model"),
            size: bytes.max(16),
            usage: self.context.output_usage(),
            mapped_at_creation: false,
        });
        let mut encoder = self
            .context
            .device()
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("quatcurve fk") });
        // Per level: its uniform, bind group and grid (made before the pass borrows them).
        let dispatches: Vec<(wgpu::BindGroup, [u32; 2])> = starts
            .windows(2)
            .map(|w| {
                let invocations = u64::from(w[1] - w[0]) * frames as u64;
                let [x, y] = self.context.grid(invocations.div_ceil(u64::from(fk.workgroup_size)))?;
                let level = FkLevel::new([w[0], w[1]], frames, joints, x * fk.workgroup_size);
                let uniform = self.context.device().create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("quatcurve fk level"),
                    contents: bytemuck::bytes_of(&level),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
                let buffers = [
                    ("fk_local", &local),
                    ("fk_parents", parents),
                    ("fk_level_joints", levels),
                    ("fk_model", &model),
                    ("fk_level", &uniform),
                ];
                let group = fk.bind_group(self.context.device(), "quatcurve fk", &buffers)?;
                Ok((group, [x, y]))
            })
            .collect::<Result<_, GpuError>>()?;
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("quatcurve fk"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&fk.pipeline);
            for (group, [x, y]) in &dispatches {
                pass.set_bind_group(0, group, &[]);
                pass.dispatch_workgroups(*x, *y, 1);
            }
        }
        self.context.queue().submit([encoder.finish()]);
        scope.pop()?;
        self.context.read_back(&model, bytes, |floats| out.copy_from_slice(&floats[..out.len()]))
    }
}
