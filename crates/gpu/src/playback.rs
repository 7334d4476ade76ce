//! Crowd playback's blend, forward kinematics and skin palettes in one submission
//! (`shaders/play.wgsl` around `shaders/fk.wgsl`), the twin of
//! [`quatcurve_eval::skeleton::blend_poses`], [`quatcurve_eval::skeleton::forward_kinematics`]
//! and [`quatcurve_eval::skeleton::palettes`]: two local poses per instance in, one palette per
//! instance out.

use super::context::{ErrorScope, GpuContext};
use super::fk::{levels, FkLevel};
use super::program::Compiled;
use super::GpuError;
use quatcurve_eval::output::{LOCAL_CHANNELS, MATRIX_CHANNELS};
use quatcurve_eval::skeleton::PaletteSkin;
use quatcurve_shader as shader;
use wgpu::util::DeviceExt;

/// Host twin of WGSL's `PlayParams` (16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PlayParams {
    /// Instances.
    pub instances: u32,
    /// Joints per pose.
    pub joints: u32,
    /// Matrices per palette.
    pub skin_joints: u32,
    /// Invocations per row of the dispatch grid.
    pub row: u32,
}

/// The playback program on one device: its three entry points.
pub struct PosePalettes {
    context: GpuContext,
    blend: Compiled,
    fk: Compiled,
    palette: Compiled,
}

impl std::fmt::Debug for PosePalettes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PosePalettes").field("context", &self.context).finish_non_exhaustive()
    }
}

impl PosePalettes {
    /// The program compiled on `context`'s device.
    ///
    /// # Errors
    /// [`GpuError::Shader`] or [`GpuError::Device`] when it cannot be built.
    pub fn new(context: &GpuContext) -> Result<Self, GpuError> {
        let (module, _) = shader::play_module().map_err(GpuError::Shader)?;
        let source = shader::play_source();
        let compile = |entry: &str| context.compile("quatcurve play", &module, &source, entry);
        Ok(Self {
            context: context.clone(),
            blend: compile(shader::PLAY_BLEND_ENTRY_POINT)?,
            fk: compile(shader::FK_ENTRY_POINT)?,
            palette: compile(shader::PLAY_PALETTE_ENTRY_POINT)?,
        })
    }

