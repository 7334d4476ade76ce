//! The fitted clip decoded as a runtime decodes it (DESIGN section 16): local poses at times
//! taken in order, in f32, from per-channel cursors that step from span to span. What a span
//! needs that does not depend on the time (its knot offsets, the basis's reciprocals, its
//! control points, sign-aligned) is computed once when a cursor enters it, so a sample costs
//! a cubic's basis and weighted sum, or two sines; no batch is built and no logarithm taken.
//! It is a fourth evaluator of the fitted families beside the CPU path, the reference and the
//! GPU, held to the reference by tests ([`super::fitted::Fitted::at`]).

use super::fitted::{knot_times, source_rate, Form, KEYS_ORDER, ORDER};
use super::{Stored, StoredClip, StoredCurve};
use quatcurve_anim::error::ContainerError;
use quatcurve_anim::{Joint, Property};

/// Floats of one joint's local pose: rotation `x, y, z, w`, translation, scale.
pub const POSE_FLOATS: usize = 10;

/// Where each property starts in a joint's [`POSE_FLOATS`].
fn slot(joint: usize, property: Property) -> usize {
    joint * POSE_FLOATS
        + match property {
            Property::Rotation => 0,
            Property::Translation => 4,
            Property::Scale => 7,
        }
}

/// A container's clips ready to decode, read from its bytes: each curve's codes decoded once
/// into f32 control points, in order, with nothing else built.
#[derive(Clone, Debug)]
pub struct Decoder {
    /// The skeleton at rest, parents by index: what the poses' joints are.
    pub joints: Vec<Joint>,
    /// One per clip, in the container's order.
    pub clips: Vec<ClipDecoder>,
}

impl Decoder {
    /// The decoder of a container's bytes.
    ///
    /// # Errors
    /// As [`super::Container::from_bytes`]: the first field that is truncated or out of its
    /// range, or a checksum that does not match.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, ContainerError> {
        let stored = Stored::from_bytes(bytes)?;
        let clips = stored.clips.into_iter().map(|clip| ClipDecoder::new(&stored.joints, clip)).collect();
        Ok(Self { joints: stored.joints, clips })
    }
}

/// One fitted clip ready to decode: its rest-and-constant pose, and a cursor per curve.
#[derive(Clone, Debug)]
pub struct ClipDecoder {
    /// The source clip's name.
    pub name: String,
    /// The source's frames a second ([`super::fitted::FittedClip::source_rate`]).
    pub rate: f64,
    /// The clip's first and last key times.
    span: [f64; 2],
    /// Every joint's rest pose with the clip's constant channels written over it.
    fixed: Vec<f32>,
    cubic_rotations: Vec<Cubic<4>>,
    cubic_vectors: Vec<Cubic<3>>,
    slerps: Vec<Slerp>,
    lerps: Vec<Lerp>,
}

