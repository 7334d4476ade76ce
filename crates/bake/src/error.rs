//! Why one input could not be baked ([`BakeError`]): the input itself, the device that
//! evaluated it, or a layout the shipped shaders and the bake disagree on ([`LayoutError`]).
//! The job goes on with the other inputs and reports it.

use quatcurve_anim::error::{AnimationError, InputError, OutputError};
use quatcurve_device::DeviceError;
use quatcurve_eval::error::Number;
use quatcurve_shader::uniform::UniformError;
use quatcurve_shader::{Program, ShaderError};
use serde::{Deserialize, Serialize};

/// Why one input could not be baked: its reading or its rules ([`InputError`]), the device, or
/// a layout.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BakeError {
    /// The input could not be read, breaks a rule, or cannot be baked as asked; or an output
    /// could not be written.
    #[error(transparent)]
    Input(#[from] InputError),
    /// The input cannot be baked as asked.
    #[error(transparent)]
    Refused(Box<Refusal>),
    /// The evaluating device refused the work or failed.
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// The device refused or failed to skin one primitive of a vertex texture.
    #[error("{primitive}: {error}")]
    Skinning {
        /// The primitive (`node 'N', mesh 'M', primitive p`).
        primitive: String,
        /// What the device said.
        error: Box<DeviceError>,
    },
    /// The shipped shaders and the bake disagree on a layout (a bug: the tests bake every
    /// program).
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// A skeleton preview that could not be drawn or written.
    #[cfg(feature = "plot")]
    #[error(transparent)]
    Preview(#[from] quatcurve_plot::PlotError),
}

impl BakeError {
    /// Whether the device or quatcurve itself failed, rather than the input being at fault
    /// (the command line's exit code 1; the others are exit code 2).
    #[must_use]
    pub fn is_internal_failure(&self) -> bool {
        match self {
            Self::Input(e) => e.is_internal_failure(),
            Self::Device(e) => e.is_device_failure(),
            Self::Skinning { error, .. } => error.is_device_failure(),
            Self::Layout(_) => true,
            Self::Refused(_) => false,
            #[cfg(feature = "plot")]
            Self::Preview(_) => false,
        }
    }

    /// Whether an output could not be written (the input itself was fine).
    #[must_use]
    pub fn is_output_failure(&self) -> bool {
        match self {
            Self::Input(e) => e.is_output_failure(),
            #[cfg(feature = "plot")]
            Self::Preview(_) => true,
            _ => false,
        }
    }
}

impl From<Refusal> for BakeError {
    fn from(e: Refusal) -> Self {
        Self::Refused(Box::new(e))
    }
}

impl From<AnimationError> for BakeError {
    fn from(e: AnimationError) -> Self {
        Self::Input(e.into())
    }
}

impl From<OutputError> for BakeError {
    fn from(e: OutputError) -> Self {
        Self::Input(e.into())
    }
}

impl From<quatcurve_eval::error::Error> for BakeError {
    /// Keys the curve builder rejects are the input's ([`InputError::Keys`]).
    fn from(e: quatcurve_eval::error::Error) -> Self {
        Self::Input(e.into())
    }
}

/// An input that cannot be baked as asked: what it lacks or breaks, and what would bake.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Refusal {
    /// A vertex texture asked of an animation without meshes.
    #[error("a vertex texture skins a glTF's meshes, which an animation alone does not have; bake it with a BakeJob")]
    VertexWithoutMeshes,
    /// A vertex texture asked of an input that is not a glTF.
    #[error("vertex textures skin a glTF's meshes, and this is {0}; bake a bone texture")]
    VertexNeedsGltf(&'static str),
    /// A skin texture asked of a file without skins.
    #[error("the file has no skin to bake a skin texture for; bake a model texture instead")]
    NoSkin,
    /// A Babylon bake of an input without a skin.
    #[error("babylon plays a glTF skin's bones, and this is {0} without one; bake a glTF with a skinned mesh, or another format")]
    BabylonNeedsSkin(&'static str),
    /// A skin whose world space Babylon cannot invert.
    #[error("skin '{skin}': {error}")]
    Singular {
        /// The skin.
        skin: String,
        /// The singular transform.
        error: SingularWorld,
    },
    /// A Babylon texture larger than its sides allow.
    #[error("{texture}: {sheet}: {error}")]
    BabylonTooLarge {
        /// The texture (`clip 'walk'`).
        texture: String,
        /// The sheet (`skin 0`).
        sheet: String,
        /// Which side.
        error: BabylonTooLarge,
    },
    /// An image layout that cannot hold the texture.
    #[error("{texture}: {error}")]
    Image {
        /// The texture or primitive.
        texture: String,
        /// Why the layout cannot hold it.
        error: GridError,
    },
    /// An image that would take more memory than `IMAGE_MEMORY_LIMIT` while it is encoded.
    #[error(
        "{texture}: its {format} image {file} would take {mib} MiB of memory while it is gathered and encoded, over \
         IMAGE_MEMORY_LIMIT = {limit} MiB; bake at a lower rate, clip by clip rather than as one atlas, or as npy \
         (streamed)",
        limit = limit >> 20
    )]
    ImageMemory {
        /// The texture.
        texture: String,
        /// The image format.
        format: &'static str,
        /// The image's file name.
        file: String,
        /// MiB it would take.
        mib: u64,
        /// The most bytes (`IMAGE_MEMORY_LIMIT`).
        limit: u64,
    },
    /// Images that together would take more memory than `IMAGE_MEMORY_LIMIT`.
    #[error(
        "{texture}: its {images} {format} images would gather {mib} MiB of rows in memory together (the largest, \
         {largest}: {largest_mib} MiB), over IMAGE_MEMORY_LIMIT = {limit} MiB; bake at a lower rate, clip by clip \
         rather than as one atlas, or as npy (streamed)",
        limit = limit >> 20
    )]
    ImagesMemory {
        /// The texture.
        texture: String,
        /// Its images.
        images: usize,
        /// The image format.
        format: &'static str,
        /// MiB they would take.
        mib: u64,
        /// The largest image's sheet.
        largest: String,
        /// MiB the largest would take.
        largest_mib: u64,
        /// The most bytes (`IMAGE_MEMORY_LIMIT`).
        limit: u64,
    },
    /// A joint sheared, which rotation, translation and scale cannot hold.
    #[error(
        "clip '{clip}', frame {frame}: joint '{joint}' is sheared (a {kind} texture's rotation and scale would be off \
         by {residual:.1e}, over SHEAR_TOLERANCE = {tolerance:e}), which rotation, translation and scale cannot hold; \
         bake a {matrices} texture (matrices) instead"
    )]
    Sheared {
        /// The clip.
        clip: String,
        /// The frame.
        frame: usize,
        /// The joint.
        joint: String,
        /// The texture's kind.
        kind: &'static str,
        /// How far off rotation and scale would be.
        residual: f64,
        /// The most allowed (`SHEAR_TOLERANCE`).
        tolerance: f64,
        /// The matrix kind that holds it.
        matrices: &'static str,
    },
    /// Root motion asked of a clip that moves several characters.
    #[error(
        "clip '{clip}': {} scene roots move ({}{}): root motion is extracted from one character per input; bake them \
         apart, or keep the root motion in the textures",
        roots.len(),
        roots.iter().take(3).map(|r| format!("'{r}'")).collect::<Vec<_>>().join(", "),
        if roots.len() > 3 { ", ..." } else { "" }
    )]
    SeveralRoots {
        /// The clip.
        clip: String,
        /// The scene roots that move.
        roots: Vec<String>,
    },
    /// An error budget asked of a fitted clip.
    #[error(
        "clip '{0}' is fitted (control points, not keys): an error budget measures a bake against keys; bake it at a \
         fixed rate"
    )]
    FittedBudget(String),
    /// No rate up to the budget's highest keeps within it.
    #[error(
        "clip '{clip}': no rate up to {} Hz (the highest a budget may choose) keeps within {}: at {} Hz the worst \
         error is {:.3} degrees (joint '{}', {:.3} s) and {:.3} cm (joint '{}', {:.3} s); {}",
        Number(*max_rate),
        within,
        Number(*rate),
        rotation.value,
        rotation.joint,
        rotation.time,
        position.value,
        position.joint,
        position.time,
        match higher {
            Ok(rate) => format!("{} Hz would (a max_rate of {})", Number(*rate), rate.ceil()),
            Err(searched) => format!("none up to {} Hz does either", Number(*searched)),
        }
    )]
    NoRateHolds {
        /// The clip.
        clip: String,
        /// The budget, in words (`1 degrees and 0.5 cm`).
        within: String,
        /// The highest rate a budget may choose (Hz).
        max_rate: f64,
        /// The rate measured last (Hz).
        rate: f64,
        /// Its largest rotation error (degrees).
        rotation: Worst,
        /// Its largest position error (cm).
        position: Worst,
        /// The rate that would hold, or the highest searched.
        higher: Result<f64, f64>,
    },
}

