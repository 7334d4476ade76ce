//! Where a bake writes one input: its files so far (taken away if it fails), the atlas being
//! gathered, and each clip's name in its files' names.
use super::budget::ChosenRate;
use super::texture_file::{SheetSpec, TextureFile, Written};
use std::path::Path;

/// Where one input's outputs go and what is written so far (taken away again if the input
/// fails), with the atlas being gathered and its row count.
pub(super) struct Outputs<'a> {
    pub(super) dir: &'a Path,
    pub(super) stem: &'a str,
    pub(super) source: &'a str,
    /// With an error budget: each clip's chosen rate and its errors, for the sidecar.
    pub(super) rates: &'a [ChosenRate],
    /// Meshes the textures do not draw, for the sidecar.
    pub(super) not_drawn: &'a [String],
    /// What a skin texture's matrices draw of the baked glTF (the meshes Babylon hangs from a
    /// skin's parent); empty for other kinds.
    pub(super) skinned: &'a [quatcurve_formats::mesh::DeclaredPrimitive],
    pub(super) written: Vec<Written>,
    /// `--atlas`: the open files every clip appends to, and their rows so far.
    pub(super) atlas: Vec<TextureFile>,
    pub(super) rows: usize,
    /// Each clip's name in its files' names ([`clip_file_names`]).
    pub(super) clip_names: Vec<String>,
    /// The files of each clip's (or the atlas's) texture.
    pub(super) sheets: Vec<SheetSpec>,
}

/// Each clip's name as it appears in its files' names (`Fox.Walk.npy`): letters, digits, `-`
/// and `_` kept, any other character `_`; an empty name is `clip<index>`, and a name that
/// two clips would share (ignoring case, as some file systems do) gets `-<index>`.
pub(super) fn clip_file_names(animation: &quatcurve_anim::Animation) -> Vec<String> {
    let safe: Vec<String> = animation
        .clips
        .iter()
        .enumerate()
        .map(|(index, clip)| {
            let name: String = clip
                .name
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' })
                .collect();
            if name.is_empty() {
                format!("clip{index}")
            } else {
                name
            }
        })
        .collect();
    let lower: Vec<String> = safe.iter().map(|n| n.to_ascii_lowercase()).collect();
    safe.iter()
        .enumerate()
        .map(|(index, name)| {
            if lower.iter().filter(|n| **n == lower[index]).count() > 1 {
                format!("{name}-{index}")
            } else {
                name.clone()
            }
        })
        .collect()
}
