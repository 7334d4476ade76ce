//! What a fit keeps of a clip, and the container stores: per channel a constant, or a curve
//! whose knots are samples of a timeline and whose control points are quantized codes, with
//! the curve those decode to; and the clip as the common model's channels, for baking.

use super::quantize::{Quantized, QuantizedRotations};
use super::timeline::Timeline;
use super::{clamped, Fit, ORDER};
use crate::bake::{Channel, Clip, Joint, Property};
use crate::quat::QuatF64;
use crate::track::Track;

/// A fitted curve: its knots as samples of its timeline, and the curve they and the decoded
/// control points make.
#[derive(Clone, Debug, PartialEq)]
pub struct Spline<T> {
    /// Index into the clip's [`FittedClip::timelines`].
    pub timeline: usize,
    /// Interior knots as sample indices of the timeline ([`Timeline::sample`]), ascending; a
    /// knot of multiplicity `m` appears `m` times.
    pub knots: Vec<u32>,
    /// The curve: knot times, and the control points as their codes decode.
    pub fit: Fit<T>,
}

impl<T> Spline<T> {
    /// The curve of `controls` on interior `knots` of `timeline` (clamped at its ends).
    fn new(timelines: &[Timeline], timeline: usize, knots: Vec<u32>, controls: Vec<T>) -> Self {
        let line = &timelines[timeline];
        let interior: Vec<f64> = knots.iter().map(|&s| line.sample(s as usize)).collect();
        let times = clamped(line.sample(0), line.sample(line.samples() - 1), &interior);
        Spline { timeline, knots, fit: Fit { knots: times, controls, worst: 0.0, worst_at: 0 } }
    }
}

/// A fitted channel's curve.
#[derive(Clone, Debug, PartialEq)]
pub enum Fitted {
    /// Every key within its tolerance of one value: stored once.
    Constant([f64; 4]),
    /// A KKS cumulative B-spline.
    Rotation(Spline<QuatF64>, QuantizedRotations),
    /// Its Euclidean analogue (translation, scale).
    Vector(Spline<[f64; 3]>, Quantized),
}

impl Fitted {
    /// A constant as the container stores it: `f32` values.
    #[must_use]
    pub fn constant(value: [f64; 4]) -> Self {
        Fitted::Constant(value.map(|v| f64::from(v as f32)))
    }

    /// The rotation curve of `codes` on `knots` of a timeline: the fit and the container
    /// decode through this one function.
    #[must_use]
    pub fn rotation(timelines: &[Timeline], timeline: usize, knots: Vec<u32>, codes: QuantizedRotations) -> Self {
        Fitted::Rotation(Spline::new(timelines, timeline, knots, codes.values()), codes)
    }

    /// The vector curve of `codes` on `knots` of a timeline, likewise.
    #[must_use]
    pub fn vector(timelines: &[Timeline], timeline: usize, knots: Vec<u32>, codes: Quantized) -> Self {
        Fitted::Vector(Spline::new(timelines, timeline, knots, codes.values()), codes)
    }

    /// Knots and control points as a [`Channel`] of the common model: `times` are the control
    /// points' Greville abscissae (strictly increasing, spanning the curve's domain), `values`
    /// the control points. A constant is one key at `span`'s start, or two when the span is
    /// not empty.
    fn channel(&self, joint: usize, property: Property, span: [f64; 2]) -> Channel {
        let (knots, values): (Vec<f64>, Vec<[f64; 4]>) = match self {
            Fitted::Constant(v) => {
                let times = if span[1] > span[0] { vec![span[0], span[1]] } else { vec![span[0]] };
                let values = vec![*v; times.len()];
                return Channel { joint, property, times, values, knots: None };
            }
            Fitted::Rotation(s, _) => (s.fit.knots.clone(), s.fit.controls.iter().map(|q| q.to_array()).collect()),
            Fitted::Vector(s, _) => {
                (s.fit.knots.clone(), s.fit.controls.iter().map(|&[x, y, z]| [x, y, z, 0.0]).collect())
            }
        };
        let greville = (0..values.len()).map(|i| knots[i + 1..i + ORDER].iter().sum::<f64>() / (ORDER - 1) as f64);
        Channel { joint, property, times: greville.collect(), values, knots: Some(knots) }
    }
}

/// A fitted channel.
#[derive(Clone, Debug, PartialEq)]
pub struct FittedChannel {
    /// Index into the animation's joints.
    pub joint: usize,
    /// What it animates.
    pub property: Property,
    /// Its curve.
    pub curve: Fitted,
}

/// A clip as fitting keeps it and the container stores it.
#[derive(Clone, Debug, PartialEq)]
pub struct FittedClip {
    /// The source clip's name.
    pub name: String,
    /// The source clip's first and last key times, seconds.
    pub span: [f64; 2],
    /// The distinct key times of its curve channels.
    pub timelines: Vec<Timeline>,
    /// In the source clip's order.
    pub channels: Vec<FittedChannel>,
}

impl FittedClip {
    /// The source's frame rate: its densest timeline's keys a second (1 for a clip of
    /// constants, which holds one pose).
    #[must_use]
    pub fn source_rate(&self) -> f64 {
        self.timelines.iter().map(|l| (l.keys() - 1) as f64 / (l.key(l.keys() - 1) - l.key(0))).fold(1.0, f64::max)
    }

    /// The clip's rotation channels as tracks of explicit knots ([`super::spline_spec`]),
    /// named `<clip>/<joint>`: what `eval` evaluates. A constant is [`ORDER`] equal control
    /// points over the clip's span, so that every track shares the clip's domain.
    #[must_use]
    pub fn rotation_tracks(&self, joints: &[Joint]) -> Vec<Track> {
        let track = |c: &FittedChannel| {
            let (knots, controls) = match (&c.curve, c.property) {
                (Fitted::Constant(v), Property::Rotation) => {
                    (clamped(self.span[0], self.span[1], &[]), vec![*v; ORDER])
                }
                (Fitted::Rotation(s, _), _) => {
                    (s.fit.knots.clone(), s.fit.controls.iter().map(|q| q.to_array()).collect())
                }
                _ => return None,
            };
            let joint = joints.get(c.joint).map_or("", |j| j.name.as_str());
            let name = Some(format!("{}/{joint}", self.name));
            Some(Track { name, rotations: controls, knots: Some(knots), ..Track::default() })
        };
        self.channels.iter().filter_map(track).collect()
    }

    /// The clip in the common model, for baking: each curve channel carries its knots and
    /// its control points ([`Channel::knots`]), each constant its value.
    #[must_use]
    pub fn to_clip(&self) -> Clip {
        let channels = self.channels.iter().map(|c| c.curve.channel(c.joint, c.property, self.span)).collect();
        Clip { name: self.name.clone(), channels }
    }
}
