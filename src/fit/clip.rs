//! A whole clip fitted within ACL's error: every channel as a B-spline ([`super`]), with
//! tolerances shared down the hierarchy so that the object-space error of every joint's
//! virtual vertices ([`crate::analysis::vertex_error`]) stays within a budget at every source
//! frame; then measured at every frame and at points between frames against the source's own
//! interpolation (keys slerped and lerped), and counted in bytes as ACL counts a raw clip
//! against the clip's bytes in the container ([`super::container`]).

use super::fitted::{Fitted, FittedChannel, FittedClip};
use super::quantize::{self, Quantized, QuantizedRotations};
use super::timeline::{Timeline, BETWEEN_POINTS};
use super::{bracket, fit_rotations, fit_vectors, Fit, ORDER};
use crate::analysis::vertex_error::{object_space, pose_errors, Transform};
use crate::bake::{Animation, Channel, Property};
use crate::error::Number;
use crate::quat::{QuatF64, Vec3F64};
use rayon::prelude::*;

/// Bytes ACL counts per joint per frame of a raw clip: `f32` rotation, translation and scale.
pub const RAW_BYTES_PER_JOINT_FRAME: usize = 40;

/// The share of a channel's tolerance its control points' quantization may take; the fit
/// takes the rest.
pub const QUANTIZATION_SHARE: f64 = 0.4;

/// A rounding of a rotation channel's control points that moves its curve by more than this
/// multiple of the rounding has joined two of them the other way round
/// ([`quantize::rotations_keeping`]); smaller moves are left to the clip's measure.
const OTHER_WAY_ROUND: f64 = 8.0;

/// Fits of a clip at most, each with every tolerance scaled by how much room the last left.
const SCALINGS: usize = 12;

/// A fit whose worst error is within this factor of the budget is not tried looser.
const ROOM_TO_GROW: f64 = 1.25;

/// The most the tolerances grow from one fit to the next.
const MAX_GROWTH: f64 = 4.0;

/// The error allowed and where it is measured, in the file's units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budget {
    /// The largest distance a virtual vertex may move, at any source frame.
    pub max_error: f64,
    /// The largest between frames, from the source's own interpolation (a looser bound: a
    /// curve through the frames alone may swing between them); infinite: not checked.
    pub between_error: f64,
    /// How far from each joint its virtual vertices are.
    pub vertex_distance: f64,
}

/// The largest error of a clip and where it is.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Worst {
    /// The distance, in file units.
    pub error: f64,
    /// The joint.
    pub joint: usize,
    /// The time, seconds.
    pub time: f64,
}

/// A clip fitted within a [`Budget`], measured.
#[derive(Clone, Debug, PartialEq)]
pub struct ClipFit {
    /// The fitted clip.
    pub clip: FittedClip,
    /// The worst error at the source frames, and between them.
    pub at_frames: Worst,
    /// See [`Self::at_frames`].
    pub between_frames: Worst,
    /// The source's frames (every channel's key times).
    pub frames: usize,
    /// [`RAW_BYTES_PER_JOINT_FRAME`] per joint per frame.
    pub raw_bytes: usize,
    /// The clip's bytes in the container ([`super::container::clip_bytes`]).
    pub fitted_bytes: usize,
}

/// Why a clip was not fitted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FitClipError {
    /// The clip or the budget cannot be fitted at all.
    #[error("{0}")]
    Input(String),
    /// Every fit was over the budget; the errors of the closest one, in file units.
    #[error(
        "no fit within the budget after {SCALINGS} scalings of the tolerances; the closest was {} at frames and {} \
         between them (file units)",
        Number(at_frames.error),
        Number(between_frames.error)
    )]
    OverBudget {
        /// Its worst at the source frames.
        at_frames: Worst,
        /// Its worst between them.
        between_frames: Worst,
    },
}

