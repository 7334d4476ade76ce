//! The sidecar JSON beside an input's textures (DESIGN section 6): what a renderer needs to
//! read them alone (joints, parents, rest pose, skins with their inverse bind matrices,
//! per-clip files, rows, rates and loops, and for image textures where each texel is). The
//! types here write it and read it back (the viewer reads bakes through them); reading is
//! lenient, as for a file an older build wrote: a field it lacks takes its default.

use super::budget::{ChosenRate, ErrorBudget, SUBSTEPS};
use super::image::{Format, Grid};
use super::root_motion::RootTrack;
use super::texture::{Precision, TextureKind};
use super::texture_file::Written;
use super::uniforms::{self, LayoutClip, LayoutOf, Layouts, ShaderRecord, UniformRecord};
use super::vertex_texture::VertexSheets;
use super::Baked;
use crate::error::LayoutError;
use quatcurve_anim::curves::CurveChoice;
use quatcurve_anim::{Animation, Interpolation};
use quatcurve_formats::mesh::DeclaredPrimitive;
use quatcurve_formats::source::Conversion;
use quatcurve_shader::Program;
use serde::{Deserialize, Serialize};

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

/// How `animation`'s channels declare their keys interpolated, each name once (glTF's).
fn declared_interpolations(animation: &Animation) -> Vec<String> {
    let mut declared: Vec<&str> = animation
        .clips
        .iter()
        .flat_map(|c| &c.channels)
        .filter_map(|c| c.interpolation().map(Interpolation::gltf_name))
        .collect();
    declared.sort_unstable();
    declared.dedup();
    declared.into_iter().map(str::to_string).collect()
}

/// The sidecar JSON next to the animation textures (DESIGN section 6).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Sidecar {
    /// The baked input's file name (or the built-in crowd's name).
    pub source: String,
    /// What the keys were interpolated with: `source` (each channel as its source plays it,
    /// `interpolation` naming how), a curve family, or `fitted-bspline` (a fitted input's own).
    pub curve: String,
    /// With `curve` `source`: how the source interpolates its channels, in glTF's words
    /// (`LINEAR`, `STEP`, `CUBICSPLINE`; BVH, FBX and SMPL frames are `LINEAR`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub interpolation: Vec<String>,
    /// The rate asked for; each clip's own rate is its `rate` (fitted to its span).
    pub requested_rate: f64,
    /// The device that evaluated the curves.
    pub device: String,
    /// The texture kind (`local`, `model`, `skin`, `model-trs`, `skin-trs`, `vertex`).
    pub texture: String,
    /// The names of a row's floats, in order.
    pub channels: Vec<String>,
    /// The element type of the files (`f32`, `f16`, `u16`).
    pub precision: String,
    /// The file format (`npy`, `exr`, `png16`, `babylon`).
    pub format: String,
    /// The files' layout in words.
    pub layout: String,
    /// Image textures (EXR, PNG16): how a joint's floats fill its texels (`channels` names per
    /// texel, empty where a texel channel is unused), and where texel `t` of joint `j` in row
    /// `r` of a file is (`address`, with each file's numbers in `textures`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texels: Option<Vec<Vec<String>>>,
    /// See [`Self::texels`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub address: Option<String>,
    /// Each image file's grid (and ranges, for PNG16 and vertex positions), and the layout
    /// uniform the shipped shaders read it with.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub textures: Vec<ImageRecord>,
    /// Image textures of a kind a shipped vertex shader plays (`skin-trs`, `vertex`): that
    /// shader, its inputs and its resources.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shader: Option<ShaderRecord>,
    /// The largest angle (radians) between a key and the baked curve at its time, over every
    /// rotation key.
    pub max_key_error_rad: Option<f64>,
    /// The error budget each clip's rate was chosen for, and how it was measured (each clip's
    /// result is its `between_frames`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_error: Option<BudgetRecord>,
    /// The baked glTF beside the textures (none for BVH inputs and the crowd).
    pub baked_file: Option<String>,
    /// Joint names.
    pub joints: Vec<String>,
    /// Parent joint index, -1 for a root.
    pub parents: Vec<i64>,
    /// Each joint's rest pose.
    pub rest: Vec<Rest>,
    /// The glTF skins.
    pub skins: Vec<SidecarSkin>,
    /// Vertex textures: the mesh they play and each primitive's sheets.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vertex: Option<VertexRecord>,
    /// `--format babylon`: how Babylon.js's `BakedVertexAnimationManager` plays the files.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub babylon: Option<BabylonRecord>,
    /// An input converted to glTF's space as it was read (FBX, DESIGN section 12).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub conversion: Option<ConversionRecord>,
    /// A pose archive's arrays (DESIGN section 11), in its order, each with what the baked
    /// archive holds of it: `resampled` at the new frames, `rate` (the new rate) or `copied`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub arrays: Vec<ArrayRecord>,
    /// Skin textures (`skin`, `skin-trs`): the baked glTF's primitives their matrices draw,
    /// skinned and rigid (a rigid part's `rigid` binding: its joint, weight 1, and the matrix
    /// into bind space), with whether each has `normals` and `texcoords` (a renderer binds
    /// zeros for a missing one; the shipped fragment shader then lights the faces).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub primitives: Vec<DeclaredPrimitive>,
    /// Meshes these textures do not draw (`node 'N', mesh 'M': why`), which a renderer
    /// drawing from them alone leaves out.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_drawn: Vec<String>,
    /// The baked clips.
    pub clips: Vec<SidecarClip>,
}

