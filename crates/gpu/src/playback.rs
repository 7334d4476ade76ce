//! Crowd playback's blend, forward kinematics and skin palettes in one submission
//! (`shaders/play.wgsl` around `shaders/fk.wgsl`), the twin of
//! [`quatcurve_eval::skeleton::blend_poses`], [`quatcurve_eval::skeleton::forward_kinematics`]
//! and [`quatcurve_eval::skeleton::palettes`]: two local poses per instance in, one palette per
//! instance out. [`CurvePalettes`] evaluates the poses too, from curves kept on the device
//! (`shaders/play_curves.wgsl`): only the instances travel per frame.

use super::context::{ErrorScope, GpuContext};
use super::fk::{levels, FkLevel};
use super::layout::{self, fixed_time, ChunkTargets, GpuTrack, Params};
use super::program::Compiled;
use crate::error::{GpuError, JobError};
use quatcurve_eval::batch::knots_are_uniform;
use quatcurve_eval::output::{LOCAL_CHANNELS, MATRIX_CHANNELS};
use quatcurve_eval::sampling::{PerTrack, SampleTimes};
use quatcurve_eval::skeleton::{PaletteSkin, PoseCurves, PoseSource, PoseTimes, POSE_PROPERTIES};
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
        let (module, _) = shader::play_module()?;
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
            let whole = format!("two poses of {joints} joints for each of {instances} instances");
            return Err(JobError::NotWhole { what: "pose floats", len: poses.len(), whole }.into());
        }
        let (skin_joints, inverse_binds) = palette_skin(skin, joints)?;
        let skin_joints = skin_joints.as_slice();
        // The largest buffer per instance (its two poses, or its model rows or palette): a crowd
        // larger than a binding holds is played a part at a time, a submission each.
        let per_instance = 4 * (2 * joints * LOCAL_CHANNELS).max(skin_joints.len().max(joints) * MATRIX_CHANNELS);
        let fits = (self.context.binding_limit() / per_instance as u64) as usize;
        if fits == 0 {
            let what = format!("one instance of {joints} joints");
            return Err(JobError::OverBinding {
                what,
                bytes: per_instance as u64,
                limit: self.context.binding_limit(),
            }
            .into());
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
        let init = |label: &str, contents: &[u8], usage| init_buffer(device, label, contents, usage);
        let storage = wgpu::BufferUsages::STORAGE;
        let scratch = |label: &str, floats: usize, usage| scratch_buffer(device, label, floats, usage);
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
        // Blend, then one forward-kinematics dispatch per level, then the palettes.
        let mut dispatches: Vec<(&Compiled, wgpu::BindGroup, [u32; 2])> = Vec::new();
        let (blend_grid, row) = grid(instances * joints, &self.blend)?;
        let blend_params = uniform("quatcurve play params", bytemuck::bytes_of(&params(row)));
        let group =
            bind(&self.blend, [&spare_read, &spare_write[0]], [&local, &spare_write[1]], &spare_level, &blend_params)?;
        dispatches.push((&self.blend, group, blend_grid));
        for w in starts.windows(2) {
            let (fk_grid, row) = grid((w[1] - w[0]) as usize * instances, &self.fk)?;
            let level = FkLevel::new([w[0], w[1]], instances, joints, row);
            let level = uniform("quatcurve play level", bytemuck::bytes_of(&level));
            let group = bind(&self.fk, [&local, &model], [&spare_write[0], &spare_write[1]], &level, &blend_params)?;
            dispatches.push((&self.fk, group, fk_grid));
        }
        let (palette_grid, row) = grid(instances * skin_joints.len(), &self.palette)?;
        let palette_params = uniform("quatcurve play params", bytemuck::bytes_of(&params(row)));
        let group =
            bind(&self.palette, [&spare_read, &model], [&spare_write[0], &palettes], &spare_level, &palette_params)?;
        dispatches.push((&self.palette, group, palette_grid));
        scope.pop()?;
        dispatch(&self.context, "quatcurve play", &dispatches)?;
        let mut out = vec![0.0f32; out_floats];
        self.context.read_back(&palettes, (out_floats * 4) as u64, |f| out.copy_from_slice(&f[..out_floats]))?;
        Ok(out)
    }
}

