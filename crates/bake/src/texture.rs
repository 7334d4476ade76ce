//! Animation textures (DESIGN section 6): what a crowd renderer samples per joint and frame,
//! frame-major so that one frame of every joint is one contiguous row.
//!
//! - [`local`]: each joint's rotation, translation and scale relative to its parent;
//! - model: forward kinematics over the hierarchy, each joint's transform relative to the
//!   scene root as a 3x4 matrix (glTF node semantics: `parent * T * R * S`);
//! - [`skin`]: `model(joint) * inverseBindMatrix(joint)` in a glTF skin's joint order, the
//!   matrices a vertex shader multiplies skinned vertices by;
//! - `model-trs` and `skin-trs`: the same transforms as rotation, translation and scale
//!   ([`rigid`]), quaternions sign-continuous along frames ([`Signs`]): what a shader can
//!   interpolate between frames without shearing a joint, which lerped matrices do.
//!
//! Forward kinematics runs where the curves ran ([`Device::forward_kinematics`]): on the GPU
//! in f32 (`shaders/fk.wgsl`), on the CPU in f64 from the f32 local rows (one rounding per
//! stored value), frames on every core.

use super::Baked;
use crate::error::{BakeError, Refusal};
use quatcurve_anim::error::InputError;
use quatcurve_anim::{Animation, Property, Skin};
use quatcurve_device::Device;
use quatcurve_eval::skeleton::{self, rigid, PaletteSkin};
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
    /// `[frames, joints, 10]`: the model matrices as rotation, translation, scale.
    ModelTrs,
    /// `[frames, skin joints, 10]` per glTF skin: the skin matrices as rotation, translation,
    /// scale.
    SkinTrs,
    /// `[frames, vertices, 6]` per skinned glTF mesh primitive: skinned position and normal
    /// (DESIGN section 8); as images, a position and a normal image, encoded.
    Vertex,
}

quatcurve_core::curve::names!(TextureKind, "texture",
    Local => "local", Model => "model", Skin => "skin", ModelTrs => "model-trs", SkinTrs => "skin-trs",
    Vertex => "vertex");

pub use quatcurve_eval::output::{LOCAL_CHANNELS, MATRIX_CHANNELS, VERTEX_CHANNELS};

impl TextureKind {
    /// Floats per joint and frame.
    #[must_use]
    pub fn channels(self) -> usize {
        match self {
            TextureKind::Vertex => VERTEX_CHANNELS,
            kind if kind.is_matrix() => MATRIX_CHANNELS,
            _ => LOCAL_CHANNELS,
        }
    }

    /// Stored as 3x4 matrices (`model`, `skin`), not as rotation, translation and scale.
    #[must_use]
    pub fn is_matrix(self) -> bool {
        matches!(self, TextureKind::Model | TextureKind::Skin)
    }

    /// The matrices held as rotation, translation and scale (`model-trs`, `skin-trs`), their
    /// shear dropped.
    #[must_use]
    pub fn is_rigid(self) -> bool {
        matches!(self, TextureKind::ModelTrs | TextureKind::SkinTrs)
    }

    /// One texture per glTF skin (`skin`, `skin-trs`).
    #[must_use]
    pub fn is_skin(self) -> bool {
        matches!(self, TextureKind::Skin | TextureKind::SkinTrs)
    }

    /// How a joint's floats fill RGBA texels of a 2D texture ([`super::image`]): each range
    /// of floats one texel, the rest of it zero. Rotation, translation, scale for `local`;
    /// the matrix's three rows for `model` and `skin`; for `vertex` one texel per vertex in
    /// each of its images (position, normal), encoded (DESIGN section 8).
    #[must_use]
    pub fn texels(self) -> &'static [std::ops::Range<usize>] {
        match self {
            TextureKind::Vertex => std::slice::from_ref(&VERTEX_TEXEL),
            kind if kind.is_matrix() => &[0..4, 4..8, 8..12],
            _ => &[0..4, 4..7, 7..10],
        }
    }

    /// What each float is, in order (the sidecar's `channels`).
    #[must_use]
    pub fn channel_names(self) -> &'static [&'static str] {
        match self {
            TextureKind::Vertex => &["px", "py", "pz", "nx", "ny", "nz"],
            kind if kind.is_matrix() => {
                &["r00", "r01", "r02", "tx", "r10", "r11", "r12", "ty", "r20", "r21", "r22", "tz"]
            }
            _ => &["qx", "qy", "qz", "qw", "tx", "ty", "tz", "sx", "sy", "sz"],
        }
    }
}