/// Clip `clip` of `animation` fitted within `budget`.
///
/// # Errors
/// A clip index out of range, a budget length that is not positive, a hierarchy that is not
/// a tree ([`FitClipError::Input`]), or a budget no fit meets ([`FitClipError::OverBudget`]).
pub fn fit_clip(animation: &Animation, clip: usize, budget: &Budget) -> Result<ClipFit, FitClipError> {
    for (name, value) in [
        ("max error", budget.max_error),
        ("between error", budget.between_error),
        ("vertex distance", budget.vertex_distance),
    ] {
        // An infinite between error leaves the points between frames unchecked.
        if !(value > 0.0 && (value.is_finite() || name == "between error")) {
            return Err(FitClipError::Input(format!("the {name} is {value}; it must be a positive length")));
        }
    }
    let order = animation.parents_first().map_err(|e| FitClipError::Input(e.to_string()))?;
    let parents: Vec<Option<usize>> = animation.joints.iter().map(|j| j.parent).collect();
    let source = animation
        .clips
        .get(clip)
        .ok_or_else(|| FitClipError::Input(format!("no clip {clip}: the animation has {}", animation.clips.len())))?;
    let channels = &source.channels;
    if let Some(c) = channels.iter().find(|c| c.knots.is_some()) {
        return Err(FitClipError::Input(format!(
            "{} is fitted already: it holds control points, not keys",
            animation.label(source, c)
        )));
    }
    let mut frames: Vec<f64> = channels.iter().flat_map(|c| c.times.iter().copied()).collect();
    frames.sort_by(f64::total_cmp);
    frames.dedup();
    let between: Vec<f64> = frames
        .windows(2)
        .flat_map(|w| (1..=BETWEEN_POINTS).map(move |k| w[0] + (w[1] - w[0]) * k as f64 / (BETWEEN_POINTS + 1) as f64))
        .collect();
    // The distinct key times of the channels with more than one key, and each one's.
    let mut timelines: Vec<Timeline> = Vec::new();
    let timeline_of: Vec<usize> = channels
        .iter()
        .map(|c| {
            if c.times.len() < 2 {
                return 0;
            }
            let line = Timeline::of(&c.times);
            timelines.iter().position(|l| *l == line).unwrap_or_else(|| {
                timelines.push(line);
                timelines.len() - 1
            })
        })
        .collect();
    let tolerances = tolerances(animation, &order, channels, budget);
    let between_share = budget.between_error / budget.max_error;
    // The shares are conservative (errors along a chain seldom add up in one direction), so
    // each channel's tolerance is scaled towards the budget by the room its joint's subtree
    // left (the worst of the virtual vertices it moves): up while there is room, down where a
    // vertex is over; the smallest fit within the budget is kept.
    let mut best: Option<ClipFit> = None;
    // Per channel, the scales of its tolerance at frames and between them: the two rooms
    // differ, and one scale for both lets a channel with room at frames ring between them.
    let mut scales = vec![[1.0, 1.0]; channels.len()];
    // The scales of the smallest fit within the budget so far.
    let mut kept = scales.clone();
    // The fit with the most room, and its errors, for the message when none is within.
    let mut closest = (0.0, Worst::default(), Worst::default());
    // Fits over the budget in a row.
    let mut overs = 0;
    for _ in 0..SCALINGS {
        let fitted: Vec<FittedChannel> = channels
            .par_iter()
            .zip(&tolerances)
            .zip(&timeline_of)
            .zip(&scales)
            .map(|(((c, &t), &line), &[at, between])| FittedChannel {
                joint: c.joint,
                property: c.property,
                curve: fit_channel(c, &timelines, line, [t * at, t * between_share * between]),
            })
            .collect();
        let measure = |times: &[f64]| worst_error(animation, &parents, &order, channels, &fitted, times, budget);
        let ((at_frames, at_joints), (between_frames, between_joints)) = (measure(&frames), measure(&between));
        let room = (budget.max_error / at_frames.error).min(budget.between_error / between_frames.error);
        if room > closest.0 {
            closest = (room, at_frames, between_frames);
        }
        let fitted = FittedClip {
            name: source.name.clone(),
            span: source.span(),
            timelines: timelines.clone(),
            channels: fitted,
        };
        let fitted_bytes = super::container::clip_bytes(&fitted);
        if room >= 1.0 && best.as_ref().map_or(true, |b| fitted_bytes < b.fitted_bytes) {
            kept.clone_from(&scales);
            best = Some(ClipFit {
                between_frames,
                fitted_bytes,
                clip: fitted,
                at_frames,
                frames: frames.len(),
                raw_bytes: RAW_BYTES_PER_JOINT_FRAME * animation.joints.len() * frames.len(),
            });
        }
        let (at, between) =
            (subtree_worst(&parents, &order, at_joints), subtree_worst(&parents, &order, between_joints));
        let rooms: Vec<[f64; 2]> = channels
            .iter()
            .map(|c| {
                [budget.max_error / at[c.joint], budget.between_error / between[c.joint]].map(|r| r.min(MAX_GROWTH))
            })
            .collect();
        if rooms.iter().flatten().all(|r| (1.0..ROOM_TO_GROW).contains(r)) {
            break;
        }
        // Over the budget after a step from the kept fit: half the step back (geometric mean),
        // for the channels over it; the second time in a row, for every channel (errors do not
        // follow tolerances smoothly, and stepping back only the channels over it can stay over
        // the budget, step after step).
        let over = room < 1.0 && best.is_some();
        let all_back = over && overs > 0;
        overs = if over { overs + 1 } else { 0 };
        for ((scale, room), kept) in scales.iter_mut().flatten().zip(rooms.iter().flatten()).zip(kept.iter().flatten())
        {
            let back = all_back || (over && *room < 1.0 && kept < scale);
            *scale = if back { (*scale * kept).sqrt() } else { *scale * 0.9 * room };
        }
    }
    best.ok_or(FitClipError::OverBudget { at_frames: closest.1, between_frames: closest.2 })
}

