//! SMPL-family pose arrays in AMASS's `.npz` layout, in and out (docs/DATASETS.md has the
//! layouts field by field).
//!
//! A file holds `poses` `[frames, joints * 3]` (each joint's rotation relative to its parent as
//! an axis-angle vector in radians, joints in the [`Family`]'s order, the width naming the
//! family), `trans` `[frames, 3]` (the root's translation), the rate as `mocap_framerate` or
//! `mocap_frame_rate`, and per-sequence fields (`betas`, `gender`, ...). It reads as a skeleton
//! of rotations: a rotation channel per joint and a translation channel for the root, keys at
//! `k / rate`. The joints' offsets are not in the file (the body model computes them from
//! `betas`), so every joint rests at its parent's origin, and only parent-relative products
//! mean anything. Written back ([`SmplFile::to_npz`]) in the same layout at the baked rate:
//! poses and the fields split from them, and `trans`, slerped and lerped in f64 from the
//! archive's own values ([`SmplFile::slerped`], the source's interpolation) or from the baked
//! rows (another curve); every other float array of the source's frame count (`dmpls`,
//! `marker_data`) linearly between frames; the rate field set; every other array copied byte
//! for byte; in the archive's order.

use npyz::{DType, NpyFile, TypeChar};
use quatcurve_anim::error::{InputError, OutputError};
use quatcurve_anim::{Animation, Channel, Clip, ClipFrames, Joint, Property};
use quatcurve_core::quat::{QuatF64, Vec3F64};
use quatcurve_eval::arrays::{member_budget, open_npy, read_floats, Floats};
use quatcurve_eval::io::npy_header;
use std::io::{Cursor, Read, Write};
use std::ops::Range;
use std::path::Path;

/// The extension of SMPL-family pose archives.
pub const EXTENSION: &str = "npz";

/// The rate's field, as SMPL-H files (AMASS) spell it and as SMPL-X files do.
pub const RATE_FIELDS: [&str; 2] = ["mocap_framerate", "mocap_frame_rate"];

/// SMPL-X's duration field, which a rate must agree with.
const DURATION_FIELD: &str = "mocap_time_length";

/// The body's 22 joints, shared by every family: name and parent.
const BODY: [(&str, Option<usize>); 22] = [
    ("pelvis", None),
    ("left_hip", Some(0)),
    ("right_hip", Some(0)),
    ("spine1", Some(0)),
    ("left_knee", Some(1)),
    ("right_knee", Some(2)),
    ("spine2", Some(3)),
    ("left_ankle", Some(4)),
    ("right_ankle", Some(5)),
    ("spine3", Some(6)),
    ("left_foot", Some(7)),
    ("right_foot", Some(8)),
    ("neck", Some(9)),
    ("left_collar", Some(9)),
    ("right_collar", Some(9)),
    ("head", Some(12)),
    ("left_shoulder", Some(13)),
    ("right_shoulder", Some(14)),
    ("left_elbow", Some(16)),
    ("right_elbow", Some(17)),
    ("left_wrist", Some(18)),
    ("right_wrist", Some(19)),
];

/// The left and right wrists, which the hands hang from.
const WRISTS: [(&str, usize); 2] = [("left", 20), ("right", 21)];

/// Each hand's fingers in joint order, three joints each from the wrist out.
const FINGERS: [&str; 5] = ["index", "middle", "pinky", "ring", "thumb"];

/// SMPL-X's face joints, children of the head.
const FACE: [&str; 3] = ["jaw", "left_eye_smplhf", "right_eye_smplhf"];

/// A member of the SMPL family, named by the width of `poses`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    /// SMPL: the body and one joint per hand, 24 joints (`poses` 72 wide).
    Smpl,
    /// SMPL+H (AMASS's SMPL-H files): the body and 15 joints per hand, 52 joints (156).
    SmplH,
    /// SMPL-X: the body, jaw, eyes and hands, 55 joints (165).
    SmplX,
}

impl Family {
    /// Every family, smallest first.
    pub const ALL: [Family; 3] = [Family::Smpl, Family::SmplH, Family::SmplX];