/// A vertex's one texel in each of a vertex texture's images (three floats).
static VERTEX_TEXEL: std::ops::Range<usize> = 0..3;

/// Element type of the written textures (`bake --precision`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// Little-endian IEEE single (`<f4`).
    #[default]
    F32,
    /// Little-endian IEEE half (`<f2`): half the bytes, about 3 significant digits.
    F16,
}

quatcurve_core::curve::names!(Precision, "precision", F32 => "f32", F16 => "f16");

impl Precision {
    /// The `.npy` element type written.
    #[must_use]
    pub fn element(self) -> quatcurve_eval::io::NpyElement {
        match self {
            Precision::F32 => quatcurve_eval::io::NpyElement::F32,
            Precision::F16 => quatcurve_eval::io::NpyElement::F16,
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
    let rest = animation.rest_row();
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
        if let Some(in_place) = baked.in_place(clip) {
            let count = in_place.roots.len();
            for (&root, row) in in_place.roots.iter().zip(&in_place.rows[frame * count..(frame + 1) * count]) {
                out[root * LOCAL_CHANNELS..(root + 1) * LOCAL_CHANNELS].copy_from_slice(row);
            }
        }
    });
    data
}

/// A skin texture `[frames, skin joints, 12]` from a model texture: `model(joint) *
/// inverseBindMatrix(joint)` in the skin's joint order ([`skeleton::palettes`]).
#[must_use]
pub fn skin(skin: &Skin, joints: usize, model: &[f32]) -> Vec<f32> {
    skeleton::palettes(PaletteSkin { joints: &skin.joints, inverse_binds: &skin.inverse_bind }, joints, model)
}

/// The box of `animation`'s joints at rest, in model space: `x, y, z` extents.
pub(super) fn rig_extent(animation: &Animation) -> Result<[f64; 3], InputError> {
    let order = animation.parents_first()?;
    let model = skeleton::forward_kinematics(&animation.parents(), &order, &animation.rest_row());
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for m in model.chunks_exact(MATRIX_CHANNELS) {
        for (c, &at) in [3, 7, 11].iter().enumerate() {
            lo[c] = lo[c].min(f64::from(m[at]));
            hi[c] = hi[c].max(f64::from(m[at]));
        }
    }
    Ok(std::array::from_fn(|c| (hi[c] - lo[c]).max(0.0)))
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
    /// A rigid kind's largest shear dropped from its matrices ([`SHEAR_TOLERANCE`]'s measure);
    /// 0 for the other kinds, which hold their values as computed.
    pub shear: f64,
}

/// The sheets a clip's texture of `kind` has, as `(suffix, width)`: one, or for
/// the skin kinds one per skin (one model sheet when the animation has no skin, as for
/// BVH). Known before anything is computed, so that files can be opened with their shapes.
#[must_use]
pub fn layout(animation: &Animation, kind: TextureKind) -> Vec<(String, usize)> {
    if kind.is_skin() && !animation.skins.is_empty() {
        animation.skins.iter().enumerate().map(|(k, s)| (format!(".skin{k}"), s.joints.len())).collect()
    } else {
        vec![(String::new(), animation.joints.len())]
    }
}

/// The textures of one clip for `kind` ([`layout`]). `order` is [`Animation::parents_first`];
/// forward kinematics runs on `device` ([`Device::forward_kinematics`]).
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
) -> Result<Vec<Sheet>, BakeError> {
    let frames: Vec<usize> = (0..baked.clips[clip].times.len()).collect();
    let mut sheets = sheet_rows(animation, order, baked, clip, kind, device, &frames)?;
    Signs::default().follow(kind, &mut sheets);
    Ok(sheets)
}

