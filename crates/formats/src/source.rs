//! Every input format behind one interface ([`Input`]): read by its extension through the
//! table of importers ([`IMPORTERS`]) into the model, with what the format needs to write baked
//! frames back. glTF and GLB, FBX, BVH, SMPL-family pose arrays and fitted containers are
//! files; the synthetic crowd is an input too. A job over inputs ([`Source`]) never names a
//! format: a new one is its module, its [`Input`] and a row of [`IMPORTERS`].

use crate::{bvh, crowd, fbx, gltf, smpl, usd};
use quatcurve_anim::error::{AnimationError, InputError};
use quatcurve_anim::{Animation, ClipFrames};
use quatcurve_core::curve::{Curve, DEFAULT_CURVE};
use quatcurve_eval::error::one_of;
use quatcurve_qcf::BvhSkeleton;
use std::path::Path;

/// One input read into the model, and what its format needs to write baked frames back.
pub trait Input: Send + Sync {
    /// What it is, for messages ("a glTF file").
    fn kind(&self) -> &'static str;

    /// The model it was read into.
    fn animation(&self) -> &Animation;

    /// The glTF scene behind it (a glTF file, an FBX file converted to one): its meshes and
    /// skins, which skin and vertex textures draw.
    fn gltf(&self) -> Option<&gltf::GltfFile> {
        None
    }

    /// The curve family a bake takes when none is asked for: `None`, the source's own
    /// interpolation of each channel ([`quatcurve_anim::Interpolation`]).
    fn default_curve(&self) -> Option<Curve> {
        None
    }

    /// Whether its joints have their rest offsets and its space a known up axis, so that
    /// model-space products (positions by forward kinematics, headings) mean anything.
    fn has_offsets(&self) -> bool {
        true
    }

    /// Every clip's baked frames written back in the input's own format (`slerped`: whether
    /// they are the source's own interpolation of its keys): the file's extension and bytes;
    /// `None` for an input without a file format of its own.
    ///
    /// # Errors
    /// [`InputError::Output`] when the file cannot be assembled (a GLB over 4 GiB).
    fn write_back(&self, frames: &[ClipFrames<'_>], slerped: bool) -> Result<Option<WrittenBack>, InputError>;

    /// How the file's units and axes were converted into the model's, when they were.
    fn conversion(&self) -> Option<Conversion> {
        None
    }

    /// The per-frame arrays beside its clip, each with what the written-back file holds of it.
    fn arrays(&self) -> Vec<(String, &'static str)> {
        Vec::new()
    }

    /// What a fitted container keeps of the file to write its clip back in the format: a
    /// BVH's hierarchy and frame time.
    fn skeleton(&self) -> Option<BvhSkeleton> {
        None
    }
}

/// A file of baked frames in an input's own format ([`Input::write_back`]).
#[derive(Clone, Debug, PartialEq)]
pub struct WrittenBack {
    /// Its extension, lower case, without the dot.
    pub extension: &'static str,
    /// Its bytes.
    pub bytes: Vec<u8>,
}

/// How an input's units and axes were converted into the model's (glTF's: metres, +Y up).
#[derive(Clone, Debug, PartialEq)]
pub struct Conversion {
    /// The length of the file's unit in metres.
    pub from_unit_metres: f64,
    /// The file's up axis (`+Y`, `+Z`, ...).
    pub from_up: String,
    /// What the joints, skins and textures are in, and how they got there, in words.
    pub to: &'static str,
}

/// How a job reads its inputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Which of a glTF's buffer URIs may be read.
    pub uris: gltf::UriPolicy,
}

/// What an importer returns: the input, or why the file could not be read.
pub type Imported = Result<Box<dyn Input>, InputError>;

/// A reader of one format: the extensions it takes (lower case) and how it reads a file.
pub struct Importer {
    /// Its files' extensions.
    pub extensions: &'static [&'static str],
    /// What its files hold, where the extension does not say (" (SMPL-family poses)").
    pub holds: &'static str,
    /// The extension of the file its inputs write baked frames back to, where they may
    /// ([`Input::write_back`]), so that a job can check the name before it reads them.
    pub writes_back: Option<&'static str>,
    /// Whether its inputs may hold meshes ([`Input::gltf`]).
    pub meshes: bool,
    /// Whether its files say their length unit (read into glTF's metre); a BVH's offsets and a
    /// container's are in whatever unit their source had.
    pub says_unit: bool,
    /// Reads one file into the model.
    pub read: fn(&Path, ReadOptions) -> Imported,
}