    /// Its name for messages and sidecars.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Family::Smpl => "SMPL",
            Family::SmplH => "SMPL-H",
            Family::SmplX => "SMPL-X",
        }
    }

    /// Joint names and parents in the order of `poses`.
    #[must_use]
    pub fn joints(self) -> Vec<(String, Option<usize>)> {
        let mut joints: Vec<(String, Option<usize>)> = BODY.iter().map(|&(n, p)| (n.to_string(), p)).collect();
        let head = joints.iter().position(|(n, _)| n == "head");
        match self {
            Family::Smpl => joints.extend(WRISTS.map(|(side, wrist)| (format!("{side}_hand"), Some(wrist)))),
            Family::SmplH => hands(&mut joints),
            Family::SmplX => {
                joints.extend(FACE.map(|n| (n.to_string(), head)));
                hands(&mut joints);
            }
        }
        joints
    }

    /// How many joints `poses` holds.
    #[must_use]
    pub fn joint_count(self) -> usize {
        match self {
            Family::Smpl => BODY.len() + WRISTS.len(),
            Family::SmplH => BODY.len() + hand_joints(),
            Family::SmplX => BODY.len() + FACE.len() + hand_joints(),
        }
    }

    /// The fields some files split `poses` into, with the joints each holds.
    #[must_use]
    pub fn parts(self) -> Vec<(&'static str, Range<usize>)> {
        let body = BODY.len();
        let mut parts = vec![("root_orient", 0..1), ("pose_body", 1..body)];
        match self {
            Family::Smpl => {}
            Family::SmplH => parts.push(("pose_hand", body..body + hand_joints())),
            Family::SmplX => {
                let face = body + FACE.len();
                parts.extend([("pose_jaw", body..body + 1), ("pose_eye", body + 1..face)]);
                parts.push(("pose_hand", face..face + hand_joints()));
            }
        }
        parts
    }

    /// The family whose `poses` is `width` floats a frame.
    #[must_use]
    pub fn of_width(width: u64) -> Option<Family> {
        Family::ALL.into_iter().find(|f| 3 * f.joint_count() as u64 == width)
    }
}

/// Joints in both hands.
fn hand_joints() -> usize {
    WRISTS.len() * FINGERS.len() * 3
}

/// Appends both hands' joints: per side, per finger, three joints from the wrist out.
fn hands(joints: &mut Vec<(String, Option<usize>)>) {
    for (side, wrist) in WRISTS {
        for finger in FINGERS {
            for k in 1..=3 {
                let parent = if k == 1 { wrist } else { joints.len() - 1 };
                joints.push((format!("{side}_{finger}{k}"), Some(parent)));
            }
        }
    }
}

/// Per-frame arrays that are not rotations: resampled linearly between frames (DMPL
/// soft-tissue coefficients are weights of linear blend shapes).
const LINEAR_FIELDS: [&str; 1] = ["dmpls"];

/// Per-sequence fields AMASS writes, copied as they are and never mistaken for per-frame data.
const SEQUENCE_FIELDS: [&str; 8] = [
    "betas",
    "num_betas",
    "gender",
    "surface_model_type",
    DURATION_FIELD,
    "markers_latent",
    "latent_labels",
    "markers_latent_vids",
];

/// How a member is written back.
#[derive(Clone, Debug, PartialEq)]
enum Stored {
    /// `poses`, from the baked rotations.
    Poses,
    /// `trans`, from the baked root translation.
    Trans,
    /// The rate field, set to the baked rate.
    Rate,
    /// A field split from `poses`, holding these joints.
    Part(Range<usize>),
    /// A per-frame array resampled linearly (`[frames, ...]`).
    Linear(Floats),
    /// Any other array, its `.npy` bytes as read.
    Copied(Vec<u8>),
}

/// One array of the archive: its name, how it is written back, its element size (4 or 8
/// bytes for floats written anew) and its entry's compression.
#[derive(Clone, Debug, PartialEq)]
struct Member {
    name: String,
    stored: Stored,
    element: usize,
    deflated: bool,
}

/// An SMPL-family archive read for baking.
#[derive(Clone, Debug, PartialEq)]
pub struct SmplFile {
    /// The family `poses`'s width names.
    pub family: Family,
    /// Keys per second: the rate field, or `N` when it is within
    /// [`crate::bvh::FRAME_TIME_SNAP`] of a whole `N` (as a BVH frame time is read).
    pub rate: f64,
    /// The rate field as this file spells it.
    pub rate_field: &'static str,
    /// `poses` `[frames, joints * 3]`, axis-angle.
    pub poses: Vec<f64>,
    /// `trans` `[frames, 3]`, where the file has it.
    pub trans: Option<Vec<f64>>,
    /// Every array in the archive's order.
    members: Vec<Member>,
}

/// An error naming the field (the array, or `file`) and the rule broken.
fn bad(field: &str, reason: impl std::fmt::Display) -> InputError {
    InputError::Arrays { field: field.to_string(), reason: reason.to_string() }
}

/// Reads an SMPL-family archive (see the module's documentation).
///
/// # Errors
/// [`InputError::Read`] for an unreadable file; [`InputError::Arrays`] naming the field for a
/// missing `poses` or rate, a width no family has, shapes that disagree, a rate that is not
/// positive or disagrees with `mocap_time_length`, a value that is not finite (naming the
/// frame and joint), a split field that is not its part of `poses`, an object array where a
/// field is read (numpy pickles those; nothing is ever unpickled) or data shorter than its
/// shape.
pub fn read(path: &Path) -> Result<SmplFile, InputError> {
    from_bytes(&std::fs::read(path).map_err(InputError::Read)?)
}

