//! Which path runs the work: the one place that maps a device choice to a path, so `eval`,
//! `bake` and `bench` choose and name devices the same way, and the one value that
//! evaluates curves, runs forward kinematics and skins meshes, so no caller matches on
//! which path it holds.

use quatcurve_eval::cpu::CpuEvaluator;
use quatcurve_eval::job::EvalJob;
pub use quatcurve_eval::options::DeviceChoice;
use quatcurve_eval::output::{FloatOutput, Output};
use quatcurve_eval::skeleton::{self, SkinnedMesh};
#[cfg(feature = "gpu")]
use quatcurve_gpu::{GpuDevice, GpuError};
use std::fmt;

/// Why a device could not be opened, refused a job, or failed while evaluating.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DeviceError {
    /// The job breaks a rule ([`EvalJob::validate`]: sample lists that do not match the batch,
    /// non-finite sample times, a frame-major layout with unequal sample counts).
    #[error(transparent)]
    Job(#[from] quatcurve_eval::error::Error),
    /// The GPU kernel cannot take this batch (a Bezier curve above its degree limit, one
    /// track's keys larger than a storage binding): `auto` hands such a batch to the CPU path.
    #[cfg(feature = "gpu")]
    #[error("{}{error}", during.prefix())]
    Unsupported {
        /// The work refused.
        during: Work,
        /// Why, as the GPU path says.
        error: GpuError,
    },
    /// The GPU is missing or failed (exit code 1 in the CLI; the others are exit code 2).
    #[cfg(feature = "gpu")]
    #[error("{}{error}", during.prefix())]
    Gpu {
        /// The work that failed.
        during: Work,
        /// How, as the GPU path says.
        error: GpuError,
    },
    /// A GPU asked of a build without the GPU path.
    #[error("{}this build of quatcurve has no GPU path (cargo feature `gpu`)", during.prefix())]
    NoGpuPath {
        /// The work asked of it.
        during: Work,
    },
}

/// The work a device error happened in, named before its message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Work {
    /// Opening the GPU.
    Open,
    /// Evaluating a job's curves (named by nothing: the job is the caller's).
    Evaluation,
    /// Forward kinematics.
    ForwardKinematics,
    /// Crowd playback.
    Playback,
    /// Mesh skinning.
    Skinning,
}

impl Work {
    /// What a message names it by, with its separator ("playback: "), or nothing.
    fn prefix(self) -> &'static str {
        match self {
            Work::Open => "gpu: ",
            Work::Evaluation => "",
            Work::ForwardKinematics => "forward kinematics: ",
            Work::Playback => "playback: ",
            Work::Skinning => "skinning: ",
        }
    }
}

impl DeviceError {
    /// Whether the device failed, rather than the job or batch being at fault.
    #[must_use]
    pub fn is_device_failure(&self) -> bool {
        match self {
            #[cfg(feature = "gpu")]
            Self::Gpu { .. } => true,
            Self::NoGpuPath { .. } => true,
            _ => false,
        }
    }
}

