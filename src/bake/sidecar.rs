//! The sidecar JSON beside an input's textures (DESIGN section 5b): what a renderer needs to
//! read them (joints, parents, rest pose, skins, per-clip files, rows, rates and loops).

use super::texture::{Precision, TextureKind};
use super::{Animation, Baked};
use serde::Serialize;

/// The job's options a sidecar records.
pub(super) struct SidecarOptions<'a> {
    pub(super) curve: &'a str,
    pub(super) rate: f64,
    pub(super) texture: TextureKind,
    pub(super) precision: Precision,
    pub(super) atlas: bool,
}

/// The sidecar JSON next to the animation textures (DESIGN section 5b).
#[derive(Serialize)]
pub(super) struct Sidecar<'a> {
    source: &'a str,
    curve: &'a str,
    rate: f64,
    device: &'a str,
    texture: &'a str,
    channels: &'static [&'static str],
    precision: &'a str,
    layout: String,
    max_key_error_rad: Option<f64>,
    baked_file: Option<String>,
    joints: Vec<&'a str>,
    /// Parent joint index, -1 for a root.
    parents: Vec<i64>,
    rest: Vec<Rest>,
    skins: Vec<SidecarSkin<'a>>,
    clips: Vec<SidecarClip>,
}

/// A joint's rest pose, parent-relative.
#[derive(Serialize)]
pub(super) struct Rest {
    translation: [f64; 3],
    rotation: [f64; 4],
    scale: [f64; 3],
}

#[derive(Serialize)]
pub(super) struct SidecarSkin<'a> {
    name: &'a str,
    /// Joint indices in the skin's order (the rows of its skin texture).
    joints: &'a [usize],
}

#[derive(Serialize)]
pub(super) struct SidecarClip {
    pub(super) name: String,
    /// The texture (for `skin`, skin 0's).
    pub(super) file: String,
    /// Every texture of the clip: one, or for `skin` one per glTF skin.
    pub(super) files: Vec<String>,
    /// First row (frame) of the clip in `file`: 0, or its place in the atlas texture.
    pub(super) first_row: usize,
    pub(super) frames: usize,
    pub(super) start: f64,
    pub(super) end: f64,
    /// Frames per second: the job's rate fitted to the clip's span (its first and last frames
    /// are its first and last keys), or with an exact rate the job's rate (open clips).
    pub(super) rate: f64,
    /// Baked as a loop: periodic curves, continuous across the seam.
    #[serde(rename = "loop")]
    pub(super) looping: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) preview: Option<String>,
}

impl<'a> Sidecar<'a> {
    /// The sidecar of one input's bake.
    pub(super) fn new(
        options: &SidecarOptions<'a>,
        animation: &'a Animation,
        baked: &Baked,
        source: &'a str,
        device: &'a str,
        baked_file: Option<String>,
        clips: Vec<SidecarClip>,
    ) -> Self {
        let &SidecarOptions { curve, rate, texture, precision, atlas } = options;
        let channels = texture.channels();
        let names = texture.channel_names().join(",");
        let layout = match (atlas, texture) {
            (false, TextureKind::Skin) if !animation.skins.is_empty() => {
                format!("per clip and skin: [frames, skin joints, {channels}] {}: {names}", precision)
            }
            (false, _) => format!("per clip: [frames, joints, {channels}] {}: {names}", precision),
            (true, _) => format!(
                "one atlas: [frames of every clip, joints, {channels}] {}: {names}; clip rows from first_row",
                precision
            ),
        };
        Sidecar {
            source,
            curve,
            rate,
            device,
            texture: texture.name(),
            channels: texture.channel_names(),
            precision: precision.name(),
            layout,
            max_key_error_rad: baked.max_key_error,
            baked_file,
            joints: animation.joints.iter().map(|j| j.name.as_str()).collect(),
            parents: animation.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i64)).collect(),
            rest: animation
                .joints
                .iter()
                .map(|j| Rest { translation: j.translation, rotation: j.rotation, scale: j.scale })
                .collect(),
            skins: animation.skins.iter().map(|s| SidecarSkin { name: &s.name, joints: &s.joints }).collect(),
            clips,
        }
    }
}
