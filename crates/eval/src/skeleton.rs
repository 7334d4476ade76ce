//! The skeleton's maths in f64, once for every user: affine transforms (`T * R * S`, composed,
//! inverted, taken apart again), forward kinematics down a joint hierarchy, and linear blend
//! skinning. It is the CPU path of `Device::forward_kinematics` and `Device::skin` (in
//! `quatcurve`) and the oracle their GPU kernels (`shaders/fk.wgsl`,
//! `shaders/skin_mesh.wgsl`) are held to; the bake's textures, its error budgets, root motion
//! and the fit's virtual-vertex error all compose transforms through it.

use crate::output::{LOCAL_CHANNELS, MATRIX_CHANNELS, VERTEX_CHANNELS};
use quatcurve_core::quat::QuatF64;
use rayon::prelude::*;

/// A 3x4 row-major affine matrix (its last row is `0 0 0 1`).
pub type Affine = [f64; 12];

/// `T * R * S` (glTF's and BVH's order) of a rotation `x, y, z, w`, a translation and a scale.
/// The rotation is normalized first: an f32 quaternion is unit only to ~1e-7.
#[must_use]
pub fn trs(rotation: [f64; 4], translation: [f64; 3], scale: [f64; 3]) -> Affine {
    let [x, y, z, w] = rotation;
    // One division, not four: a fifth of a bake's forward kinematics went to dividing.
    let inverse_norm = 1.0 / (x * x + y * y + z * z + w * w).sqrt();
    let (x, y, z, w) = (x * inverse_norm, y * inverse_norm, z * inverse_norm, w * inverse_norm);
    let ([tx, ty, tz], [sx, sy, sz]) = (translation, scale);
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

/// [`trs`] of a local row ([`LOCAL_CHANNELS`] floats: `x, y, z, w`, translation, scale).
#[must_use]
pub fn trs_row(row: &[f32]) -> Affine {
    let v = |i: usize| f64::from(row[i]);
    trs([v(0), v(1), v(2), v(3)], [v(4), v(5), v(6)], [v(7), v(8), v(9)])
}

/// The inverse of an affine matrix; `None` when it is singular.
#[must_use]
pub fn inverse(m: &Affine) -> Option<Affine> {
    let a = |r: usize, c: usize| m[4 * r + c];
    let det = a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) - a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0))
        + a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
    if !det.is_normal() {
        return None;
    }
    // The adjugate over the determinant: A^-1; the translation is -A^-1 t.
    let inv = [
        [
            a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1),
            a(0, 2) * a(2, 1) - a(0, 1) * a(2, 2),
            a(0, 1) * a(1, 2) - a(0, 2) * a(1, 1),
        ],
        [
            a(1, 2) * a(2, 0) - a(1, 0) * a(2, 2),
            a(0, 0) * a(2, 2) - a(0, 2) * a(2, 0),
            a(0, 2) * a(1, 0) - a(0, 0) * a(1, 2),
        ],
        [
            a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0),
            a(0, 1) * a(2, 0) - a(0, 0) * a(2, 1),
            a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0),
        ],
    ]
    .map(|row| row.map(|v| v / det));
    let t = [m[3], m[7], m[11]];
    let mut out = [0.0; 12];
    for r in 0..3 {
        out[4 * r..4 * r + 3].copy_from_slice(&inv[r]);
        out[4 * r + 3] = -(inv[r][0] * t[0] + inv[r][1] * t[1] + inv[r][2] * t[2]);
    }
    Some(out)
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

/// `point` transformed by `m`.
#[must_use]
pub fn transform_point(m: &Affine, point: [f64; 3]) -> [f64; 3] {
    let [x, y, z] = point;
    std::array::from_fn(|r| m[4 * r] * x + m[4 * r + 1] * y + m[4 * r + 2] * z + m[4 * r + 3])
}

