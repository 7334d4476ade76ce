//! Animation textures (DESIGN section 5b): what a crowd renderer samples per joint and frame,
//! frame-major so that one frame of every joint is one contiguous row.
//!
//! - [`local`]: each joint's rotation, translation and scale relative to its parent;
//! - [`model`]: forward kinematics over the hierarchy, each joint's transform relative to the
//!   scene root as a 3x4 matrix (glTF node semantics: `parent * T * R * S`);
//! - [`skin`]: `model(joint) * inverseBindMatrix(joint)` in a glTF skin's joint order, the
//!   matrices a vertex shader multiplies skinned vertices by.
//!
//! Forward kinematics runs where the curves ran ([`model_on`]): on the GPU in f32
//! (`shaders/fk.wgsl`), on the CPU in f64 from the f32 local rows (one rounding per stored
//! value), frames on every core.

use super::InputError;
use super::{Animation, Baked, Property, Skin};
use crate::device::Device;
use rayon::prelude::*;

/// Which texture `bake --texture` writes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TextureKind {
    /// `[frames, joints, 10]`: rotation `x, y, z, w`, translation, scale, parent-relative.
    #[default]
    Local,
    /// `[frames, joints, 12]`: 3x4 row-major model matrices.
    Model,
    /// `[frames, skin joints, 12]` per glTF skin: model matrix times inverse bind matrix.
    Skin,
}

crate::curve::names!(TextureKind, "texture", Local => "local", Model => "model", Skin => "skin");

pub use crate::output::{LOCAL_CHANNELS, MATRIX_CHANNELS};

impl TextureKind {
    /// Floats per joint and frame.
    #[must_use]
    pub fn channels(self) -> usize {
        match self {
            TextureKind::Local => LOCAL_CHANNELS,
            TextureKind::Model | TextureKind::Skin => MATRIX_CHANNELS,
        }
    }

    /// How a joint's floats fill RGBA texels of a 2D texture ([`super::image`]): each range
    /// of floats one texel, the rest of it zero. Rotation, translation, scale for `local`;
    /// the matrix's three rows for `model` and `skin`.
    #[must_use]
    pub fn texels(self) -> &'static [std::ops::Range<usize>] {
        match self {
            TextureKind::Local => &[0..4, 4..7, 7..10],
            TextureKind::Model | TextureKind::Skin => &[0..4, 4..8, 8..12],
        }
    }

    /// What each float is, in order (the sidecar's `channels`).
    #[must_use]
    pub fn channel_names(self) -> &'static [&'static str] {
        match self {
            TextureKind::Local => &["qx", "qy", "qz", "qw", "tx", "ty", "tz", "sx", "sy", "sz"],
            TextureKind::Model | TextureKind::Skin => {
                &["r00", "r01", "r02", "tx", "r10", "r11", "r12", "ty", "r20", "r21", "r22", "tz"]
            }
        }
    }
}

/// Element type of the written textures (`bake --precision`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// Little-endian IEEE single (`<f4`).
    #[default]
    F32,
    /// Little-endian IEEE half (`<f2`): half the bytes, about 3 significant digits.
    F16,
}

crate::curve::names!(Precision, "precision", F32 => "f32", F16 => "f16");

impl Precision {
    /// The `.npy` element type written.
    #[must_use]
    pub fn element(self) -> crate::io::NpyElement {
        match self {
            Precision::F32 => crate::io::NpyElement::F32,
            Precision::F16 => crate::io::NpyElement::F16,
        }
    }
}

/// A clip as a local texture: frame-major `[frames, joints, 10]` (rotation `x, y, z, w`,
/// translation, scale), joints in [`Animation::joints`] order; what the clip does not
/// animate keeps the joint's rest value.
#[must_use]
pub fn local(animation: &Animation, baked: &Baked, clip: usize) -> Vec<f32> {
    let frames: Vec<usize> = (0..baked.clips[clip].times.len()).collect();
    local_rows(animation, baked, clip, &frames)
}

