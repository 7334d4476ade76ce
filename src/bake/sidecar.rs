//! The sidecar JSON beside an input's textures (DESIGN section 5b): what a renderer needs to
//! read them alone (joints, parents, rest pose, skins with their inverse bind matrices,
//! per-clip files, rows, rates and loops, and for image textures where each texel is).

use super::budget::{ChosenRate, ErrorBudget, SUBSTEPS};
use super::image::{Format, Grid};
use super::root_motion::RootTrack;
use super::texture::{Precision, TextureKind};
use super::texture_file::Written;
use super::vertex_texture::VertexSheets;
use super::Baked;
use crate::anim::Animation;
use serde::Serialize;

/// The job's options a sidecar records, and the device that ran the input.
pub(super) struct SidecarOptions<'a> {
    pub(super) device: &'a str,
    pub(super) curve: &'a str,
    pub(super) rate: f64,
    pub(super) texture: TextureKind,
    pub(super) precision: Precision,
    pub(super) format: Format,
    pub(super) atlas: bool,
    pub(super) max_error: Option<&'a ErrorBudget>,
}

/// The sidecar JSON next to the animation textures (DESIGN section 5b).
#[derive(Serialize)]
pub(super) struct Sidecar<'a> {
    source: &'a str,
    curve: &'a str,
    /// The rate asked for; each clip's own rate is its `rate` (fitted to its span).
    requested_rate: f64,
    device: &'a str,
    texture: &'a str,
    channels: &'static [&'static str],
    precision: &'a str,
    format: &'a str,
    layout: String,
    /// Image textures (EXR, PNG16): how a joint's floats fill its texels (`channels` names per
    /// texel, empty where a texel channel is unused), and where texel `t` of joint `j` in row
    /// `r` of a file is (`address`, with each file's numbers in `textures`).
    #[serde(skip_serializing_if = "Option::is_none")]
    texels: Option<Vec<Vec<&'static str>>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    address: Option<&'static str>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    textures: Vec<ImageRecord>,
    max_key_error_rad: Option<f64>,
    /// `--max-error`, `--max-error-mm`: the budget each clip's rate was chosen for, and how it
    /// was measured (each clip's result is its `between_frames`).
    #[serde(skip_serializing_if = "Option::is_none")]
    max_error: Option<BudgetRecord>,
    baked_file: Option<String>,
    joints: Vec<&'a str>,
    /// Parent joint index, -1 for a root.
    parents: Vec<i64>,
    rest: Vec<Rest>,
    skins: Vec<SidecarSkin<'a>>,
    /// Vertex textures: the mesh they play and each primitive's sheets.
    #[serde(skip_serializing_if = "Option::is_none")]
    vertex: Option<VertexRecord>,
    clips: Vec<SidecarClip>,
}

/// How a vertex texture's files are read (DESIGN section 5d).
#[derive(Serialize)]
pub(super) struct VertexRecord {
    /// The GLB of the skinned primitives as plain meshes, `TEXCOORD_0` each vertex's address.
    mesh_file: String,
    /// How a `.pos` texel decodes (with its file's `low` and `span` in `textures`).
    position: &'static str,
    /// How a `.nrm` texel decodes.
    normal: &'static str,
    /// Where vertex `v`'s texel of frame `frame` is, from its `TEXCOORD_0` `(u, v)`.
    texcoord: &'static str,
    primitives: Vec<VertexPrimitive>,
}

/// One skinned primitive of a vertex texture.
#[derive(Serialize)]
struct VertexPrimitive {
    /// `node 'N', mesh 'M', primitive p`.
    name: String,
    node: usize,
    mesh: usize,
    primitive: usize,
    skin: usize,
    vertices: usize,
    influences: usize,
    normals: bool,
    /// Vertices whose weights did not sum to 1 and were divided by their sum.
    normalized: usize,
    /// The file-name suffix of its sheets (before `.pos`/`.nrm` for images), and its mesh
    /// in `mesh_file`.
    suffix: String,
    mesh_in_file: usize,
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
    /// Per joint, its inverse bind matrix, 3x4 row-major (the last row `0 0 0 1`): what a
    /// `local` or `model` texture is multiplied by for skinning.
    inverse_bind: &'a [[f64; 12]],
}

/// One image texture file and where its texels are ([`Grid`]).
#[derive(Serialize)]
pub(super) struct ImageRecord {
    file: String,
    /// Joints per frame.
    joints: usize,
    #[serde(flatten)]
    grid: Grid,
    /// PNG16: per texel slot and channel, the `[min, max]` that 0 and 65535 stand for.
    #[serde(skip_serializing_if = "Option::is_none")]
    remap: Option<Vec<[[f32; 2]; 4]>>,
    /// A vertex texture's positions: `position = low + texel.xyz * span`.
    #[serde(skip_serializing_if = "Option::is_none")]
    low: Option<[f64; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    span: Option<[f64; 3]>,
}

/// The budget a bake chose its rates for.
#[derive(Serialize)]
struct BudgetRecord {
    degrees: Option<f64>,
    millimetres: Option<f64>,
    unit_mm: f64,
    max_rate: f64,
    /// Points of each frame interval the error was measured at.
    substeps: usize,
    /// How the frames are blended: `bone_pose` of `quatcurve shaders`.
    interpolation: &'static str,
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
    /// Baked as a loop: periodic curves, continuous across the seam. A loop's last row is the
    /// seam and equals its first: its period is `frames - 1` rows.
    #[serde(rename = "loop")]
    pub(super) looping: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) preview: Option<String>,
    /// With an error budget: the worst rotation (degrees) and model-space position (mm)
    /// errors between this clip's frames, where and when, and its bytes against `--rate`'s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) between_frames: Option<ChosenRate>,
    /// With `--root-motion extract`: the root's horizontal motion and heading per frame, taken
    /// out of the textures (`model = Root(t) * model in place`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) root_motion: Option<RootTrack>,
}