/// Reads an SMPL-family archive from its bytes (see [`read`]).
///
/// # Errors
/// As [`read`].
pub fn from_bytes(bytes: &[u8]) -> Result<SmplFile, InputError> {
    let mut zip =
        zip::ZipArchive::new(Cursor::new(bytes)).map_err(|e| bad("file", format!("not a zip archive (.npz): {e}")))?;
    let mut raw: Vec<(String, Vec<u8>, bool)> = Vec::with_capacity(zip.len().min(1024));
    for index in 0..zip.len() {
        let mut entry = zip.by_index(index).map_err(|e| bad("file", format!("archive entry {index}: {e}")))?;
        let Some(name) = npyz::npz::array_name_from_file_name(entry.name()).map(str::to_string) else {
            continue;
        };
        let budget = member_budget(entry.size(), entry.compressed_size());
        let mut bytes = Vec::with_capacity(budget.min(1 << 24) as usize);
        (&mut entry).take(budget).read_to_end(&mut bytes).map_err(|e| bad(&name, e))?;
        if (bytes.len() as u64) < entry.size() {
            return Err(bad(&name, format!("holds {} bytes, its entry says {}", bytes.len(), entry.size())));
        }
        raw.push((name, bytes, entry.compression() != zip::CompressionMethod::Stored));
    }
    parse(raw)
}

/// The archive's arrays as `(name, .npy bytes, deflated)` read into a file (see [`read`]).
fn parse(raw: Vec<(String, Vec<u8>, bool)>) -> Result<SmplFile, InputError> {
    let floats = |name: &str, bytes: &[u8]| -> Result<Floats, InputError> {
        read_floats(npy_of(name, bytes)?, bytes.len() as u64).map_err(|e| bad(name, e))
    };
    if let Some((name, ..)) =
        raw.iter().enumerate().find(|(i, (n, ..))| raw[..*i].iter().any(|(m, ..)| m == n)).map(|(_, r)| r)
    {
        return Err(bad(name, "appears twice in the archive"));
    }
    let find = |name: &str| raw.iter().find(|(n, ..)| n == name);
    let (_, poses_bytes, _) = find("poses")
        .ok_or_else(|| bad("poses", "missing: the archive needs poses [frames, joints * 3], axis-angle"))?;
    let poses = floats("poses", poses_bytes)?;
    let widths: Vec<String> = Family::ALL.iter().map(|f| format!("{} for {}", 3 * f.joint_count(), f.name())).collect();
    let (frames, family) = match poses.shape[..] {
        [frames, width] => (frames as usize, Family::of_width(width)),
        _ => (0, None),
    };
    let family = family.ok_or_else(|| {
        bad("poses", format!("shape {:?}; expected [frames, width] with width {}", poses.shape, widths.join(", ")))
    })?;
    if frames == 0 {
        return Err(bad("poses", "holds no frame"));
    }
    let names = family.joints();
    let width = 3 * names.len();
    finite("poses", &poses.data, width, |i| names[i / 3].0.clone())?;
    let trans = match find("trans") {
        Some((_, bytes, _)) => {
            let trans = floats("trans", bytes)?;
            if trans.shape[..] != [frames as u64, 3] {
                return Err(bad("trans", format!("shape {:?}; expected [{frames}, 3] to match poses", trans.shape)));
            }
            finite("trans", &trans.data, 3, |_| "root".into())?;
            Some(trans.data)
        }
        None => None,
    };
    let (rate_field, rate_bytes) =
        RATE_FIELDS.into_iter().find_map(|f| find(f).map(|(_, bytes, _)| (f, bytes))).ok_or_else(|| {
            bad(RATE_FIELDS[0], format!("missing: the archive needs its frame rate as {}", RATE_FIELDS.join(" or ")))
        })?;
    let rate = scalar(rate_field, rate_bytes)?;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(bad(rate_field, format!("{rate} is not a positive number of frames per second")));
    }
    let rate = 1.0 / crate::bvh::exact_frame_time(1.0 / rate);
    if let Some((_, bytes, _)) = find(DURATION_FIELD) {
        check_duration(scalar(DURATION_FIELD, bytes)?, rate, rate_field, frames)?;
    }
    let parts = family.parts();
    let mut members = Vec::with_capacity(raw.len());
    for (name, bytes, deflated) in &raw {
        // Only the header: an array that is only copied may be an object array (numpy saves a
        // dict or a list that way), copied as its bytes and never unpickled.
        let file = open_npy(&bytes[..]).map_err(|e| bad(name, format!("not a .npy array: {e}")))?;
        let (leading, element) = (file.shape().first().copied(), element_of(&file));
        let stored = if name == "poses" {
            Stored::Poses
        } else if name == "trans" {
            Stored::Trans
        } else if RATE_FIELDS.contains(&name.as_str()) {
            Stored::Rate
        } else if let Some((_, joints)) = parts.iter().find(|(p, _)| p == name) {
            let part = floats(name, bytes)?;
            check_part(name, &part, joints.clone(), &poses.data, width, frames)?;
            Stored::Part(joints.clone())
        } else if LINEAR_FIELDS.contains(&name.as_str()) {
            let values = floats(name, bytes)?;
            if values.shape.first() != Some(&(frames as u64)) {
                return Err(bad(name, format!("shape {:?}; expected [{frames}, ...] to match poses", values.shape)));
            }
            finite(name, &values.data, values.data.len() / frames, |_| "its".into())?;
            Stored::Linear(values)
        } else if leading == Some(frames as u64) && frames > 1 && !SEQUENCE_FIELDS.contains(&name.as_str()) {
            // Any other array of the source's frame count (AMASS's marker_data) is per-frame:
            // resampled linearly as it is (a NaN, an occluded marker, stays one), never left
            // at the old count.
            if !matches!(file.dtype(), DType::Plain(ty) if ty.type_char() == TypeChar::Float) {
                return Err(bad(
                    name,
                    format!(
                        "has the source's {frames} rows but is not an array of floats, which quatcurve resamples \
                         linearly; save the archive without it or as floats"
                    ),
                ));
            }
            Stored::Linear(floats(name, bytes)?)
        } else {
            Stored::Copied(bytes.clone())
        };
        members.push(Member { name: name.clone(), stored, element, deflated: *deflated });
    }
    Ok(SmplFile { family, rate, rate_field, poses: poses.data, trans, members })
}