/// The rows of [`local`] for the clip's `frames` only, in that order (a block of a texture
/// streamed to disk, or the frames a preview draws).
#[must_use]
pub fn local_rows(animation: &Animation, baked: &Baked, clip: usize, frames: &[usize]) -> Vec<f32> {
    let values = baked.values(clip);
    let rest: Vec<f32> = animation
        .joints
        .iter()
        .flat_map(|j| j.rotation.iter().chain(&j.translation).chain(&j.scale).map(|&v| v as f32).collect::<Vec<_>>())
        .collect();
    let row = rest.len();
    let mut data = vec![0.0f32; frames.len() * row];
    data.par_chunks_mut(row.max(1)).zip(frames).for_each(|(out, &frame)| {
        out.copy_from_slice(&rest);
        for (channel, values) in animation.clips[clip].channels.iter().zip(&values) {
            let at = channel.joint * LOCAL_CHANNELS;
            let v = &values[frame];
            match channel.property {
                Property::Rotation => out[at..at + 4].copy_from_slice(v),
                Property::Translation => out[at + 4..at + 7].copy_from_slice(&v[..3]),
                Property::Scale => out[at + 7..at + 10].copy_from_slice(&v[..3]),
            }
        }
    });
    data
}

/// A 3x4 row-major affine matrix (its last row is `0 0 0 1`).
pub type Affine = [f64; 12];

/// `T * R * S` of a local row (`x, y, z, w`, translation, scale). The rotation is normalized
/// first: an f32 quaternion is unit only to ~1e-7.
#[must_use]
pub fn trs(row: &[f32]) -> Affine {
    let [x, y, z, w] = [row[0], row[1], row[2], row[3]].map(f64::from);
    let n = (x * x + y * y + z * z + w * w).sqrt();
    let (x, y, z, w) = (x / n, y / n, z / n, w / n);
    let [tx, ty, tz, sx, sy, sz] = [row[4], row[5], row[6], row[7], row[8], row[9]].map(f64::from);
    let r = [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ];
    [
        r[0][0] * sx,
        r[0][1] * sy,
        r[0][2] * sz,
        tx,
        r[1][0] * sx,
        r[1][1] * sy,
        r[1][2] * sz,
        ty,
        r[2][0] * sx,
        r[2][1] * sy,
        r[2][2] * sz,
        tz,
    ]
}

/// `a * b` for affine matrices.
#[must_use]
pub fn compose(a: &Affine, b: &Affine) -> Affine {
    let mut out = [0.0; 12];
    for i in 0..3 {
        for j in 0..4 {
            let mut v = a[4 * i] * b[j] + a[4 * i + 1] * b[4 + j] + a[4 * i + 2] * b[8 + j];
            if j == 3 {
                v += a[4 * i + 3];
            }
            out[4 * i + j] = v;
        }
    }
    out
}

/// Forward kinematics: the model texture `[frames, joints, 12]` of a local texture
/// (`[frames, joints, 10]`), joints composed in `order` (parents first,
/// [`Animation::parents_first`]).
#[must_use]
pub fn model(animation: &Animation, order: &[usize], local: &[f32]) -> Vec<f32> {
    let joints = animation.joints.len();
    let frames = local.len() / (joints * LOCAL_CHANNELS).max(1);
    let mut data = vec![0.0f32; frames * joints * MATRIX_CHANNELS];
    data.par_chunks_mut((joints * MATRIX_CHANNELS).max(1)).enumerate().for_each_init(
        || vec![[0.0; 12]; joints],
        |world, (frame, out)| {
            let rows = &local[frame * joints * LOCAL_CHANNELS..(frame + 1) * joints * LOCAL_CHANNELS];
            for &j in order {
                let own = trs(&rows[j * LOCAL_CHANNELS..(j + 1) * LOCAL_CHANNELS]);
                world[j] = match animation.joints[j].parent {
                    Some(p) => compose(&world[p], &own),
                    None => own,
                };
                for (o, &v) in out[j * MATRIX_CHANNELS..(j + 1) * MATRIX_CHANNELS].iter_mut().zip(&world[j]) {
                    *o = v as f32;
                }
            }
        },
    );
    data
}

/// A skin texture `[frames, skin joints, 12]` from a model texture: `model(joint) *
/// inverseBindMatrix(joint)` in the skin's joint order.
#[must_use]
pub fn skin(skin: &Skin, joints: usize, model: &[f32]) -> Vec<f32> {
    let frames = model.len() / (joints * MATRIX_CHANNELS).max(1);
    let width = skin.joints.len() * MATRIX_CHANNELS;
    let mut data = vec![0.0f32; frames * width];
    data.par_chunks_mut(width.max(1)).enumerate().for_each(|(frame, out)| {
        for (k, (&joint, ibm)) in skin.joints.iter().zip(&skin.inverse_bind).enumerate() {
            let at = (frame * joints + joint) * MATRIX_CHANNELS;
            let m: Affine = std::array::from_fn(|i| f64::from(model[at + i]));
            for (o, v) in out[k * MATRIX_CHANNELS..(k + 1) * MATRIX_CHANNELS].iter_mut().zip(compose(&m, ibm)) {
                *o = v as f32;
            }
        }
    });
    data
}