/// Each channel's tolerance: the budget split evenly over the animated channels of the longest
/// chain from a root, a rotation's as the angle that moves the farthest vertex it carries (at
/// rest) by that share, a scale's likewise, a translation's the share itself.
fn tolerances(animation: &Animation, order: &[usize], channels: &[Channel], budget: &Budget) -> Vec<f64> {
    let joints = &animation.joints;
    let parents: Vec<Option<usize>> = joints.iter().map(|j| j.parent).collect();
    let at: Vec<Vec3F64> = object_space(&parents, order, &rest_pose(animation))
        .iter()
        .map(|m| Vec3F64::new(m.translation.x, m.translation.y, m.translation.z))
        .collect();
    // Reach: the farthest joint it carries, plus the vertex distance.
    let mut reach = vec![budget.vertex_distance; joints.len()];
    // Animated channels on the way from a root down to each joint, itself included.
    let mut depth = vec![0usize; joints.len()];
    let animated = |j: usize| channels.iter().filter(|c| c.joint == j && c.times.len() > 1).count();
    for &j in order {
        depth[j] = joints[j].parent.map_or(0, |p| depth[p]) + animated(j);
        let mut a = joints[j].parent;
        while let Some(p) = a {
            reach[p] = reach[p].max((at[j] - at[p]).length() + budget.vertex_distance);
            a = joints[p].parent;
        }
    }
    let share = budget.max_error / depth.iter().copied().max().unwrap_or(1).max(1) as f64;
    channels
        .iter()
        .map(|c| match c.property {
            Property::Translation => share,
            Property::Rotation | Property::Scale => share / reach[c.joint],
        })
        .collect()
}

