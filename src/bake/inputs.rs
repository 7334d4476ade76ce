//! A bake's inputs: files and directories expanded and sorted (the order every shard shares),
//! their output stems (two inputs may not write the same outputs), and each file read into the
//! common model with what it needs to write itself back ([`Source`]).

use super::error::{BakeError, InputError};
use super::{bvh, gltf, Animation};
use std::path::{Path, PathBuf};

/// A source read into the common model, with what it needs to write itself back.
pub(super) enum Source {
    Gltf(Box<gltf::GltfFile>),
    Bvh(bvh::BvhFile, Animation),
    Crowd(Animation),
}

impl Source {
    /// Reads the file at `path` by its extension (glTF/GLB or BVH); a glTF's buffer URIs as
    /// `uris` allows.
    pub(super) fn read(path: &Path, uris: gltf::UriPolicy) -> Result<Self, InputError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("gltf" | "glb") => Ok(Source::Gltf(Box::new(gltf::read(path, uris)?))),
            Some("bvh") => {
                let file = bvh::read(path)?;
                let name = path.file_stem().map_or_else(|| "motion".into(), |s| s.to_string_lossy().into_owned());
                let animation = file.animation(&name);
                Ok(Source::Bvh(file, animation))
            }
            _ => Err(InputError::UnknownFormat),
        }
    }

    pub(super) fn animation(&self) -> &Animation {
        match self {
            Source::Gltf(f) => &f.animation,
            Source::Bvh(_, a) | Source::Crowd(a) => a,
        }
    }
}

/// Files given, with directories replaced by their .gltf/.glb/.bvh files, sorted by path. A
/// directory without one is an error: baking the built-in crowd instead would be a surprise.
pub(super) fn expand(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, BakeError> {
    let known = |p: &Path| {
        matches!(
            p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref(),
            Some("gltf" | "glb" | "bvh")
        )
    };
    let mut files = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let entries = std::fs::read_dir(input)
                .map_err(|e| BakeError::option("input", format!("{}: cannot list: {e}", input.display())))?;
            let found: Vec<PathBuf> =
                entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file() && known(p)).collect();
            if found.is_empty() {
                return Err(BakeError::option(
                    "input",
                    format!("{}: the directory holds no .gltf, .glb or .bvh file", input.display()),
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
pub(super) fn output_stems(inputs: &[PathBuf]) -> Result<Vec<String>, BakeError> {
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