/// A buffer holding `contents` (16 zero bytes for none: a binding may not be empty).
fn init_buffer(device: &wgpu::Device, label: &str, contents: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    let contents = if contents.is_empty() { &[0u8; 16][..] } else { contents };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
}

/// A buffer of `floats` f32 (at least 16 bytes) that a kernel fills.
fn scratch_buffer(device: &wgpu::Device, label: &str, floats: usize, usage: wgpu::BufferUsages) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: (floats as u64 * 4).max(16),
        usage,
        mapped_at_creation: false,
    })
}

/// `dispatches` recorded in order in one compute pass (WebGPU orders the dispatches of a
/// pass, so each reads the one before complete) and submitted.
fn dispatch(
    context: &GpuContext,
    label: &str,
    dispatches: &[(&Compiled, wgpu::BindGroup, [u32; 2])],
) -> Result<(), GpuError> {
    let device = context.device();
    let scope = ErrorScope::push(device);
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    {
        let mut pass =
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        for (program, group, [x, y]) in dispatches {
            pass.set_pipeline(&program.pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(*x, *y, 1);
        }
    }
    context.queue().submit([encoder.finish()]);
    scope.pop()
}

/// One frame's palettes on the device ([`CurvePalettes::frame`]): `[instances, skin joints,
/// 12]` f32 in a storage buffer, for a vertex shader to read where it lies.
#[derive(Debug)]
pub struct PaletteFrame {
    buffer: wgpu::Buffer,
    floats: usize,
}

impl PaletteFrame {
    /// The storage buffer of the palettes.
    #[must_use]
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Floats in it that are palettes (the buffer may be longer).
    #[must_use]
    pub fn floats(&self) -> usize {
        self.floats
    }
}

/// A palette's joints and inverse binds as f32 rows: `skin`'s, or every joint's with
/// identities (model matrices) without one.
fn palette_skin(skin: Option<PaletteSkin<'_>>, joints: usize) -> Result<(Vec<usize>, Vec<f32>), GpuError> {
    match skin {
        Some(s) if s.joints.len() == s.inverse_binds.len() && s.joints.iter().all(|&j| j < joints) => {
            Ok((s.joints.to_vec(), s.inverse_binds.iter().flatten().map(|&v| v as f32).collect()))
        }
        Some(_) => Err(JobError::Skin.into()),
        None => {
            let identity = [1.0f32, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
            Ok(((0..joints).collect(), identity.repeat(joints)))
        }
    }
}

/// Host twin of WGSL's `PlayInstance` (32 bytes): one instance's two poses this frame.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PlayInstance {
    /// The first pose's clip.
    pub first_clip: u32,
    /// The second pose's clip.
    pub second_clip: u32,
    /// The second pose's weight.
    pub weight: f32,
    /// Padding.
    pub pad: u32,
    /// The first pose's curve time, 32.32 fixed point.
    pub first_time: [u32; 2],
    /// The second pose's curve time.
    pub second_time: [u32; 2],
}

/// Host twin of WGSL's `PlayTrack` (32 bytes): a loop's domain start and period (period 0:
/// open) in 32.32 fixed point, and a vector loop's per-cycle offset per second.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PlayTrack {
    /// The domain's start.
    pub start: [u32; 2],
    /// The period.
    pub period: [u32; 2],
    /// Per-cycle offset per second (`xyz`; `w` unused).
    pub drift: [f32; 4],
}

/// Marks a source that is a constant value (WGSL `PLAY_SOURCE_VALUE`, checked by a test).
pub const PLAY_SOURCE_VALUE: u32 = 0x8000_0000;

