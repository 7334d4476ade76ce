//! Why the GPU path failed ([`GpuError`]): the device, the programs ([`ResourceError`]), or
//! work it cannot take ([`PackError`]).

use quatcurve_shader::ShaderError;

/// Why the GPU path failed.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter could be found.
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
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
    Device(String),
    /// The device was lost.
    #[error("GPU device lost: {0}")]
    DeviceLost(String),
    /// The batch cannot be packed for the kernel.
    #[error("{0}")]
    Pack(#[from] PackError),
    /// Inputs that do not fit together.
    #[error("{0}")]
    Job(String),
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