/// One pose's object-space transforms into `object`: joint `j`'s is its parent's times
/// `local(j)` (a root's is `local(j)`), joints taken in `order` (parents first,
/// `anim::Animation::parents_first`).
pub fn pose_into(parents: &[Option<usize>], order: &[usize], local: impl Fn(usize) -> Affine, object: &mut [Affine]) {
    for &j in order {
        let own = local(j);
        object[j] = match parents[j] {
            Some(p) => compose(&object[p], &own),
            None => own,
        };
    }
}

/// [`pose_into`] a new list.
#[must_use]
pub fn pose(parents: &[Option<usize>], order: &[usize], local: impl Fn(usize) -> Affine) -> Vec<Affine> {
    let mut object = vec![[0.0; 12]; parents.len()];
    pose_into(parents, order, local, &mut object);
    object
}

/// Forward kinematics of every frame: model rows `[frames, joints, 12]` (3x4 row-major) from
/// local rows `[frames, joints, 10]`, in f64 from the f32 rows (one rounding per stored value),
/// frames on every core.
#[must_use]
pub fn forward_kinematics(parents: &[Option<usize>], order: &[usize], local: &[f32]) -> Vec<f32> {
    let joints = parents.len();
    let frames = local.len() / (joints * LOCAL_CHANNELS).max(1);
    let mut data = vec![0.0f32; frames * joints * MATRIX_CHANNELS];
    data.par_chunks_mut((joints * MATRIX_CHANNELS).max(1)).enumerate().for_each_init(
        || vec![[0.0; 12]; joints],
        |object, (frame, out)| {
            let rows = &local[frame * joints * LOCAL_CHANNELS..(frame + 1) * joints * LOCAL_CHANNELS];
            pose_into(parents, order, |j| trs_row(&rows[j * LOCAL_CHANNELS..(j + 1) * LOCAL_CHANNELS]), object);
            for (o, &v) in out.iter_mut().zip(object.iter().flatten()) {
                *o = v as f32;
            }
        },
    );
    data
}

/// Two local poses per instance (`[instances, 2, joints, 10]`) blended by `weights` (one per
/// instance, the second pose's) as [`play_palettes`] blends them: `[instances, joints, 10]`.
///
/// # Panics
/// When `poses` is not two poses of `joints` joints per weight.
#[must_use]
pub fn blend_poses(poses: &[f32], weights: &[f32], joints: usize) -> Vec<f32> {
    let row = joints * LOCAL_CHANNELS;
    assert_eq!(poses.len(), 2 * row * weights.len(), "two poses of {joints} joints per weight");
    let mut out = vec![0.0f32; row * weights.len()];
    out.par_chunks_mut(row.max(1))
        .zip(poses.par_chunks(2 * row.max(1)))
        .zip(weights)
        .for_each(|((out, pair), &weight)| blend_row(pair, weight, out));
    out
}

/// One instance's two local rows (`pair`: the first pose's joints, then the second's) blended
/// into `out` by `weight`: rotations by slerp on the shorter arc (in f64), translations and
/// scales by lerp; weight 0 is the first pose as it is. The twin of `shaders/play.wgsl`'s
/// `play_blend`.
fn blend_row(pair: &[f32], weight: f32, out: &mut [f32]) {
    let (a, b) = pair.split_at(out.len());
    if weight == 0.0 {
        out.copy_from_slice(a);
        return;
    }
    let w = f64::from(weight);
    let q = |r: &[f32]| QuatF64::from_array([r[0], r[1], r[2], r[3]].map(f64::from)).normalize();
    let joints =
        out.chunks_exact_mut(LOCAL_CHANNELS).zip(a.chunks_exact(LOCAL_CHANNELS)).zip(b.chunks_exact(LOCAL_CHANNELS));
    for ((o, a), b) in joints {
        for (o, m) in o[..4].iter_mut().zip(q(a).slerp(q(b), w).to_array()) {
            *o = m as f32;
        }
        for ((o, &a), &b) in o[4..].iter_mut().zip(&a[4..]).zip(&b[4..]) {
            *o = a + (b - a) * weight;
        }
    }
}