/// `channel` fitted at the samples of its timeline (`timelines[line]`: its keys and the points
/// between them), within `tolerance[0]` at keys and `tolerance[1]` between them,
/// against its own interpolation; a channel whose every key is within `tolerance` of its first
/// is stored once.
fn fit_channel(channel: &Channel, timelines: &[Timeline], line: usize, [tolerance, between]: [f64; 2]) -> Fitted {
    let first = channel.values[0];
    let rotation = channel.property == Property::Rotation;
    let off = |v: &[f64; 4]| {
        if rotation {
            QuatF64::from_array(*v).angle_to(QuatF64::from_array(first))
        } else {
            (Vec3F64::new(v[0], v[1], v[2]) - Vec3F64::new(first[0], first[1], first[2])).length()
        }
    };
    if channel.times.len() < 2 || channel.values.iter().all(|v| off(v) <= tolerance) {
        return Fitted::constant(if rotation { first } else { [first[0], first[1], first[2], 0.0] });
    }
    let samples = timelines[line].sample_times();
    let times: Vec<f64> = samples.iter().map(|&(t, _)| t).collect();
    let fitting: Vec<f64> =
        samples.iter().map(|&(_, key)| (1.0 - QUANTIZATION_SHARE) * if key { tolerance } else { between }).collect();
    let values: Vec<[f64; 4]> = times.iter().map(|&t| source_at(channel, t)).collect();
    let rounding = tolerance * QUANTIZATION_SHARE;
    // Every knot is one of the samples; the container stores its index.
    let sample_of = |knot: &f64| {
        let s = times.partition_point(|&t| t < *knot);
        debug_assert_eq!(times[s], *knot, "a knot at a sample");
        s as u32
    };
    let interior = |knots: &[f64]| knots[ORDER..knots.len() - ORDER].iter().map(sample_of).collect();
    if rotation {
        let rotations: Vec<QuatF64> = values.iter().map(|v| QuatF64::from_array(*v)).collect();
        let fit = fit_rotations(&times, &rotations, &fitting);
        let knots: Vec<u32> = interior(&fit.knots);
        // The curve before rounding, which the decoded one must stay near.
        let unrounded = fit.evaluate(&times).unwrap_or_default();
        let keeps = |codes: &QuantizedRotations| {
            let decoded = Fit { knots: fit.knots.clone(), controls: codes.values(), worst: 0.0, worst_at: 0 };
            decoded.evaluate(&times).is_ok_and(|decoded| {
                decoded.iter().zip(&unrounded).all(|(d, u)| d.angle_to(*u) <= OTHER_WAY_ROUND * rounding)
            })
        };
        Fitted::rotation(timelines, line, knots, quantize::rotations_keeping(&fit.controls, rounding, keeps))
    } else {
        let vectors: Vec<[f64; 3]> = values.iter().map(|v| [v[0], v[1], v[2]]).collect();
        let fit = fit_vectors(&times, &vectors, &fitting);
        Fitted::vector(timelines, line, interior(&fit.knots), Quantized::of(&fit.controls, rounding))
    }
}

/// Every joint's rest transform.
fn rest_pose(animation: &Animation) -> Vec<Transform> {
    animation
        .joints
        .iter()
        .map(|j| Transform { rotation: j.rotation, translation: j.translation, scale: j.scale })
        .collect()
}

/// The source's value of `channel` at `t`: keys slerped (rotations) or lerped, held outside.
fn source_at(channel: &Channel, t: f64) -> [f64; 4] {
    if channel.times.len() < 2 {
        return channel.values[0];
    }
    let (j, h) = bracket(&channel.times, t);
    let (a, b) = (channel.values[j], channel.values[j + 1]);
    if channel.property == Property::Rotation {
        QuatF64::from_array(a).slerp(QuatF64::from_array(b).aligned_with(QuatF64::from_array(a)), h).to_array()
    } else {
        std::array::from_fn(|c| a[c] + (b[c] - a[c]) * h)
    }
}

/// The worst object-space error over `times` between the source and the fitted channels, and
/// each joint's worst.
fn worst_error(
    animation: &Animation,
    parents: &[Option<usize>],
    order: &[usize],
    channels: &[Channel],
    fitted: &[FittedChannel],
    times: &[f64],
    budget: &Budget,
) -> (Worst, Vec<f64>) {
    // Every fitted channel at every time, evaluated once per channel.
    let curves: Vec<Vec<[f64; 4]>> = fitted
        .par_iter()
        .map(|f| match &f.curve {
            Fitted::Constant(v) => vec![*v; times.len()],
            Fitted::Rotation(spline, _) => {
                spline.fit.evaluate(times).expect("a fitted curve evaluates").iter().map(|q| q.to_array()).collect()
            }
            Fitted::Vector(spline, _) => spline
                .fit
                .evaluate(times)
                .expect("a fitted curve evaluates")
                .iter()
                .map(|v| {
                    let [x, y, z] = v.to_array();
                    [x, y, z, 0.0]
                })
                .collect(),
        })
        .collect();
    let rest = rest_pose(animation);
    let pose = |values: &dyn Fn(usize) -> [f64; 4]| {
        let mut local = rest.clone();
        for (k, c) in channels.iter().enumerate() {
            let v = values(k);
            let t = &mut local[c.joint];
            match c.property {
                Property::Rotation => t.rotation = v,
                Property::Translation => t.translation = [v[0], v[1], v[2]],
                Property::Scale => t.scale = [v[0], v[1], v[2]],
            }
        }
        local
    };
    let joints = parents.len();
    times
        .par_iter()
        .enumerate()
        .map(|(i, &t)| {
            let raw = pose(&|k| source_at(&channels[k], t));
            let lossy = pose(&|k| curves[k][i]);
            let errors = pose_errors(parents, order, &raw, &lossy, budget.vertex_distance);
            let (joint, error) =
                errors.iter().copied().enumerate().fold((0, 0.0), |w, (j, e)| if e > w.1 { (j, e) } else { w });
            (Worst { error, joint, time: t }, errors)
        })
        .reduce(
            || (Worst::default(), vec![0.0; joints]),
            |(a, ea), (b, eb)| {
                let worst = if b.error > a.error { b } else { a };
                (worst, ea.iter().zip(&eb).map(|(x, y)| x.max(*y)).collect())
            },
        )
}