/// An animation's curves packed as the playback program reads them: the evaluator's records
/// for rotation tracks and then, on the same layout, the vector curves; each track's loop; each
/// clip's joint sources; the constants. Built on the host once, uploaded once.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PackedCurves {
    /// Track records (rotations, then vectors).
    pub tracks: Vec<GpuTrack>,
    /// Points `[x, y, z, w]`.
    pub points: Vec<[f32; 4]>,
    /// Coefficients.
    pub coefs: Vec<[f32; 4]>,
    /// Knots, 32.32 fixed point.
    pub knots: Vec<[u32; 2]>,
    /// Per track, its loop.
    pub loops: Vec<PlayTrack>,
    /// `[clips, joints, POSE_PROPERTIES]`: a track index or [`PLAY_SOURCE_VALUE`] | a value
    /// index.
    pub sources: Vec<u32>,
    /// Constant values.
    pub values: Vec<[f32; 4]>,
}

/// A loop's domain start and period in fixed point (an open track's: zero).
fn play_track(domain: [f64; 2], looping: bool, drift: [f64; 3]) -> PlayTrack {
    if !looping {
        return PlayTrack::default();
    }
    let ticks = |t: f64| {
        let [lo, hi] = fixed_time(t);
        (i64::from(hi as i32) << 32) | i64::from(lo)
    };
    let period = ticks(domain[1]) - ticks(domain[0]);
    PlayTrack {
        start: fixed_time(domain[0]),
        period: [period as u32, (period >> 32) as u32],
        drift: [drift[0] as f32, drift[1] as f32, drift[2] as f32, 0.0],
    }
}

/// Packs `curves` for [`CurvePalettes`]: the rotation batch as the evaluator packs it (one
/// chunk), then every vector curve on the same layout.
///
/// # Errors
/// [`GpuError::Job`] naming the track when the kernel cannot take it ([`layout::plan_chunks`]'s
/// rules), or when the curves do not fit one storage binding.
pub fn pack_curves(curves: &PoseCurves<'_>, binding_limit: u64) -> Result<PackedCurves, GpuError> {
    let mut packed = PackedCurves::default();
    if let Some(batch) = curves.batch {
        let none = SampleTimes::per_track(batch, |_, _| Ok(PerTrack::List(&[])))?;
        let plans = layout::plan_chunks(batch, &none, 4, binding_limit)?;
        let [plan] = plans.as_slice() else {
            let (bindings, limit) = (plans.len(), binding_limit);
            return Err(JobError::Bindings { what: "the rotation curves", bindings, limit, pass: "playback" }.into());
        };
        packed.points = vec![[0.0; 4]; plan.points];
        packed.coefs = vec![[0.0; 4]; plan.coefs];
        packed.knots = vec![[0; 2]; plan.knots];
        let mut times: Vec<u8> = Vec::new();
        packed.tracks = layout::pack(
            plan,
            batch,
            &none,
            ChunkTargets {
                points: bytemuck::cast_slice_mut::<_, u8>(&mut packed.points).into(),
                coefs: bytemuck::cast_slice_mut::<_, u8>(&mut packed.coefs).into(),
                knots: bytemuck::cast_slice_mut::<_, u8>(&mut packed.knots).into(),
                times: times.as_mut_slice().into(),
            },
        );
        packed.loops = batch.tracks().iter().map(|t| play_track(t.domain(), t.looping(), [0.0; 3])).collect();
    }
    let rotations = packed.tracks.len();
    for (v, curve) in curves.vectors.iter().enumerate() {
        if let Some(knot) = layout::collapsed_span(curve.knots()) {
            return Err(JobError::KnotsTooClose { curve: v, knot }.into());
        }
        let vec4 = |p: &quatcurve_core::quat::Vec3F64| [p.x as f32, p.y as f32, p.z as f32, 0.0];
        packed.tracks.push(GpuTrack {
            curve: layout::curve_code(curve.curve()),
            order: curve.order() as u32,
            blend: layout::blend_code(curve.blend()),
            point_offset: packed.points.len() as u32,
            point_count: curve.points().len() as u32,
            coef_offset: packed.coefs.len() as u32,
            knot_offset: packed.knots.len() as u32,
            knot_count: curve.knots().len() as u32,
            flags: if knots_are_uniform(curve.knots()) { layout::FLAG_UNIFORM_KNOTS } else { 0 },
            ..GpuTrack::default()
        });
        packed.points.extend(curve.points().iter().map(vec4));
        packed.coefs.extend(curve.coefs().iter().map(vec4));
        packed.knots.extend(curve.knots().iter().map(|&k| fixed_time(k)));
        let drift = curve.drift();
        packed.loops.push(play_track(curve.domain(), drift.is_some(), drift.map_or([0.0; 3], |d| [d.x, d.y, d.z])));
    }
    for source in &curves.sources {
        packed.sources.push(match *source {
            PoseSource::Rotation(track) => track as u32,
            PoseSource::Vector(v) => (rotations + v) as u32,
            PoseSource::Value(value) => {
                packed.values.push(value);
                PLAY_SOURCE_VALUE | (packed.values.len() - 1) as u32
            }
        });
    }
    let bytes = [
        packed.tracks.len() * std::mem::size_of::<GpuTrack>(),
        packed.points.len() * 16,
        packed.coefs.len() * 16,
        packed.knots.len() * 8,
        packed.loops.len() * std::mem::size_of::<PlayTrack>(),
        packed.sources.len() * 4,
        packed.values.len() * 16,
    ];
    if let Some(&largest) = bytes.iter().filter(|&&b| b as u64 > binding_limit).max() {
        let what = "the curves".to_string();
        return Err(JobError::OverBinding { what, bytes: largest as u64, limit: binding_limit }.into());
    }
    Ok(packed)
}