/// Every format read as an input, by extension.
pub static IMPORTERS: [Importer; 6] = [
    Importer {
        extensions: &["gltf", "glb"],
        holds: "",
        writes_back: Some("glb"),
        meshes: true,
        says_unit: true,
        read: |path, options| Ok(Box::new(gltf::read(path, options.uris)?)),
    },
    Importer {
        extensions: &[fbx::EXTENSION],
        holds: "",
        writes_back: Some("glb"),
        meshes: true,
        says_unit: true,
        read: |path, _| Ok(Box::new(fbx::read(path)?)),
    },
    Importer {
        extensions: &usd::EXTENSIONS,
        holds: "",
        writes_back: Some("glb"),
        meshes: true,
        says_unit: true,
        read: |path, _| Ok(Box::new(usd::read(path)?)),
    },
    Importer {
        extensions: &["bvh"],
        holds: "",
        writes_back: Some("bvh"),
        meshes: false,
        says_unit: false,
        read: |path, _| Ok(Box::new(Bvh::new(bvh::read(path)?, &clip_name(path)))),
    },
    Importer {
        extensions: &[smpl::EXTENSION],
        holds: " (SMPL-family poses)",
        writes_back: Some(smpl::EXTENSION),
        meshes: false,
        says_unit: true,
        read: |path, _| Ok(Box::new(Smpl::new(smpl::read(path)?, &clip_name(path)))),
    },
    Importer {
        extensions: &[quatcurve_qcf::EXTENSION],
        holds: " (a fitted container)",
        // A container of a BVH source bakes to BVH again.
        writes_back: Some("bvh"),
        meshes: false,
        says_unit: false,
        read: |path, _| fitted(&quatcurve_qcf::Container::read(path)?),
    },
];

/// The importer of `path`'s extension, if any takes it.
#[must_use]
pub fn importer(path: &Path) -> Option<&'static Importer> {
    let extension = extension(path)?;
    IMPORTERS.iter().find(|i| i.extensions.contains(&extension.as_str()))
}

/// The formats [`IMPORTERS`] read, for messages: ".gltf, .glb, ... or .qcf (a fitted container)".
fn expected() -> String {
    one_of(IMPORTERS.iter().flat_map(|i| i.extensions.iter().map(move |e| format!(".{e}{}", i.holds))))
}

/// The extensions read as inputs, lower case, in [`IMPORTERS`]' order.
pub fn input_extensions() -> impl Iterator<Item = &'static str> {
    IMPORTERS.iter().flat_map(|i| i.extensions.iter().copied())
}

/// The one clip of a single-clip file: the file's stem.
fn clip_name(path: &Path) -> String {
    path.file_stem().map_or_else(|| "motion".into(), |s| s.to_string_lossy().into_owned())
}

/// `path`'s extension, lower case.
pub fn extension(path: &Path) -> Option<String> {
    path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase)
}

/// An input of any format, as a job over inputs takes it.
pub struct Source(Box<dyn Input>);

impl Source {
    /// Reads the file at `path` with the importer of its extension ([`IMPORTERS`]).
    ///
    /// # Errors
    /// [`InputError::UnknownFormat`] for an extension no importer takes; the importer's errors.
    pub fn read(path: &Path, options: ReadOptions) -> Result<Self, InputError> {
        let importer = importer(path).ok_or_else(|| InputError::UnknownFormat { expected: expected() })?;
        Ok(Self((importer.read)(path, options)?))
    }

    /// The built-in crowd of `characters` characters ([`crowd::crowd`]).
    #[must_use]
    pub fn crowd(characters: usize) -> Self {
        Self(Box::new(Crowd(crowd::crowd(characters))))
    }

    /// Refuses work that needs positions (`needs`, what it is, and `instead`, what would work)
    /// when the joints have no offsets ([`Input::has_offsets`]): their positions would be wrong.
    ///
    /// # Errors
    /// [`InputError::Animation`] saying why and what would work.
    pub fn require_offsets(&self, needs: &'static str, instead: &'static str) -> Result<(), InputError> {
        if self.has_offsets() {
            return Ok(());
        }
        Err(AnimationError::RotationsAlone { kind: self.kind(), needs, instead }.into())
    }
}

impl std::ops::Deref for Source {
    type Target = dyn Input;

    fn deref(&self) -> &Self::Target {
        &*self.0
    }
}

impl Input for gltf::GltfFile {
    fn kind(&self) -> &'static str {
        "a glTF file"
    }

    fn animation(&self) -> &Animation {
        &self.animation
    }

    fn gltf(&self) -> Option<&gltf::GltfFile> {
        Some(self)
    }

    fn write_back(&self, frames: &[ClipFrames<'_>], _: bool) -> Result<Option<WrittenBack>, InputError> {
        Ok(Some(WrittenBack { extension: "glb", bytes: self.to_glb(frames)? }))
    }
}

