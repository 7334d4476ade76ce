//! BVH motion capture in and out.
//!
//! A joint's rotation channels, read left to right, compose as `R = R_1(a_1) R_2(a_2) ...`
//! about the parent's axes after the joint's own (the BVH convention: `v' = R v` with the
//! first listed channel outermost); angles are in degrees. Position channels (usually only on
//! the root) give the joint's translation as `OFFSET + (X, Y, Z)position`. Writing back keeps
//! the hierarchy text byte for byte and converts each resampled rotation to the joint's own
//! channel order, unwrapping angles to the previous frame so curves stay continuous.

use quatcurve_anim::error::{AnimationError, InputError};
use quatcurve_anim::{Animation, Channel, Clip, ClipFrames, Joint, Property};
use quatcurve_core::quat::{QuatF64, Vec3F64};
use std::fmt::Write as _;
use std::path::Path;

/// A BVH channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BvhChannel {
    /// Translation along an axis (0 = X, 1 = Y, 2 = Z).
    Position(usize),
    /// Rotation about an axis, degrees.
    Rotation(usize),
}

/// A joint of the hierarchy with its channels (End Sites are not joints).
#[derive(Clone, Debug, PartialEq)]
pub struct BvhJoint {
    /// Name.
    pub name: String,
    /// The enclosing joint, `None` for a ROOT.
    pub parent: Option<usize>,
    /// OFFSET from the parent.
    pub offset: [f64; 3],
    /// CHANNELS in file order.
    pub channels: Vec<BvhChannel>,
}

/// A BVH file read for baking.
#[derive(Clone, Debug, PartialEq)]
pub struct BvhFile {
    /// Joints in file order (the order of the motion columns).
    pub joints: Vec<BvhJoint>,
    /// Seconds per frame: `1 / N` exactly when the file writes that rounded
    /// ([`exact_frame_time`]).
    pub frame_time: f64,
    /// Per frame, every channel value in column order.
    pub frames: Vec<Vec<f64>>,
    /// The file's text before `MOTION`, written back unchanged.
    hierarchy: String,
}

fn bad(line: usize, msg: impl std::fmt::Display) -> InputError {
    InputError::Bvh { line, reason: msg.to_string() }
}

/// Reads a BVH file.
///
/// # Errors
/// [`InputError::Read`], or [`InputError::Bvh`] naming the line for a malformed hierarchy or
/// motion section.
pub fn read(path: &Path) -> Result<BvhFile, InputError> {
    let text = std::fs::read_to_string(path).map_err(InputError::Read)?;
    parse(&text)
}

/// Parses BVH text (see [`read`]).
///
/// # Errors
/// As [`read`].
pub fn parse(text: &str) -> Result<BvhFile, InputError> {
    let motion_at = text.find("MOTION").ok_or_else(|| bad(text.lines().count(), "no MOTION section"))?;
    let hierarchy = &text[..motion_at];
    let joints = parse_hierarchy(hierarchy)?;
    let (frame_time, frames) = parse_motion(&text[motion_at..], hierarchy.lines().count() + 1, &joints)?;
    Ok(BvhFile { joints, frame_time, frames, hierarchy: hierarchy.to_string() })
}

/// A BVH file without frames from a fitted container's skeleton ((`quatcurve_qcf`)),
/// to write baked frames under the source's hierarchy.
///
/// # Errors
/// [`InputError::Bvh`] for a malformed hierarchy; [`InputError::Animation`] when its joints are
/// not the container's, in order.
pub fn skeleton(skeleton: &quatcurve_qcf::BvhSkeleton, animation: &Animation) -> Result<BvhFile, InputError> {
    let joints = parse_hierarchy(&skeleton.hierarchy)?;
    let (hierarchy, skeleton_joints): (Vec<String>, Vec<String>) =
        (joints.iter().map(|j| j.name.clone()).collect(), animation.joints.iter().map(|j| j.name.clone()).collect());
    if hierarchy != skeleton_joints {
        return Err(AnimationError::HierarchyNotSkeleton { hierarchy, skeleton: skeleton_joints }.into());
    }
    Ok(BvhFile { joints, frame_time: skeleton.frame_time, frames: Vec::new(), hierarchy: skeleton.hierarchy.clone() })
}

/// A token with its line, or the error that the text ended where `what` was expected.
type Token<'a> = Result<(usize, &'a str), InputError>;

