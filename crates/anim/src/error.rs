//! Why one input could not be read or used ([`InputError`]): a job over files goes on with the
//! other inputs and reports it.

use quatcurve_eval::error::Number;

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
    /// An FBX file ufbx cannot load, or a stack it cannot bake; the description is ufbx's.
    #[error("{0}")]
    Fbx(FormatError),
    /// A USD stage openusd cannot read, or a skeleton, animation or mesh breaking a rule of
    /// UsdSkel, named by its prim path.
    #[error("{0}")]
    Usd(FormatError),
    /// A glTF file that is corrupt or breaks a rule of the format; the rule names the node,
    /// accessor, skin or buffer.
    #[error("{0}")]
    Gltf(FormatError),
    /// A malformed BVH hierarchy or motion section.
    #[error("line {line}: {reason}")]
    Bvh {
        /// 1-based line of the file.
        line: usize,
        /// What is wrong there.
        reason: String,
    },
    /// An animation that cannot be used as asked, naming the clip, joint or channel.
    #[error(transparent)]
    Animation(#[from] AnimationError),
    /// Keys the curve builder rejects (the one key validation of the library), naming the
    /// channel as the track and the key; or a sampling grid it refuses.
    #[error(transparent)]
    Keys(#[from] quatcurve_eval::error::Error),
    /// An output that could not be written or assembled.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// quatcurve itself failed.
    #[error(transparent)]
    Internal(#[from] InternalError),
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

/// A rule of a file format broken, in the format's own terms, with the lower library's error
/// when one found it (kept as the source, not as text).
#[derive(Debug)]
pub struct FormatError {
    /// The rule broken and where (`buffer 2 (uri a.bin)`, `not a valid glTF file`).
    pub rule: String,
    /// The reader's or parser's error, when one found it.
    pub source: Option<Box<dyn std::error::Error + Send + Sync>>,
}

impl FormatError {
    /// A rule broken, found here.
    #[must_use]
    pub fn rule(rule: impl Into<String>) -> Self {
        Self { rule: rule.into(), source: None }
    }

    /// A rule broken, found by a lower library's `error`.
    #[must_use]
    pub fn caused(rule: impl Into<String>, error: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> Self {
        Self { rule: rule.into(), source: Some(error.into()) }
    }
}

impl std::fmt::Display for FormatError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.source {
            Some(error) => write!(f, "{}: {error}", self.rule),
            None => f.write_str(&self.rule),
        }
    }
}

impl std::error::Error for FormatError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.source.as_deref().map(|e| e as &(dyn std::error::Error + 'static))
    }
}

/// An animation that cannot be used as asked: a broken hierarchy, a loop that does not close,
/// a clip, skin or instance that is not there.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AnimationError {
    /// A joint whose parent index is past the joints.
    #[error("joint {joint} ({name}): parent {parent} does not exist")]
    MissingParent {
        /// The joint.
        joint: usize,
        /// Its name.
        name: String,
        /// The parent index it names.
        parent: usize,
    },
    /// A joint on a cycle of the hierarchy.
    #[error("joint {joint} ({name}) is its own ancestor: the hierarchy has a cycle")]
    Cycle {
        /// The joint.
        joint: usize,
        /// Its name.
        name: String,
    },
    /// Nothing animated to bake.
    #[error("no rotation, translation or scale animation to bake")]
    NothingAnimated,
    /// Nothing to play.
    #[error("nothing to play: the file has no clip")]
    NoClip,
    /// Loop mode on for a fitted clip, an open curve of control points.
    #[error("clip '{clip}' is fitted (an open curve of control points); loop mode on needs keys")]
    FittedLoop {
        /// The clip.
        clip: String,
    },
    /// Loop mode on with a curve that cannot loop.
    #[error(
        "clip '{clip}': loop mode on needs a curve that loops; {curve} does not (the curves that loop are {looping})"
    )]
    CurveDoesNotLoop {
        /// The clip.
        clip: String,
        /// The curve asked for.
        curve: String,
        /// The curves that loop.
        looping: String,
    },
    /// Loop mode on for a rotation channel that does not end on its first rotation.
    #[error(
        "{channel}: loop mode on needs every rotation channel to end on its first rotation, but its last key is \
         {angle} rad from its first (at most {tolerance})",
        angle = Number(*angle),
        tolerance = Number(*tolerance)
    )]
    LoopOpen {
        /// The channel (`clip 'walk', hip rotation`).
        channel: String,
        /// Radians between its last and first keys.
        angle: f64,
        /// The most allowed.
        tolerance: f64,
    },
    /// A skin index past the file's skins.
    #[error("skin {skin} asked for, but the file has {skins} skin(s)")]
    NoSuchSkin {
        /// The index asked for.
        skin: usize,
        /// Skins the file has.
        skins: usize,
    },
    /// A skin joint the played file does not have.
    #[error("skin '{skin}': joint '{joint}' is not a joint of the played file")]
    SkinJoint {
        /// The skin.
        skin: String,
        /// The joint's name.
        joint: String,
    },
    /// An instance posed in a clip the file does not have.
    #[error("instance {instance}: clip {clip} asked for, but the file has {clips} clip(s)")]
    InstanceClip {
        /// The instance.
        instance: usize,
        /// The clip asked for.
        clip: usize,
        /// Clips the file has.
        clips: usize,
    },
    /// A clip named (or numbered) that the file does not have.
    #[error("no clip '{given}': the clips are {clips}")]
    NoSuchClip {
        /// The name or index given.
        given: String,
        /// The file's clips, by index and name (`0 'Survey', 1 'Walk' or 2 'Run'`).
        clips: String,
    },
    /// An instance at a time that is not finite.
    #[error("instance {instance}: time {time} is not finite")]
    InstanceTime {
        /// The instance.
        instance: usize,
        /// Its time.
        time: f64,
    },
    /// A blend weight outside `[0, 1]`.
    #[error("instance {instance}: blend weight {weight} is outside [0, 1]")]
    InstanceWeight {
        /// The instance.
        instance: usize,
        /// Its weight.
        weight: f32,
    },
    /// Work that needs the joints' positions, on an input of rotations alone.
    #[error(
        "{kind} holds rotations alone (its joints' offsets come from the body model's shape, and its up axis is not \
         recorded), so {needs} would be wrong; {instead}"
    )]
    RotationsAlone {
        /// The input's kind.
        kind: &'static str,
        /// The work asked for.
        needs: &'static str,
        /// What would work.
        instead: &'static str,
    },
    /// A container's BVH hierarchy whose joints are not its skeleton's.
    #[error("the container's BVH hierarchy has joints [{}] but its skeleton [{}]", hierarchy.join(", "), skeleton.join(", "))]
    HierarchyNotSkeleton {
        /// The hierarchy's joints.
        hierarchy: Vec<String>,
        /// The skeleton's.
        skeleton: Vec<String>,
    },
    /// A clip whose frames would bring a bake past the samples it may hold.
    #[error(
        "clip '{clip}' spans {} s: {} frames at {} Hz of {channels} channels and {joints} joints bring the bake of \
         this input past {limit} samples (2 GiB of output); bake at a lower rate",
        Number(*span),
        Number(*frames),
        Number(*rate)
    )]
    TooManySamples {
        /// The clip.
        clip: String,
        /// Its span (s).
        span: f64,
        /// Frames at the rate.
        frames: f64,
        /// The rate (Hz).
        rate: f64,
        /// Its channels.
        channels: usize,
        /// The joints.
        joints: usize,
        /// The most samples a bake may hold.
        limit: usize,
    },
    /// A GLB that would exceed 4 GiB; the words say which and what to do.
    #[error("{0}")]
    GlbTooLarge(&'static str),
}