/// `bytes` as a `.npy` array to read, refusing object arrays (which numpy pickles).
fn npy_of<'a>(name: &str, bytes: &'a [u8]) -> Result<NpyFile<impl Read + 'a>, InputError> {
    let file = open_npy(bytes).map_err(|e| bad(name, format!("not a .npy array: {e}")))?;
    if file.uses_pickled_array() {
        return Err(bad(
            name,
            "an object array, which numpy pickles and quatcurve never unpickles: save it as a plain array",
        ));
    }
    Ok(file)
}

/// Bytes per element of a float array written anew in place of `file`'s: 4 for float32, else 8.
fn element_of<R: Read>(file: &NpyFile<R>) -> usize {
    match file.dtype() {
        DType::Plain(ty) if ty.type_char() == TypeChar::Float && ty.size_field() == 4 => 4,
        _ => 8,
    }
}

/// Every value finite, else an error naming the frame and what `column` names (`width`
/// values a frame).
fn finite(field: &str, values: &[f64], width: usize, column: impl Fn(usize) -> String) -> Result<(), InputError> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(bad(
            field,
            format!(
                "frame {}: {} value {} is {}",
                i / width.max(1),
                column(i % width.max(1)),
                i % width.max(1),
                values[i]
            ),
        )),
    }
}

/// A 0-d (or one-element) number, integer or float.
fn scalar(field: &str, bytes: &[u8]) -> Result<f64, InputError> {
    let file = npy_of(field, bytes)?;
    if file.shape().iter().try_fold(1u64, |a, &d| a.checked_mul(d)) != Some(1) {
        return Err(bad(field, format!("shape {:?}; expected one number", file.shape())));
    }
    let DType::Plain(ty) = file.dtype() else { return Err(bad(field, "a structured array; expected one number")) };
    let read = || npy_of(field, bytes);
    let value = match (ty.type_char(), ty.size_field()) {
        (TypeChar::Float, _) => read_floats(read()?, bytes.len() as u64).map_err(|e| bad(field, e))?.data[0],
        (TypeChar::Int, 1) => f64::from(first::<i8>(field, read()?)?),
        (TypeChar::Int, 2) => f64::from(first::<i16>(field, read()?)?),
        (TypeChar::Int, 4) => f64::from(first::<i32>(field, read()?)?),
        (TypeChar::Int, 8) => first::<i64>(field, read()?)? as f64,
        (TypeChar::Uint, 1) => f64::from(first::<u8>(field, read()?)?),
        (TypeChar::Uint, 2) => f64::from(first::<u16>(field, read()?)?),
        (TypeChar::Uint, 4) => f64::from(first::<u32>(field, read()?)?),
        (TypeChar::Uint, 8) => first::<u64>(field, read()?)? as f64,
        _ => return Err(bad(field, format!("dtype {ty}; expected a number"))),
    };
    Ok(value)
}