/// The joints of the HIERARCHY section, parents first.
fn parse_hierarchy(hierarchy: &str) -> Result<Vec<BvhJoint>, InputError> {
    let mut tokens =
        hierarchy.lines().enumerate().flat_map(|(i, l)| l.split_whitespace().map(move |t| (i + 1, t))).peekable();
    let mut next = |what: &str| {
        tokens
            .next()
            .ok_or_else(|| bad(hierarchy.lines().count(), format!("the hierarchy ends where {what} was expected")))
    };
    let (line, word) = next("HIERARCHY")?;
    if word != "HIERARCHY" {
        return Err(bad(line, format!("expected HIERARCHY, found {word}")));
    }
    let mut joints: Vec<BvhJoint> = Vec::new();
    // The joints whose braces are open, innermost last.
    let mut enclosing: Vec<usize> = Vec::new();
    while let Ok((line, word)) = next("a joint") {
        match word {
            "ROOT" | "JOINT" => {
                joints.push(parse_joint(&mut next, word, enclosing.last().copied())?);
                enclosing.push(joints.len() - 1);
            }
            "End" => {
                // End Site { OFFSET x y z }: geometry only, no channels.
                for _ in 0..6 {
                    next("End Site")?;
                }
                let (line, close) = next("}")?;
                if close != "}" {
                    return Err(bad(line, format!("expected }} closing End Site, found {close}")));
                }
            }
            "}" => {
                enclosing.pop().ok_or_else(|| bad(line, "unbalanced }"))?;
            }
            other => return Err(bad(line, format!("unexpected {other} in the hierarchy"))),
        }
    }
    if !enclosing.is_empty() || joints.is_empty() {
        return Err(bad(hierarchy.lines().count(), "the hierarchy is empty or its braces are unbalanced"));
    }
    Ok(joints)
}

/// A number token.
fn number((line, word): (usize, &str)) -> Result<f64, InputError> {
    word.parse::<f64>().map_err(|_| bad(line, format!("expected a number, found {word}")))
}

/// One `ROOT` or `JOINT` (`word`) after its keyword: name, `{`, OFFSET and CHANNELS.
fn parse_joint<'a>(
    next: &mut impl FnMut(&str) -> Token<'a>,
    word: &str,
    parent: Option<usize>,
) -> Result<BvhJoint, InputError> {
    let (_, name) = next("a joint name")?;
    let (line, open) = next("{")?;
    if open != "{" {
        return Err(bad(line, format!("expected {{ after {word} {name}, found {open}")));
    }
    let (line, kw) = next("OFFSET")?;
    if kw != "OFFSET" {
        return Err(bad(line, format!("expected OFFSET in joint {name}, found {kw}")));
    }
    let offset = [number(next("OFFSET x")?)?, number(next("OFFSET y")?)?, number(next("OFFSET z")?)?];
    let (line, kw) = next("CHANNELS")?;
    if kw != "CHANNELS" {
        return Err(bad(line, format!("expected CHANNELS in joint {name}, found {kw}")));
    }
    let (line, count) = next("a channel count")?;
    let count: usize = count.parse().map_err(|_| bad(line, format!("bad channel count {count}")))?;
    // Three positions and three rotations at most; a larger count is corruption
    // (and must not size an allocation).
    if count > 6 {
        return Err(bad(line, format!("joint {name} declares {count} channels; a BVH joint has at most 6")));
    }
    let mut channels = Vec::with_capacity(count);
    for _ in 0..count {
        let (line, c) = next("a channel name")?;
        let axis = match c.as_bytes().first() {
            Some(b'X' | b'x') => 0,
            Some(b'Y' | b'y') => 1,
            Some(b'Z' | b'z') => 2,
            _ => return Err(bad(line, format!("unknown channel {c} in joint {name}"))),
        };
        channels.push(match &c[1..] {
            "position" => BvhChannel::Position(axis),
            "rotation" => BvhChannel::Rotation(axis),
            _ => return Err(bad(line, format!("unknown channel {c} in joint {name}"))),
        });
    }
    // Writing back solves for the angles, which needs 0, 1 or 3 distinct axes (found by
    // fuzzing: 4 rotation channels, or one axis twice, crashed the writer).
    let mut axes: Vec<usize> =
        channels.iter().filter_map(|c| if let BvhChannel::Rotation(a) = c { Some(*a) } else { None }).collect();
    let listed = axes.len();
    axes.sort_unstable();
    axes.dedup();
    if !matches!(listed, 0 | 1 | 3) || axes.len() != listed {
        return Err(bad(
            line,
            format!(
                "joint {name} has {listed} rotation channels about {} distinct axes; 0, 1 or 3 \
            distinct axes are supported",
                axes.len()
            ),
        ));
    }
    Ok(BvhJoint { name: name.to_string(), parent, offset, channels })
}