impl ClipDecoder {
    /// A stored clip of a container of `joints`.
    fn new(joints: &[Joint], clip: StoredClip) -> Self {
        let mut fixed: Vec<f32> = Vec::with_capacity(joints.len() * POSE_FLOATS);
        for joint in joints {
            let pose = joint.rotation.iter().chain(&joint.translation).chain(&joint.scale);
            fixed.extend(pose.map(|&v| v as f32));
        }
        let mut decoder = Self {
            name: clip.name,
            rate: source_rate(&clip.timelines),
            span: clip.span,
            fixed,
            cubic_rotations: Vec::new(),
            cubic_vectors: Vec::new(),
            slerps: Vec::new(),
            lerps: Vec::new(),
        };
        for channel in clip.channels {
            let at = slot(channel.joint, channel.property);
            match channel.curve {
                StoredCurve::Constant(v) => {
                    let n = if channel.property == Property::Rotation { 4 } else { 3 };
                    decoder.fixed[at..at + n].iter_mut().zip(v).for_each(|(o, v)| *o = v as f32);
                }
                StoredCurve::Rotation(line, form, knots, codes) => {
                    // Each control point on the side of the one before it, as the batch packs
                    // them: the sign flips where a point's dot with the one before, as decoded,
                    // is negative, so that no point waits for the one before it to be aligned.
                    let mut points: Vec<[f32; 4]> = Vec::with_capacity(codes.largest.len());
                    let (mut previous, mut sign) = ([0.0f64; 4], 1.0f64);
                    for q in codes.decoded() {
                        let q = q.to_array();
                        let dot = q[0] * previous[0] + q[1] * previous[1] + q[2] * previous[2] + q[3] * previous[3];
                        if dot < 0.0 {
                            sign = -sign;
                        }
                        previous = q;
                        points.push(q.map(|v| (sign * v) as f32));
                    }
                    let knots = knot_times(&clip.timelines, line, form, &knots);
                    match form {
                        Form::Cubic => decoder.cubic_rotations.push(Cubic::new(at, knots, points)),
                        Form::Keys => decoder.slerps.push(Slerp { keys: Keys::new(at, knots), points, arc: None }),
                    }
                }
                StoredCurve::Vector(line, form, knots, codes) => {
                    let points = codes.decoded().map(|p| p.map(|v| v as f32)).collect();
                    let knots = knot_times(&clip.timelines, line, form, &knots);
                    match form {
                        Form::Cubic => decoder.cubic_vectors.push(Cubic::new(at, knots, points)),
                        Form::Keys => decoder.lerps.push(Lerp { keys: Keys::new(at, knots), points }),
                    }
                }
            }
        }
        decoder
    }

    /// Floats of one pose: [`POSE_FLOATS`] per joint.
    #[must_use]
    pub fn pose_floats(&self) -> usize {
        self.fixed.len()
    }

    /// Bytes the decoded clip holds on the heap (its control points and knot times, its
    /// cursors and fixed pose): what a player that keeps it to play it again pays in memory
    /// for not reading its codes again.
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val as size;
        let rotations: usize = self.cubic_rotations.iter().map(|c| size(&c.knots[..]) + size(&c.points[..])).sum();
        let vectors: usize = self.cubic_vectors.iter().map(|c| size(&c.knots[..]) + size(&c.points[..])).sum();
        let slerps: usize = self.slerps.iter().map(|s| size(&s.keys.knots[..]) + size(&s.points[..])).sum();
        let lerps: usize = self.lerps.iter().map(|l| size(&l.keys.knots[..]) + size(&l.points[..])).sum();
        let cursors = size(&self.cubic_rotations[..])
            + size(&self.cubic_vectors[..])
            + size(&self.slerps[..])
            + size(&self.lerps[..]);
        size(&self.fixed[..]) + cursors + rotations + vectors + slerps + lerps
    }

    /// The clip's first and last key times, seconds.
    #[must_use]
    pub fn span(&self) -> [f64; 2] {
        self.span
    }

    /// The local pose at `t` (clamped to the clip's span) into `pose` ([`Self::pose_floats`]
    /// floats). Fastest at times taken in order: a cursor steps forward from its span, and
    /// starts over at the clip's start for an earlier time.
    ///
    /// # Errors
    /// `t` is not finite, or `pose` is not [`Self::pose_floats`] long; `pose` is left as it was.
    pub fn pose(&mut self, t: f64, pose: &mut [f32]) -> Result<(), PoseError> {
        if !t.is_finite() {
            return Err(PoseError::Time { clip: self.name.clone(), time: t });
        }
        if pose.len() != self.fixed.len() {
            return Err(PoseError::Length { clip: self.name.clone(), floats: self.fixed.len(), given: pose.len() });
        }
        let t = t.clamp(self.span[0], self.span[1]);
        pose.copy_from_slice(&self.fixed);
        for c in &mut self.cubic_rotations {
            let q = c.at(t);
            let inv = 1.0 / q.iter().map(|v| v * v).sum::<f32>().sqrt();
            pose[c.slot..c.slot + 4].iter_mut().zip(q).for_each(|(o, v)| *o = v * inv);
        }
        for c in &mut self.cubic_vectors {
            let v = c.at(t);
            pose[c.slot..c.slot + 3].copy_from_slice(&v);
        }
        for s in &mut self.slerps {
            let q = s.at(t);
            pose[s.keys.slot..s.keys.slot + 4].copy_from_slice(&q);
        }
        for l in &mut self.lerps {
            let v = l.at(t);
            pose[l.keys.slot..l.keys.slot + 3].copy_from_slice(&v);
        }
        Ok(())
    }

    /// The local poses at `times`, one after another, into `poses` (`times.len()` poses).
    ///
    /// # Errors
    /// As [`Self::pose`], for the first time that fails, or `poses` is not `times.len()`
    /// poses long.
    pub fn poses(&mut self, times: &[f64], poses: &mut [f32]) -> Result<(), PoseError> {
        let n = self.fixed.len();
        if poses.len() != times.len() * n {
            return Err(PoseError::Length { clip: self.name.clone(), floats: times.len() * n, given: poses.len() });
        }
        for (&t, pose) in times.iter().zip(poses.chunks_exact_mut(n.max(1))) {
            self.pose(t, pose)?;
        }
        Ok(())
    }
}

