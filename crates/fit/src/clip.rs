//! A whole clip fitted within ACL's error: every channel as a B-spline ([`super`]), with
//! tolerances shared down the hierarchy so that the object-space error of every joint's
//! virtual vertices ([`quatcurve_analysis::vertex_error`]) stays within a budget at every source
//! frame; then measured at every frame and at points between frames against the source's own
//! interpolation (keys slerped and lerped), and counted in bytes as ACL counts a raw clip
//! against the clip's bytes in the container ([`quatcurve_qcf`]).

use super::{bracket, fit_vectors, spans_of_order, RotationStart};
use quatcurve_analysis::vertex_error::{joint_errors, object_space, Transform};
use quatcurve_anim::error::AnimationError;
use quatcurve_anim::{Animation, Channel, Property};
use quatcurve_core::quat::{tan_quarter, QuatF64, Vec3F64};
use quatcurve_eval::error::Number;
use quatcurve_eval::skeleton::Affine;
use quatcurve_qcf::fitted::ORDER;
use quatcurve_qcf::fitted::{Between, Fit, Fitted, FittedChannel, FittedClip, Form, Spline};
use quatcurve_qcf::quantize::{self, Quantized};
use quatcurve_qcf::timeline::{Timeline, BETWEEN_POINTS};
use rayon::prelude::*;

/// Bytes ACL counts per joint per frame of a raw clip: `f32` rotation, translation and scale.
pub const RAW_BYTES_PER_JOINT_FRAME: usize = 40;

/// The share of a channel's tolerance the fit leaves to its control points' quantization:
/// the fit is made within the rest, and the codes take the fewest bits whose decoded curve is
/// within the whole.
pub const QUANTIZATION_SHARE: f64 = 0.25;

/// The bit-width search starts this many bits below the width the rounding bound asks for:
/// the bound is loose (rounding errors seldom line up): on CMU 131_01 the search ends 2 or 3
/// bits below it for 96% of the forms, and from the bound it takes 4.5 curve evaluations a
/// form.
const BITS_BELOW_BOUND: u32 = 2;

/// Fits of a clip at most, each with every tolerance scaled by how much room the last left.
const SCALINGS: usize = 12;

/// A fit whose worst error at frames is within this factor of the budget is not tried looser:
/// the search ends once every channel's room at frames is below it and none is over the
/// budget between frames. Room left between frames alone does not hold it (the points between
/// frames take a bound 30 times looser, which seldom decides a channel's bytes: CMU 131_01's
/// search ends after 8 fits, not 12, in the same bytes, and no other clip of the shared files
/// moves by more than a byte).
const ROOM_TO_GROW: f64 = 1.25;

/// A fit within the budget that is within [`CLOSE_ENOUGH`] of it and not this fraction smaller
/// than the smallest one before it ends the search: the clip uses its budget and the scalings
/// have converged; later fits only share the budget out differently among the channels. On
/// CMU 131_03 they took 5 more fits (1.5-1.7 s against 0.9-1.0 s) for 0.7% fewer bytes at
/// 0.01 cm, 2.4% at 0.1 cm and 3% without the check between frames; of the other clips of the
/// shared files only Fox's container moved, by 4 bytes, and none at 24 Hz. The clip's room
/// alone ends too early: the first fit, from an even split, is often close to the budget
/// with most channels far from theirs (without the check between frames, 23.2:1 for 25.2:1).
const LEAST_GAIN: f64 = 0.01;

/// See [`LEAST_GAIN`].
const CLOSE_ENOUGH: f64 = 1.02;

/// The most the tolerances grow from one fit to the next.
const MAX_GROWTH: f64 = 4.0;

/// After the first step, a channel's scale moves by this power of its room: errors follow
/// tolerances loosely, and whole steps overshot back and forth around the budget (CMU 131_03:
/// 60.0 KB after 12 fits with whole steps, 58.9 KB with square roots; no clip of the shared
/// files larger).
const LATER_STEPS: f64 = 0.5;

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
    /// The clip's bytes in the container ([`quatcurve_qcf::clip_bytes`]).
    pub fitted_bytes: usize,
}