/// The rows of [`sheets`] for the clip's `frames` only, in that order: every frame's rows
/// depend on that frame alone, so a texture can be computed and written a block at a time.
/// The rigid kinds' quaternions come with `w >= 0`; [`Signs::follow`] makes them continuous.
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
) -> Result<Vec<Sheet>, BakeError> {
    if kind == TextureKind::Vertex {
        return Err(Refusal::VertexWithoutMeshes.into());
    }
    let local = local_rows(animation, baked, clip, frames);
    if kind == TextureKind::Local {
        return Ok(vec![Sheet { suffix: String::new(), width: animation.joints.len(), data: local, shear: 0.0 }]);
    }
    let model = device.forward_kinematics(&animation.parents(), order, &local)?;
    let (matrices, joints): (Vec<Vec<f32>>, Vec<Vec<usize>>) = if !kind.is_skin() || animation.skins.is_empty() {
        (vec![model], vec![(0..animation.joints.len()).collect()])
    } else {
        animation.skins.iter().map(|s| (skin(s, animation.joints.len(), &model), s.joints.clone())).unzip()
    };
    let mut sheets = Vec::with_capacity(matrices.len());
    for (((suffix, width), data), joints) in layout(animation, kind).into_iter().zip(matrices).zip(joints) {
        let (data, shear) = if kind.is_matrix() {
            (data, 0.0)
        } else {
            rigid_rows(&data, width).map_err(|(row, k, residual)| Refusal::Sheared {
                clip: animation.clips[clip].name.clone(),
                frame: frames[row],
                joint: animation.joints[joints[k]].name.clone(),
                kind: kind.name(),
                residual,
                tolerance: SHEAR_TOLERANCE,
                matrices: if kind.is_skin() { TextureKind::Skin } else { TextureKind::Model }.name(),
            })?
        };
        sheets.push(Sheet { suffix, width, data, shear });
    }
    Ok(sheets)
}

/// Largest difference, relative to the largest scale, between a matrix and the rotation,
/// translation and scale [`rigid`] makes of it: beyond it the matrix is sheared (a child
/// rotated under a non-uniform scale), and only a matrix texture holds it. f32 matrices of
/// rigid transforms come within about 1e-6.
pub const SHEAR_TOLERANCE: f64 = 1e-4;

/// A matrix over [`SHEAR_TOLERANCE`]: `(frame of the rows, joint, residual)`.
type Sheared = (usize, usize, f64);

/// [`rigid`] over matrix rows `[frames, joints, 12]`, to `[frames, joints, 10]`, and the
/// largest residual (the shear dropped).
///
/// # Errors
/// The first matrix over [`SHEAR_TOLERANCE`], in frame order.
fn rigid_rows(matrices: &[f32], joints: usize) -> Result<(Vec<f32>, f64), Sheared> {
    let rows: Vec<Result<(Vec<f32>, f64), Sheared>> = matrices
        .par_chunks(joints.max(1) * MATRIX_CHANNELS)
        .enumerate()
        .map(|(row, frame)| {
            let (mut out, mut worst) = (Vec::with_capacity(joints * LOCAL_CHANNELS), 0.0f64);
            for (k, m) in frame.chunks_exact(MATRIX_CHANNELS).enumerate() {
                let (values, residual) = rigid(&std::array::from_fn(|i| f64::from(m[i])));
                if residual.is_nan() || residual > SHEAR_TOLERANCE {
                    return Err((row, k, residual));
                }
                worst = worst.max(residual);
                out.extend(values.map(|v| v as f32));
            }
            Ok((out, worst))
        })
        .collect();
    let rows = rows.into_iter().collect::<Result<Vec<_>, _>>()?;
    let worst = rows.iter().map(|(_, w)| *w).fold(0.0, f64::max);
    Ok((rows.into_iter().flat_map(|(r, _)| r).collect(), worst))
}

/// The last quaternion of every joint of every sheet: what [`Signs::follow`] keeps the next
/// frame's on the same side of, across the blocks a texture is computed in.
#[derive(Clone, Debug, Default)]
pub struct Signs {
    last: Vec<Vec<[f32; 4]>>,
}