/// Why a pose was not decoded.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PoseError {
    /// The time asked for is NaN or infinite.
    #[error("clip '{clip}': the time {time} s is not finite")]
    Time {
        /// The clip's name.
        clip: String,
        /// The time asked for.
        time: f64,
    },
    /// The output is not as long as the poses asked for.
    #[error("clip '{clip}': the poses take {floats} floats, the output holds {given}")]
    Length {
        /// The clip's name.
        clip: String,
        /// Floats the poses take.
        floats: usize,
        /// Floats the output holds.
        given: usize,
    },
}

/// A clamped cubic B-spline's cursor: its span `l` (`knots[l] <= t < knots[l + 1]`, the last
/// span taking its end) and what the span's basis needs besides the time.
#[derive(Clone, Debug)]
struct Cubic<const C: usize> {
    slot: usize,
    knots: Vec<f64>,
    points: Vec<[f32; C]>,
    /// The span; 0 before the first sample.
    l: usize,
    /// `knots[l]`, the origin of the span's time `u`, and `knots[l + 1]`, where it ends.
    origin: f64,
    end: f64,
    /// `knots[l] - knots[l - 1]`, `knots[l] - knots[l - 2]`: `u` less the left differences.
    a: [f32; 2],
    /// `knots[l + j] - knots[l]`, `j = 1..=3`: the right differences' ends.
    b: [f32; 3],
    /// The reciprocals of the Cox-de Boor triangle's six denominators (all positive on a
    /// span of positive length).
    inv: [f32; 6],
}

impl<const C: usize> Cubic<C> {
    fn new(slot: usize, knots: Vec<f64>, points: Vec<[f32; C]>) -> Self {
        debug_assert_eq!(knots.len(), points.len() + ORDER);
        Self {
            slot,
            knots,
            points,
            l: 0,
            origin: f64::INFINITY,
            end: f64::NEG_INFINITY,
            a: [0.0; 2],
            b: [0.0; 3],
            inv: [0.0; 6],
        }
    }

    /// Moves to the span of `t`, from the start when `t` is before the current one.
    #[inline]
    fn seek(&mut self, t: f64) {
        let last = self.points.len() - 1;
        if t < self.origin {
            self.l = ORDER - 1;
        }
        while self.l < last && t >= self.knots[self.l + 1] {
            self.l += 1;
        }
        // A last span of no length (an interior knot at the end) takes the one before it.
        while self.l > ORDER - 1 && self.knots[self.l] == self.knots[self.l + 1] {
            self.l -= 1;
        }
        let (k, l) = (&self.knots, self.l);
        self.origin = k[l];
        self.end = if l == last { f64::INFINITY } else { k[l + 1] };
        let d = |i: usize, j: usize| (k[i] - k[j]) as f32;
        let ([a2, a3], [b1, b2, b3]) = ([d(l, l - 1), d(l, l - 2)], [d(l + 1, l), d(l + 2, l), d(l + 3, l)]);
        self.a = [a2, a3];
        self.b = [b1, b2, b3];
        // One division of eight lanes rather than six of one.
        let denominators = [b1, b1 + a2, b2, b1 + a3, b2 + a2, b3, 1.0, 1.0];
        let mut inv = [0.0f32; 8];
        for (i, d) in inv.iter_mut().zip(denominators) {
            *i = 1.0 / d;
        }
        self.inv.copy_from_slice(&inv[..6]);
    }