/// Per joint, the worst of `errors` over it and its descendants: what a change to its channels
/// can move.
fn subtree_worst(parents: &[Option<usize>], order: &[usize], mut errors: Vec<f64>) -> Vec<f64> {
    for &j in order.iter().rev() {
        if let Some(p) = parents[j] {
            errors[p] = errors[p].max(errors[j]);
        }
    }
    errors
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::{Clip, Joint};

    /// A three-joint arm (10 cm bones) waving smoothly for two seconds at 120 Hz, its root
    /// also moving.
    fn arm() -> Animation {
        let joints = vec![
            Joint::at("root".into(), None, [0.0; 3]),
            Joint::at("elbow".into(), Some(0), [10.0, 0.0, 0.0]),
            Joint::at("hand".into(), Some(1), [10.0, 0.0, 0.0]),
        ];
        let times: Vec<f64> = (0..=240).map(|f| f64::from(f) / 120.0).collect();
        let turn = |joint: usize, speed: f64| Channel {
            joint,
            property: Property::Rotation,
            times: times.clone(),
            values: times
                .iter()
                .map(|&t| {
                    QuatF64::from_rotation_vector(Vec3F64::new(
                        0.2 * (speed * t).sin(),
                        0.1 * t,
                        0.5 * (speed * t).cos(),
                    ))
                    .to_array()
                })
                .collect(),
            knots: None,
        };
        let slide = Channel {
            joint: 0,
            property: Property::Translation,
            times: times.clone(),
            values: times.iter().map(|&t| [5.0 * t, (3.0 * t).sin(), 0.0, 0.0]).collect(),
            knots: None,
        };
        let still = Channel {
            joint: 2,
            property: Property::Rotation,
            times: times.clone(),
            values: vec![[0.0, 0.0, 0.0, 1.0]; times.len()],
            knots: None,
        };
        let clip = Clip { name: "wave".into(), channels: vec![turn(0, 2.0), turn(1, 3.0), slide, still] };
        Animation { joints, clips: vec![clip], skins: Vec::new() }
    }

    #[test]
    fn a_clip_fits_within_its_budget_at_frames_and_between_them_in_fewer_bytes() {
        let animation = arm();
        let budget = Budget { max_error: 0.01, between_error: 0.3, vertex_distance: 3.0 };
        let fit = fit_clip(&animation, 0, &budget).unwrap();
        assert!(fit.at_frames.error <= budget.max_error, "{:?}", fit.at_frames);
        assert!(fit.between_frames.error <= budget.between_error, "{:?}", fit.between_frames);
        // Measured again here, at every frame, from the fitted curves and the keys.
        let channels = &animation.clips[0].channels;
        let order = animation.parents_first().unwrap();
        let parents: Vec<Option<usize>> = animation.joints.iter().map(|j| j.parent).collect();
        let again =
            worst_error(&animation, &parents, &order, channels, &fit.clip.channels, &channels[0].times, &budget);
        assert_eq!(again.0, fit.at_frames);
        assert!(matches!(fit.clip.channels[3].curve, Fitted::Constant(_)), "the still hand is stored once");
        assert_eq!(fit.raw_bytes, RAW_BYTES_PER_JOINT_FRAME * 3 * 241);
        assert!(fit.fitted_bytes * 4 < fit.raw_bytes, "{} of {} bytes", fit.fitted_bytes, fit.raw_bytes);
        let none = Budget { max_error: 0.0, ..budget };
        assert_eq!(
            fit_clip(&animation, 0, &none).unwrap_err().to_string(),
            "the max error is 0; it must be a positive length"
        );
        assert_eq!(fit_clip(&animation, 1, &budget).unwrap_err().to_string(), "no clip 1: the animation has 1");
    }
}
