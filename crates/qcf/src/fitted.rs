//! What a fit keeps of a clip, and the container stores: per channel a constant, or a curve
//! whose knots are samples of a timeline and whose control points are quantized codes, with
//! the curve those decode to; and the clip as the common model's channels, for baking.

use super::quantize::{Quantized, QuantizedRotations};
use super::timeline::Timeline;
pub use quatcurve_anim::spline::{order_of, spline_spec, CUBIC_ROTATIONS, ORDER};
use quatcurve_anim::{Channel, ChannelCurve, Clip, Joint, Property};
use quatcurve_core::basis::BasisJet;
use quatcurve_core::curve::CurveSpec;
use quatcurve_core::quat::{QuatF64, Vec3F64};
use quatcurve_eval::batch::BatchBuilder;
use quatcurve_eval::error::TrackId;
use quatcurve_eval::euclidean::VectorCurve;
use quatcurve_eval::track::Track;

/// A time's span `l` on a fitted channel's knots and the cumulative basis there
/// (`B~_{l-k+2..=l}`, [`quatcurve_core::basis::bspline_cumulative`]): its first `k - 1`
/// entries, `k` the curve's order (at most [`ORDER`]). Held inline: a fit computes one per
/// sample and knot vector.
pub type SpanBasis = (usize, [BasisJet; ORDER - 1]);

/// A fitted channel: the knot vector (clamped: [`ORDER`] copies of each end) and the control
/// points, with the largest error over the samples and where.
#[derive(Clone, Debug, PartialEq)]
pub struct Fit<T> {
    /// `controls.len() + ORDER` knots.
    pub knots: Vec<f64>,
    /// The control points.
    pub controls: Vec<T>,
    /// The largest error over the samples: radians for rotations, the values' units for vectors.
    pub worst: f64,
    /// The sample where it is.
    pub worst_at: usize,
}

/// The spec of a fitted track of explicit knots ([`Fit::track`], a container's
/// [`FittedClip::rotation_tracks`]): the order its knots and control points make.
#[must_use]
pub fn track_spec(track: &Track) -> CurveSpec {
    spline_spec(order_of(track.knots.as_ref().map_or(0, Vec::len), track.rotations.len()))
}

impl<T> Fit<T> {
    /// The curve's B-spline order ([`order_of`]).
    #[must_use]
    pub fn order(&self) -> usize {
        order_of(self.knots.len(), self.controls.len())
    }
}

impl Fit<QuatF64> {
    /// The fitted curve as a track of explicit knots, and its spec.
    #[must_use]
    pub fn track(&self) -> (Track, CurveSpec) {
        let track = Track {
            rotations: self.controls.iter().map(|q| q.to_array()).collect(),
            knots: Some(self.knots.clone()),
            ..Track::default()
        };
        (track, spline_spec(self.order()))
    }

    /// The curve packed as the decoders read it: a batch of its one track.
    fn batch(&self) -> quatcurve_eval::error::Result<quatcurve_eval::batch::Batch> {
        let (track, spec) = self.track();
        let mut builder = BatchBuilder::new();
        builder.add(&track, &spec)?;
        builder.build()
    }

    /// The curve at `times`, by the reference evaluator.
    ///
    /// # Errors
    /// The batch builder's, for a knot vector it refuses (a fit never makes one).
    pub fn evaluate(&self, times: &[f64]) -> quatcurve_eval::error::Result<Vec<QuatF64>> {
        let batch = self.batch()?;
        Ok(times.iter().map(|&t| quatcurve_eval::reference::evaluate_rotation(batch.view(0), t)).collect())
    }

    /// The curve at times given by their spans and cumulative basis values
    /// ([`quatcurve_eval::reference::bspline_rotation_at`]): [`Self::evaluate`] without
    /// locating each time and computing its basis again, for a fit that evaluates one knot
    /// vector at the same times step after step.
    ///
    /// # Errors
    /// As [`Self::evaluate`].
    pub fn evaluate_spans(&self, spans: &[SpanBasis]) -> quatcurve_eval::error::Result<Vec<QuatF64>> {
        Ok(self.spans_lazily(spans)?.collect())
    }