/// What crowd playback keeps on a device (DESIGN section 17), as bytes ready to upload: each
/// resident buffer by the shader's name, the pose kernel's specialization, and what a frame's
/// dispatches are planned from. [`CurvePalettes`] uploads it through wgpu; a browser's WebGPU
/// uploads the same bytes (`quatcurve view`), so both hosts run one plan.
#[derive(Clone, Debug)]
pub struct ResidentCurves {
    /// The buffers, in the order uploaded.
    pub buffers: Vec<ResidentBuffer>,
    /// The pose kernel's override constants: values only, and the families, orders and knot
    /// spacing these curves have (on a software adapter every branch a kernel holds runs,
    /// masked).
    pub constants: Vec<(&'static str, f64)>,
    /// Joints per pose.
    pub joints: usize,
    /// Matrices per palette.
    pub skin_joints: usize,
    /// Clips (the first index of `play_sources`).
    pub clips: usize,
    /// Where each level of the hierarchy starts in `fk_level_joints`, and its end.
    pub starts: Vec<u32>,
}

/// One resident buffer: the shader's variable, its bytes, and whether it is a uniform (else a
/// read-only storage buffer).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResidentBuffer {
    /// The WGSL variable it binds.
    pub name: &'static str,
    /// Its contents (at least 16 bytes: a binding may not be empty).
    pub bytes: Vec<u8>,
    /// A uniform buffer.
    pub uniform: bool,
}

/// A buffer a frame's dispatches write, per instance: what one entry point writes and the next
/// reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameBuffer {
    /// The blended local poses, `[instances, joints, 10]`.
    Local,
    /// The model matrices, `[instances, joints, 12]`.
    Model,
    /// The skin palettes, `[instances, skin joints, 12]`.
    Palettes,
}

impl FrameBuffer {
    /// Every frame buffer.
    pub const ALL: [FrameBuffer; 3] = [FrameBuffer::Local, FrameBuffer::Model, FrameBuffer::Palettes];

    /// Its name, as a host's plan names it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            FrameBuffer::Local => "local",
            FrameBuffer::Model => "model",
            FrameBuffer::Palettes => "palettes",
        }
    }
}

/// The shader's variables that bind the frame buffers: `play_local` (written by `play_curves`)
/// is `fk_local` to forward kinematics, whose `fk_model` `play_palette` reads. A host binds
/// each entry point's variables by this table.
pub const FRAME_BINDINGS: [(&str, FrameBuffer); 4] = [
    ("play_local", FrameBuffer::Local),
    ("fk_local", FrameBuffer::Local),
    ("fk_model", FrameBuffer::Model),
    ("play_palettes", FrameBuffer::Palettes),
];

