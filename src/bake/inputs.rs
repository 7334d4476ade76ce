//! A bake's inputs: files and directories expanded and sorted (the order every shard shares),
//! their output stems (two inputs may not write the same outputs), and each file read into the
//! common model with what it needs to write itself back (`Source`): glTF, BVH or a fitted container.

use super::error::BakeError;
use quatcurve_anim::error::InputError;
use quatcurve_anim::Animation;
use quatcurve_anim::{bvh, gltf};
use std::path::{Path, PathBuf};

/// A source read into the common model, with what it needs to write itself back.
pub(super) enum Source {
    Gltf(Box<gltf::GltfFile>),
    Bvh(bvh::BvhFile, Animation),
    Crowd(Animation),
    /// A fitted container without a BVH skeleton (one with it reads as [`Source::Bvh`]).
    Fitted(Animation),
}

/// The extensions a bake reads, lower case.
pub const INPUT_EXTENSIONS: [&str; 4] = ["gltf", "glb", "bvh", quatcurve_anim::qcf::EXTENSION];

/// `path`'s extension, lower case.
pub(crate) fn extension(path: &Path) -> Option<String> {
    path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase)
}

impl Source {
    /// Reads the file at `path` by its extension ([`INPUT_EXTENSIONS`]); a glTF's buffer URIs
    /// as `uris` allows.
    pub(super) fn read(path: &Path, uris: gltf::UriPolicy) -> Result<Self, InputError> {
        match extension(path).as_deref() {
            Some("gltf" | "glb") => Ok(Source::Gltf(Box::new(gltf::read(path, uris)?))),
            Some("bvh") => {
                let file = bvh::read(path)?;
                let name = path.file_stem().map_or_else(|| "motion".into(), |s| s.to_string_lossy().into_owned());
                let animation = file.animation(&name);
                Ok(Source::Bvh(file, animation))
            }
            Some(quatcurve_anim::qcf::EXTENSION) => {
                let container = quatcurve_anim::qcf::Container::read(path)?;
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
    pub(super) fn kind(&self) -> &'static str {
        match self {
            Source::Gltf(_) => "a glTF file",
            Source::Bvh(..) => "a BVH file",
            Source::Crowd(_) => "the built-in crowd",
            Source::Fitted(_) => "a fitted container",
        }
    }

    pub(super) fn animation(&self) -> &Animation {
        match self {
            Source::Gltf(f) => &f.animation,
            Source::Bvh(_, a) | Source::Crowd(a) | Source::Fitted(a) => a,
        }
    }
}

/// Files given, with directories replaced by their files of the `known` extensions (lower
/// case), sorted by path. A directory without one is an error: baking the built-in crowd
/// instead would be a surprise.
pub fn expand(inputs: &[PathBuf], known: &[&str]) -> Result<Vec<PathBuf>, BakeError> {
    let listed = known.iter().map(|e| format!(".{e}")).collect::<Vec<_>>().join(", ");
    let known = |p: &Path| extension(p).is_some_and(|e| known.contains(&e.as_str()));
    let mut files = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let entries = std::fs::read_dir(input)
                .map_err(|e| BakeError::option("inputs", format!("{}: cannot list: {e}", input.display())))?;
            let found: Vec<PathBuf> =
                entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file() && known(p)).collect();
            if found.is_empty() {
                return Err(BakeError::option(
                    "inputs",
                    format!("{}: the directory holds no file of {listed}", input.display()),
                ));
            }
            files.extend(found);
        } else {
            files.push(input.clone());
        }
    }
    // One order for every shard (DESIGN section 7): by path, bytewise.
    files.sort_by(|a, b| a.as_os_str().as_encoded_bytes().cmp(b.as_os_str().as_encoded_bytes()));
    Ok(files)
}

/// Each input's output stem (its file name without extension). Two inputs with one stem
/// (`walk/idle.glb`, `run/idle.bvh`) would write the same outputs, the second silently
/// replacing the first: refused before anything is baked.
pub fn output_stems(inputs: &[PathBuf]) -> Result<Vec<String>, BakeError> {
    let stems: Vec<String> = inputs
        .iter()
        .map(|p| p.file_stem().map_or_else(|| "out".into(), |s| s.to_string_lossy().into_owned()))
        .collect();
    let mut seen: std::collections::HashMap<&str, &Path> = std::collections::HashMap::new();
    for (stem, path) in stems.iter().zip(inputs) {
        if let Some(first) = seen.insert(stem, path) {
            return Err(BakeError::Job(format!(
                "{} and {} would both write {stem}.*; bake them into separate output directories",
                first.display(),
                path.display(),
            )));
        }
    }
    Ok(stems)
}