/// One texture of a clip, `[frames, width, channels]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Sheet {
    /// File-name suffix: empty, or `.skin<k>` for skin `k`.
    pub suffix: String,
    /// Joints per frame (rows of `channels` floats).
    pub width: usize,
    /// The floats, frame-major.
    pub data: Vec<f32>,
}

/// The sheets a clip's texture of `kind` has, as `(suffix, width)`: one, or for
/// [`TextureKind::Skin`] one per skin (one model sheet when the animation has no skin, as for
/// BVH). Known before anything is computed, so that files can be opened with their shapes.
#[must_use]
pub fn layout(animation: &Animation, kind: TextureKind) -> Vec<(String, usize)> {
    if kind == TextureKind::Skin && !animation.skins.is_empty() {
        animation.skins.iter().enumerate().map(|(k, s)| (format!(".skin{k}"), s.joints.len())).collect()
    } else {
        vec![(String::new(), animation.joints.len())]
    }
}

/// The textures of one clip for `kind` ([`layout`]). `order` is [`Animation::parents_first`];
/// forward kinematics runs on `device` ([`model_on`]).
///
/// # Errors
/// The GPU's, when forward kinematics runs there.
pub fn sheets(
    animation: &Animation,
    order: &[usize],
    baked: &Baked,
    clip: usize,
    kind: TextureKind,
    device: &Device,
) -> Result<Vec<Sheet>, InputError> {
    let frames: Vec<usize> = (0..baked.clips[clip].times.len()).collect();
    sheet_rows(animation, order, baked, clip, kind, device, &frames)
}

/// The rows of [`sheets`] for the clip's `frames` only, in that order: every frame's rows
/// depend on that frame alone, so a texture can be computed and written a block at a time.
///
/// # Errors
/// As [`sheets`].
pub fn sheet_rows(
    animation: &Animation,
    order: &[usize],
    baked: &Baked,
    clip: usize,
    kind: TextureKind,
    device: &Device,
    frames: &[usize],
) -> Result<Vec<Sheet>, InputError> {
    let local = local_rows(animation, baked, clip, frames);
    let data = if kind == TextureKind::Local {
        vec![local]
    } else {
        let model = model_on(device, animation, order, &local)?;
        if kind == TextureKind::Model || animation.skins.is_empty() {
            vec![model]
        } else {
            animation.skins.iter().map(|s| skin(s, animation.joints.len(), &model)).collect()
        }
    };
    Ok(layout(animation, kind)
        .into_iter()
        .zip(data)
        .map(|((suffix, width), data)| Sheet { suffix, width, data })
        .collect())
}

/// [`model`] where the curves run: the GPU kernel (`shaders/fk.wgsl`) on a device with a GPU,
/// else the CPU (f64, every core).
///
/// # Errors
/// The GPU's (a device failure, a frame larger than a storage binding).
pub fn model_on(
    device: &Device,
    animation: &Animation,
    order: &[usize],
    local: &[f32],
) -> Result<Vec<f32>, InputError> {
    match device {
        #[cfg(feature = "gpu")]
        Device::Gpu(g) | Device::Auto(g, _) => {
            let parents: Vec<Option<usize>> = animation.joints.iter().map(|j| j.parent).collect();
            g.forward_kinematics(&parents, order, local)
                .map_err(|e| InputError::Device(crate::device::DeviceError::Device(format!("forward kinematics: {e}"))))
        }
        Device::Cpu(_) | Device::Reference => Ok(model(animation, order, local)),
    }
}

/// Frames a skeleton preview overlays.
pub const PREVIEW_FRAMES: usize = 5;

/// The frames a preview of a clip of `frames` frames draws: [`PREVIEW_FRAMES`] evenly spaced
/// from the first to the last (all of them when there are fewer).
#[must_use]
pub fn preview_frames(frames: usize) -> Vec<usize> {
    let count = PREVIEW_FRAMES.min(frames);
    (0..count).map(|i| if count > 1 { i * (frames - 1) / (count - 1) } else { 0 }).collect()
}

/// The translation column of joint `j` in frame `frame` of a model texture: where the joint is.
#[must_use]
pub fn position(model: &[f32], joints: usize, frame: usize, j: usize) -> [f32; 3] {
    let at = (frame * joints + j) * MATRIX_CHANNELS;
    [model[at + 3], model[at + 7], model[at + 11]]
}