/// The workgroup widths of a frame's three kernels, read from the shader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameKernels {
    /// `play_curves`.
    pub curves: u32,
    /// `forward_kinematics`.
    pub fk: u32,
    /// `play_palette`.
    pub palette: u32,
}

impl FrameKernels {
    /// The widths in `module` (the playback-from-curves program).
    ///
    /// # Errors
    /// [`GpuError::Shader`] for an entry point missing or not one-dimensional.
    pub fn of(module: &naga::Module) -> Result<Self, GpuError> {
        let width = |entry| shader::entry_workgroup_size(module, entry);
        Ok(Self {
            curves: width(shader::PLAY_CURVES_ENTRY_POINT)?,
            fk: width(shader::FK_ENTRY_POINT)?,
            palette: width(shader::PLAY_PALETTE_ENTRY_POINT)?,
        })
    }
}

/// One dispatch of a frame, in submission order: its entry point, its grid, and its uniforms
/// (`play_params`; `fk_level` for a level of forward kinematics).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameDispatch {
    /// The entry point.
    pub entry: &'static str,
    /// Workgroups in x and y.
    pub groups: [u32; 2],
    /// The dispatch's `play_params`.
    pub params: PlayParams,
    /// The level's `fk_level` (forward kinematics only).
    pub level: Option<FkLevel>,
}