    /// [`Self::evaluate_spans`] one time at a time, as they are asked for: a check that stops
    /// at the first sample out of bounds evaluates no further.
    ///
    /// # Errors
    /// As [`Self::evaluate`].
    pub fn spans_lazily<'s>(
        &self,
        spans: &'s [SpanBasis],
    ) -> quatcurve_eval::error::Result<impl Iterator<Item = QuatF64> + 's> {
        let batch = self.batch()?;
        let k = self.order();
        Ok(spans
            .iter()
            .map(move |(l, basis)| quatcurve_eval::reference::bspline_rotation_at(batch.view(0), *l, &basis[..k - 1])))
    }
}

impl Fit<[f64; 3]> {
    /// The curve at `times`, by the vector evaluator ([`VectorCurve`], the Euclidean analogue).
    ///
    /// # Errors
    /// The evaluator's, for a knot vector it refuses (a fit never makes one).
    pub fn evaluate(&self, times: &[f64]) -> quatcurve_eval::error::Result<Vec<Vec3F64>> {
        let id = TrackId { index: 0, name: None };
        let curve = VectorCurve::new(&id, None, &self.controls, Some(&self.knots), &spline_spec(self.order()))?;
        Ok(times.iter().map(|&t| curve.evaluate(t)).collect())
    }
}

/// `[start; order]`, `interior`, `[end; order]`.
pub fn clamped(order: usize, start: f64, end: f64, interior: &[f64]) -> Vec<f64> {
    let mut knots = Vec::with_capacity(interior.len() + 2 * order);
    knots.extend(std::iter::repeat(start).take(order));
    knots.extend_from_slice(interior);
    knots.extend(std::iter::repeat(end).take(order));
    knots
}

/// The B-spline order of a [`Form::Keys`] curve.
pub const KEYS_ORDER: usize = 2;

/// How a fitted curve passes between its knots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// A clamped cubic B-spline whose knots are samples of its timeline: `knots + ORDER`
    /// control points.
    Cubic,
    /// Some of the source's keys, slerped or lerped between as the source is: a clamped
    /// B-spline of [`KEYS_ORDER`] (KKS's order 2 is slerp from each control point to the next)
    /// whose knots are the kept interior keys and whose `knots + 2` control points are the kept
    /// keys' values.
    Keys,
}

/// A fitted curve: its knots on its timeline, and the curve they and the decoded control
/// points make.
#[derive(Clone, Debug, PartialEq)]
pub struct Spline<T> {
    /// Index into the clip's [`FittedClip::timelines`].
    pub timeline: usize,
    /// How it passes between its knots.
    pub form: Form,
    /// Interior knots, ascending: for [`Form::Cubic`] sample indices of the timeline
    /// ([`Timeline::sample`]), a knot of multiplicity `m` appearing `m` times; for
    /// [`Form::Keys`] key indices ([`Timeline::key`]), each once.
    pub knots: Vec<u32>,
    /// The curve as every evaluator reads it: knot times and control points of a clamped
    /// B-spline ([`Fit::order`]).
    pub fit: Fit<T>,
}

/// A point `h` of the way from a control point to the next, along the shortest path: what a
/// [`Form::Keys`] curve is between its keys.
pub trait Between: Copy {
    /// The point `h` (0 to 1) of the way to `next`.
    #[must_use]
    fn between(self, next: Self, h: f64) -> Self;
}

impl Between for QuatF64 {
    fn between(self, next: Self, h: f64) -> Self {
        self.slerp(next.aligned_with(self), h)
    }
}

impl Between for [f64; 3] {
    fn between(self, next: Self, h: f64) -> Self {
        std::array::from_fn(|c| self[c] + (next[c] - self[c]) * h)
    }
}