/// One array of a pose archive and what the baked archive holds of it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ArrayRecord {
    /// The array's name in the archive.
    pub name: String,
    /// `resampled`, `rate` or `copied`.
    pub written: String,
}

/// How a vertex texture's files are read (DESIGN section 8).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VertexRecord {
    /// The GLB of the drawn primitives (skinned, and rigid parts) as plain meshes, `TEXCOORD_0`
    /// each vertex's address.
    pub mesh_file: String,
    /// How a `.pos` texel decodes (with its file's `low` and `span` in `textures`).
    pub position: String,
    /// How a `.nrm` texel decodes.
    pub normal: String,
    /// Where vertex `v`'s texel of frame `frame` is, from its `TEXCOORD_0` `(u, v)`.
    pub texcoord: String,
    /// The drawn primitives, in the order of their sheets.
    pub primitives: Vec<VertexPrimitive>,
}

/// How an input was converted to glTF's space as it was read (DESIGN section 12).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ConversionRecord {
    /// The length of the file's unit in metres.
    pub from_unit_metres: f64,
    /// The file's up axis (`+Y`, `+Z`, ...).
    pub from_up: String,
    /// What the joints, skins and textures are in, and how they got there, in words.
    pub to: String,
}

impl From<Conversion> for ConversionRecord {
    fn from(c: Conversion) -> Self {
        Self { from_unit_metres: c.from_unit_metres, from_up: c.from_up, to: c.to.into() }
    }
}

/// How Babylon.js plays a `--format babylon` bake (DESIGN section 10).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BabylonRecord {
    /// Per skin, the node Babylon's glTF loader parents its meshes to, whose space at rest the
    /// bones' matrices are in (`None`: the scene root).
    pub mesh_parents: Vec<Option<String>>,
    /// Per clip, the manager's `animationParameters` (or an instance's
    /// `bakedVertexAnimationSettingsInstanced`) that play it on the source's clock
    /// ([`super::babylon::settings`]): first row, last row, offset in rows, speed in rows a second.
    pub clips: Vec<[f64; 4]>,
    /// How to use `clips`, in words.
    pub settings: String,
}

/// [`BabylonRecord::settings`].
const BABYLON_SETTINGS: &str = "clip k plays with Vector4(...clips[k]) as the manager's animationParameters or an \
    instance's bakedVertexAnimationSettingsInstanced, its phase added to the offset in rows; Babylon takes the row \
    floor(time * speed) (no blending between rows) and after a loop's first cycle skips first_row, its repeated seam \
    row, so a loop's speed is rate * frames / (frames - 1) and its offset -1: every cycle after the first is the \
    source's period on its rows, the first a row late";

