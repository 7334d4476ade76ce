//! Every input format read by its extension into the model, with what it needs to write
//! itself back ([`Source`]): glTF and GLB, FBX, BVH, SMPL-family pose arrays, a fitted container;
//! the synthetic crowd is one too.

use crate::error::InputError;
use crate::Animation;
use crate::{bvh, fbx, gltf, qcf, smpl};
use quatcurve_core::curve::{Curve, DEFAULT_CURVE};
use std::path::Path;

/// A source read into the common model, with what it needs to write itself back.
pub enum Source {
    /// A glTF or GLB file.
    Gltf(Box<gltf::GltfFile>),
    /// An FBX file, as the glTF scene it converts to.
    Fbx(Box<fbx::FbxFile>),
    /// A BVH file (or a fitted container of one), read as its one clip.
    Bvh(bvh::BvhFile, Animation),
    /// SMPL-family pose arrays (AMASS's `.npz`), read as their one clip.
    Smpl(Box<smpl::SmplFile>, Animation),
    /// The built-in crowd ([`crate::crowd`]).
    Crowd(Animation),
    /// A fitted container without a BVH skeleton (one with it reads as [`Source::Bvh`]).
    Fitted(Animation),
}

/// The extensions read as inputs, lower case.
pub const INPUT_EXTENSIONS: [&str; 6] = ["gltf", "glb", fbx::EXTENSION, "bvh", smpl::EXTENSION, qcf::EXTENSION];

/// The one clip of a single-clip file: the file's stem.
fn clip_name(path: &Path) -> String {
    path.file_stem().map_or_else(|| "motion".into(), |s| s.to_string_lossy().into_owned())
}

/// `path`'s extension, lower case.
pub fn extension(path: &Path) -> Option<String> {
    path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase)
}

impl Source {
    /// Reads the file at `path` by its extension ([`INPUT_EXTENSIONS`]); a glTF's buffer URIs
    /// as `uris` allows.
    pub fn read(path: &Path, uris: gltf::UriPolicy) -> Result<Self, InputError> {
        match extension(path).as_deref() {
            Some("gltf" | "glb") => Ok(Source::Gltf(Box::new(gltf::read(path, uris)?))),
            Some(fbx::EXTENSION) => Ok(Source::Fbx(Box::new(fbx::read(path)?))),
            Some("bvh") => {
                let file = bvh::read(path)?;
                let animation = file.animation(&clip_name(path));
                Ok(Source::Bvh(file, animation))
            }
            Some(smpl::EXTENSION) => {
                let file = smpl::read(path)?;
                let animation = file.animation(&clip_name(path));
                Ok(Source::Smpl(Box::new(file), animation))
            }
            Some(qcf::EXTENSION) => {
                let container = qcf::Container::read(path)?;
                let animation = container.animation();
                match &container.bvh {
                    Some(skeleton) => Ok(Source::Bvh(bvh::skeleton(skeleton, &animation)?, animation)),
                    None => Ok(Source::Fitted(animation)),
                }
            }
            _ => Err(InputError::UnknownFormat),
        }
    }

    /// What the source is, for messages.
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Source::Gltf(_) => "a glTF file",
            Source::Fbx(_) => "an FBX file",
            Source::Bvh(..) => "a BVH file",
            Source::Smpl(..) => "an SMPL-family pose archive",
            Source::Crowd(_) => "the built-in crowd",
            Source::Fitted(_) => "a fitted container",
        }
    }

    /// What was read, in the model.
    #[must_use]
    pub fn animation(&self) -> &Animation {
        match self {
            Source::Gltf(f) => &f.animation,
            Source::Fbx(f) => &f.gltf.animation,
            Source::Bvh(_, a) | Source::Smpl(_, a) | Source::Crowd(a) | Source::Fitted(a) => a,
        }
    }

    /// The glTF scene of a glTF or FBX file (meshes, skins and the writer of a baked GLB).
    #[must_use]
    pub fn gltf(&self) -> Option<&gltf::GltfFile> {
        match self {
            Source::Gltf(f) => Some(f),
            Source::Fbx(f) => Some(&f.gltf),
            _ => None,
        }
    }

    /// The curve family a bake takes when none is asked for: `None`, the source's own
    /// interpolation of each channel ([`crate::Interpolation`]), for every file; the C2 curve
    /// ([`DEFAULT_CURVE`]) for the built-in crowd, whose keys are samples of a smooth motion.
    #[must_use]
    pub fn default_curve(&self) -> Option<Curve> {
        match self {
            Source::Crowd(_) => Some(DEFAULT_CURVE),
            _ => None,
        }
    }

    /// Refuses work that needs positions (`needs`, what it is, and `instead`, what would work)
    /// when the joints have no offsets ([`Self::has_offsets`]): their positions would be wrong.
    ///
    /// # Errors
    /// [`InputError::Animation`] saying why and what would work.
    pub fn require_offsets(&self, needs: &str, instead: &str) -> Result<(), InputError> {
        if self.has_offsets() {
            return Ok(());
        }
        Err(InputError::Animation(format!(
            "{} holds rotations alone (its joints' offsets come from the body model's shape, and its up axis is not \
             recorded), so {needs} would be wrong; {instead}",
            self.kind()
        )))
    }

    /// Whether its joints have their rest offsets and its space a known up axis, so that
    /// model-space products (positions by forward kinematics, headings) mean anything:
    /// SMPL-family arrays hold rotations alone, the offsets being the body model's, and say
    /// nothing of their axes (AMASS is Z up, other SMPL-X data Y up).
    #[must_use]
    pub fn has_offsets(&self) -> bool {
        !matches!(self, Source::Smpl(..))
    }
}