/// Crowd playback's palettes on the host, one instance at a time (its rows stay in cache):
/// its two local poses blended (rotations by slerp on the shorter arc, the rest by lerp),
/// forward kinematics in f64 ([`pose_into`]) and `skin`'s palette (`model * inverseBind`,
/// [`palettes`]' formula), or every joint's model matrix without one: `[instances, matrices,
/// 12]`. The twin of `shaders/play.wgsl` with `fk.wgsl`.
///
/// # Panics
/// As [`blend_poses`].
#[must_use]
pub fn play_palettes(
    parents: &[Option<usize>],
    order: &[usize],
    poses: &[f32],
    weights: &[f32],
    skin: Option<PaletteSkin<'_>>,
) -> Vec<f32> {
    let joints = parents.len();
    let row = joints * LOCAL_CHANNELS;
    assert_eq!(poses.len(), 2 * row * weights.len(), "two poses of {joints} joints per weight");
    let matrices = skin.map_or(joints, |s| s.joints.len());
    let mut out = vec![0.0f32; matrices * MATRIX_CHANNELS * weights.len()];
    out.par_chunks_mut((matrices * MATRIX_CHANNELS).max(1))
        .zip(poses.par_chunks(2 * row.max(1)))
        .zip(weights)
        .for_each_init(
            || (vec![0.0f32; row], vec![[0.0; 12]; joints]),
            |(local, object), ((out, pair), &weight)| {
                blend_row(pair, weight, local);
                pose_into(parents, order, |j| trs_row(&local[j * LOCAL_CHANNELS..(j + 1) * LOCAL_CHANNELS]), object);
                let matrix = |k: usize| match skin {
                    Some(s) => compose(&object[s.joints[k]], &s.inverse_binds[k]),
                    None => object[k],
                };
                for (k, o) in out.chunks_exact_mut(MATRIX_CHANNELS).enumerate() {
                    for (o, v) in o.iter_mut().zip(matrix(k)) {
                        *o = v as f32;
                    }
                }
            },
        );
    out
}

/// The joints a palette holds and their inverse binds (a glTF skin's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaletteSkin<'a> {
    /// The skin's joints (indices into the model rows' joints), in its order.
    pub joints: &'a [usize],
    /// One inverse bind matrix per skin joint, 3x4 row-major.
    pub inverse_binds: &'a [[f64; 12]],
}

/// Where a played clip takes one joint property from (DESIGN section 17).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PoseSource {
    /// A rotation: track `i` of the rotation batch.
    Rotation(usize),
    /// A translation or scale: vector curve `i`.
    Vector(usize),
    /// A constant: a one-key channel, or the rest value of a property the clip leaves alone.
    Value([f32; 4]),
}

/// Sources per joint in [`PoseCurves::sources`]: rotation, translation, scale (WGSL
/// `PLAY_PROPERTIES`).
pub const POSE_PROPERTIES: usize = 3;

/// An animation's clips as curves, for a device that keeps them resident and evaluates every
/// instance's pose itself (the GPU's playback from curves).
#[derive(Clone, Debug)]
pub struct PoseCurves<'a> {
    /// Every clip's rotation tracks, `None` when no clip animates a rotation.
    pub batch: Option<&'a crate::batch::Batch>,
    /// Every clip's translation and scale curves.
    pub vectors: Vec<&'a crate::euclidean::VectorCurve>,
    /// `[clips, joints, POSE_PROPERTIES]`: each joint's rotation, translation and scale source
    /// per clip.
    pub sources: Vec<PoseSource>,
    /// Each joint's parent.
    pub parents: &'a [Option<usize>],
    /// The joints, every parent before its children.
    pub order: &'a [usize],
    /// The palette's skin; `None`: every joint's model matrix.
    pub skin: Option<PaletteSkin<'a>>,
}

/// What one instance plays in a frame of playback from curves: its two `(clip, curve time)`
/// poses (a loop's time may lie past the clip's end; each curve wraps it) and the second's
/// weight (0: the first alone).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseTimes {
    /// Clip indices.
    pub clips: [usize; 2],
    /// Times on the clips' curves, seconds.
    pub times: [f64; 2],
    /// The second pose's weight.
    pub weight: f32,
}