    /// Palettes `[instances, skin joints, 12]` of `poses` (`[instances, 2, joints, 10]`, each
    /// instance's two local poses) blended by `weights` (one per instance), forward kinematics
    /// over `parents` in `order` (parents first), and `skin`'s inverse binds; every joint's
    /// model matrix without a skin. One submission, one read-back; f32 throughout.
    ///
    /// # Errors
    /// [`GpuError::Job`] for inputs that do not fit together or a buffer larger than a
    /// binding; device errors.
    pub fn run(
        &self,
        parents: &[Option<usize>],
        order: &[usize],
        poses: &[f32],
        weights: &[f32],
        skin: Option<PaletteSkin<'_>>,
    ) -> Result<Vec<f32>, GpuError> {
        let joints = parents.len();
        let instances = weights.len();
        if joints == 0 || poses.len() != instances * 2 * joints * LOCAL_CHANNELS {
            return Err(GpuError::Job(format!(
                "{} pose floats are not two poses of {joints} joints for each of {instances} instances",
                poses.len()
            )));
        }
        let all: Vec<usize>;
        let (skin_joints, inverse_binds): (&[usize], Vec<f32>) = match skin {
            Some(s) if s.joints.len() == s.inverse_binds.len() && s.joints.iter().all(|&j| j < joints) => {
                (s.joints, s.inverse_binds.iter().flatten().map(|&v| v as f32).collect())
            }
            Some(_) => return Err(GpuError::Job("a skin joint out of range, or not one inverse bind each".into())),
            None => {
                all = (0..joints).collect();
                let identity = [1.0f32, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
                (&all, identity.repeat(joints))
            }
        };
        // The largest buffer per instance (its two poses, or its model rows or palette): a crowd
        // larger than a binding holds is played a part at a time, a submission each.
        let per_instance = 4 * (2 * joints * LOCAL_CHANNELS).max(skin_joints.len().max(joints) * MATRIX_CHANNELS);
        let fits = (self.context.binding_limit() / per_instance as u64) as usize;
        if fits == 0 {
            return Err(GpuError::Job(format!(
                "one instance of {joints} joints needs {per_instance} bytes in one buffer, more than a storage binding \
                 ({})",
                self.context.binding_limit()
            )));
        }
        if instances > fits {
            let mut out = Vec::with_capacity(instances * skin_joints.len() * MATRIX_CHANNELS);
            let row = 2 * joints * LOCAL_CHANNELS;
            for (poses, weights) in poses.chunks(fits * row).zip(weights.chunks(fits)) {
                out.extend(self.run(parents, order, poses, weights, skin)?);
            }
            return Ok(out);
        }
        let (by_level, starts) = levels(parents, order)?;
        let parents: Vec<i32> = parents.iter().map(|p| p.map_or(-1, |p| p as i32)).collect();
        let skin_indices: Vec<u32> = skin_joints.iter().map(|&j| j as u32).collect();
        let device = self.context.device();
        let scope = ErrorScope::push(device);
        let init = |label: &str, contents: &[u8], usage: wgpu::BufferUsages| {
            // A binding may not be empty.
            let contents = if contents.is_empty() { &[0u8; 16][..] } else { contents };
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        let storage = wgpu::BufferUsages::STORAGE;
        let scratch = |label: &str, floats: usize, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (floats as u64 * 4).max(16),
                usage,
                mapped_at_creation: false,
            })
        };
        let poses_buffer = init("quatcurve play poses", bytemuck::cast_slice(poses), storage);
        let weights_buffer = init("quatcurve play weights", bytemuck::cast_slice(weights), storage);
        let skin_buffer = init("quatcurve play skin joints", bytemuck::cast_slice(&skin_indices), storage);
        let binds_buffer = init("quatcurve play inverse binds", bytemuck::cast_slice(&inverse_binds), storage);
        let parents_buffer = init("quatcurve play parents", bytemuck::cast_slice(&parents), storage);
        let levels_buffer = init("quatcurve play levels", bytemuck::cast_slice(&by_level), storage);
        let local = scratch("quatcurve play local", instances * joints * LOCAL_CHANNELS, storage);
        let model = scratch("quatcurve play model", instances * joints * MATRIX_CHANNELS, storage);
        let out_floats = instances * skin_joints.len() * MATRIX_CHANNELS;
        let palettes = scratch("quatcurve play palettes", out_floats, self.context.output_usage());
        // A dispatch binds every buffer of the module; those it does not use are these.
        let spare_read = scratch("quatcurve play spare", 4, storage);
        let spare_write = [scratch("quatcurve play spare", 4, storage), scratch("quatcurve play spare", 4, storage)];
        let spare_level =
            init("quatcurve play spare level", bytemuck::bytes_of(&FkLevel::default()), wgpu::BufferUsages::UNIFORM);
        let grid = |invocations: usize, program: &Compiled| -> Result<([u32; 2], u32), GpuError> {
            let [x, y] = self.context.grid((invocations as u64).div_ceil(u64::from(program.workgroup_size)))?;
            Ok(([x, y], x * program.workgroup_size))
        };
        let params = |row: u32| PlayParams {
            instances: instances as u32,
            joints: joints as u32,
            skin_joints: skin_joints.len() as u32,
            row,
        };
        let uniform = |label: &str, bytes: &[u8]| init(label, bytes, wgpu::BufferUsages::UNIFORM);
        let bind = |program: &Compiled,
                    [fk_local, fk_model]: [&wgpu::Buffer; 2],
                    [play_local, play_palettes]: [&wgpu::Buffer; 2],
                    level: &wgpu::Buffer,
                    play: &wgpu::Buffer| {
            let buffers = [
                ("fk_local", fk_local),
                ("fk_parents", &parents_buffer),
                ("fk_level_joints", &levels_buffer),
                ("fk_model", fk_model),
                ("fk_level", level),
                ("play_poses", &poses_buffer),
                ("play_weights", &weights_buffer),
                ("play_local", play_local),
                ("play_skin_joints", &skin_buffer),
                ("play_inverse_binds", &binds_buffer),
                ("play_palettes", play_palettes),
                ("play_params", play),
            ];
            program.bind_group(device, "quatcurve play", &buffers)
        };
        // Blend, then one forward-kinematics dispatch per level, then the palettes; WebGPU
        // orders the dispatches of a pass, so each reads the one before complete.
        let mut dispatches: Vec<(&Compiled, wgpu::BindGroup, [u32; 2])> = Vec::new();
        let (blend_grid, row) = grid(instances * joints, &self.blend)?;
        let blend_params = uniform("quatcurve play params", bytemuck::bytes_of(&params(row)));
        let group =
            bind(&self.blend, [&spare_read, &spare_write[0]], [&local, &spare_write[1]], &spare_level, &blend_params)?;
        dispatches.push((&self.blend, group, blend_grid));
        for w in starts.windows(2) {
            let (fk_grid, row) = grid((w[1] - w[0]) as usize * instances, &self.fk)?;
            let level = FkLevel {
                first: w[0],
                count: w[1] - w[0],
                frames: instances as u32,
                joints: joints as u32,
                row,
                pad: [0; 3],
            };
            let level = uniform("quatcurve play level", bytemuck::bytes_of(&level));
            let group = bind(&self.fk, [&local, &model], [&spare_write[0], &spare_write[1]], &level, &blend_params)?;
            dispatches.push((&self.fk, group, fk_grid));
        }
        let (palette_grid, row) = grid(instances * skin_joints.len(), &self.palette)?;
        let palette_params = uniform("quatcurve play params", bytemuck::bytes_of(&params(row)));
        let group =
            bind(&self.palette, [&spare_read, &model], [&spare_write[0], &palettes], &spare_level, &palette_params)?;
        dispatches.push((&self.palette, group, palette_grid));
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("quatcurve play") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("quatcurve play"),
                timestamp_writes: None,
            });
            for (program, group, [x, y]) in &dispatches {
                pass.set_pipeline(&program.pipeline);
                pass.set_bind_group(0, group, &[]);
                pass.dispatch_workgroups(*x, *y, 1);
            }
        }
        self.context.queue().submit([encoder.finish()]);
        scope.pop()?;
        let mut out = vec![0.0f32; out_floats];
        self.context
            .read_back(&palettes, (out_floats * 4) as u64, |floats| out.copy_from_slice(&floats[..out_floats]))?;
        Ok(out)
    }
}