/// Where an error is largest.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Worst {
    /// Degrees, or centimetres.
    pub value: f64,
    /// The joint's name.
    pub joint: String,
    /// Seconds from the clip's start.
    pub time: f64,
}

/// A node whose world matrix at rest has no inverse (a zero scale), so no bone can be written
/// in its space.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("node '{node}', the skinned mesh's parent in Babylon, has a singular world matrix at rest")]
pub struct SingularWorld {
    /// The node's name.
    pub node: String,
}

/// A Babylon texture over a side of the maximum texture size.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum BabylonTooLarge {
    /// Too many bones for one row.
    #[error("Babylon's texture is {width} texels wide ((bones + 1) * 4), over a side of {max}; raise the maximum texture size")]
    Wide {
        /// Texels a row takes.
        width: usize,
        /// The most a side may take.
        max: usize,
    },
    /// Too many frames for one column.
    #[error(
        "Babylon's texture is {frames} rows tall (one per frame, never wrapped), over a side of {max}; bake at a lower \
         rate, clip by clip rather than as one atlas, or raise the maximum texture size"
    )]
    Tall {
        /// Rows it takes.
        frames: usize,
        /// The most a side may take.
        max: usize,
    },
}

/// Why a texture's frames do not fit an image of the largest side.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum GridError {
    /// A joint's texels wider than a texture side.
    #[error("a joint takes {texels_per_joint} texels, more than a texture side of {max}")]
    JointTooWide {
        /// Texels a joint takes.
        texels_per_joint: usize,
        /// The largest side.
        max: usize,
    },
    /// More frames than the rows and columns of the largest side hold.
    #[error(
        "{frames} frames of {joints} joints take {texels} texels ({rows_per_frame} rows of {frame_width} per frame), more \
         than a texture side of {max} can hold in rows and columns; bake at a lower rate, clip by clip rather than as one \
         atlas, or raise the maximum texture size"
    )]
    FramesDoNotFit {
        /// Frames of the texture.
        frames: usize,
        /// Joints (or vertices) a frame.
        joints: usize,
        /// Texels of every frame.
        texels: usize,
        /// Rows a frame takes.
        rows_per_frame: usize,
        /// Texels a frame's row.
        frame_width: usize,
        /// The largest side.
        max: usize,
    },
}

