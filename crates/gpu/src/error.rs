//! Why the GPU path failed ([`GpuError`]): the device, the programs ([`ResourceError`]), or
//! work it cannot take ([`PackError`]).

use quatcurve_shader::ShaderError;

/// Why the GPU path failed.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter could be found.
    #[error("no GPU adapter: {0}")]
    NoAdapter(#[from] wgpu::RequestAdapterError),
    /// The adapter would not open a device.
    #[error("GPU device error: {0}")]
    OpenDevice(#[from] wgpu::RequestDeviceError),
    /// The WGSL program failed naga validation or reflection (a bug in this crate).
    #[error("shader: {0}")]
    Shader(#[from] ShaderError),
    /// A program's resource the host cannot bind (a bug in this crate).
    #[error("shader: {0}")]
    Resource(#[from] ResourceError),
    /// The job or the times break a rule of evaluation.
    #[error(transparent)]
    Eval(#[from] quatcurve_eval::error::Error),
    /// The device rejected an operation (validation, out of memory, internal error).
    #[error("GPU device error: {0}")]
    Device(#[from] wgpu::Error),
    /// Waiting for the device failed.
    #[error("GPU device error: {0}")]
    Poll(#[from] wgpu::PollError),
    /// A buffer could not be mapped for the host to write or read.
    #[error("GPU device error: {during}: {error}")]
    Map {
        /// What the mapping was for.
        during: &'static str,
        /// wgpu's reason.
        error: MapError,
    },
    /// The device was lost.
    #[error("GPU device lost: {reason:?}: {message}")]
    DeviceLost {
        /// wgpu's reason.
        reason: wgpu::DeviceLostReason,
        /// The driver's words.
        message: String,
    },
    /// The batch cannot be packed for the kernel.
    #[error("{0}")]
    Pack(#[from] PackError),
    /// Inputs that do not fit together, or do not fit the device.
    #[error("{0}")]
    Job(#[from] JobError),
}

/// Why a buffer could not be mapped.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    /// The map request failed.
    #[error("{0}")]
    Async(#[from] wgpu::BufferAsyncError),
    /// The mapped range could not be viewed.
    #[error("{0}")]
    Range(#[from] wgpu::MapRangeError),
    /// The map callback was dropped unrun.
    #[error("a map callback never ran")]
    NeverRan,
}

/// Inputs to a GPU pass that do not fit together, or do not fit the device.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum JobError {
    /// An evaluation order that puts a joint before its parent.
    #[error("joint {joint} comes before its parent {parent} in the order")]
    ParentAfterChild {
        /// The joint.
        joint: usize,
        /// Its parent.
        parent: usize,
    },
    /// An evaluation order that leaves joints out.
    #[error("the order misses some joints")]
    OrderIncomplete,
    /// A flat array that is not whole units of what it holds.
    #[error("{len} {what} are not {whole}")]
    NotWhole {
        /// What the array holds (`local floats`).
        what: &'static str,
        /// Its length.
        len: usize,
        /// The unit it must be whole numbers of (`whole frames of 3 joints`).
        whole: String,
    },
    /// A joint index past the joints.
    #[error("joint index {index} with {joints} joints")]
    JointIndex {
        /// The index.
        index: u32,
        /// Joints there are.
        joints: usize,
    },
    /// A skin whose joints or inverse binds do not match the skeleton.
    #[error("a skin joint out of range, or not one inverse bind each")]
    Skin,
    /// One unit of work larger than a storage binding.
    #[error("{what} needs {bytes} bytes in one storage binding, more than the device's {limit}")]
    OverBinding {
        /// The unit (`one frame of 3 joints`).
        what: String,
        /// Bytes it needs.
        bytes: u64,
        /// The device's binding limit.
        limit: u64,
    },
    /// Work that needs several bindings where the pass takes one.
    #[error("{what} need {bindings} storage bindings of {limit} bytes; {pass} keeps them in one")]
    Bindings {
        /// The data (`the rotation curves`).
        what: &'static str,
        /// Bindings needed.
        bindings: usize,
        /// The device's binding limit.
        limit: u64,
        /// The pass (`evaluate_into`).
        pass: &'static str,
    },
    /// A caller's buffer smaller than the batch.
    #[error("target buffer has {has} bytes, the batch needs {needs}")]
    TargetTooSmall {
        /// Its bytes.
        has: u64,
        /// Bytes needed.
        needs: u64,
    },
    /// Two knots of a vector curve closer than the kernel's fixed-point times resolve.
    #[error("vector curve {curve}: knots {knot} and {next} are closer than the GPU's time resolution", next = knot + 1)]
    KnotsTooClose {
        /// The curve.
        curve: usize,
        /// The first knot.
        knot: usize,
    },
    /// An instance's clips or weight out of range.
    #[error("instance {instance}: clips {clips:?} or weight {weight} out of range")]
    Instance {
        /// The instance.
        instance: usize,
        /// Its two clips.
        clips: [usize; 2],
        /// Its blend weight.
        weight: f32,
    },
    /// More instances than one binding of palettes holds.
    #[error("{instances} instances are more than one binding of palettes holds ({max}): play them in parts")]
    TooManyInstances {
        /// Instances asked for.
        instances: usize,
        /// The most one frame plays.
        max: usize,
    },
    /// More workgroups than one 2D dispatch has.
    #[error("{0} workgroups exceed one 2D dispatch")]
    Workgroups(u64),
}

/// Why a batch cannot go to the GPU.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PackError {
    /// One track's keys alone exceed a binding limit (its samples are cut into pieces).
    #[error(
        "{track}: its keys need {bytes} bytes in one GPU binding, more than the device's {limit}; use the cpu device"
    )]
    TrackTooLarge {
        /// The track, by index and name.
        track: String,
        /// Bytes it would take.
        bytes: u64,
        /// The binding limit (bytes).
        limit: u64,
    },
    /// A Bezier degree beyond the shader's fixed arrays.
    #[error("{track}: Bezier degree {degree} is above the GPU limit of {max}; use the cpu or reference device")]
    BezierTooLong {
        /// The track, by index and name.
        track: String,
        /// The track's degree.
        degree: usize,
        /// The most allowed.
        max: usize,
    },
    /// Too many samples in one track for exact in-shader time generation.
    #[error("{track}: {count} samples is more than the GPU limit of {max} per track")]
    TooManySamples {
        /// The track, by index and name.
        track: String,
        /// Its samples.
        count: usize,
        /// The most allowed.
        max: usize,
    },
    /// Two distinct knots (key times) that the kernel's 32.32 fixed-point times cannot tell
    /// apart: the span between them would have zero length there (NaN samples).
    #[error("{track}: knots {knot} and {next} are {gap:e} s apart, closer than the GPU's time resolution of \
        {resolution:e} s; use the cpu device", next = knot + 1)]
    KnotsTooClose {
        /// The track, by index and name.
        track: String,
        /// The knot's index.
        knot: usize,
        /// The distance between the two knots (s).
        gap: f64,
        /// The smallest distance the kernel resolves (s).
        resolution: f64,
    },
}

/// A resource of a compute program the host cannot bind as it binds every other.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ResourceError {
    /// A bound variable without a name.
    #[error("the resource at binding {binding} has no name")]
    Unnamed {
        /// Its binding number.
        binding: u32,
    },
    /// A resource outside group 0.
    #[error("`{name}` is in group {group}; the host binds group 0 only")]
    Group {
        /// The variable.
        name: String,
        /// Its group.
        group: u32,
    },
    /// A resource that is not a uniform or storage buffer.
    #[error("`{name}` is in {space}, not a buffer")]
    NotBuffer {
        /// The variable.
        name: String,
        /// Its address space, as naga names it.
        space: String,
    },
    /// No buffer of this name.
    #[error("the shader has no buffer `{name}`")]
    Missing {
        /// The buffer asked for.
        name: String,
    },
}