/// Skin palettes `[frames, skin joints, 12]` of model rows `[frames, joints, 12]`:
/// `model(joint) * inverseBind(joint)` in the skin's joint order, composed in f64. The twin of
/// `shaders/play.wgsl`'s `play_palette`, and the bake's `skin` texture.
#[must_use]
pub fn palettes(skin: PaletteSkin<'_>, joints: usize, model: &[f32]) -> Vec<f32> {
    let frames = model.len() / (joints * MATRIX_CHANNELS).max(1);
    let width = skin.joints.len() * MATRIX_CHANNELS;
    let mut data = vec![0.0f32; frames * width];
    data.par_chunks_mut(width.max(1)).enumerate().for_each(|(frame, out)| {
        for (k, (&joint, ibm)) in skin.joints.iter().zip(skin.inverse_binds).enumerate() {
            let at = (frame * joints + joint) * MATRIX_CHANNELS;
            let m: Affine = std::array::from_fn(|i| f64::from(model[at + i]));
            for (o, v) in out[k * MATRIX_CHANNELS..(k + 1) * MATRIX_CHANNELS].iter_mut().zip(compose(&m, ibm)) {
                *o = v as f32;
            }
        }
    });
    data
}

/// A rigid row's transform (`T * R * S`) held as its parts: a unit rotation, a translation
/// and a scale per axis. Two compose in quaternions, with no matrix built or taken apart
/// again ([`trs_pose`]), wherever the first's scale is one for every axis: what a budget's
/// dense truth needs, millions of times.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trs {
    /// Unit rotation.
    pub rotation: QuatF64,
    /// Translation.
    pub translation: [f64; 3],
    /// Scale per axis.
    pub scale: [f64; 3],
}

/// Relative difference between a transform's largest and smallest scale within which
/// [`Trs::then`] takes them for one: the shear a rigid row drops ([`rigid`]) is of this
/// order, and exporters leave scales of one about 1e-5 apart (BrainStem's).
pub const UNIFORM_SCALE_TOLERANCE: f64 = 1e-4;

impl Trs {
    /// The identity.
    #[must_use]
    pub fn identity() -> Self {
        Self { rotation: QuatF64::identity(), translation: [0.0; 3], scale: [1.0; 3] }
    }

    /// A rigid row's (`x, y, z, w`, translation, scale), its rotation normalized as [`trs`]
    /// normalizes it.
    #[must_use]
    pub fn from_row(row: &[f32]) -> Self {
        Self::from_values(std::array::from_fn(|i| f64::from(row[i])))
    }

    /// An affine matrix's parts ([`rigid`]), when it is rigid within `tolerance` (its
    /// residual).
    #[must_use]
    pub fn from_affine(m: &Affine, tolerance: f64) -> Option<Self> {
        let (row, residual) = rigid(m);
        (residual <= tolerance).then(|| Self::from_values(row))
    }

    /// [`Self::from_row`] of a row in f64.
    fn from_values(row: [f64; 10]) -> Self {
        let rotation = QuatF64::from_array([row[0], row[1], row[2], row[3]]);
        Self {
            rotation: rotation.mul_scalar(1.0 / rotation.length()),
            translation: [row[4], row[5], row[6]],
            scale: [row[7], row[8], row[9]],
        }
    }

    /// `self * other` (`other`'s transform, then `self`'s) in parts; `None` unless `self`'s
    /// scale is one for every axis ([`UNIFORM_SCALE_TOLERANCE`]): a rotation after a scale
    /// that differs by axis shears, and only a matrix holds it.
    #[must_use]
    pub fn then(&self, other: &Self) -> Option<Self> {
        let [sx, sy, sz] = self.scale;
        let (low, high) = (sx.min(sy).min(sz), sx.max(sy).max(sz));
        // NaN scales are not one either.
        let one = high - low <= UNIFORM_SCALE_TOLERANCE * low.abs().max(high.abs());
        if !one {
            return None;
        }
        let [x, y, z] = std::array::from_fn(|c| self.scale[c] * other.translation[c]);
        let turned = self.rotation.rotate(quatcurve_core::quat::Vec3F64::new(x, y, z)).to_array();
        Some(Self {
            rotation: self.rotation * other.rotation,
            translation: std::array::from_fn(|c| self.translation[c] + turned[c]),
            scale: std::array::from_fn(|c| self.scale[c] * other.scale[c]),
        })
    }

