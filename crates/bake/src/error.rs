//! Why one input could not be baked ([`BakeError`]): the input itself, the device that
//! evaluated it, or a layout the shipped shaders and the bake disagree on ([`LayoutError`]).
//! The job goes on with the other inputs and reports it.

use quatcurve_anim::error::InputError;
use quatcurve_device::DeviceError;
use quatcurve_shader::uniform::UniformError;
use quatcurve_shader::{Program, ShaderError};

/// Why one input could not be baked: its reading or its rules ([`InputError`]), the device, or
/// a layout.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BakeError {
    /// The input could not be read, breaks a rule, or cannot be baked as asked; or an output
    /// could not be written.
    #[error(transparent)]
    Input(#[from] InputError),
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

impl From<quatcurve_eval::error::Error> for BakeError {
    /// Keys the curve builder rejects are the input's ([`InputError::Keys`]).
    fn from(e: quatcurve_eval::error::Error) -> Self {
        Self::Input(e.into())
    }
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
