//! What can go wrong in a bake: a job that cannot start ([`BakeError`]), and one input that
//! cannot be baked ([`InputError`]: the job goes on with the others and reports it).

use crate::device::DeviceError;

/// Why a bake job could not start, or could not keep its manifest.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BakeError {
    /// An option outside its rules; `option` is its name (`rate`, `shard`, `output`, ...),
    /// which the command line shows as its flag.
    #[error("{option} {reason}")]
    Option {
        /// The option's name.
        option: &'static str,
        /// What is wrong with it, said after the name.
        reason: String,
    },
    /// The job as a whole is inconsistent (two inputs writing the same outputs, a scheduler's
    /// index without its count).
    #[error("{0}")]
    Job(String),
    /// The manifest could not be written.
    #[error(transparent)]
    Manifest(#[from] crate::io::IoError),
}

impl BakeError {
    pub(crate) fn option(option: &'static str, reason: impl Into<String>) -> Self {
        Self::Option { option, reason: reason.into() }
    }
}

/// Why one input could not be baked. Every kind but a failing device is the input's (the
/// command line's exit code 2; a device failure is exit code 1).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum InputError {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Read(std::io::Error),
    /// Not one of [`super::inputs::INPUT_EXTENSIONS`].
    #[error("unknown format: expected .gltf, .glb, .bvh or .qcf (a fitted container)")]
    UnknownFormat,
    /// A fitted container ([`crate::fit::container`]) with a field truncated or out of range.
    #[error("fitted container {0}")]
    Container(#[from] crate::fit::container::ContainerError),
    /// A glTF file that is corrupt or breaks a rule of the format; the message names the node,
    /// accessor, skin or buffer.
    #[error("{0}")]
    Gltf(String),
    /// A malformed BVH hierarchy or motion section.
    #[error("line {line}: {reason}")]
    Bvh {
        /// 1-based line of the file.
        line: usize,
        /// What is wrong there.
        reason: String,
    },
    /// An animation that cannot be baked as asked: nothing animated, a joint hierarchy with a
    /// cycle, a loop that does not close, more samples than a bake may hold, a skin texture
    /// for a file without skins. The message names the clip, joint or channel.
    #[error("{0}")]
    Animation(String),
    /// Keys the curve builder rejects (the one key validation of the library), naming the
    /// channel as the track and the key.
    #[error(transparent)]
    Keys(#[from] crate::error::Error),
    /// An output that could not be written or assembled.
    #[error("{0}")]
    Output(String),
    /// The evaluating device refused the work or failed.
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// quatcurve itself failed (a worker thread that stopped).
    #[error("{0}")]
    Internal(String),
}

impl InputError {
    /// Whether the device or quatcurve itself failed, rather than the input being at fault.
    #[must_use]
    pub fn is_internal_failure(&self) -> bool {
        matches!(self, Self::Internal(_)) || matches!(self, Self::Device(e) if e.is_device_failure())
    }

    /// Whether an output could not be written (the input itself was fine).
    #[must_use]
    pub fn is_output_failure(&self) -> bool {
        matches!(self, Self::Output(_))
    }
}