/// An output that could not be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// A file that could not be created, written or committed (naming it).
    #[error(transparent)]
    File(#[from] quatcurve_eval::io::IoError),
    /// An output that would overwrite its input.
    #[error("{} would overwrite the input; choose another output directory", .0.display())]
    OverwritesInput(std::path::PathBuf),
    /// An output path that is a directory.
    #[error("{}: is a directory", .0.display())]
    IsDirectory(std::path::PathBuf),
    /// An output this build cannot write.
    #[error("{what} need the `{feature}` cargo feature")]
    NotBuilt {
        /// The output (`previews`).
        what: &'static str,
        /// The feature that writes it.
        feature: &'static str,
    },
    /// An archive that could not be assembled.
    #[error("{what}: {error}")]
    Archive {
        /// The archive (`the .npz archive`).
        what: &'static str,
        /// The archive writer's error.
        error: Box<dyn std::error::Error + Send + Sync>,
    },
}

/// quatcurve itself failed: a bug, never the input's fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum InternalError {
    /// A worker thread that panicked.
    #[error("the {0} panicked")]
    Panicked(&'static str),
    /// A finer grid whose frames are not whole substeps of a coarser one's intervals.
    #[error("clip '{clip}': {frames} dense frames are not {substeps} per each of {intervals} intervals")]
    Grid {
        /// The clip.
        clip: String,
        /// Frames of the finer grid.
        frames: usize,
        /// Substeps asked for per interval.
        substeps: usize,
        /// Intervals of the coarser grid.
        intervals: usize,
    },
    /// An output given more values than its shape holds.
    #[error("{}: more values than its shape holds", .0.display())]
    Overfull(std::path::PathBuf),
    /// An output finished short of its shape.
    #[error("{}: {left} values short of its shape", file.display())]
    Short {
        /// The output.
        file: std::path::PathBuf,
        /// Values missing.
        left: u64,
    },
    /// Data that could not be encoded as its format.
    #[error("{what}: {error}")]
    Encode {
        /// What was being encoded (a file, `the GLB`).
        what: String,
        /// The encoder's error.
        error: Box<dyn std::error::Error + Send + Sync>,
    },
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