/// One skinned primitive of a vertex texture.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VertexPrimitive {
    /// `node 'N', mesh 'M', primitive p`.
    pub name: String,
    /// The glTF node that draws it.
    pub node: usize,
    /// The node's mesh.
    pub mesh: usize,
    /// The primitive's index in the mesh.
    pub primitive: usize,
    /// Its skin, an index into `skins`.
    pub skin: usize,
    /// A rigid part's joint (an index into its skin's joints), which alone moves it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rigid_joint: Option<usize>,
    /// Vertices.
    pub vertices: usize,
    /// Influences per vertex.
    pub influences: usize,
    /// Whether it has normals (and so `.nrm` sheets).
    pub normals: bool,
    /// Vertices whose weights did not sum to 1 and were divided by their sum.
    pub normalized: usize,
    /// The file-name suffix of its sheets (before `.pos`/`.nrm` for images), and its mesh
    /// in `mesh_file`.
    pub suffix: String,
    /// See [`Self::suffix`].
    pub mesh_in_file: usize,
}

/// A joint's rest pose, parent-relative.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Rest {
    /// Translation.
    pub translation: [f64; 3],
    /// Rotation `x, y, z, w`.
    pub rotation: [f64; 4],
    /// Scale.
    pub scale: [f64; 3],
}

/// A glTF skin.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SidecarSkin {
    /// The skin's name.
    pub name: String,
    /// Joint indices in the skin's order (the rows of its skin texture).
    pub joints: Vec<usize>,
    /// Per joint, its inverse bind matrix, 3x4 row-major (the last row `0 0 0 1`): what a
    /// `local` or `model` texture is multiplied by for skinning.
    pub inverse_bind: Vec<[f64; 12]>,
}

/// One image texture file and where its texels are ([`Grid`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageRecord {
    /// The file's name, beside the sidecar.
    pub file: String,
    /// Joints per frame.
    pub joints: usize,
    /// Where each texel is.
    #[serde(flatten)]
    pub grid: Grid,
    /// PNG16: per texel slot and channel, the `[min, max]` that 0 and 65535 stand for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub remap: Option<Vec<[[f32; 2]; 4]>>,
    /// A vertex texture's positions: `position = low + texel.xyz * span`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub low: Option<[f64; 3]>,
    /// See [`Self::low`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub span: Option<[f64; 3]>,
    /// The shaders' layout uniform for this file (`bone_layout` of a bone texture,
    /// `vertex_layout` of a vertex texture's `.pos` file, which its `.nrm` file shares).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layout: Option<UniformRecord>,
}

/// The budget a bake chose its rates for.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BudgetRecord {
    /// The rotation budget, degrees.
    pub degrees: Option<f64>,
    /// The position budget, centimetres.
    pub centimetres: Option<f64>,
    /// Centimetres per unit of the input's positions.
    pub unit_cm: f64,
    /// The highest rate the budget could choose, Hz.
    pub max_rate: f64,
    /// Points of each frame interval the error was measured at.
    pub substeps: usize,
    /// How the frames are blended: `bone_pose` of `quatcurve shaders`.
    pub interpolation: String,
}