/// The MOTION section (from its keyword, whose line is `first_line`): the frame time and one
/// row of channel values per frame.
fn parse_motion(motion: &str, first_line: usize, joints: &[BvhJoint]) -> Result<(f64, Vec<Vec<f64>>), InputError> {
    let mut lines = motion.lines().enumerate().map(|(i, l)| (first_line + i, l)).skip(1);
    let mut header = |key: &str| -> Result<f64, InputError> {
        let (line, l) = lines.next().ok_or_else(|| bad(first_line, format!("missing {key}")))?;
        let value = l.trim().strip_prefix(key).ok_or_else(|| bad(line, format!("expected {key}")))?;
        value.trim().parse().map_err(|_| bad(line, format!("bad {key} {}", value.trim())))
    };
    let count = header("Frames:")?;
    let frame_time = header("Frame Time:")?;
    if !(frame_time.is_finite() && frame_time > 0.0) || count.fract() != 0.0 || count < 1.0 {
        return Err(bad(
            first_line,
            format!("need at least one frame and a positive frame time (Frames: {count}, Frame Time: {frame_time})"),
        ));
    }
    let frame_time = exact_frame_time(frame_time);
    let columns: usize = joints.iter().map(|j| j.channels.len()).sum();
    // `Frames:` is checked against the lines present afterwards; it never sizes an allocation
    // by itself (a crafted header could ask for billions).
    let mut frames = Vec::with_capacity((count as usize).min(motion.len() / (2 * columns.max(1)) + 1));
    for (line, l) in lines.filter(|(_, l)| !l.trim().is_empty()) {
        let row: Vec<f64> = l
            .split_whitespace()
            .map(|w| w.parse::<f64>().map_err(|_| bad(line, format!("frame {}: {w} is not a number", frames.len()))))
            .collect::<Result<_, _>>()?;
        if row.len() != columns {
            return Err(bad(
                line,
                format!("frame {} has {} values but the hierarchy has {columns} channels", frames.len(), row.len()),
            ));
        }
        frames.push(row);
    }
    if frames.len() != count as usize {
        return Err(bad(first_line, format!("Frames: {count} but {} frame lines follow", frames.len())));
    }
    Ok((frame_time, frames))
}

/// A `Frame Time` within this relative difference of `1 / N` for a whole `N` is read as
/// exactly `1 / N`: files write the frame time rounded (CMU's `.0083333` for 120 Hz, 4e-6
/// off), and reading it as written drifts the frames from the grid they were captured on.
pub const FRAME_TIME_SNAP: f64 = 1e-5;

/// `frame_time`, or `1 / N` when it is within [`FRAME_TIME_SNAP`] of it for a whole `N`.
#[must_use]
pub fn exact_frame_time(frame_time: f64) -> f64 {
    let n = (1.0 / frame_time).round();
    let exact = 1.0 / n;
    if n >= 1.0 && ((frame_time - exact) / exact).abs() < FRAME_TIME_SNAP {
        exact
    } else {
        frame_time
    }
}

/// The rotation `R_1(a_1) R_2(a_2) ...` of a joint's rotation channels (degrees).
#[must_use]
pub fn euler_to_quat(channels: &[BvhChannel], values: &[f64]) -> QuatF64 {
    channels.iter().zip(values).fold(QuatF64::identity(), |q, (&c, &degrees)| match c {
        BvhChannel::Rotation(axis) => q * axis_rotation(axis, degrees.to_radians()),
        BvhChannel::Position(_) => q,
    })
}

fn axis_rotation(axis: usize, radians: f64) -> QuatF64 {
    let mut v = [0.0; 3];
    v[axis] = 0.5 * radians;
    QuatF64::exp(Vec3F64::from_array(v))
}

/// Angles (degrees) of rotation `q` about `axes` (one axis, or three distinct ones) such that
/// `R_{axes[0]}(a_0) R_{axes[1]}(a_1) R_{axes[2]}(a_2) = q`, each within 180 degrees of
/// `near` (the previous frame's angles) so angle curves do not jump by whole turns.
#[must_use]
pub fn quat_to_euler(axes: &[usize], q: QuatF64, near: &[f64]) -> Vec<f64> {
    let raw = match *axes {
        [a] => {
            let v = [q.x, q.y, q.z];
            vec![2.0 * v[a].atan2(q.w)]
        }
        [i, j, k] => {
            // For R = R_i(a) R_j(b) R_k(c) with (i, j, k) a permutation of parity s:
            // R[i][k] = s sin b, R[i][j] = -s cos b sin c, R[i][i] = cos b cos c. The
            // quaternion is normalized first (an f32 one is unit to ~1e-7), b is taken by atan2
            // against cos b = |(R[i][i], R[i][j])| (asin near 90 degrees turns 1e-7 into 1e-4),
            // and a from what is left once c and b are undone, so the three angles give back q
            // even where cos b is near 0 and the split between a and c is arbitrary.
            let q = q.normalize();
            let m = q.to_mat3();
            let s = if (j + 3 - i) % 3 == 1 { 1.0 } else { -1.0 };
            let b = (s * m[i][k]).atan2(m[i][i].hypot(m[i][j]));
            let c = (-s * m[i][j]).atan2(m[i][i]);
            let rest = q * axis_rotation(k, -c) * axis_rotation(j, -b);
            let a = 2.0 * [rest.x, rest.y, rest.z][i].atan2(rest.w);
            vec![a, b, c]
        }
        _ => Vec::new(),
    };
    raw.iter()
        .zip(near.iter().copied().chain(std::iter::repeat(0.0)))
        .map(|(&r, near)| {
            let d = r.to_degrees();
            d + 360.0 * ((near - d) / 360.0).round()
        })
        .collect()
}