/// What a device evaluates into: the output type is the caller's choice of precision. The
/// reference computes in f64 and the fast paths in f32; each output takes either, converted
/// once.
pub trait EvalOutput {
    /// Takes the fast paths' float32 rows of `job`.
    fn take_rows(&mut self, rows: FloatOutput, job: &EvalJob<'_>);
    /// Takes the reference's f64 results of `job`.
    fn take_output(&mut self, out: Output, job: &EvalJob<'_>);
    /// Float32 rows the CPU path may write in place, for an output that keeps them.
    fn rows_in_place(&mut self) -> Option<&mut FloatOutput> {
        None
    }
}

/// f64 results, the fast paths' rows widened.
impl EvalOutput for Output {
    fn take_rows(&mut self, rows: FloatOutput, job: &EvalJob<'_>) {
        *self = rows.to_output(job.options.derivatives);
    }

    fn take_output(&mut self, out: Output, _: &EvalJob<'_>) {
        *self = out;
    }
}

/// Float32 rows, for consumers that store f32 anyway (the bake), which then skip widening
/// every sample to f64 and narrowing it back; the reference's results rounded.
impl EvalOutput for FloatOutput {
    fn take_rows(&mut self, rows: FloatOutput, _: &EvalJob<'_>) {
        *self = rows;
    }

    fn take_output(&mut self, out: Output, job: &EvalJob<'_>) {
        *self = FloatOutput::from_output(&out, job.options.matrix);
    }

    fn rows_in_place(&mut self) -> Option<&mut FloatOutput> {
        Some(self)
    }
}

/// An opened evaluator.
pub enum Device {
    /// The f64 reference ([`EvalJob::run`]).
    Reference,
    /// The WGSL kernel.
    #[cfg(feature = "gpu")]
    Gpu(Box<GpuDevice>),
    /// The fast f32 CPU path.
    Cpu(CpuEvaluator),
    /// `auto` with a hardware adapter: the GPU, and the CPU path for a batch the kernel cannot take
    /// (a Bezier above degree 32, one track's keys larger than a binding), so `auto` never
    /// fails where `cpu` works. [`Device::evaluate_into`] says which one ran.
    #[cfg(feature = "gpu")]
    Auto(Box<GpuDevice>, CpuEvaluator),
}

impl fmt::Debug for Device {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

impl Device {
    /// Opens what `choice` asks for.
    ///
    /// # Errors
    /// [`DeviceError::Gpu`] for `gpu` without an adapter; [`DeviceError::NoGpuPath`] in a build
    /// without the GPU path.
    pub fn open(choice: DeviceChoice) -> Result<Self, DeviceError> {
        match choice {
            DeviceChoice::Reference => Ok(Device::Reference),
            #[cfg(feature = "gpu")]
            DeviceChoice::Gpu => GpuDevice::new()
                .map(|g| Device::Gpu(Box::new(g)))
                .map_err(|error| DeviceError::Gpu { during: Work::Open, error }),
            #[cfg(not(feature = "gpu"))]
            DeviceChoice::Gpu => Err(DeviceError::NoGpuPath { during: Work::Open }),
            #[cfg(feature = "gpu")]
            DeviceChoice::Auto => Ok(match GpuDevice::new() {
                Ok(g) if !g.is_software() => Device::Auto(Box::new(g), CpuEvaluator::new()),
                _ => Device::Cpu(CpuEvaluator::new()),
            }),
            #[cfg(not(feature = "gpu"))]
            DeviceChoice::Auto => Ok(Device::Cpu(CpuEvaluator::new())),
            DeviceChoice::Cpu => Ok(Device::Cpu(CpuEvaluator::new())),
        }
    }

    /// The name outputs report: `reference`, `cpu: <name>` or `gpu: <adapter>` (DESIGN
    /// section 5).
    #[must_use]
    pub fn name(&self) -> String {
        match self {
            Device::Reference => "reference".into(),
            #[cfg(feature = "gpu")]
            Device::Gpu(g) | Device::Auto(g, _) => format!("gpu: {}", g.adapter_name()),
            Device::Cpu(c) => format!("cpu: {}", c.name()),
        }
    }

    /// Evaluates a job in its layout; results in f64 whatever the device computed in
    /// ([`Device::evaluate_into`] lets the caller choose the precision and names the device).
    ///
    /// # Errors
    /// [`DeviceError::Job`] for a job that breaks a rule, [`DeviceError::Unsupported`] for a
    /// batch the GPU kernel cannot take, [`DeviceError::Gpu`] for device failures.
    pub fn evaluate(&self, job: &EvalJob<'_>) -> Result<Output, DeviceError> {
        let mut out = Output::default();
        self.evaluate_into(job, &mut out)?;
        Ok(out)
    }

    /// Evaluates a job into `out`, whose type is the caller's choice of precision
    /// ([`EvalOutput`]: f64 [`Output`] or the fast paths' own float32 [`FloatOutput`], which
    /// the CPU path fills in place, so one kept from job to job is not allocated again), and
    /// returns the name of the device that ran it ([`Device::name`], or for `auto` the CPU
    /// path's when the GPU kernel could not take the batch).
    ///
    /// # Errors
    /// As [`Device::evaluate`].
    pub fn evaluate_into(&self, job: &EvalJob<'_>, out: &mut impl EvalOutput) -> Result<String, DeviceError> {
        // A kept buffer (one with room already) is written in place; a new one is allocated
        // by the CPU path, on huge pages where the OS offers them.
        if let (Device::Cpu(c), Some(rows)) = (self, out.rows_in_place().filter(|r| r.data.capacity() > 0)) {
            // Not cleared: the CPU path writes every float (zeroing a kept buffer cost a
            // fiftieth of a decode); it checks the job's rules itself.
            rows.channels = job.options.row().channels();
            rows.data.resize(job.times.total() * rows.channels, 0.0);
            c.evaluate_into(job, &mut rows.data)?;
            return Ok(self.name());
        }
        // First, so that a job breaking a rule is the same typed error on every device.
        job.validate()?;
        let rows = match self {
            Device::Reference => {
                out.take_output(job.run()?, job);
                return Ok(self.name());
            }
            Device::Cpu(c) => on_cpu(c, job)?,
            #[cfg(feature = "gpu")]
            Device::Gpu(g) => on_gpu(g, job)?,
            #[cfg(feature = "gpu")]
            Device::Auto(g, c) => match on_gpu(g, job) {
                Err(DeviceError::Unsupported { .. }) => {
                    out.take_rows(on_cpu(c, job)?, job);
                    return Ok(format!("cpu: {}", c.name()));
                }
                other => other?,
            },
        };
        out.take_rows(rows, job);
        Ok(self.name())
    }

    /// Forward kinematics: model rows `[frames, joints, 12]` of local rows `[frames, joints,
    /// 10]` (`parents[j]` is joint `j`'s parent, `order` lists parents first). The GPU's in
    /// f32 (`shaders/fk.wgsl`); the CPU path and the reference in f64 from the f32 rows
    /// ([`skeleton::forward_kinematics`]), which is all the reference could add.
    ///
    /// # Errors
    /// [`DeviceError::Gpu`] for the GPU's failures (a frame larger than a storage binding
    /// among them).
    pub fn forward_kinematics(
        &self,
        parents: &[Option<usize>],
        order: &[usize],
        local: &[f32],
    ) -> Result<Vec<f32>, DeviceError> {
        match self {
            #[cfg(feature = "gpu")]
            Device::Gpu(g) | Device::Auto(g, _) => g
                .forward_kinematics(parents, order, local)
                .map_err(|error| DeviceError::Gpu { during: Work::ForwardKinematics, error }),
            Device::Cpu(_) | Device::Reference => Ok(skeleton::forward_kinematics(parents, order, local)),
        }
    }

    /// Crowd playback's palettes (DESIGN section 17): each instance's two local poses
    /// (`poses`, `[instances, 2, joints, 10]`) blended by its weight (`weights`: rotations by
    /// slerp on the shorter arc, the rest by lerp), forward kinematics, and `skin`'s palette
    /// (`[instances, skin joints, 12]`; every joint's model matrix without one). The GPU's in
    /// one submission (`shaders/play.wgsl` around `shaders/fk.wgsl`, f32); the CPU path and the
    /// reference in f64, an instance at a time ([`skeleton::play_palettes`]).
    ///
    /// # Errors
    /// [`DeviceError::Gpu`] for the GPU's failures.
    pub fn play_palettes(
        &self,
        parents: &[Option<usize>],
        order: &[usize],
        poses: &[f32],
        weights: &[f32],
        skin: Option<skeleton::PaletteSkin<'_>>,
    ) -> Result<Vec<f32>, DeviceError> {
        match self {
            #[cfg(feature = "gpu")]
            Device::Gpu(g) | Device::Auto(g, _) => g
                .play_palettes(parents, order, poses, weights, skin)
                .map_err(|error| DeviceError::Gpu { during: Work::Playback, error }),
            Device::Cpu(_) | Device::Reference => Ok(skeleton::play_palettes(parents, order, poses, weights, skin)),
        }
    }

    /// Playback from curves kept on this device (DESIGN section 17), where the device keeps
    /// them: the GPU's ([`ResidentPlayback`]: the clips uploaded once, one submission a
    /// frame). `None` on the CPU path and the reference, which evaluate poses on the host, and
    /// for `auto` with curves the kernel cannot take.
    ///
    /// # Errors
    /// [`DeviceError::Unsupported`] for curves the GPU cannot take (named);
    /// [`DeviceError::Gpu`] for its failures.
    pub fn resident_playback(
        &self,
        curves: &skeleton::PoseCurves<'_>,
    ) -> Result<Option<ResidentPlayback>, DeviceError> {
        match self {
            #[cfg(feature = "gpu")]
            Device::Gpu(g) | Device::Auto(g, _) => match g.curve_palettes(curves) {
                Ok(gpu) => Ok(Some(ResidentPlayback { gpu })),
                // `auto` plays what the kernel cannot take on the host path.
                Err(GpuError::Pack(_) | GpuError::Job(_) | GpuError::Eval(_)) if matches!(self, Device::Auto(..)) => {
                    Ok(None)
                }
                Err(error @ (GpuError::Pack(_) | GpuError::Job(_) | GpuError::Eval(_))) => {
                    Err(DeviceError::Unsupported { during: Work::Playback, error })
                }
                Err(error) => Err(DeviceError::Gpu { during: Work::Playback, error }),
            },
            Device::Cpu(_) | Device::Reference => {
                let _ = curves;
                Ok(None)
            }
        }
    }

    /// `mesh` skinned at every frame of `matrices` (`[frames, skin joints, 12]`, 3x4 row-major
    /// skinning matrices): `[frames, vertices, 6]`, position and normal, in f32. The GPU's
    /// `shaders/skin_mesh.wgsl`; the CPU path and the reference [`skeleton::skin`] in f64.
    ///
    /// # Errors
    /// [`DeviceError::Gpu`] for the GPU's failures.
    pub fn skin(&self, mesh: &SkinnedMesh, skin_joints: usize, matrices: &[f32]) -> Result<Vec<f32>, DeviceError> {
        match self {
            #[cfg(feature = "gpu")]
            Device::Gpu(g) | Device::Auto(g, _) => g
                .skin_mesh(&quatcurve_gpu::skinning::BindMesh::of(mesh), skin_joints, matrices)
                .map_err(|error| DeviceError::Gpu { during: Work::Skinning, error }),
            Device::Cpu(_) | Device::Reference => {
                Ok(skeleton::skin(mesh, skin_joints, matrices).into_iter().map(|v| v as f32).collect())
            }
        }
    }
}

/// The GPU path's errors as a device's: a job that breaks a rule is [`DeviceError::Job`], as on
/// every path; a batch the kernel cannot take (including one too large for a dispatch) is
/// [`DeviceError::Unsupported`], which `auto` hands to the CPU path.
#[cfg(feature = "gpu")]
fn on_gpu(g: &GpuDevice, job: &EvalJob<'_>) -> Result<FloatOutput, DeviceError> {
    g.evaluate(job).map_err(|e| match e {
        GpuError::Eval(e) => DeviceError::Job(e),
        error @ (GpuError::Pack(_) | GpuError::Job(_)) => DeviceError::Unsupported { during: Work::Evaluation, error },
        error => DeviceError::Gpu { during: Work::Evaluation, error },
    })
}

fn on_cpu(c: &CpuEvaluator, job: &EvalJob<'_>) -> Result<FloatOutput, DeviceError> {
    Ok(c.evaluate(job)?)
}

/// An animation's curves kept on a device for playback ([`Device::resident_playback`]).
#[derive(Debug)]
pub struct ResidentPlayback {
    #[cfg(feature = "gpu")]
    gpu: quatcurve_gpu::CurvePalettes,
}

impl ResidentPlayback {
    /// The GPU program holding the curves: [`quatcurve_gpu::CurvePalettes::frame`] leaves a
    /// frame's palettes on the device for a renderer's vertex shader.
    #[cfg(feature = "gpu")]
    #[must_use]
    pub fn gpu(&self) -> &quatcurve_gpu::CurvePalettes {
        &self.gpu
    }

    /// Palettes `[instances, palette joints, 12]` of `instances` this frame
    /// ([`quatcurve_gpu::CurvePalettes::run`] on the GPU).
    ///
    /// # Errors
    /// [`DeviceError::Gpu`] for the device's failures and instances out of range.
    pub fn palettes(&self, instances: &[skeleton::PoseTimes]) -> Result<Vec<f32>, DeviceError> {
        #[cfg(feature = "gpu")]
        return self.gpu.run(instances).map_err(|error| DeviceError::Gpu { during: Work::Playback, error });
        #[cfg(not(feature = "gpu"))]
        {
            let _ = instances;
            Err(DeviceError::NoGpuPath { during: Work::Playback })
        }
    }
}
