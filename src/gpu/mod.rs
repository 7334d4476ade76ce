//! The GPU path: WGSL compute shaders (in `shaders/`) evaluating the same packed batch as the
//! reference, in f32, through wgpu.
//!
//! - [`shader`]: the WGSL program, validated by naga; layout facts are read from it.
//! - [`layout`]: host twins of the kernel's structs; packing and chunking.
//! - [`evaluator`]: [`GpuEvaluator`], created once and reused.

pub mod evaluator;
pub mod fk;
pub mod layout;
pub mod shader;

pub use evaluator::{GpuEvaluator, GpuOutput, PreparedBatch};

/// Why the GPU path failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GpuError {
    /// No adapter could be found.
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    /// The WGSL program failed naga validation (a bug in this crate).
    #[error("shader: {0}")]
    Shader(String),
    /// The device rejected an operation (validation, out of memory, internal error).
    #[error("GPU device error: {0}")]
    Device(String),
    /// The device was lost.
    #[error("GPU device lost: {0}")]
    DeviceLost(String),
    /// The batch cannot be packed for the kernel.
    #[error("{0}")]
    Pack(#[from] layout::PackError),
    /// Inputs that do not fit together.
    #[error("{0}")]
    Job(String),
}