/// The one value of a one-element array of `T`.
fn first<T: npyz::Deserialize>(field: &str, npy: NpyFile<impl Read>) -> Result<T, InputError> {
    npy.into_vec::<T>().map_err(|e| bad(field, e))?.pop().ok_or_else(|| bad(field, "holds no value"))
}

/// A duration field (seconds) must be what `frames` at `rate` last, counted either way
/// (`frames / rate` or `(frames - 1) / rate`) within 1%.
fn check_duration(duration: f64, rate: f64, rate_field: &str, frames: usize) -> Result<(), InputError> {
    let near = |d: f64| (duration - d).abs() <= 0.01 * d.max(1.0 / rate);
    if duration.is_finite() && (near(frames as f64 / rate) || near((frames as f64 - 1.0) / rate)) {
        return Ok(());
    }
    Err(bad(
        rate_field,
        format!(
            "{rate} frames per second disagrees with {DURATION_FIELD} {duration} s over {frames} frames (which \
             implies {:.4}); fix whichever is wrong",
            frames as f64 / duration
        ),
    ))
}

/// A field split from `poses` must hold its joints of every frame.
fn check_part(
    name: &str,
    part: &Floats,
    joints: Range<usize>,
    poses: &[f64],
    width: usize,
    frames: usize,
) -> Result<(), InputError> {
    let columns = 3 * joints.len();
    if part.shape.iter().product::<u64>() != (frames * columns) as u64 || part.shape.first() != Some(&(frames as u64)) {
        return Err(bad(name, format!("shape {:?}; expected [{frames}, {columns}] to match poses", part.shape)));
    }
    for (f, row) in part.data.chunks_exact(columns).enumerate() {
        let from_poses = &poses[f * width + 3 * joints.start..f * width + 3 * joints.end];
        if let Some(c) = row.iter().zip(from_poses).position(|(a, b)| (a - b).abs() > 1e-6) {
            return Err(bad(
                name,
                format!("frame {f}, value {c}: {} but poses holds {}; the two must be one pose", row[c], from_poses[c]),
            ));
        }
    }
    Ok(())
}

/// The rotation of an axis-angle vector.
fn from_axis_angle(v: [f64; 3]) -> QuatF64 {
    QuatF64::exp(Vec3F64::from_array(v.map(|x| 0.5 * x)))
}

/// The axis-angle vector of a rotation, angle in `[0, pi]`.
fn to_axis_angle(q: QuatF64) -> [f64; 3] {
    let q = if q.w < 0.0 { QuatF64::from_array(q.to_array().map(|x| -x)) } else { q };
    q.log().to_array().map(|x| 2.0 * x)
}

impl SmplFile {
    /// Frames in the file.
    #[must_use]
    pub fn frames(&self) -> usize {
        self.poses.len() / (3 * self.family.joint_count())
    }

    /// Every array of the archive, in its order, with what a bake writes of it: `resampled`
    /// (poses by slerp, the rest linearly, at the new frames), `rate` (the new rate) or
    /// `copied` (byte for byte).
    #[must_use]
    pub fn arrays(&self) -> Vec<(String, &'static str)> {
        let written = |stored: &Stored| match stored {
            Stored::Poses | Stored::Part(_) | Stored::Trans | Stored::Linear(_) => "resampled",
            Stored::Rate => "rate",
            Stored::Copied(_) => "copied",
        };
        self.members.iter().map(|m| (m.name.clone(), written(&m.stored))).collect()
    }

    /// The common model: the family's joints at rest at their parents' origins, one clip
    /// (`clip_name`) with a rotation channel per joint and the root's translation from
    /// `trans`, keys at `k / rate`.
    #[must_use]
    pub fn animation(&self, clip_name: &str) -> Animation {
        let frames = self.frames();
        let width = 3 * self.family.joint_count();
        let times: Vec<f64> = (0..frames).map(|k| k as f64 / self.rate).collect();
        let joints: Vec<Joint> =
            self.family.joints().into_iter().map(|(name, parent)| Joint::at(name, parent, [0.0; 3])).collect();
        let mut channels: Vec<Channel> = (0..joints.len())
            .map(|j| {
                let values = (0..frames)
                    .map(|f| {
                        let v = &self.poses[f * width + 3 * j..f * width + 3 * j + 3];
                        from_axis_angle([v[0], v[1], v[2]]).to_array()
                    })
                    .collect();
                Channel::keys(j, Property::Rotation, times.clone(), values)
            })
            .collect();
        if let Some(trans) = &self.trans {
            let values = trans.chunks_exact(3).map(|t| [t[0], t[1], t[2], 0.0]).collect();
            channels.push(Channel::keys(0, Property::Translation, times, values));
        }
        Animation { joints, clips: vec![Clip { name: clip_name.to_string(), channels }], skins: Vec::new() }
    }