/// Why a clip was not fitted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FitClipError {
    /// A budget length that is not positive.
    #[error("the {name} is {value}; it must be a positive length")]
    Budget {
        /// The budget's length (`max error`).
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A hierarchy that is not a tree.
    #[error(transparent)]
    Hierarchy(#[from] AnimationError),
    /// A clip index past the clips.
    #[error("no clip {clip}: the animation has {clips}")]
    NoClip {
        /// The index asked for.
        clip: usize,
        /// Clips there are.
        clips: usize,
    },
    /// A channel that holds control points already.
    #[error("{0} is fitted already: it holds control points, not keys")]
    Fitted(String),
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
/// a tree, a channel fitted already, or a budget no fit meets ([`FitClipError::OverBudget`]).
pub fn fit_clip(animation: &Animation, clip: usize, budget: &Budget) -> Result<ClipFit, FitClipError> {
    for (name, value) in [
        ("max error", budget.max_error),
        ("between error", budget.between_error),
        ("vertex distance", budget.vertex_distance),
    ] {
        // An infinite between error leaves the points between frames unchecked.
        if !(value > 0.0 && (value.is_finite() || name == "between error")) {
            return Err(FitClipError::Budget { name, value });
        }
    }
    let order = animation.parents_first()?;
    let parents = animation.parents();
    let source = animation.clips.get(clip).ok_or(FitClipError::NoClip { clip, clips: animation.clips.len() })?;
    let channels = &source
        .channels
        .iter()
        .map(|c| Keyed::of(c).ok_or_else(|| FitClipError::Fitted(animation.label(source, c))))
        .collect::<Result<Vec<_>, _>>()?;
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
            let line = Timeline::of(c.times);
            timelines.iter().position(|l| *l == line).unwrap_or_else(|| {
                timelines.push(line);
                timelines.len() - 1
            })
        })
        .collect();
    let tolerances = tolerances(animation, &order, channels, budget);
    // What the scalings share: each channel's source at its timeline's samples, and the
    // source's poses where the clip's error is measured.
    let sampled: Vec<Vec<[f64; 4]>> = channels
        .par_iter()
        .zip(&timeline_of)
        .map(|(c, &line)| {
            let times = if c.times.len() < 2 { Vec::new() } else { timelines[line].sample_times() };
            times.iter().map(|&(t, _)| source_at(c, t)).collect()
        })
        .collect();
    let (source_frames, source_between) = (
        SourcePoses::at(animation, &parents, &order, channels, &frames),
        SourcePoses::at(animation, &parents, &order, channels, &between),
    );
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
    for scaling in 0..SCALINGS {
        let fitted: Vec<FittedChannel> = channels
            .par_iter()
            .zip(&tolerances)
            .zip(&timeline_of)
            .zip(&scales)
            .zip(&sampled)
            .map(|((((c, &t), &line), &[at, between]), values)| FittedChannel {
                joint: c.joint,
                property: c.property,
                curve: fit_channel(c, values, &timelines, line, [t * at, t * between_share * between]),
            })
            .collect();
        let measure =
            |source: &SourcePoses| worst_error(animation, &parents, &order, channels, &fitted, source, budget);
        let ((at_frames, at_joints), (between_frames, between_joints)) =
            (measure(&source_frames), measure(&source_between));
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
        let fitted_bytes = quatcurve_qcf::clip_bytes(&fitted);
        let smallest = best.as_ref().map(|b| b.fitted_bytes);
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
        if search_ends(&rooms, room, fitted_bytes, smallest) {
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
            // The first step leaves the even split by the whole room; later ones by its root.
            let step = if scaling == 0 { 0.9 * room } else { (0.9 * room).powf(LATER_STEPS) };
            *scale = if back { (*scale * kept).sqrt() } else { *scale * step };
        }
    }
    best.ok_or(FitClipError::OverBudget { at_frames: closest.1, between_frames: closest.2 })
}