/// The knot vector, in seconds, of a curve in `form` on interior `knots` of `timeline`
/// (clamped at the timeline's ends): what every evaluator of a stored curve reads.
#[must_use]
pub fn knot_times(timelines: &[Timeline], timeline: usize, form: Form, knots: &[u32]) -> Vec<f64> {
    let line = &timelines[timeline];
    let (start, end) = (line.sample(0), line.sample(line.samples() - 1));
    let (order, interior): (usize, Vec<f64>) = match form {
        Form::Cubic => (ORDER, knots.iter().map(|&s| line.sample(s as usize)).collect()),
        Form::Keys => (KEYS_ORDER, knots.iter().map(|&k| line.key(k as usize)).collect()),
    };
    clamped(order, start, end, &interior)
}

impl<T> Spline<T> {
    /// The curve of `controls` in `form` on interior `knots` of `timeline` (clamped at its ends).
    pub fn new(timelines: &[Timeline], timeline: usize, form: Form, knots: Vec<u32>, controls: Vec<T>) -> Self {
        let fit = Fit { knots: knot_times(timelines, timeline, form, &knots), controls, worst: 0.0, worst_at: 0 };
        Spline { timeline, form, knots, fit }
    }
}

impl Spline<QuatF64> {
    /// The curve at `times` as `x, y, z, w` ([`Fitted::at`]).
    #[must_use]
    pub fn at(&self, times: &[f64]) -> Vec<[f64; 4]> {
        let curve = self.fit.evaluate(times).expect("a fitted curve evaluates");
        curve.iter().map(|q| q.to_array()).collect()
    }
}

impl Spline<[f64; 3]> {
    /// The curve at `times` as `x, y, z, 0` ([`Fitted::at`]).
    #[must_use]
    pub fn at(&self, times: &[f64]) -> Vec<[f64; 4]> {
        let curve = self.fit.evaluate(times).expect("a fitted curve evaluates");
        curve.iter().map(|v| v.to_array()).map(|[x, y, z]| [x, y, z, 0.0]).collect()
    }
}

/// A fitted channel's curve.
#[derive(Clone, Debug, PartialEq)]
pub enum Fitted {
    /// Every key within its tolerance of one value: stored once.
    Constant([f64; 4]),
    /// A rotation curve ([`spline_spec`]).
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

    /// The rotation curve in `form` of `codes` on `knots` of a timeline: the fit and the
    /// container decode through this one function.
    #[must_use]
    pub fn rotation(
        timelines: &[Timeline],
        timeline: usize,
        form: Form,
        knots: Vec<u32>,
        codes: QuantizedRotations,
    ) -> Self {
        Fitted::Rotation(Spline::new(timelines, timeline, form, knots, codes.values()), codes)
    }

    /// The vector curve in `form` of `codes` on `knots` of a timeline, likewise.
    #[must_use]
    pub fn vector(timelines: &[Timeline], timeline: usize, form: Form, knots: Vec<u32>, codes: Quantized) -> Self {
        Fitted::Vector(Spline::new(timelines, timeline, form, knots, codes.values()), codes)
    }

    /// The curve at `times`, by the reference evaluator: a rotation's `x, y, z, w`, a vector's
    /// `x, y, z, 0`.
    #[must_use]
    pub fn at(&self, times: &[f64]) -> Vec<[f64; 4]> {
        match self {
            Fitted::Constant(v) => vec![*v; times.len()],
            Fitted::Rotation(spline, _) => spline.at(times),
            Fitted::Vector(spline, _) => spline.at(times),
        }
    }

    /// The curve as a [`Channel`] of the common model: its knots and control points, or a
    /// constant as one key at `span`'s start (two when the span is not empty).
    fn channel(&self, joint: usize, property: Property, span: [f64; 2]) -> Channel {
        let (knots, controls): (Vec<f64>, Vec<[f64; 4]>) = match self {
            Fitted::Constant(v) => {
                let times = if span[1] > span[0] { vec![span[0], span[1]] } else { vec![span[0]] };
                let values = vec![*v; times.len()];
                return Channel::keys(joint, property, times, values);
            }
            Fitted::Rotation(s, _) => (s.fit.knots.clone(), s.fit.controls.iter().map(|q| q.to_array()).collect()),
            Fitted::Vector(s, _) => {
                (s.fit.knots.clone(), s.fit.controls.iter().map(|&[x, y, z]| [x, y, z, 0.0]).collect())
            }
        };
        Channel { joint, property, curve: ChannelCurve::Spline { knots, controls } }
    }
}

