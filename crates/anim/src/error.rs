//! Why one input could not be read or used ([`InputError`]): a job over files goes on with the
//! other inputs and reports it.

/// Why one input could not be read into the model or used as asked. Every kind but
/// [`InputError::Internal`] is the input's (the command line's exit code 2; quatcurve's own
/// failure is exit code 1).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum InputError {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Read(std::io::Error),
    /// An extension no importer takes (`quatcurve_formats::source::IMPORTERS`).
    #[error("unknown format: expected {expected}")]
    UnknownFormat {
        /// The formats read, by extension.
        expected: String,
    },
    /// A fitted container (`quatcurve_qcf`) with a field truncated or out of range.
    #[error("fitted container {0}")]
    Container(#[from] ContainerError),
    /// An archive of numpy arrays (SMPL-family poses, `quatcurve_formats::smpl`) with a field missing, of
    /// the wrong shape or type, or out of its range; `field` is the array (or `file`).
    #[error("{field}: {reason}")]
    Arrays {
        /// The array, as the archive names it.
        field: String,
        /// What is wrong with it, naming the frame and joint where one is at fault.
        reason: String,
    },
    /// An FBX file ufbx cannot load, or a stack it cannot bake; the message is ufbx's.
    #[error("{0}")]
    Fbx(String),
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
    Keys(#[from] quatcurve_eval::error::Error),
    /// An output that could not be written or assembled.
    #[error("{0}")]
    Output(String),
    /// quatcurve itself failed (a worker thread that stopped).
    #[error("{0}")]
    Internal(String),
}

impl InputError {
    /// Whether quatcurve itself failed, rather than the input being at fault.
    #[must_use]
    pub fn is_internal_failure(&self) -> bool {
        matches!(self, Self::Internal(_))
    }

    /// Whether an output could not be written (the input itself was fine).
    #[must_use]
    pub fn is_output_failure(&self) -> bool {
        matches!(self, Self::Output(_))
    }
}

/// A field of a fitted container (`quatcurve_qcf`) that is missing, truncated or out of its range.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("byte {offset}: {field}: {reason}")]
pub struct ContainerError {
    /// Where the field starts.
    pub offset: usize,
    /// Which field (`clip 0 'walk', channel 3, knot 2`).
    pub field: String,
    /// What is wrong with it.
    pub reason: String,
}