/// Whether the budget search ends after a fit whose channels left `rooms` (at frames, between
/// them) and the clip `room`, of `bytes` where the smallest fit within the budget before took
/// `smallest`: every channel within [`ROOM_TO_GROW`] of its budget and none over, or the clip
/// within [`CLOSE_ENOUGH`] of its budget and less than [`LEAST_GAIN`] smaller than the
/// smallest before it.
fn search_ends(rooms: &[[f64; 2]], room: f64, bytes: usize, smallest: Option<usize>) -> bool {
    rooms.iter().all(|&[at, between]| (1.0..ROOM_TO_GROW).contains(&at) && between >= 1.0)
        || ((1.0..CLOSE_ENOUGH).contains(&room)
            && smallest.is_some_and(|s| bytes as f64 > (1.0 - LEAST_GAIN) * s as f64))
}

/// Each channel's tolerance: the budget split evenly over the animated channels of the longest
/// chain from a root, a rotation's as the angle that moves the farthest vertex it carries (at
/// rest) by that share, a scale's likewise, a translation's the share itself.
fn tolerances(animation: &Animation, order: &[usize], channels: &[Keyed], budget: &Budget) -> Vec<f64> {
    let joints = &animation.joints;
    let parents = animation.parents();
    let at: Vec<Vec3F64> =
        object_space(&parents, order, &rest_pose(animation)).iter().map(|m| Vec3F64::new(m[3], m[7], m[11])).collect();
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
/// is stored once. `values` is the source at those samples (none for a single key), the same
/// for every fit of the clip.
fn fit_channel(
    channel: &Keyed,
    values: &[[f64; 4]],
    timelines: &[Timeline],
    line: usize,
    [tolerance, between]: [f64; 2],
) -> Fitted {
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
    // Each sample's bound on the decoded curve; the fit takes its share of it.
    let limits: Vec<f64> = samples.iter().map(|&(_, key)| if key { tolerance } else { between }).collect();
    let fitting: Vec<f64> = limits.iter().map(|l| (1.0 - QUANTIZATION_SHARE) * l).collect();
    let errors = |curve: &[[f64; 4]]| -> Vec<f64> {
        curve.iter().zip(values).map(|(a, b)| distance(channel.property, a, b)).collect()
    };
    // Every knot is one of the samples; the container stores its index.
    let sample_of = |knot: &f64| {
        let s = times.partition_point(|&t| t < *knot);
        debug_assert_eq!(times[s], *knot, "a knot at a sample");
        s as u32
    };
    let interior = |knots: &[f64]| -> Vec<u32> { knots[ORDER..knots.len() - ORDER].iter().map(sample_of).collect() };
    let kept = kept_keys(channel.property, values, &times, &fitting);
    let at_kept = |k: &usize| values[k * (BETWEEN_POINTS + 1)];
    let kept_values: Vec<[f64; 4]> =
        [0].iter().chain(&kept).chain([timelines[line].keys() - 1].iter()).map(at_kept).collect();
    let keys = (
        Form::Keys,
        kept.iter().map(|&k| k as u32).collect(),
        if rotation {
            Controls::Rotations(kept_values.iter().map(|v| QuatF64::from_array(*v)).collect())
        } else {
            Controls::Vectors(kept_values.iter().map(|v| [v[0], v[1], v[2]]).collect())
        },
    );
    let cubic = if rotation {
        let rotations: Vec<QuatF64> = values.iter().map(|v| QuatF64::from_array(*v)).collect();
        // A cubic of as many control points as the kept keys is not fitted on (noisy frames at
        // a low rate, or flips): the nonlinear fit is the most costly step.
        let most = kept_values.len();
        let fit = RotationStart::below(&times, &rotations, &fitting, most).and_then(|start| start.fit_below(most));
        fit.map(|fit| (Form::Cubic, interior(&fit.knots), Controls::Rotations(fit.controls)))
    } else {
        let vectors: Vec<[f64; 3]> = values.iter().map(|v| [v[0], v[1], v[2]]).collect();
        let fit = fit_vectors(&times, &vectors, &fitting);
        Some((Form::Cubic, interior(&fit.knots), Controls::Vectors(fit.controls)))
    };
    // Each form in the fewest bits whose decoded curve is within every sample's bound, or,
    // where the fit itself missed its share, within the rounding's share past the fit's own
    // error; the form of fewer bytes is kept. A rotation cubic whose rounded control points
    // break the normalized form's rule (two of a span half a turn apart) is not one.
    cubic
        .into_iter()
        .chain([keys])
        .filter_map(|(form, knots, controls)| {
            // The unrounded curve and every width tried share the knots, so a rotation's spans
            // and basis at the samples are computed once (the same bits as `Fitted::at`).
            let spans = std::cell::OnceCell::new();
            let rotation_at = |fit: &Fit<QuatF64>| {
                let spans = spans.get_or_init(|| spans_of_order(&fit.knots, fit.order(), &times));
                fit.spans_lazily(spans).ok()
            };
            let unrounded: Vec<f64> = match &controls {
                Controls::Rotations(c) => {
                    let fit = Spline::new(timelines, line, form, knots.clone(), c.clone()).fit;
                    let curve = rotation_at(&fit)?;
                    curve.zip(values).map(|(q, v)| distance(channel.property, &q.to_array(), v)).collect()
                }
                Controls::Vectors(c) => {
                    errors(&Spline::new(timelines, line, form, knots.clone(), c.clone()).at(&times))
                }
            };
            // Each sample's bound, as `within` compares it.
            let bounds: Vec<f64> = unrounded
                .iter()
                .zip(&limits)
                .map(|(&u, &l)| checked_bound(channel.property, l.max(u + QUANTIZATION_SHARE * l)))
                .collect();
            // Each sample held to its bound, as far as the first one out of it: a refused
            // width (every search tries one) stops there.
            let within = |curve: &Fitted| match curve {
                Fitted::Rotation(spline, _) => rotation_at(&spline.fit).is_some_and(|curve| {
                    curve.zip(values).zip(&bounds).all(|((q, v), &b)| q.within(QuatF64::from_array(*v), b))
                }),
                _ => curve
                    .at(&times)
                    .iter()
                    .zip(values)
                    .zip(&bounds)
                    .all(|((a, v), &b)| within(channel.property, a, v, b)),
            };
            let start = controls.bits_within(tolerance * QUANTIZATION_SHARE).saturating_sub(BITS_BELOW_BOUND).max(1);
            let curve = |bits| controls.quantized(timelines, line, form, knots.clone(), bits);
            let fewest = quantize::fewest_bits(start, curve, within);
            match &fewest {
                Fitted::Rotation(spline, _) => rotation_at(&spline.fit).is_some().then_some(fewest),
                _ => Some(fewest),
            }
        })
        .min_by_key(|curve| {
            quatcurve_qcf::channel_bytes(&FittedChannel {
                joint: channel.joint,
                property: channel.property,
                curve: curve.clone(),
            })
        })
        .expect("the keys at least")
}

/// A channel's control points before quantization.
enum Controls {
    Rotations(Vec<QuatF64>),
    Vectors(Vec<[f64; 3]>),
}

impl Controls {
    /// The fewest bits whose rounding moves no control point by more than `error`.
    fn bits_within(&self, error: f64) -> u32 {
        match self {
            Controls::Rotations(c) => quantize::rotations(c, error).smallest.bits,
            Controls::Vectors(c) => Quantized::bits_within(c, error),
        }
    }

    /// The curve of the control points quantized in `bits`, as the container decodes it.
    fn quantized(&self, timelines: &[Timeline], line: usize, form: Form, knots: Vec<u32>, bits: u32) -> Fitted {
        match self {
            Controls::Rotations(c) => {
                Fitted::rotation(timelines, line, form, knots, quantize::rotations_with_bits(c, bits))
            }
            Controls::Vectors(c) => Fitted::vector(timelines, line, form, knots, Quantized::with_bits(c, bits)),
        }
    }
}

/// The distance between two values of `property`: radians between rotations, else Euclidean.
fn distance(property: Property, a: &[f64; 4], b: &[f64; 4]) -> f64 {
    match property {
        Property::Rotation => QuatF64::from_array(*a).angle_to(QuatF64::from_array(*b)),
        _ => (Vec3F64::new(a[0], a[1], a[2]) - Vec3F64::new(b[0], b[1], b[2])).length(),
    }
}

/// A bound on [`distance`] as [`within`] reads it: a rotation's as its quarter's tangent
/// ([`QuatF64::within`]), a vector's as it is.
fn checked_bound(property: Property, bound: f64) -> f64 {
    match property {
        Property::Rotation => tan_quarter(bound),
        _ => bound,
    }
}

/// Whether [`distance`] is at most the bound `checked` ([`checked_bound`]) says.
fn within(property: Property, a: &[f64; 4], b: &[f64; 4], checked: f64) -> bool {
    match property {
        Property::Rotation => QuatF64::from_array(*a).within(QuatF64::from_array(*b), checked),
        _ => distance(property, a, b) <= checked,
    }
}

/// The interior keys a [`Form::Keys`] curve keeps (key indices, ascending): from each kept
/// key, the farthest key that the source's interpolation between the two holds within
/// `tolerances` at every sample of `values` between them (its keys and the points between).
fn kept_keys(property: Property, values: &[[f64; 4]], times: &[f64], tolerances: &[f64]) -> Vec<usize> {
    let step = BETWEEN_POINTS + 1;
    let last = (values.len() - 1) / step;
    let between = |a: usize, b: usize, s: usize| -> [f64; 4] {
        let (sa, sb) = (a * step, b * step);
        let h = (times[s] - times[sa]) / (times[sb] - times[sa]);
        match property {
            Property::Rotation => {
                let (p, q) = (QuatF64::from_array(values[sa]), QuatF64::from_array(values[sb]));
                p.between(q, h).to_array()
            }
            _ => {
                let [x, y, z] = [values[sa][0], values[sa][1], values[sa][2]]
                    .between([values[sb][0], values[sb][1], values[sb][2]], h);
                [x, y, z, 0.0]
            }
        }
    };
    let bounds: Vec<f64> = tolerances.iter().map(|&t| checked_bound(property, t)).collect();
    let holds = |a: usize, b: usize| {
        (a * step + 1..b * step).all(|s| within(property, &between(a, b, s), &values[s], bounds[s]))
    };
    let mut kept = Vec::new();
    let mut a = 0;
    while a < last {
        let mut b = a + 1;
        while b < last && holds(a, b + 1) {
            b += 1;
        }
        if b < last {
            kept.push(b);
        }
        a = b;
    }
    kept
}

/// A source channel as the fit reads it: its keys (a fitted channel is refused).
struct Keyed<'a> {
    joint: usize,
    property: Property,
    times: &'a [f64],
    values: &'a [[f64; 4]],
}