/// The [`Input`] of a scene converted to glTF as it was read (`$kind`, "an FBX file"), with its
/// `gltf`, `source_unit_metres` and `source_up`, and what it was converted to (`$to`).
macro_rules! converted_input {
    ($file:ty, $kind:expr, $to:expr) => {
        impl Input for $file {
            fn kind(&self) -> &'static str {
                $kind
            }

            fn animation(&self) -> &Animation {
                &self.gltf.animation
            }

            fn gltf(&self) -> Option<&gltf::GltfFile> {
                Some(&self.gltf)
            }

            fn write_back(&self, frames: &[ClipFrames<'_>], _: bool) -> Result<Option<WrittenBack>, InputError> {
                Ok(Some(WrittenBack { extension: "glb", bytes: self.gltf.to_glb(frames)? }))
            }

            fn conversion(&self) -> Option<Conversion> {
                Some(Conversion {
                    from_unit_metres: self.source_unit_metres,
                    from_up: self.source_up.to_string(),
                    to: $to,
                })
            }
        }
    };
}

converted_input!(
    fbx::FbxFile,
    "an FBX file",
    "metres, +Y up, right-handed (glTF's space), by adjusting the nodes' transforms as ufbx loads the file; mesh \
     data and inverse bind matrices are the file's"
);

converted_input!(
    usd::UsdFile,
    "a USD stage",
    "metres, +Y up (glTF's space), by each skeleton's node; joints, mesh data and inverse bind matrices are the \
     stage's"
);

/// A BVH file (or a fitted container of one), read as its one clip.
struct Bvh {
    file: bvh::BvhFile,
    animation: Animation,
}

impl Bvh {
    fn new(file: bvh::BvhFile, clip_name: &str) -> Self {
        let animation = file.animation(clip_name);
        Self { file, animation }
    }
}

impl Input for Bvh {
    fn kind(&self) -> &'static str {
        "a BVH file"
    }

    fn animation(&self) -> &Animation {
        &self.animation
    }

    fn write_back(&self, frames: &[ClipFrames<'_>], _: bool) -> Result<Option<WrittenBack>, InputError> {
        let text = self.file.to_text(&self.animation.clips[0], &frames[0]);
        Ok(Some(WrittenBack { extension: "bvh", bytes: text.into_bytes() }))
    }

    fn skeleton(&self) -> Option<BvhSkeleton> {
        Some(BvhSkeleton { hierarchy: self.file.hierarchy().to_string(), frame_time: self.file.frame_time })
    }
}

/// SMPL-family pose arrays (AMASS's `.npz`), read as their one clip.
struct Smpl {
    file: smpl::SmplFile,
    animation: Animation,
}

impl Smpl {
    fn new(file: smpl::SmplFile, clip_name: &str) -> Self {
        let animation = file.animation(clip_name);
        Self { file, animation }
    }
}

impl Input for Smpl {
    fn kind(&self) -> &'static str {
        "an SMPL-family pose archive"
    }

    fn animation(&self) -> &Animation {
        &self.animation
    }

    /// SMPL-family arrays hold rotations alone, the offsets being the body model's, and say
    /// nothing of their axes (AMASS is Z up, other SMPL-X data Y up).
    fn has_offsets(&self) -> bool {
        false
    }

    fn write_back(&self, frames: &[ClipFrames<'_>], slerped: bool) -> Result<Option<WrittenBack>, InputError> {
        Ok(Some(WrittenBack { extension: smpl::EXTENSION, bytes: self.file.to_npz(&frames[0], slerped)? }))
    }

    fn arrays(&self) -> Vec<(String, &'static str)> {
        self.file.arrays()
    }
}

/// The built-in crowd: keys sampled from a smooth motion, baked with the C2 curve
/// ([`DEFAULT_CURVE`]) unless another is asked for; no file of its own.
struct Crowd(Animation);

impl Input for Crowd {
    fn kind(&self) -> &'static str {
        "the built-in crowd"
    }

    fn animation(&self) -> &Animation {
        &self.0
    }

    fn default_curve(&self) -> Option<Curve> {
        Some(DEFAULT_CURVE)
    }

    fn write_back(&self, _: &[ClipFrames<'_>], _: bool) -> Result<Option<WrittenBack>, InputError> {
        Ok(None)
    }
}

/// A fitted container without a BVH skeleton: no file format of its own to write back.
struct Fitted(Animation);

impl Input for Fitted {
    fn kind(&self) -> &'static str {
        "a fitted container"
    }

    fn animation(&self) -> &Animation {
        &self.0
    }

    fn write_back(&self, _: &[ClipFrames<'_>], _: bool) -> Result<Option<WrittenBack>, InputError> {
        Ok(None)
    }
}

/// A fitted container's clips; one that keeps its source's BVH skeleton reads as that BVH.
fn fitted(container: &quatcurve_qcf::Container) -> Imported {
    let animation = container.animation();
    Ok(match &container.bvh {
        Some(skeleton) => Box::new(Bvh { file: bvh::skeleton(skeleton, &animation)?, animation }),
        None => Box::new(Fitted(animation)),
    })
}