impl<'a> Sidecar<'a> {
    /// The sidecar of one input's bake; `vertex` with the mesh file's name for vertex
    /// textures.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        options: &SidecarOptions<'a>,
        animation: &'a Animation,
        baked: &Baked,
        source: &'a str,
        baked_file: Option<String>,
        clips: Vec<SidecarClip>,
        written: &[Written],
        vertex: Option<(&VertexSheets, String)>,
    ) -> Self {
        let &SidecarOptions { device, curve, rate, texture, precision, format, atlas, max_error } = options;
        let channels = texture.channels();
        let names = texture.channel_names().join(",");
        let precision = if format == Format::Png16 { "u16" } else { precision.name() };
        let layout = match (atlas, texture) {
            (false, TextureKind::Vertex) => {
                format!("per clip and skinned primitive: [frames, vertices, {channels}] {precision}: {names}")
            }
            (false, kind) if kind.is_skin() && !animation.skins.is_empty() => {
                format!("per clip and skin: [frames, skin joints, {channels}] {}: {names}", precision)
            }
            (false, _) => format!("per clip: [frames, joints, {channels}] {}: {names}", precision),
            (true, _) => format!(
                "one atlas: [frames of every clip, joints, {channels}] {}: {names}; clip rows from first_row",
                precision
            ),
        };
        let image = format != Format::Npy;
        let names_of = |range: &std::ops::Range<usize>| {
            let mut slot: Vec<&'static str> = texture.channel_names()[range.clone()].to_vec();
            slot.resize(4, "");
            slot
        };
        let textures = written
            .iter()
            .filter_map(|w| {
                let file = w.path.file_name()?.to_string_lossy().into_owned();
                w.image.as_ref().map(|i| ImageRecord {
                    file,
                    joints: i.joints,
                    grid: i.grid,
                    remap: i.remap.clone(),
                    low: i.bounds.map(|b| b.low),
                    span: i.bounds.map(|b| b.span()),
                })
            })
            .collect();
        let layout = match (image, texture) {
            (true, TextureKind::Vertex) => format!(
                "{layout}; as {format} RGBA images, .pos (positions) and .nrm (normals) per primitive, one texel per \
                 vertex (joint j = vertex, t = 0): see vertex, address and textures"
            ),
            (true, _) => format!("{layout}; as {format} RGBA images of texels: see texels, address and textures"),
            (false, _) => layout,
        };
        Sidecar {
            source,
            curve,
            requested_rate: rate,
            device,
            texture: texture.name(),
            channels: texture.channel_names(),
            precision,
            format: format.name(),
            layout,
            texels: (image && texture != TextureKind::Vertex).then(|| texture.texels().iter().map(names_of).collect()),
            address: image.then_some(super::image::ADDRESS),
            textures,
            max_key_error_rad: baked.max_key_error,
            max_error: max_error.map(|b| BudgetRecord {
                degrees: b.degrees,
                millimetres: b.millimetres,
                unit_mm: b.unit_mm,
                max_rate: b.max_rate,
                substeps: SUBSTEPS,
                interpolation: "nlerp of rotations on the shorter arc, lerp of translations and scales (bone_pose)",
            }),
            baked_file,
            joints: animation.joints.iter().map(|j| j.name.as_str()).collect(),
            parents: animation.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i64)).collect(),
            rest: animation
                .joints
                .iter()
                .map(|j| Rest { translation: j.translation, rotation: j.rotation, scale: j.scale })
                .collect(),
            skins: animation
                .skins
                .iter()
                .map(|s| SidecarSkin { name: &s.name, joints: &s.joints, inverse_bind: &s.inverse_bind })
                .collect(),
            vertex: vertex.map(|(sheets, mesh_file)| VertexRecord {
                mesh_file,
                position: POSITION_DECODING,
                normal: NORMAL_DECODING,
                texcoord: TEXCOORD_ADDRESS,
                primitives: sheets
                    .primitives
                    .iter()
                    .enumerate()
                    .map(|(k, p)| VertexPrimitive {
                        name: p.name.clone(),
                        node: p.node,
                        mesh: p.mesh,
                        primitive: p.primitive,
                        skin: p.skin,
                        vertices: p.vertices(),
                        influences: p.influences,
                        normals: p.normals.is_some(),
                        normalized: p.normalized,
                        suffix: super::vertex_texture::suffix(k),
                        mesh_in_file: k,
                    })
                    .collect(),
            }),
            clips,
        }
    }
}

/// [`super::vertex_encoding::Bounds::decode`] in words.
const POSITION_DECODING: &str = "position = low + texel.xyz * span (low and span of the file, in textures); \
    as npy: px, py, pz as they are";
/// [`super::vertex_encoding::decode_normal`] in words.
const NORMAL_DECODING: &str = "(u, v) = 2 * texel.xy - 1; z = 1 - |u| - |v|; f = max(-z, 0); \
    n = normalize(u - f * sign(u), v - f * sign(v), z), sign(0) = 1; as npy: nx, ny, nz as they are";
/// Where a vertex's texel is, from the mesh file's `TEXCOORD_0` (`vertex_glb::address`).
const TEXCOORD_ADDRESS: &str = "TEXCOORD_0 = (v mod frame_width, v div frame_width); for r = first_row + frame: \
    x = (r / frames_per_column) * frame_width + u, y = (r % frames_per_column) * rows_per_frame + v \
    (integer division)";