impl BvhFile {
    /// The common model: one clip (`clip_name`) with a rotation channel per joint that has
    /// rotation channels and a translation channel per joint that has position channels.
    #[must_use]
    pub fn animation(&self, clip_name: &str) -> Animation {
        let times: Vec<f64> = (0..self.frames.len()).map(|i| i as f64 * self.frame_time).collect();
        let mut channels = Vec::new();
        let mut column = 0;
        for (index, joint) in self.joints.iter().enumerate() {
            let range = column..column + joint.channels.len();
            column = range.end;
            let values =
                |f: &dyn Fn(&[f64]) -> [f64; 4]| self.frames.iter().map(|row| f(&row[range.clone()])).collect();
            if joint.channels.iter().any(|c| matches!(c, BvhChannel::Rotation(_))) {
                let values = values(&|row| euler_to_quat(&joint.channels, row).to_array());
                channels.push(Channel::keys(index, Property::Rotation, times.clone(), values));
            }
            if joint.channels.iter().any(|c| matches!(c, BvhChannel::Position(_))) {
                let values = values(&|row| {
                    let mut p = [joint.offset[0], joint.offset[1], joint.offset[2], 0.0];
                    for (&c, &v) in joint.channels.iter().zip(row) {
                        if let BvhChannel::Position(axis) = c {
                            p[axis] += v;
                        }
                    }
                    p
                });
                channels.push(Channel::keys(index, Property::Translation, times.clone(), values));
            }
        }
        let joints = self.joints.iter().map(|j| Joint::at(j.name.clone(), j.parent, j.offset)).collect();
        Animation { joints, clips: vec![Clip { name: clip_name.to_string(), channels }], skins: Vec::new() }
    }

    /// The file's text before `MOTION`, as it was read.
    #[must_use]
    pub fn hierarchy(&self) -> &str {
        &self.hierarchy
    }

    /// BVH text of the baked clip at its baked rate: the original hierarchy, new frames.
    #[must_use]
    pub fn to_text(&self, clip: &Clip, baked: &ClipFrames<'_>) -> String {
        let (frames, values) = (baked.times.len(), &baked.values);
        let mut out = self.hierarchy.clone();
        // Shortest text that reads back as the same f64 (`{}`), so the rate round-trips.
        let _ = write!(out, "MOTION\nFrames: {frames}\nFrame Time: {}\n", 1.0 / baked.rate);
        // Per joint: its baked rotation and translation series, if any.
        let series = |joint: usize, property: Property| {
            clip.channels.iter().position(|c| c.joint == joint && c.property == property).map(|i| values[i])
        };
        let mut previous: Vec<Vec<f64>> = vec![Vec::new(); self.joints.len()];
        let mut row = String::new();
        for frame in 0..frames {
            row.clear();
            for (index, joint) in self.joints.iter().enumerate() {
                let axes: Vec<usize> = joint
                    .channels
                    .iter()
                    .filter_map(|c| if let BvhChannel::Rotation(a) = c { Some(*a) } else { None })
                    .collect();
                let angles = series(index, Property::Rotation).map(|s| {
                    let q = QuatF64::from_array(s[frame].map(f64::from));
                    quat_to_euler(&axes, q, &previous[index])
                });
                if let Some(angles) = &angles {
                    previous[index].clone_from(angles);
                }
                let position = series(index, Property::Translation).map(|s| s[frame]);
                let mut rotation = 0;
                for &c in &joint.channels {
                    let value = match c {
                        BvhChannel::Position(axis) => position.map_or(0.0, |p| f64::from(p[axis]) - joint.offset[axis]),
                        BvhChannel::Rotation(_) => {
                            rotation += 1;
                            angles.as_ref().map_or(0.0, |a| a[rotation - 1])
                        }
                    };
                    let _ = write!(row, "{value:.6} ");
                }
            }
            out.push_str(row.trim_end());
            out.push('\n');
        }
        out
    }
}