    /// The curve at `t`, unnormalized: the basis by Cox-de Boor (The NURBS Book, A2.2) on
    /// the span's offsets, then the weighted sum of its four control points.
    #[inline]
    fn at(&mut self, t: f64) -> [f32; C] {
        if t >= self.end || t < self.origin {
            self.seek(t);
        }
        let u = (t - self.origin) as f32;
        let ([a2, a3], [b1, b2, b3], i) = (self.a, self.b, self.inv);
        let (l1, l2, l3, r1, r2, r3) = (u, u + a2, u + a3, b1 - u, b2 - u, b3 - u);
        let temp = i[0];
        let (n0, n1) = (r1 * temp, l1 * temp);
        let t0 = n0 * i[1];
        let t1 = n1 * i[2];
        let (n0, n1, n2) = (r1 * t0, l2 * t0 + r2 * t1, l1 * t1);
        let t0 = n0 * i[3];
        let t1 = n1 * i[4];
        let t2 = n2 * i[5];
        let w = [r1 * t0, l3 * t0 + r2 * t1, l2 * t1 + r3 * t2, l1 * t2];
        let p: &[[f32; C]; ORDER] = self.points[self.l + 1 - ORDER..=self.l].try_into().expect("a span's four points");
        let mut sum = [0.0f32; C];
        for (c, s) in sum.iter_mut().enumerate() {
            *s = w[0] * p[0][c] + w[1] * p[1][c] + w[2] * p[2][c] + w[3] * p[3][c];
        }
        sum
    }
}

/// An order-2 B-spline's cursor on its keys: span `l` from key `l - 1` to key `l`.
#[derive(Clone, Debug)]
struct Keys {
    slot: usize,
    knots: Vec<f64>,
    l: usize,
    origin: f64,
    end: f64,
    /// `1 / (knots[l + 1] - knots[l])`.
    inv: f64,
}

impl Keys {
    fn new(slot: usize, knots: Vec<f64>) -> Self {
        Self { slot, knots, l: 0, origin: f64::INFINITY, end: f64::NEG_INFINITY, inv: 0.0 }
    }

    /// The span of `t` and `t`'s fraction of it; whether the span changed.
    #[inline]
    fn seek(&mut self, t: f64) -> (f32, bool) {
        let moved = t >= self.end || t < self.origin;
        if moved {
            let last = self.knots.len() - KEYS_ORDER - 1;
            if t < self.origin {
                self.l = KEYS_ORDER - 1;
            }
            while self.l < last && t >= self.knots[self.l + 1] {
                self.l += 1;
            }
            let k = &self.knots;
            self.origin = k[self.l];
            self.end = if self.l == last { f64::INFINITY } else { k[self.l + 1] };
            self.inv = 1.0 / (k[self.l + 1] - k[self.l]);
        }
        (((t - self.origin) * self.inv).min(1.0) as f32, moved)
    }
}

/// A fraction of a keys span within which a time is taken to be on its key: `2^-24`, f32's
/// rounding, which moves a slerp by at most that times its angle (at most `pi / 2`), 1e-7 rad.
const ON_KEY: f32 = f32::EPSILON / 2.0;

/// Rotation keys slerped (KKS's order 2).
#[derive(Clone, Debug)]
struct Slerp {
    keys: Keys,
    points: Vec<[f32; 4]>,
    /// The span's angle between its keys and its sine's reciprocal (0 for keys too close to
    /// part, which are lerped), once a time inside the span asked for them.
    arc: Option<[f32; 2]>,
}