/// One baked clip.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SidecarClip {
    /// The clip's name.
    pub name: String,
    /// The texture (for `skin`, skin 0's).
    pub file: String,
    /// Every texture of the clip: one, or for `skin` one per glTF skin.
    pub files: Vec<String>,
    /// First row (frame) of the clip in `file`: 0, or its place in the atlas texture.
    pub first_row: usize,
    /// Frames (rows).
    pub frames: usize,
    /// The clip's first frame's time in the source, seconds.
    pub start: f64,
    /// Its last frame's.
    pub end: f64,
    /// Frames per second: the job's rate fitted to the clip's span (its first and last frames
    /// are its first and last keys), or with an exact rate the job's rate (open clips).
    pub rate: f64,
    /// Baked as a loop: periodic curves, continuous across the seam. Its period is `frames - 1`
    /// rows; its last row is its first a period later (to f32 rounding, but for a travelling
    /// translation, moved by its per-cycle offset).
    #[serde(rename = "loop")]
    pub looping: bool,
    /// Its skeleton preview's file name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preview: Option<String>,
    /// With an error budget: the worst rotation (degrees) and model-space position (cm)
    /// errors between this clip's frames, where and when, and its bytes against the fixed
    /// rate's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub between_frames: Option<ChosenRate>,
    /// With the root motion extracted: the root's horizontal motion and heading per frame,
    /// taken out of the textures (`model = Root(t) * model in place`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub root_motion: Option<RootTrack>,
    /// Rigid kinds (`model-trs`, `skin-trs`): the largest shear dropped from the clip's
    /// matrices, relative to each one's largest scale (at most
    /// [`crate::texture::SHEAR_TOLERANCE`], or the bake refuses): how far the texture is from
    /// the matrices.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dropped_shear: Option<f64>,
}

impl Sidecar {
    /// The sidecar of one input's bake; `vertex` with the mesh file's name for vertex
    /// textures; `skinned`, the primitives a skin texture's matrices draw (or
    /// that Babylon hangs from their skin's parent).
    ///
    /// # Errors
    /// A texture's numbers that its shader layout cannot hold (a clip's first row past `u32`).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        options: &SidecarOptions<'_>,
        animation: &Animation,
        baked: &Baked,
        source: &str,
        baked_file: Option<String>,
        clips: Vec<SidecarClip>,
        written: &[Written],
        vertex: Option<(&VertexSheets, String)>,
        skinned: &[DeclaredPrimitive],
    ) -> Result<Self, LayoutError> {
        let &SidecarOptions { device, curve, rate, texture, precision, format, atlas, max_error } = options;
        let channels = texture.channels();
        let names = texture.channel_names().join(",");
        let precision = if format == Format::Png16 { "u16" } else { precision.name() }.to_string();
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
        let image = format.is_image();
        let names_of = |range: &std::ops::Range<usize>| {
            let mut slot: Vec<String> = texture.channel_names()[range.clone()].iter().map(|c| c.to_string()).collect();
            slot.resize(4, String::new());
            slot
        };
        let mut textures: Vec<ImageRecord> = written
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
                    layout: None,
                })
            })
            .collect();
        let files: Vec<String> = textures.iter().map(|r| r.file.clone()).collect();
        if !textures.is_empty() {
            let layouts = Layouts::new(texture)?;
            for record in &mut textures {
                record.layout = layout_of(&layouts, record, texture, &files, &clips)
                    .map_err(|e| LayoutError::Texture { file: record.file.clone(), error: Box::new(e) })?;
            }
        }
        let shader = match texture {
            _ if !image => None,
            TextureKind::SkinTrs => Some(uniforms::shader_record(Program::Bones)?),
            TextureKind::Vertex => Some(uniforms::shader_record(Program::Vertex)?),
            _ => None,
        };
        let layout = match (image, texture) {
            _ if format == Format::Babylon => format!(
                "per {} and skin: Babylon.js's baked vertex animation JSON {{vertexData, width, height}}, vertexData the \
                 base64 of f32 rows of (skin joints + 1) 4x4 column-major matrices a frame: each joint's skin matrix in \
                 the space of its skin's mesh parent at rest (babylon.mesh_parents), then the identity",
                if atlas { "atlas of every clip (clip rows from first_row)" } else { "clip" }
            ),
            (true, TextureKind::Vertex) => format!(
                "{layout}; as {format} RGBA images, .pos (positions) and .nrm (normals) per primitive, one texel per \
                 vertex (joint j = vertex, t = 0): see vertex, address and textures"
            ),
            (true, _) => format!("{layout}; as {format} RGBA images of texels: see texels, address and textures"),
            (false, _) => layout,
        };
        Ok(Sidecar {
            source: source.to_string(),
            curve: curve.to_string(),
            interpolation: if curve == CurveChoice::SOURCE { declared_interpolations(animation) } else { Vec::new() },
            requested_rate: rate,
            device: device.to_string(),
            texture: texture.name().to_string(),
            channels: texture.channel_names().iter().map(|c| c.to_string()).collect(),
            precision,
            format: format.name().to_string(),
            layout,
            texels: (image && texture != TextureKind::Vertex).then(|| texture.texels().iter().map(names_of).collect()),
            address: image.then(|| super::image::ADDRESS.to_string()),
            textures,
            shader,
            max_key_error_rad: baked.max_key_error,
            max_error: max_error.map(|b| BudgetRecord {
                degrees: b.degrees,
                centimetres: b.centimetres,
                unit_cm: b.unit_cm,
                max_rate: b.max_rate,
                substeps: SUBSTEPS,
                interpolation: "nlerp of rotations on the shorter arc, lerp of translations and scales (bone_pose)"
                    .into(),
            }),
            baked_file,
            joints: animation.joints.iter().map(|j| j.name.clone()).collect(),
            parents: animation.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i64)).collect(),
            rest: animation
                .joints
                .iter()
                .map(|j| Rest { translation: j.translation, rotation: j.rotation, scale: j.scale })
                .collect(),
            skins: animation
                .skins
                .iter()
                .map(|s| SidecarSkin {
                    name: s.name.clone(),
                    joints: s.joints.clone(),
                    inverse_bind: s.inverse_bind.clone(),
                })
                .collect(),
            conversion: None,
            arrays: Vec::new(),
            primitives: skinned.to_vec(),
            not_drawn: Vec::new(),
            babylon: (format == Format::Babylon).then(|| BabylonRecord {
                mesh_parents: super::babylon::mesh_parents(animation, skinned)
                    .into_iter()
                    .map(|parent| parent.map(|j| animation.joints[j].name.clone()))
                    .collect(),
                clips: clips
                    .iter()
                    .map(|c| super::babylon::settings(c.first_row, c.frames, c.rate, c.looping))
                    .collect(),
                settings: BABYLON_SETTINGS.into(),
            }),
            vertex: vertex.map(|(sheets, mesh_file)| VertexRecord {
                mesh_file,
                position: POSITION_DECODING.into(),
                normal: NORMAL_DECODING.into(),
                texcoord: TEXCOORD_ADDRESS.into(),
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
                        rigid_joint: p.rigid.as_ref().map(|r| r.joint),
                        vertices: p.vertices(),
                        influences: p.bind.influences,
                        normals: p.bind.normals.is_some(),
                        normalized: p.normalized,
                        suffix: super::vertex_texture::suffix(k),
                        mesh_in_file: k,
                    })
                    .collect(),
            }),
            clips,
        })
    }
}