    /// `poses` and `trans` at the baked frames (channels in [`SmplFile::animation`]'s
    /// order): axis-angles with angles in `[0, pi]`, and the root's translation. With
    /// `slerped` (the bake took the source's own interpolation) they are computed here in f64
    /// from the source's frames ([`Self::slerped`]) at the baked times; otherwise they are the
    /// baked (f32) values.
    #[must_use]
    pub fn resampled(&self, baked: &ClipFrames<'_>, slerped: bool) -> Resampled {
        let joints = self.family.joint_count();
        if slerped {
            return self.slerped(baked.times, baked.rate);
        }
        let poses = (0..baked.times.len())
            .flat_map(|f| (0..joints).map(move |j| (f, j)))
            .flat_map(|(f, j)| to_axis_angle(QuatF64::from_array(baked.values[j][f].map(f64::from))))
            .collect();
        let trans = self
            .trans
            .as_ref()
            .map(|_| baked.values[joints].iter().flat_map(|t| t[..3].iter().map(|&x| f64::from(x))).collect());
        let per_frame = self.per_frame(baked.times);
        Resampled { poses, trans, per_frame, rate: baked.rate, frames: baked.times.len() }
    }

    /// Every per-frame array other than `poses` and `trans` at `times`, linearly.
    fn per_frame(&self, times: &[f64]) -> Vec<(String, Vec<u64>, Vec<f64>)> {
        let linear = self.members.iter().filter_map(|m| match &m.stored {
            Stored::Linear(values) => Some((&m.name, values)),
            _ => None,
        });
        linear
            .map(|(name, values)| {
                let width = values.data.len() / (values.shape[0] as usize).max(1);
                let mut shape = values.shape.clone();
                shape[0] = times.len() as u64;
                (name.clone(), shape, lerped(&values.data, width, self.rate, times))
            })
            .collect()
    }

    /// `poses` and `trans` at `times` (seconds from the first frame; `rate`, theirs) in f64, as
    /// scipy's `Slerp` and `np.interp` compute them: each joint slerped on the shorter arc
    /// between the two source frames around the time, the translation lerped; at a source
    /// frame, its own values exactly (an integer ratio gives the source's frames).
    #[must_use]
    pub fn slerped(&self, times: &[f64], rate: f64) -> Resampled {
        let width = 3 * self.family.joint_count();
        let frames = self.frames();
        let mut poses = Vec::with_capacity(times.len() * width);
        for &t in times {
            let (r, h) = between(t * self.rate, frames);
            let row = |r: usize| &self.poses[r * width..(r + 1) * width];
            if h == 0.0 {
                poses.extend_from_slice(row(r));
                continue;
            }
            for (a, b) in row(r).chunks_exact(3).zip(row(r + 1).chunks_exact(3)) {
                let (q0, q1) = (from_axis_angle([a[0], a[1], a[2]]), from_axis_angle([b[0], b[1], b[2]]));
                let step = q0.conjugate() * q1;
                let step = if step.w < 0.0 { -step } else { step };
                poses.extend(to_axis_angle(q0 * QuatF64::exp(step.log().scale(h))));
            }
        }
        let trans = self.trans.as_ref().map(|trans| lerped(trans, 3, self.rate, times));
        Resampled { poses, trans, per_frame: self.per_frame(times), rate, frames: times.len() }
    }

    /// The archive at the baked rate: every member in the read order, poses and the fields
    /// split from them and the root's translation as [`SmplFile::resampled`], per-frame
    /// coefficients linearly at the baked times, the rate field set to the baked rate.
    ///
    /// # Errors
    /// [`InputError::Output`] if the archive cannot be assembled.
    pub fn to_npz(&self, baked: &ClipFrames<'_>, slerped: bool) -> Result<Vec<u8>, InputError> {
        let resampled = self.resampled(baked, slerped);
        let frames = resampled.frames as u64;
        let width = 3 * self.family.joint_count();
        let columns = |joints: &Range<usize>| -> Vec<f64> {
            resampled.poses.chunks_exact(width).flat_map(|row| row[3 * joints.start..3 * joints.end].to_vec()).collect()
        };
        let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
        let failed = |e: Box<dyn std::error::Error + Send + Sync>| -> InputError {
            OutputError::Archive { what: "the .npz archive", error: e }.into()
        };
        for member in &self.members {
            let bytes = match &member.stored {
                Stored::Copied(bytes) => bytes.clone(),
                Stored::Rate => npy(8, &[], &[resampled.rate]),
                Stored::Poses => npy(member.element, &[frames, width as u64], &resampled.poses),
                Stored::Part(joints) => npy(member.element, &[frames, 3 * joints.len() as u64], &columns(joints)),
                Stored::Trans => npy(member.element, &[frames, 3], resampled.trans.as_deref().unwrap_or_default()),
                Stored::Linear(_) => {
                    let (_, shape, values) = resampled
                        .per_frame
                        .iter()
                        .find(|(name, ..)| *name == member.name)
                        .expect("every per-frame member is resampled");
                    npy(member.element, shape, values)
                }
            };
            let method =
                if member.deflated { zip::CompressionMethod::Deflated } else { zip::CompressionMethod::Stored };
            zip.start_file(
                npyz::npz::file_name_from_array_name(&member.name),
                // A fixed time (the zip epoch, 1980), so that a bake's bytes do not depend on when it ran.
                zip::write::FileOptions::default()
                    .compression_method(method)
                    .last_modified_time(zip::DateTime::default()),
            )
            .map_err(|e| failed(e.into()))?;
            zip.write_all(&bytes).map_err(|e| failed(e.into()))?;
        }
        Ok(zip.finish().map_err(|e| failed(e.into()))?.into_inner())
    }