    /// As a rigid row (`x, y, z, w` with `w >= 0`, translation, scale), as [`rigid`] gives it.
    #[must_use]
    pub fn row(&self) -> [f64; 10] {
        let q = self.rotation.to_array();
        let k = if q[3] < 0.0 { -1.0 } else { 1.0 };
        let ([tx, ty, tz], [sx, sy, sz]) = (self.translation, self.scale);
        [k * q[0], k * q[1], k * q[2], k * q[3], tx, ty, tz, sx, sy, sz]
    }
}

/// [`forward_kinematics`] of one pose's local rows (`[joints, 10]`) in parts into `object`,
/// joints in `order` (parents first): each joint's its parent's then its own ([`Trs::then`]).
/// `None` when a parent's scale differs by axis, where only the matrices hold the pose.
pub fn trs_pose(parents: &[Option<usize>], order: &[usize], rows: &[f32], object: &mut [Trs]) -> Option<()> {
    for &j in order {
        let own = Trs::from_row(&rows[j * LOCAL_CHANNELS..(j + 1) * LOCAL_CHANNELS]);
        object[j] = match parents[j] {
            Some(p) => object[p].then(&own)?,
            None => own,
        };
    }
    Some(())
}

/// A 3x4 matrix as rotation `x, y, z, w` (`w >= 0`), translation and scale (`T * R * S`, as
/// glTF nodes), with the difference between the matrix and that transform's relative to the
/// largest scale. A mirroring matrix (negative determinant) takes a negative uniform sign on
/// the scale.
#[must_use]
pub fn rigid(m: &Affine) -> ([f64; 10], f64) {
    let column = |c: usize| [m[c], m[4 + c], m[8 + c]];
    let [c0, c1, c2] = [column(0), column(1), column(2)];
    let det = c0[0] * (c1[1] * c2[2] - c1[2] * c2[1]) - c0[1] * (c1[0] * c2[2] - c1[2] * c2[0])
        + c0[2] * (c1[0] * c2[1] - c1[1] * c2[0]);
    let sign = if det < 0.0 { -1.0 } else { 1.0 };
    let scale = [c0, c1, c2].map(|c| sign * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt());
    let largest = scale.iter().fold(0.0f64, |a, s| a.max(s.abs()));
    if scale.iter().any(|s| !s.is_normal()) {
        return ([0.0, 0.0, 0.0, 1.0, m[3], m[7], m[11], scale[0], scale[1], scale[2]], f64::INFINITY);
    }
    // The rotation's entries r[row][col] = m[row][col] / scale[col], by reciprocals: divisions
    // were most of the time of a decomposition.
    let inverse_scale = scale.map(|s| 1.0 / s);
    let r = |i: usize, j: usize| m[4 * i + j] * inverse_scale[j];
    let trace = r(0, 0) + r(1, 1) + r(2, 2);
    // Shepperd's method: divide by the largest of the four candidates.
    let q = if trace > 0.0 {
        let s = 2.0 * (1.0 + trace).sqrt();
        let k = 1.0 / s;
        [(r(2, 1) - r(1, 2)) * k, (r(0, 2) - r(2, 0)) * k, (r(1, 0) - r(0, 1)) * k, s / 4.0]
    } else if r(0, 0) > r(1, 1) && r(0, 0) > r(2, 2) {
        let s = 2.0 * (1.0 + r(0, 0) - r(1, 1) - r(2, 2)).sqrt();
        let k = 1.0 / s;
        [s / 4.0, (r(0, 1) + r(1, 0)) * k, (r(0, 2) + r(2, 0)) * k, (r(2, 1) - r(1, 2)) * k]
    } else if r(1, 1) > r(2, 2) {
        let s = 2.0 * (1.0 + r(1, 1) - r(0, 0) - r(2, 2)).sqrt();
        let k = 1.0 / s;
        [(r(0, 1) + r(1, 0)) * k, s / 4.0, (r(1, 2) + r(2, 1)) * k, (r(0, 2) - r(2, 0)) * k]
    } else {
        let s = 2.0 * (1.0 + r(2, 2) - r(0, 0) - r(1, 1)).sqrt();
        let k = 1.0 / s;
        [(r(0, 2) + r(2, 0)) * k, (r(1, 2) + r(2, 1)) * k, s / 4.0, (r(1, 0) - r(0, 1)) * k]
    };
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let k = if q[3] < 0.0 { -1.0 } else { 1.0 } / n;
    let q = q.map(|v| v * k);
    let out = [q[0], q[1], q[2], q[3], m[3], m[7], m[11], scale[0], scale[1], scale[2]];
    let back = trs_row(&out.map(|v| v as f32));
    let residual = (0..12).filter(|i| i % 4 != 3).map(|i| (back[i] - m[i]).abs()).fold(0.0, f64::max) / largest;
    (out, residual)
}