/// Why a layout uniform or a shader record could not be made: the shipped shaders and the bake
/// disagree (a bug: the tests bake every program).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LayoutError {
    /// naga could not parse, translate or reflect the program.
    #[error(transparent)]
    Shader(#[from] ShaderError),
    /// The layout struct could not be filled from its fields or read back.
    #[error(transparent)]
    Uniform(#[from] UniformError),
    /// A layout of one program asked of the other's.
    #[error("a {layout} layout among the {program} program's")]
    Program {
        /// The layout's program.
        layout: Program,
        /// The program asked.
        program: Program,
    },
    /// A limit the shader does not declare.
    #[error("the shader has no `{name}`")]
    NoConstant {
        /// The constant.
        name: &'static str,
    },
    /// A vertex input whose glTF attribute the bake does not know.
    #[error("no glTF source for input `{name}`")]
    InputSource {
        /// The WGSL input.
        name: String,
    },
    /// A location naga's GLSL declares no input at.
    #[error("naga's GLSL names no input at location {location}")]
    NoGlslInput {
        /// The location.
        location: u32,
    },
    /// A texture file's layout.
    #[error("{file}: {error}")]
    Texture {
        /// The file.
        file: String,
        /// What is wrong with its layout.
        error: Box<LayoutError>,
    },
}