/// The layout uniform of image `record` of a `texture` bake: a bone texture's, or a vertex
/// texture's `.pos` file's (the file with its `low` and `span`, whose `.nrm` file is in `files`
/// or not); none for a `.nrm` file.
fn layout_of(
    layouts: &Layouts,
    record: &ImageRecord,
    texture: TextureKind,
    files: &[String],
    clips: &[SidecarClip],
) -> Result<Option<UniformRecord>, LayoutError> {
    let of = match (texture, record.low, record.span) {
        (TextureKind::Vertex, Some(low), Some(span)) => {
            // The sheet's own part of the name is its last `.pos.` (the stem may hold one).
            let normals = record.file.rfind(".pos.").is_some_and(|at| {
                let nrm = format!("{}.nrm.{}", &record.file[..at], &record.file[at + ".pos.".len()..]);
                files.contains(&nrm)
            });
            LayoutOf::Vertex { low, span, normals }
        }
        (TextureKind::Vertex, ..) => return Ok(None),
        _ => LayoutOf::Bones { remap: record.remap.as_deref() },
    };
    let held: Vec<LayoutClip> = clips
        .iter()
        .enumerate()
        .filter(|(_, c)| c.files.contains(&record.file))
        .map(|(index, c)| LayoutClip {
            index,
            first_row: c.first_row,
            frames: c.frames,
            looping: c.looping,
            rate: c.rate,
        })
        .collect();
    layouts.layout(&record.grid, &of, &held).map(Some)
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
