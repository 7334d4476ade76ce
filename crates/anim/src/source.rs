//! Every input format read by its extension into the model, with what it needs to write
//! itself back ([`Source`]): glTF and GLB, BVH, a fitted container; the synthetic crowd is
//! one too.

use crate::error::InputError;
use crate::Animation;
use crate::{bvh, gltf, qcf};
use std::path::Path;

/// A source read into the common model, with what it needs to write itself back.
pub enum Source {
    /// A glTF or GLB file.
    Gltf(Box<gltf::GltfFile>),
    /// A BVH file (or a fitted container of one), read as its one clip.
    Bvh(bvh::BvhFile, Animation),
    /// The built-in crowd ([`crate::crowd`]).
    Crowd(Animation),
    /// A fitted container without a BVH skeleton (one with it reads as [`Source::Bvh`]).
    Fitted(Animation),
}

/// The extensions read as inputs, lower case.
pub const INPUT_EXTENSIONS: [&str; 4] = ["gltf", "glb", "bvh", qcf::EXTENSION];

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
            Some("bvh") => {
                let file = bvh::read(path)?;
                let name = path.file_stem().map_or_else(|| "motion".into(), |s| s.to_string_lossy().into_owned());
                let animation = file.animation(&name);
                Ok(Source::Bvh(file, animation))
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
            Source::Bvh(..) => "a BVH file",
            Source::Crowd(_) => "the built-in crowd",
            Source::Fitted(_) => "a fitted container",
        }
    }

    /// What was read, in the model.
    #[must_use]
    pub fn animation(&self) -> &Animation {
        match self {
            Source::Gltf(f) => &f.animation,
            Source::Bvh(_, a) | Source::Crowd(a) | Source::Fitted(a) => a,
        }
    }
}