    /// A file of arrays given in memory: `poses` `[frames, width]` (row-major), `trans`
    /// `[frames, 3]` if given, `rate` frames per second, and `per_frame` arrays (name, shape,
    /// values: `dmpls` and any other of `frames` rows); read by the rules of [`read`].
    ///
    /// # Errors
    /// As [`read`], naming `poses`, `trans`, the rate (as `mocap_framerate`) or the array.
    pub fn from_arrays(
        poses: &[f64],
        width: usize,
        trans: Option<&[f64]>,
        rate: f64,
        per_frame: &[(String, Vec<u64>, Vec<f64>)],
    ) -> Result<SmplFile, InputError> {
        let frames = (poses.len() / width.max(1)) as u64;
        if poses.len() != frames as usize * width {
            return Err(bad("poses", format!("{} values do not fill rows of {width}", poses.len())));
        }
        let mut raw = vec![("poses".to_string(), npy(8, &[frames, width as u64], poses), false)];
        if let Some(trans) = trans {
            if trans.len() % 3 != 0 {
                return Err(bad("trans", format!("{} values do not fill rows of 3", trans.len())));
            }
            raw.push(("trans".to_string(), npy(8, &[(trans.len() / 3) as u64, 3], trans), false));
        }
        raw.push((RATE_FIELDS[0].to_string(), npy(8, &[], &[rate]), false));
        for (name, shape, values) in per_frame {
            if ["poses", "trans", RATE_FIELDS[0]].contains(&name.as_str()) || raw.iter().any(|(n, ..)| n == name) {
                return Err(bad(name, "is given twice"));
            }
            if shape.first() != Some(&frames) || shape.iter().product::<u64>() != values.len() as u64 {
                return Err(bad(name, format!("shape {shape:?}; expected [{frames}, ...] to match poses")));
            }
            raw.push((name.clone(), npy(8, shape, values), false));
        }
        parse(raw)
    }
}

/// SMPL-family arrays at a new rate ([`SmplFile::resampled`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Resampled {
    /// `[frames, joints * 3]` axis-angles.
    pub poses: Vec<f64>,
    /// `[frames, 3]`, where the source had a translation.
    pub trans: Option<Vec<f64>>,
    /// Every other per-frame array (`dmpls`, `marker_data`, ...), in the archive's order: its
    /// name, its shape at the new frame count and its values, linearly at the new times.
    pub per_frame: Vec<(String, Vec<u64>, Vec<f64>)>,
    /// Frames per second.
    pub rate: f64,
    /// Frames.
    pub frames: usize,
}

/// Where `at` (a time in source frames) falls among `frames` frames: the frame at or before it
/// and the fraction of the way to the next (0 at a frame: `at` within 1e-9 of a whole number
/// is that frame, so that a time `k / rate` meant to land on a frame does), held at the ends.
fn between(at: f64, frames: usize) -> (usize, f64) {
    let last = frames.saturating_sub(1);
    let at = if (at - at.round()).abs() <= FRAME_SNAP { at.round() } else { at };
    let at = at.clamp(0.0, last as f64);
    let r = (at.floor() as usize).min(last);
    if r == last {
        return (r, 0.0);
    }
    (r, at - r as f64)
}

/// A time this close to a whole number of source frames (in frames) is that frame.
const FRAME_SNAP: f64 = 1e-9;