impl ResidentCurves {
    /// `curves` packed for a device whose storage bindings hold `binding_limit` bytes.
    ///
    /// # Errors
    /// [`pack_curves`]'s; [`GpuError::Job`] for sources that are not `[clips, joints,
    /// POSE_PROPERTIES]`, a skin joint out of range or a hierarchy out of order.
    pub fn new(curves: &PoseCurves<'_>, binding_limit: u64) -> Result<Self, GpuError> {
        let joints = curves.parents.len();
        if joints == 0 || curves.sources.is_empty() || curves.sources.len() % (POSE_PROPERTIES * joints) != 0 {
            let whole = format!("{POSE_PROPERTIES} per joint of {joints} per clip");
            return Err(JobError::NotWhole { what: "sources", len: curves.sources.len(), whole }.into());
        }
        let packed = pack_curves(curves, binding_limit)?;
        let (skin_joints, inverse_binds) = palette_skin(curves.skin, joints)?;
        let (by_level, starts) = levels(curves.parents, curves.order)?;
        let parents: Vec<i32> = curves.parents.iter().map(|p| p.map_or(-1, |p| p as i32)).collect();
        let skin_indices: Vec<u32> = skin_joints.iter().map(|&j| j as u32).collect();
        let buffer = |name: &'static str, bytes: &[u8], uniform: bool| ResidentBuffer {
            name,
            bytes: if bytes.is_empty() { vec![0; 16] } else { bytes.to_vec() },
            uniform,
        };
        let buffers = vec![
            buffer("tracks", bytemuck::cast_slice(&packed.tracks), false),
            buffer("points", bytemuck::cast_slice(&packed.points), false),
            buffer("coefs", bytemuck::cast_slice(&packed.coefs), false),
            buffer("knots", bytemuck::cast_slice(&packed.knots), false),
            buffer("poly", bytemuck::cast_slice(&layout::polynomial_table()), true),
            buffer("play_tracks", bytemuck::cast_slice(&packed.loops), false),
            buffer("play_sources", bytemuck::cast_slice(&packed.sources), false),
            buffer("play_values", bytemuck::cast_slice(&packed.values), false),
            buffer("fk_parents", bytemuck::cast_slice(&parents), false),
            buffer("fk_level_joints", bytemuck::cast_slice(&by_level), false),
            buffer("play_skin_joints", bytemuck::cast_slice(&skin_indices), false),
            buffer("play_inverse_binds", bytemuck::cast_slice(&inverse_binds), false),
        ];
        Ok(Self {
            buffers,
            constants: layout::value_specialization(&packed.tracks).to_vec(),
            joints,
            skin_joints: skin_joints.len(),
            clips: curves.sources.len() / (POSE_PROPERTIES * joints),
            starts,
        })
    }

    /// The most instances one frame plays on a device whose storage bindings hold
    /// `binding_limit` bytes: as many as the largest per-instance buffer fits (at least one).
    #[must_use]
    pub fn max_frame_instances(&self, binding_limit: u64) -> usize {
        let (joints, skin_joints) = (self.joints, self.skin_joints);
        let per_instance = 4 * (joints * LOCAL_CHANNELS).max(joints.max(skin_joints) * MATRIX_CHANNELS);
        (binding_limit / per_instance as u64).max(1) as usize
    }

    /// Floats per instance of frame buffer `buffer`.
    #[must_use]
    pub fn frame_floats(&self, buffer: FrameBuffer) -> usize {
        match buffer {
            FrameBuffer::Local => self.joints * LOCAL_CHANNELS,
            FrameBuffer::Model => self.joints * MATRIX_CHANNELS,
            FrameBuffer::Palettes => self.skin_joints * MATRIX_CHANNELS,
        }
    }

    /// The kernel's records of `instances`, checked: what a host uploads each frame.
    ///
    /// # Errors
    /// [`GpuError::Job`] for a clip out of range or a weight outside `[0, 1]`, naming the
    /// instance.
    pub fn records(&self, instances: &[PoseTimes]) -> Result<Vec<PlayInstance>, GpuError> {
        instances
            .iter()
            .enumerate()
            .map(|(i, p)| {
                if p.clips.iter().any(|&c| c >= self.clips) || !(0.0..=1.0).contains(&p.weight) {
                    return Err(JobError::Instance { instance: i, clips: p.clips, weight: p.weight }.into());
                }
                Ok(PlayInstance {
                    first_clip: p.clips[0] as u32,
                    second_clip: p.clips[1] as u32,
                    weight: p.weight,
                    pad: 0,
                    first_time: fixed_time(p.times[0]),
                    second_time: fixed_time(p.times[1]),
                })
            })
            .collect()
    }

    /// The dispatches of a frame of `instances`, in order: the poses from the curves, one
    /// forward-kinematics dispatch per level of the hierarchy, the palettes. Grids are 2D past
    /// `max_groups` workgroups a side.
    ///
    /// # Errors
    /// [`GpuError::Job`] for more workgroups than a 2D grid holds.
    pub fn frame_plan(
        &self,
        instances: usize,
        kernels: FrameKernels,
        max_groups: u32,
    ) -> Result<Vec<FrameDispatch>, GpuError> {
        let (joints, skin_joints) = (self.joints, self.skin_joints);
        let planned = |entry: &'static str, invocations: usize, width: u32, level: Option<[u32; 2]>| {
            let groups = layout::grid((invocations as u64).div_ceil(u64::from(width)), max_groups)?;
            let row = groups[0] * width;
            let params =
                PlayParams { instances: instances as u32, joints: joints as u32, skin_joints: skin_joints as u32, row };
            let level = level.map(|span| FkLevel::new(span, instances, joints, row));
            Ok::<_, GpuError>(FrameDispatch { entry, groups, params, level })
        };
        let mut plan = vec![planned(shader::PLAY_CURVES_ENTRY_POINT, instances * joints, kernels.curves, None)?];
        for w in self.starts.windows(2) {
            let invocations = (w[1] - w[0]) as usize * instances;
            plan.push(planned(shader::FK_ENTRY_POINT, invocations, kernels.fk, Some([w[0], w[1]]))?);
        }
        plan.push(planned(shader::PLAY_PALETTE_ENTRY_POINT, instances * skin_joints, kernels.palette, None)?);
        Ok(plan)
    }
}