impl<'a> Keyed<'a> {
    /// `channel`'s keys; `None` for a fitted spline.
    fn of(channel: &'a Channel) -> Option<Self> {
        let (times, values) = channel.keyed()?;
        Some(Keyed { joint: channel.joint, property: channel.property, times, values })
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
fn source_at(channel: &Keyed, t: f64) -> [f64; 4] {
    if channel.times.len() < 2 {
        return channel.values[0];
    }
    let (j, h) = bracket(channel.times, t);
    let (a, b) = (channel.values[j], channel.values[j + 1]);
    if channel.property == Property::Rotation {
        QuatF64::from_array(a).slerp(QuatF64::from_array(b).aligned_with(QuatF64::from_array(a)), h).to_array()
    } else {
        std::array::from_fn(|c| a[c] + (b[c] - a[c]) * h)
    }
}

/// The source's poses at the times a clip's error is measured, in object space, and whether
/// each scales a joint: the same for every fit of the clip.
struct SourcePoses {
    times: Vec<f64>,
    object: Vec<Vec<Affine>>,
    scales: Vec<bool>,
}

impl SourcePoses {
    fn at(
        animation: &Animation,
        parents: &[Option<usize>],
        order: &[usize],
        channels: &[Keyed],
        times: &[f64],
    ) -> Self {
        let rest = rest_pose(animation);
        let (object, scales) = times
            .par_iter()
            .map(|&t| {
                let local = pose(&rest, channels, |k| source_at(&channels[k], t));
                (object_space(parents, order, &local), local.iter().any(Transform::scales))
            })
            .unzip();
        Self { times: times.to_vec(), object, scales }
    }
}

/// The local pose of `rest` with each of `channels` set to its value from `values` (by index).
fn pose(rest: &[Transform], channels: &[Keyed], values: impl Fn(usize) -> [f64; 4]) -> Vec<Transform> {
    let mut local = rest.to_vec();
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
}

/// The worst object-space error over the `source`'s times between it and the fitted channels
/// (ACL's metric: the third vertex counts when either pose scales), and each joint's worst.
fn worst_error(
    animation: &Animation,
    parents: &[Option<usize>],
    order: &[usize],
    channels: &[Keyed],
    fitted: &[FittedChannel],
    source: &SourcePoses,
    budget: &Budget,
) -> (Worst, Vec<f64>) {
    // Every fitted channel at every time, evaluated once per channel.
    let curves: Vec<Vec<[f64; 4]>> = fitted.par_iter().map(|f| f.curve.at(&source.times)).collect();
    let rest = rest_pose(animation);
    let joints = parents.len();
    source
        .times
        .par_iter()
        .enumerate()
        .map(|(i, &t)| {
            let lossy = pose(&rest, channels, |k| curves[k][i]);
            let scales = source.scales[i] || lossy.iter().any(Transform::scales);
            let lossy = object_space(parents, order, &lossy);
            let errors = joint_errors(&source.object[i], &lossy, budget.vertex_distance, scales);
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
    use quatcurve_analysis::vertex_error::pose_errors;
    use quatcurve_anim::{Clip, Joint};

    /// A three-joint arm (10 cm bones) waving smoothly for two seconds at 120 Hz, its root
    /// also moving.
    fn arm() -> Animation {
        let joints = vec![
            Joint::at("root".into(), None, [0.0; 3]),
            Joint::at("elbow".into(), Some(0), [10.0, 0.0, 0.0]),
            Joint::at("hand".into(), Some(1), [10.0, 0.0, 0.0]),
        ];
        let times: Vec<f64> = (0..=240).map(|f| f64::from(f) / 120.0).collect();
        let turn = |joint: usize, speed: f64| {
            let values = times
                .iter()
                .map(|&t| {
                    QuatF64::from_rotation_vector(Vec3F64::new(
                        0.2 * (speed * t).sin(),
                        0.1 * t,
                        0.5 * (speed * t).cos(),
                    ))
                    .to_array()
                })
                .collect();
            Channel::keys(joint, Property::Rotation, times.clone(), values)
        };
        let slide = Channel::keys(
            0,
            Property::Translation,
            times.clone(),
            times.iter().map(|&t| [5.0 * t, (3.0 * t).sin(), 0.0, 0.0]).collect(),
        );
        let still = Channel::keys(2, Property::Rotation, times.clone(), vec![[0.0, 0.0, 0.0, 1.0]; times.len()]);
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
        // Measured again here, at every frame, from the fitted curves and the keys, pose by pose
        // with the metric's own function (the fit computes the source's poses once).
        let channels: Vec<Keyed> = animation.clips[0].channels.iter().map(|c| Keyed::of(c).unwrap()).collect();
        let order = animation.parents_first().unwrap();
        let parents = animation.parents();
        let rest = rest_pose(&animation);
        let worst = channels[0]
            .times
            .iter()
            .map(|&t| {
                let raw = pose(&rest, &channels, |k| source_at(&channels[k], t));
                let lossy = pose(&rest, &channels, |k| fit.clip.channels[k].curve.at(&[t])[0]);
                pose_errors(&parents, &order, &raw, &lossy, budget.vertex_distance).into_iter().fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        assert_eq!(worst, fit.at_frames.error);
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

    #[test]
    fn the_search_ends_when_every_channel_is_close_to_its_budget_or_the_clip_gains_little_there() {
        let room = [[1.1, 1.0], [3.0, 30.0]];
        // Every channel within its budget, close to it.
        assert!(search_ends(&[[1.1, 1.0], [1.2, 30.0]], 1.1, 100, None));
        // A channel with room: the search goes on unless the clip is close to its budget and
        // gained less than 1% on the smallest fit before.
        assert!(search_ends(&room, 1.01, 995, Some(1000)));
        assert!(!search_ends(&room, 1.01, 100, None), "the first fit");
        assert!(!search_ends(&room, 1.01, 98, Some(100)), "a gain of 2%");
        assert!(!search_ends(&room, 1.05, 995, Some(1000)), "room for the clip");
        assert!(!search_ends(&room, 0.99, 995, Some(1000)), "over the budget");
    }

    #[test]
    fn keys_on_one_arc_are_dropped_and_a_corner_is_kept() {
        let times: Vec<f64> = (0..=8 * (BETWEEN_POINTS + 1)).map(|s| s as f64 / 10.0).collect();
        let turn = |t: f64| {
            // One arc at constant speed up to t = 2, then another about a second axis.
            let about = |x: f64, y: f64| QuatF64::from_rotation_vector(Vec3F64::new(x, y, 0.0));
            if t <= 2.0 { about(0.4 * t, 0.0) } else { about(0.8, 0.0) * about(0.0, 0.3 * (t - 2.0)) }.to_array()
        };
        // The points between keys are the keys' slerps, as `source_at` makes them.
        let step = BETWEEN_POINTS + 1;
        let values: Vec<[f64; 4]> = (0..times.len())
            .map(|s| {
                let (a, b) = (s / step * step, (s / step * step + step).min(times.len() - 1));
                let h = if a == b { 0.0 } else { (times[s] - times[a]) / (times[b] - times[a]) };
                QuatF64::from_array(turn(times[a])).between(QuatF64::from_array(turn(times[b])), h).to_array()
            })
            .collect();
        let kept = kept_keys(Property::Rotation, &values, &times, &vec![1e-9; times.len()]);
        // Key k is at time k / 2: the corner is key 4.
        assert_eq!(kept, vec![4]);
    }

    #[test]
    fn a_clip_keyed_sparsely_is_stored_as_its_keys_and_exact_between_them() {
        let mut animation = arm();
        // Five keys over two seconds, each channel's interpolation linear between them.
        for channel in &mut animation.clips[0].channels {
            let keep = |i: &usize| i % 60 == 0;
            let (times, values) = channel.keyed().unwrap();
            let times = times.iter().enumerate().filter(|(i, _)| keep(i)).map(|(_, &t)| t).collect();
            let values = values.iter().enumerate().filter(|(i, _)| keep(i)).map(|(_, &v)| v).collect();
            *channel = Channel::keys(channel.joint, channel.property, times, values);
        }
        // Between frames held as tightly as at them: only the keys' own interpolation is within.
        let budget = Budget { max_error: 0.01, between_error: 0.01, vertex_distance: 3.0 };
        let fit = fit_clip(&animation, 0, &budget).unwrap();
        for (k, channel) in fit.clip.channels.iter().enumerate().take(3) {
            assert!(
                matches!(&channel.curve, Fitted::Rotation(s, _) if s.form == Form::Keys)
                    || matches!(&channel.curve, Fitted::Vector(s, _) if s.form == Form::Keys),
                "channel {k}: {:?}",
                channel.curve
            );
        }
        assert!(fit.between_frames.error <= budget.max_error, "{:?}", fit.between_frames);
    }
}