/// What linear blend skinning needs of a mesh: bind-space vertices and each one's joints and
/// weights.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkinnedMesh {
    /// Bind-space positions.
    pub positions: Vec<[f64; 3]>,
    /// Bind-space normals, when the mesh has them.
    pub normals: Option<Vec<[f64; 3]>>,
    /// Influences per vertex.
    pub influences: usize,
    /// Per vertex, [`Self::influences`] indices into the skin's joints.
    pub joints: Vec<u32>,
    /// Per vertex, [`Self::influences`] weights, summing to 1.
    pub weights: Vec<f64>,
}

impl SkinnedMesh {
    /// Vertices.
    #[must_use]
    pub fn vertices(&self) -> usize {
        self.positions.len()
    }
}

/// Every vertex of `mesh` at every frame of `matrices` (`[frames, skin joints, 12]`, 3x4
/// row-major skinning matrices of the mesh's skin, as `bake::texture::skin` makes them):
/// `[frames, vertices, VERTEX_CHANNELS]`. A mesh without normals gets zero normals.
///
/// # Panics
/// When `matrices` is not whole frames of the skin's joints, or a joint index is out of range
/// (both checked when the mesh was read).
#[must_use]
pub fn skin(mesh: &SkinnedMesh, skin_joints: usize, matrices: &[f32]) -> Vec<f64> {
    let frame = skin_joints * MATRIX_CHANNELS;
    assert!(frame > 0 && matrices.len() % frame == 0, "skinning matrices are whole frames of the skin's joints");
    let vertices = mesh.vertices();
    let mut out = vec![0.0; matrices.len() / frame * vertices * VERTEX_CHANNELS];
    out.par_chunks_mut((vertices * VERTEX_CHANNELS).max(1)).zip(matrices.par_chunks(frame)).for_each(|(out, m)| {
        for (v, o) in out.chunks_exact_mut(VERTEX_CHANNELS).enumerate() {
            let blended = blend(mesh, v, m);
            let [x, y, z] = mesh.positions[v];
            let row = |r: usize| &blended[4 * r..4 * r + 4];
            for (r, o) in o[..3].iter_mut().enumerate() {
                *o = row(r)[0] * x + row(r)[1] * y + row(r)[2] * z + row(r)[3];
            }
            if let Some(normals) = &mesh.normals {
                let [x, y, z] = normals[v];
                let n: [f64; 3] = std::array::from_fn(|r| row(r)[0] * x + row(r)[1] * y + row(r)[2] * z);
                let length = n.iter().map(|c| c * c).sum::<f64>().sqrt();
                for (o, n) in o[3..].iter_mut().zip(n) {
                    *o = if length > 0.0 { n / length } else { 0.0 };
                }
            }
        }
    });
    out
}