/// Crowd playback from curves kept on the device (DESIGN section 17): the clips uploaded once;
/// per frame, one submission evaluates every instance's joints at its own times, blends its two
/// poses, runs forward kinematics and multiplies the inverse binds (`shaders/play_curves.wgsl`,
/// then fk.wgsl and `play_palette`). Only the instances travel per frame.
pub struct CurvePalettes {
    context: GpuContext,
    curves: Compiled,
    fk: Compiled,
    palette: Compiled,
    kernels: FrameKernels,
    plan: ResidentCurves,
    /// The resident buffers, by the shader's names.
    resident: Vec<(&'static str, wgpu::Buffer)>,
}

impl std::fmt::Debug for CurvePalettes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CurvePalettes")
            .field("context", &self.context)
            .field("joints", &self.plan.joints)
            .finish_non_exhaustive()
    }
}

impl CurvePalettes {
    /// Compiles the program and uploads `curves`.
    ///
    /// # Errors
    /// [`ResidentCurves::new`]'s; device errors.
    pub fn new(context: &GpuContext, curves: &PoseCurves<'_>) -> Result<Self, GpuError> {
        let mut plan = ResidentCurves::new(curves, context.binding_limit())?;
        let (module, _) = shader::play_curves_module()?;
        let source = shader::play_curves_source();
        let constants = &plan.constants;
        let compile =
            |entry: &str| context.compile_specialized("quatcurve play curves", &module, &source, entry, constants);
        let device = context.device();
        let scope = ErrorScope::push(device);
        let upload = |name: &'static str, contents: &[u8], uniform: bool| {
            let usage = if uniform { wgpu::BufferUsages::UNIFORM } else { wgpu::BufferUsages::STORAGE };
            (name, init_buffer(device, &format!("quatcurve play {name}"), contents, usage))
        };
        let mut resident: Vec<_> = plan.buffers.iter().map(|b| upload(b.name, &b.bytes, b.uniform)).collect();
        // What no dispatch here reads, bound because this host's layout holds every binding of
        // the module: the evaluator's per-job bindings, given poses.
        resident.extend([
            upload("params", bytemuck::bytes_of(&Params::default()), true),
            upload("times", &[], false),
            upload("play_poses", &[], false),
            upload("play_weights", &[], false),
        ]);
        // The bytes are on the device; the plan keeps the rest.
        plan.buffers.clear();
        scope.pop()?;
        Ok(Self {
            context: context.clone(),
            curves: compile(shader::PLAY_CURVES_ENTRY_POINT)?,
            fk: compile(shader::FK_ENTRY_POINT)?,
            palette: compile(shader::PLAY_PALETTE_ENTRY_POINT)?,
            kernels: FrameKernels::of(&module)?,
            plan,
            resident,
        })
    }

    /// Matrices per palette.
    #[must_use]
    pub fn palette_joints(&self) -> usize {
        self.plan.skin_joints
    }

    /// Palettes `[instances, skin joints, 12]` of `instances` this frame, read back (for tests
    /// and the CLI; a renderer binds [`CurvePalettes::frame`]'s buffer instead). A crowd larger
    /// than a binding holds is played a part at a time, a submission each.
    ///
    /// # Errors
    /// [`GpuError::Job`] for a clip out of range or a weight outside `[0, 1]`; device errors.
    pub fn run(&self, instances: &[PoseTimes]) -> Result<Vec<f32>, GpuError> {
        let records = self.plan.records(instances)?;
        let mut out = Vec::with_capacity(instances.len() * self.plan.skin_joints * MATRIX_CHANNELS);
        for part in records.chunks(self.max_frame_instances()) {
            out.extend(self.read(&self.submit(part)?)?);
        }
        Ok(out)
    }

    /// This frame's palettes left on the device, for a vertex shader to read: one submission,
    /// no read-back (the render path).
    ///
    /// # Errors
    /// [`CurvePalettes::run`]'s, and [`GpuError::Job`] for more instances than one binding of
    /// palettes holds ([`CurvePalettes::max_frame_instances`]).
    pub fn frame(&self, instances: &[PoseTimes]) -> Result<PaletteFrame, GpuError> {
        if instances.len() > self.max_frame_instances() {
            let (instances, max) = (instances.len(), self.max_frame_instances());
            return Err(JobError::TooManyInstances { instances, max }.into());
        }
        self.submit(&self.plan.records(instances)?)
    }

    /// The most instances [`CurvePalettes::frame`] plays in one buffer.
    #[must_use]
    pub fn max_frame_instances(&self) -> usize {
        self.plan.max_frame_instances(self.context.binding_limit())
    }

    /// A frame's palettes read back: `[instances, skin joints, 12]`.
    ///
    /// # Errors
    /// Device errors.
    pub fn read(&self, frame: &PaletteFrame) -> Result<Vec<f32>, GpuError> {
        let floats = frame.floats;
        let mut out = vec![0.0f32; floats];
        self.context.read_back(&frame.buffer, (floats * 4) as u64, |f| out.copy_from_slice(&f[..floats]))?;
        Ok(out)
    }

    /// One submission for `instances`: [`ResidentCurves::frame_plan`]'s dispatches.
    fn submit(&self, instances: &[PlayInstance]) -> Result<PaletteFrame, GpuError> {
        let count = instances.len();
        let plan = self.plan.frame_plan(count, self.kernels, self.context.max_groups_per_dim())?;
        let device = self.context.device();
        let scope = ErrorScope::push(device);
        let storage = wgpu::BufferUsages::STORAGE;
        let init = |label: &str, contents: &[u8], usage| init_buffer(device, label, contents, usage);
        let scratch = |label: &str, floats: usize, usage| scratch_buffer(device, label, floats, usage);
        let records = init("quatcurve play instances", bytemuck::cast_slice(instances), storage);
        let local = scratch("quatcurve play local", count * self.plan.frame_floats(FrameBuffer::Local), storage);
        let model = scratch("quatcurve play model", count * self.plan.frame_floats(FrameBuffer::Model), storage);
        let out_floats = count * self.plan.frame_floats(FrameBuffer::Palettes);
        let palettes = scratch("quatcurve play palettes", out_floats, self.context.output_usage());
        let spare_write: [wgpu::Buffer; 3] = std::array::from_fn(|_| scratch("quatcurve play spare", 4, storage));
        let spare_read = scratch("quatcurve play spare", 4, storage);
        let [w0, w1, w2] = &spare_write;
        // Every binding of the module, the frame's as each kernel uses them and the rest spare
        // (the writable ones distinct within a dispatch).
        let mut dispatches: Vec<(&Compiled, wgpu::BindGroup, [u32; 2])> = Vec::new();
        for d in &plan {
            let (program, [out, fk_local, fk_model], [play_local, play_palettes]) = match d.entry {
                e if e == shader::PLAY_CURVES_ENTRY_POINT => (&self.curves, [w0, &spare_read, w1], [&local, w2]),
                e if e == shader::FK_ENTRY_POINT => (&self.fk, [w0, &local, &model], [w1, w2]),
                _ => (&self.palette, [w0, &spare_read, &model], [w1, &palettes]),
            };
            let level = init(
                "quatcurve play level",
                bytemuck::bytes_of(&d.level.unwrap_or_default()),
                wgpu::BufferUsages::UNIFORM,
            );
            let params = init("quatcurve play params", bytemuck::bytes_of(&d.params), wgpu::BufferUsages::UNIFORM);
            let mut buffers: Vec<(&str, &wgpu::Buffer)> = self.resident.iter().map(|(n, b)| (*n, b)).collect();
            buffers.extend([
                ("out", out),
                ("fk_local", fk_local),
                ("fk_model", fk_model),
                ("fk_level", &level),
                ("play_local", play_local),
                ("play_palettes", play_palettes),
                ("play_params", &params),
                ("play_instances", &records),
            ]);
            dispatches.push((program, program.bind_group(device, "quatcurve play curves", &buffers)?, d.groups));
        }
        scope.pop()?;
        dispatch(&self.context, "quatcurve play curves", &dispatches)?;
        Ok(PaletteFrame { buffer: palettes, floats: out_floats })
    }
}