impl Slerp {
    #[inline]
    fn at(&mut self, t: f64) -> [f32; 4] {
        let (h, moved) = self.keys.seek(t);
        let (a, b) = (self.points[self.keys.l - 1], self.points[self.keys.l]);
        if moved {
            self.arc = None;
        }
        // On a key, or nearer one than f32 tells apart (a frame's time is often a rounding
        // either side of its key's): the key itself, and the span's angle not computed.
        if h < ON_KEY {
            return a;
        }
        if h > 1.0 - ON_KEY {
            return b;
        }
        let [angle, inv] = *self.arc.get_or_insert_with(|| {
            // The angle between the keys from half their chord, `|a - b| = 2 sin(angle / 2)`,
            // which keeps its precision for close keys where `acos` of their dot does not;
            // `sin(angle) = 2 s sqrt(1 - s^2)`.
            let s = 0.5 * (0..4).map(|c| (a[c] - b[c]) * (a[c] - b[c])).sum::<f32>().sqrt();
            let angle = 2.0 * s.min(1.0).asin();
            let sin = 2.0 * s * (1.0 - s * s).max(0.0).sqrt();
            if angle > 1e-3 {
                [angle, 1.0 / sin]
            } else {
                [0.0; 2]
            }
        });
        let (wa, wb) =
            if angle > 0.0 { (sin_poly((1.0 - h) * angle) * inv, sin_poly(h * angle) * inv) } else { (1.0 - h, h) };
        // Unit to f32's rounding without a normalization: slerp keeps unit keys unit, and
        // keys too close to part lerp to within `angle^2 / 8` (1.3e-7) of unit.
        let mut q = [0.0f32; 4];
        for (c, q) in q.iter_mut().enumerate() {
            *q = wa * a[c] + wb * b[c];
        }
        q
    }
}

/// `sin x` for `0 <= x <= pi / 2` (keys sign-aligned are at most a half-turn apart, half
/// that in the quaternions' angle): Taylor to `x^11`, whose remainder there is below f32's
/// rounding (`(pi / 2)^13 / 13!` is 5e-9).
#[inline(always)]
fn sin_poly(x: f32) -> f32 {
    const C: [f32; 5] = [-1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0, -1.0 / 39_916_800.0];
    let x2 = x * x;
    let tail = C.iter().rev().fold(0.0f32, |acc, &c| acc * x2 + c);
    x + x * x2 * tail
}

/// Vector keys lerped.
#[derive(Clone, Debug)]
struct Lerp {
    keys: Keys,
    points: Vec<[f32; 3]>,
}