/// The weighted sum of vertex `v`'s joints' matrices in one frame's `matrices`.
fn blend(mesh: &SkinnedMesh, v: usize, matrices: &[f32]) -> [f64; MATRIX_CHANNELS] {
    let n = mesh.influences;
    let mut sum = [0.0; MATRIX_CHANNELS];
    for (&joint, &weight) in mesh.joints[v * n..(v + 1) * n].iter().zip(&mesh.weights[v * n..(v + 1) * n]) {
        if weight == 0.0 {
            continue;
        }
        let m = &matrices[joint as usize * MATRIX_CHANNELS..(joint as usize + 1) * MATRIX_CHANNELS];
        for (s, &c) in sum.iter_mut().zip(m) {
            *s += weight * f64::from(c);
        }
    }
    sum
}

/// The translation column of joint `j` in frame `frame` of model rows `[frames, joints, 12]`
/// (3x4 row-major, [`forward_kinematics`]'s): where the joint is.
#[must_use]
pub fn position(model: &[f32], joints: usize, frame: usize, j: usize) -> [f32; 3] {
    let at = (frame * joints + j) * MATRIX_CHANNELS;
    [model[at + 3], model[at + 7], model[at + 11]]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Numbers in [-1, 1) from a fixed seed: the same poses on every run.
    fn numbers(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// A chain of `joints` joints, each the previous one's child but the second root, and a
    /// pose of them: unit rotations, translations, and one scale per joint (`uniform`) or three.
    fn pose(joints: usize, uniform: bool, seed: u64) -> (Vec<Option<usize>>, Vec<f32>) {
        let mut next = numbers(seed);
        let parents = (0..joints).map(|j| (j > 0 && j != 2).then(|| j - 1)).collect();
        let mut rows = Vec::new();
        for _ in 0..joints {
            let q = QuatF64::from_xyzw(next(), next(), next(), next()).normalize().to_array();
            let t = [next(), next(), next()];
            let s = 1.0 + 0.5 * next();
            let scale = if uniform { [s; 3] } else { [s, s * 1.2, s * 0.9] };
            rows.extend(q.iter().chain(&t).chain(&scale).map(|&v| v as f32));
        }
        (parents, rows)
    }

    #[test]
    fn parts_compose_to_the_matrices_rows_and_refuse_a_turn_under_scales_that_differ() {
        for seed in 0..20 {
            let (parents, rows) = pose(7, true, seed);
            let order: Vec<usize> = (0..7).collect();
            let mut object = vec![Trs::identity(); 7];
            trs_pose(&parents, &order, &rows, &mut object).expect("uniform scales");
            let matrices = forward_kinematics(&parents, &order, &rows);
            // A bind with scales of its own, composed after each joint's, is the skin row.
            let bind_row = &pose(1, false, seed + 100).1;
            let (bind, bind_matrix) = (Trs::from_row(bind_row), trs_row(bind_row));
            assert!(Trs::from_affine(&bind_matrix, 1e-6).is_some_and(|b| {
                (0..3).all(|c| (b.scale[c] - bind.scale[c]).abs() < 1e-6)
                    && b.rotation.dot(bind.rotation).abs() > 1.0 - 1e-9
            }));
            for j in 0..7 {
                let m: Affine = std::array::from_fn(|i| f64::from(matrices[j * MATRIX_CHANNELS + i]));
                let expected = rigid(&m).0;
                let got = object[j].row();
                let skin_expected = rigid(&compose(&m, &bind_matrix)).0;
                let skin_got = object[j].then(&bind).expect("a uniform scale").row();
                for (got, expected) in [(got, expected), (skin_got, skin_expected)] {
                    for c in 0..10 {
                        assert!(
                            (got[c] - expected[c]).abs() < 2e-5 * expected[c].abs().max(1.0),
                            "seed {seed} joint {j} channel {c}: {got:?} against {expected:?}"
                        );
                    }
                }
            }
            // Scales that differ on a leaf compose; on a parent they are refused.
            let (parents, rows) = pose(7, false, seed);
            assert_eq!(trs_pose(&parents, &order, &rows, &mut object), None, "seed {seed}");
            let leaf = [None, Some(0)];
            let mut two = pose(2, true, seed).1;
            two[LOCAL_CHANNELS + 8] *= 1.5;
            assert_eq!(trs_pose(&leaf, &[0, 1], &two, &mut object[..2]), Some(()), "seed {seed}");
        }
    }
}