/// Rows of `width` values (`[frames, ...]` flattened, rows `1 / rate` apart) at `times`
/// (seconds from the first row), each value linearly between its two rows as `np.interp`
/// computes it; at a row, the row exactly (NaNs and all).
fn lerped(values: &[f64], width: usize, rate: f64, times: &[f64]) -> Vec<f64> {
    let frames = values.len() / width.max(1);
    let row = |r: usize| &values[r * width..(r + 1) * width];
    let mut out = Vec::with_capacity(times.len() * width);
    for &t in times {
        let (r, h) = between(t * rate, frames);
        if h == 0.0 {
            out.extend_from_slice(row(r));
        } else {
            out.extend(row(r).iter().zip(row(r + 1)).map(|(a, b)| a + h * (b - a)));
        }
    }
    out
}

/// A little-endian `.npy` of floats of `element` bytes (4 or 8).
fn npy(element: usize, shape: &[u64], values: &[f64]) -> Vec<u8> {
    let mut out = npy_header(if element == 4 { "<f4" } else { "<f8" }, shape);
    for &v in values {
        if element == 4 {
            out.extend_from_slice(&(v as f32).to_le_bytes());
        } else {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_families_have_the_documented_joints_parents_first() {
        for family in Family::ALL {
            let joints = family.joints();
            assert_eq!(joints.len(), family.joint_count(), "{}", family.name());
            assert_eq!(Family::of_width(3 * joints.len() as u64), Some(family));
            for (j, (name, parent)) in joints.iter().enumerate() {
                assert!(parent.map_or(j == 0, |p| p < j), "{} {name}", family.name());
            }
            let parts = family.parts();
            assert_eq!(parts.last().unwrap().1.end, if family == Family::Smpl { 22 } else { joints.len() });
        }
        let x = Family::SmplX.joints();
        assert_eq!((x[22].0.as_str(), x[22].1), ("jaw", Some(15)));
        assert_eq!((x[25].0.as_str(), x[25].1), ("left_index1", Some(20)));
        assert_eq!((x[54].0.as_str(), x[54].1), ("right_thumb3", Some(53)));
        let h = Family::SmplH.joints();
        assert_eq!((h[37].0.as_str(), h[37].1), ("right_index1", Some(21)));
        assert_eq!((h[36].0.as_str(), h[36].1), ("left_thumb3", Some(35)));
    }

    #[test]
    fn axis_angles_round_trip_with_angles_up_to_a_half_turn() {
        for v in [[0.0, 0.0, 0.0], [1e-9, -2e-9, 0.0], [0.3, -1.2, 2.0], [0.0, 3.1, 0.0]] {
            let back = to_axis_angle(from_axis_angle(v));
            assert!(back.iter().zip(v).all(|(a, b)| (a - b).abs() < 1e-12), "{v:?} -> {back:?}");
        }
        // Past a half turn, the same rotation the short way round.
        let back = to_axis_angle(from_axis_angle([0.0, 0.0, 4.0]));
        assert!((back[2] - (4.0 - std::f64::consts::TAU)).abs() < 1e-12, "{back:?}");
    }

    #[test]
    fn a_rate_is_read_from_any_number_type() {
        for (descr, bytes) in [
            ("<f8", 60.0f64.to_le_bytes().to_vec()),
            ("<f4", 59.94f32.to_le_bytes().to_vec()),
            ("<i8", 120i64.to_le_bytes().to_vec()),
            ("<i4", 30i32.to_le_bytes().to_vec()),
            ("|u1", vec![25u8]),
        ] {
            let mut npy = npy_header(descr, &[]);
            npy.extend(&bytes);
            let value = scalar("mocap_frame_rate", &npy).unwrap();
            assert!([60.0, 120.0, 30.0, 25.0].contains(&value) || (value - 59.94).abs() < 1e-5, "{descr}: {value}");
        }
        let mut text = npy_header("<U2", &[]);
        text.extend("60".chars().flat_map(|c| (c as u32).to_le_bytes()));
        assert!(scalar("mocap_framerate", &text).unwrap_err().to_string().contains("expected a number"));
    }

    #[test]
    fn per_frame_arrays_resample_linearly_keep_their_frames_exactly_and_hold_the_ends() {
        let values = [0.0, 10.0, 1.0, 20.0, 3.0, f64::NAN];
        let data = lerped(&values, 2, 2.0, &[0.0, 0.25, 0.5, 0.75, 1.0, 1.5]);
        assert_eq!(data[..7], [0.0, 10.0, 0.5, 15.0, 1.0, 20.0, 2.0]);
        // At a frame, the frame (its neighbour's NaN does not leak in); beside a NaN, NaN; the end held.
        assert!(data[7].is_nan() && data[8] == 3.0 && data[9].is_nan() && data[10] == 3.0);
        // A time meant to land on a frame does, though k / rate * rate is not always k.
        let third = 1.0 / 3.0;
        assert_eq!(between(3.0 * third * 3.0, 10), (3, 0.0));
        assert_eq!(between(0.1 * 30.0, 10), (3, 0.0));
    }
}