impl Lerp {
    #[inline]
    fn at(&mut self, t: f64) -> [f32; 3] {
        let (h, _) = self.keys.seek(t);
        let (a, b) = (self.points[self.keys.l - 1], self.points[self.keys.l]);
        std::array::from_fn(|c| a[c] + (b[c] - a[c]) * h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tests::container;
    use crate::Container;

    /// Every joint's pose at `times` by the reference: each channel's [`Fitted::at`], the rest
    /// pose where a joint has none.
    fn reference_poses(container: &Container, times: &[f64]) -> Vec<Vec<f64>> {
        let clip = &container.clips[0];
        let rest: Vec<f64> = container
            .joints
            .iter()
            .flat_map(|j| j.rotation.iter().chain(&j.translation).chain(&j.scale))
            .copied()
            .collect();
        let mut poses = vec![rest; times.len()];
        for channel in &clip.channels {
            let at = slot(channel.joint, channel.property);
            let n = if channel.property == Property::Rotation { 4 } else { 3 };
            let clamped: Vec<f64> = times.iter().map(|t| t.clamp(clip.span[0], clip.span[1])).collect();
            for (pose, value) in poses.iter_mut().zip(channel.curve.at(&clamped)) {
                pose[at..at + n].copy_from_slice(&value[..n]);
            }
        }
        poses
    }

    /// The largest difference from the reference over `times`: the angle between rotations
    /// (either sign), and between vectors' components relative to the larger of 1 and the
    /// reference's (f32 rounding of values up to 10).
    fn worst(decoder: &mut ClipDecoder, container: &Container, times: &[f64]) -> (f64, f64) {
        let mut poses = vec![0.0; times.len() * decoder.pose_floats()];
        decoder.poses(times, &mut poses).unwrap();
        let (mut angle, mut distance) = (0.0f64, 0.0f64);
        for (got, want) in poses.chunks_exact(decoder.pose_floats()).zip(reference_poses(container, times)) {
            for joint in 0..container.joints.len() {
                let (g, w) = (&got[joint * POSE_FLOATS..], &want[joint * POSE_FLOATS..]);
                // The rotation angle between them, `4 atan2(|g - w|, |g + w|)`, `w` on `g`'s side.
                let side = if (0..4).map(|c| f64::from(g[c]) * w[c]).sum::<f64>() < 0.0 { -1.0 } else { 1.0 };
                let length = |s: f64| (0..4).map(|c| (f64::from(g[c]) + s * side * w[c]).powi(2)).sum::<f64>().sqrt();
                angle = angle.max(4.0 * length(-1.0).atan2(length(1.0)));
                for c in 4..POSE_FLOATS {
                    distance = distance.max((f64::from(g[c]) - w[c]).abs() / w[c].abs().max(1.0));
                }
            }
        }
        (angle, distance)
    }

    #[test]
    fn every_form_decodes_as_the_reference_evaluates_it_in_order_and_out_of_it() {
        let container = container();
        let mut decoder = Decoder::from_bytes(&container.to_bytes()).unwrap().clips.remove(0);
        assert_eq!((decoder.name.as_str(), decoder.rate), ("turn", container.clips[0].source_rate()));
        assert_eq!(decoder.pose_floats(), 3 * POSE_FLOATS);
        // In order, on and between knots, and past both ends (clamped).
        let times: Vec<f64> = (-10..=1210).map(|i| f64::from(i) / 600.0).collect();
        let (angle, distance) = worst(&mut decoder, &container, &times);
        assert!(angle < 2e-6 && distance < 1e-6, "in order: {angle:e} rad, {distance:e}");
        // Backwards and scattered: the cursors start over.
        let scattered: Vec<f64> = (0..500).map(|i| f64::from((i * 7919) % 1201) / 600.0).collect();
        let (angle, distance) = worst(&mut decoder, &container, &scattered);
        assert!(angle < 2e-6 && distance < 1e-6, "scattered: {angle:e} rad, {distance:e}");
    }

    #[test]
    fn a_time_a_rounding_either_side_of_a_key_is_that_key() {
        let mut decoder = Decoder::from_bytes(&container().to_bytes()).unwrap().clips.remove(0);
        // Joint 2's rotation keeps keys at 0, 0.5 and 2 s.
        let mut rotation = |t: f64| {
            let mut pose = vec![0.0; decoder.pose_floats()];
            decoder.pose(t, &mut pose).unwrap();
            pose[2 * POSE_FLOATS..2 * POSE_FLOATS + 4].to_vec()
        };
        let key = rotation(0.5);
        let (below, above) = (f64::from_bits(0.5f64.to_bits() - 1), f64::from_bits(0.5f64.to_bits() + 1));
        assert_eq!((rotation(below), rotation(above)), (key.clone(), key.clone()));
        assert_ne!(rotation(0.5 + 1e-4), key, "a time inside the span slerps");
    }

    #[test]
    fn a_time_that_is_not_finite_or_an_output_of_another_length_is_named() {
        let mut decoder = Decoder::from_bytes(&container().to_bytes()).unwrap().clips.remove(0);
        let mut pose = vec![7.0; decoder.pose_floats()];
        let e = decoder.pose(f64::NAN, &mut pose).unwrap_err();
        assert_eq!(e.to_string(), "clip 'turn': the time NaN s is not finite");
        assert!(pose.iter().all(|&v| v == 7.0), "left as it was");
        let e = decoder.pose(0.5, &mut pose[1..]).unwrap_err();
        assert_eq!(e.to_string(), "clip 'turn': the poses take 30 floats, the output holds 29");
        let e = decoder.poses(&[0.0, 1.0], &mut pose).unwrap_err();
        assert_eq!(e.to_string(), "clip 'turn': the poses take 60 floats, the output holds 30");
        // A finite time past the clip is its end.
        let mut end = pose.clone();
        decoder.pose(1e300, &mut pose).unwrap();
        decoder.pose(decoder.span()[1], &mut end).unwrap();
        assert_eq!(pose, end);
    }
}