/// A clip's source frame rate from its `timelines` ([`FittedClip::source_rate`]).
#[must_use]
pub fn source_rate(timelines: &[Timeline]) -> f64 {
    timelines.iter().map(|l| (l.keys() - 1) as f64 / (l.key(l.keys() - 1) - l.key(0))).fold(1.0, f64::max)
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
        source_rate(&self.timelines)
    }

    /// The clip's rotation channels as tracks of explicit knots ([`spline_spec`]),
    /// named `<clip>/<joint>`: what `eval` evaluates. A constant is [`ORDER`] equal control
    /// points over the clip's span, so that every track shares the clip's domain.
    #[must_use]
    pub fn rotation_tracks(&self, joints: &[Joint]) -> Vec<Track> {
        let track = |c: &FittedChannel| {
            let (knots, controls) = match (&c.curve, c.property) {
                (Fitted::Constant(v), Property::Rotation) => {
                    (clamped(ORDER, self.span[0], self.span[1], &[]), vec![*v; ORDER])
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

    /// The clip in the common model, for baking: each curve channel its spline
    /// ([`ChannelCurve::Spline`]), each constant its value as keys.
    #[must_use]
    pub fn to_clip(&self) -> Clip {
        let channels = self.channels.iter().map(|c| c.curve.channel(c.joint, c.property, self.span)).collect();
        Clip { name: self.name.clone(), channels }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use quatcurve_core::quat::Vec3F64;

    #[test]
    fn a_keyed_curve_is_its_keys_slerped_and_lerped_between_them() {
        let line = Timeline::Listed(vec![0.0, 0.1, 0.25, 0.3, 0.7, 1.0]);
        // Kept keys 0, 2, 3, 5; steps up to 170 degrees between them.
        let kept = [0usize, 2, 3, 5];
        let turns: Vec<QuatF64> = [0.0, 2.9, 2.0, -0.7]
            .iter()
            .enumerate()
            .map(|(i, &a)| QuatF64::from_rotation_vector(Vec3F64::new(a, 0.3 * i as f64, -0.2)))
            .collect();
        let points: Vec<[f64; 3]> = (0..4).map(|i| [f64::from(i * i), -2.0 * f64::from(i), 0.5]).collect();
        let knots: Vec<u32> = vec![2, 3];
        let rotations = Spline::new(std::slice::from_ref(&line), 0, Form::Keys, knots.clone(), turns.clone());
        let vectors = Spline::new(std::slice::from_ref(&line), 0, Form::Keys, knots, points.clone());
        assert_eq!((rotations.fit.order(), rotations.fit.controls.len()), (KEYS_ORDER, kept.len()));
        for j in 0..kept.len() - 1 {
            let (a, b) = (line.key(kept[j]), line.key(kept[j + 1]));
            let times: Vec<f64> = (0..=20).map(|i| a + (b - a) * f64::from(i) / 20.0).collect();
            let curve = rotations.fit.evaluate(&times).unwrap();
            let path = vectors.fit.evaluate(&times).unwrap();
            for (i, &t) in times.iter().enumerate() {
                let h = (t - a) / (b - a);
                let slerped = turns[j].between(turns[j + 1], h);
                assert!(curve[i].angle_to(slerped) < 1e-9, "segment {j} at {h}: {}", curve[i].angle_to(slerped));
                let lerped = Vec3F64::from_array(points[j].between(points[j + 1], h));
                assert!((path[i] - lerped).length() < 1e-12, "segment {j} at {h}");
            }
        }
    }
}