impl Signs {
    /// Flips each rigid-kind quaternion whose dot product with the joint's previous one is
    /// negative, frame after frame, so that the two neighbours a shader blends (or a texture
    /// unit filters) lie on the same side; `q` and `-q` are the same rotation. `local` keeps
    /// the curve's own quaternions, continuous already; matrices have none.
    pub fn follow(&mut self, kind: TextureKind, sheets: &mut [Sheet]) {
        if !matches!(kind, TextureKind::ModelTrs | TextureKind::SkinTrs) {
            return;
        }
        self.last.resize(sheets.len(), Vec::new());
        for (sheet, last) in sheets.iter_mut().zip(&mut self.last) {
            for row in sheet.data.chunks_exact_mut(sheet.width.max(1) * LOCAL_CHANNELS) {
                if last.is_empty() {
                    last.extend(row.chunks_exact(LOCAL_CHANNELS).map(|j| [j[0], j[1], j[2], j[3]]));
                    continue;
                }
                for (j, previous) in row.chunks_exact_mut(LOCAL_CHANNELS).zip(last.iter_mut()) {
                    let dot: f32 = (0..4).map(|i| j[i] * previous[i]).sum();
                    if dot < 0.0 {
                        j[..4].iter_mut().for_each(|v| *v = -*v);
                    }
                    *previous = [j[0], j[1], j[2], j[3]];
                }
            }
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use quatcurve_eval::skeleton::trs_row;

    /// A rotation `x, y, z, w` from a seed, not normalized.
    fn rotation(seed: u64) -> [f32; 4] {
        let mut rng = quatcurve_eval::synthetic::SplitMix::new(seed);
        std::array::from_fn(|_| (rng.unit() * 2.0 - 1.0) as f32)
    }

    #[test]
    fn rigid_gives_back_the_rotation_translation_and_scale_of_a_matrix() {
        for seed in 0..2000u64 {
            let q = rotation(seed);
            let n = q.iter().map(|v| v * v).sum::<f32>().sqrt();
            let sign = if seed % 7 == 0 { -1.0 } else { 1.0 };
            let s = [0.5 + (seed % 5) as f32 * 0.3, 1.0, 2.0].map(|v| v * sign);
            let row = [q[0], q[1], q[2], q[3], 1.0, -2.0, 3.0, s[0], s[1], s[2]];
            let (back, residual) = rigid(&trs_row(&row));
            assert!(residual < 1e-6, "seed {seed}: residual {residual}");
            // The same rotation up to sign, w >= 0; the scale's sign is uniform.
            let side = if q[3] < 0.0 { -1.0 } else { 1.0 };
            for i in 0..4 {
                assert!((back[i] - f64::from(side * q[i] / n)).abs() < 1e-6, "seed {seed}: {back:?} vs {q:?}");
            }
            for i in 0..3 {
                assert!((back[7 + i] - f64::from(s[i])).abs() < 1e-6, "seed {seed}: scale {back:?}");
            }
            assert_eq!(&back[4..7], &[1.0, -2.0, 3.0]);
        }
    }

    #[test]
    fn a_sheared_or_flat_matrix_is_not_rigid() {
        let mut m = trs_row(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        m[1] = 0.3;
        assert!(rigid(&m).1 > SHEAR_TOLERANCE);
        let flat = trs_row(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0]);
        assert!(rigid(&flat).1 > SHEAR_TOLERANCE);
    }

    #[test]
    fn signs_follow_across_blocks_as_over_the_whole() {
        // One joint turning about z through 720 degrees, each frame's quaternion with w >= 0.
        let frames = 50;
        let data: Vec<f32> = (0..frames)
            .flat_map(|f| {
                let half = f as f64 * 4.0 * std::f64::consts::PI / frames as f64 / 2.0;
                let q = [0.0, 0.0, half.sin(), half.cos()];
                let side = if q[3] < 0.0 { -1.0 } else { 1.0 };
                let mut row = vec![0.0f32; LOCAL_CHANNELS];
                for i in 0..4 {
                    row[i] = (side * q[i]) as f32;
                }
                row
            })
            .collect();
        let sheet = |rows: std::ops::Range<usize>| Sheet {
            suffix: String::new(),
            width: 1,
            data: data[rows.start * LOCAL_CHANNELS..rows.end * LOCAL_CHANNELS].to_vec(),
            shear: 0.0,
        };
        let mut whole = vec![sheet(0..frames)];
        Signs::default().follow(TextureKind::ModelTrs, &mut whole);
        let mut signs = Signs::default();
        let mut blocks = Vec::new();
        for range in [0..7, 7..31, 31..frames] {
            let mut block = vec![sheet(range)];
            signs.follow(TextureKind::ModelTrs, &mut block);
            blocks.extend(block.remove(0).data);
        }
        assert_eq!(blocks, whole[0].data);
        let flips = whole[0].data.chunks_exact(LOCAL_CHANNELS).collect::<Vec<_>>();
        assert!(flips.windows(2).all(|w| (0..4).map(|i| w[0][i] * w[1][i]).sum::<f32>() > 0.0));
        // The canonical input did flip (w >= 0 each frame), so following changed something.
        assert_ne!(whole[0].data, data);
        // Matrices and local rows are left alone.
        let mut local = vec![sheet(0..frames)];
        Signs::default().follow(TextureKind::Local, &mut local);
        assert_eq!(local[0].data, data);
    }
}
