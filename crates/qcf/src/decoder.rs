//! The fitted clip decoded as a runtime decodes it (DESIGN section 16): local poses at times
//! taken in order, in f32, straight from compressed bytes. A [`Decoder`] checks a container
//! once and keeps its clips in a runtime form (fixed-width streams); opening a clip reads its
//! channels' fields and nothing else, and each curve's cursor reads its knots and control points from their packed
//! streams as it steps onto them. What a span needs that does not depend on the time (its knot
//! offsets, the basis's reciprocals, its control points, sign-aligned) is computed once when a
//! cursor enters it, so a sample costs a cubic's basis and weighted sum, or two sines; no
//! batch is built and no logarithm taken. It is a fourth evaluator of the fitted families
//! beside the CPU path, the reference and the GPU, held to the reference by tests
//! ([`super::fitted::Fitted::at`]).

use super::fitted::{source_rate, Form, ORDER};
use super::packed::{FixedCodes, FixedKnots};
use super::quantize::{rotation, step, value};
use super::timeline::KeyTimes;
use super::{
    least_delta, runtime_clips, Channel, ChannelFields, CurveFields, Largest, Reader, Stored, RUNTIME_PADDING,
};
use quatcurve_anim::error::ContainerError;
use quatcurve_anim::{Joint, Property};
use wide::f32x4;

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

/// A container's clips ready to open: every field and code checked once, then each clip's
/// timelines and channels kept as the container stores them but for their knots' and codes'
/// packing, fixed widths instead of Rice codes (`runtime_clips`, DESIGN section 16): a few percent more
/// bytes, read without each value waiting on the one before it. That is all a clip is decoded
/// from.
#[derive(Clone, Debug)]
pub struct Decoder {
    /// The skeleton at rest, parents by index: what the poses' joints are.
    pub joints: Vec<Joint>,
    /// Every joint's rest pose, [`POSE_FLOATS`] a joint.
    rest: Vec<f32>,
    clips: Vec<Clip>,
    /// Every clip's body, at fixed widths.
    bytes: Vec<u8>,
}

/// One clip of a [`Decoder`].
#[derive(Clone, Debug)]
pub struct Clip {
    /// The source clip's name.
    pub name: String,
    /// The source's frames a second ([`super::fitted::FittedClip::source_rate`]).
    pub rate: f64,
    /// The clip's first and last key times, seconds.
    pub span: [f64; 2],
    /// Where its body starts in the decoder's bytes.
    body: usize,
}

impl Decoder {
    /// The decoder of a container's bytes.
    ///
    /// # Errors
    /// As [`super::Container::from_bytes`]: the first field that is truncated or out of its
    /// range, or a checksum that does not match.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, ContainerError> {
        let stored = Stored::from_bytes(bytes)?;
        let rest = stored
            .joints
            .iter()
            .flat_map(|joint| joint.rotation.iter().chain(&joint.translation).chain(&joint.scale))
            .map(|&v| v as f32)
            .collect();
        let (bytes, bodies) = runtime_clips(&stored.clips);
        let clips = stored
            .clips
            .iter()
            .zip(bodies)
            .map(|(clip, body)| Clip {
                name: clip.name.clone(),
                rate: source_rate(&clip.timelines),
                span: clip.span,
                body,
            })
            .collect();
        Ok(Self { joints: stored.joints, rest, clips, bytes })
    }

    /// The clips, in the container's order.
    #[must_use]
    pub fn clips(&self) -> &[Clip] {
        &self.clips
    }

    /// Bytes the decoder holds for its clips: their bodies and the rest pose (the joints'
    /// names, read into [`Self::joints`], besides).
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.bytes.len() + std::mem::size_of_val(&self.rest[..])
    }

    /// Bytes of clip `index`'s runtime form (0 for no such clip).
    #[must_use]
    pub fn clip_bytes(&self, index: usize) -> usize {
        let end = self.clips.get(index + 1).map_or(self.bytes.len() - RUNTIME_PADDING, |next| next.body);
        self.clips.get(index).map_or(0, |clip| end - clip.body)
    }

    /// Clip `index` at its start: its channels' fields read, each curve's cursor before its
    /// first span.
    ///
    /// # Errors
    /// `index` is not one of the clips; or a field of the runtime form does not read, which a
    /// checked container's cannot fail to (its reader returns errors all the same).
    pub fn open(&self, index: usize) -> Result<ClipDecoder<'_>, OpenError> {
        let clip = self.clips.get(index).ok_or(OpenError::NoClip { index, clips: self.clips.len() })?;
        let mut r = Reader { bytes: &self.bytes, at: clip.body };
        let timelines = r.timelines(&clip.name, false)?;
        let count = r.channel_count(&clip.name)?;
        let mut decoder = ClipDecoder {
            name: &clip.name,
            rate: clip.rate,
            span: clip.span,
            fixed: self.rest.clone(),
            // Room for every channel in each, so that no push moves the cursors again.
            cubic_rotations: Vec::with_capacity(count),
            groups: Vec::new(),
            cubic_vectors: Vec::with_capacity(count),
            slerps: Vec::with_capacity(count),
            lerps: Vec::with_capacity(count),
        };
        for index in 0..count {
            let field = Channel { clip: &clip.name, index, joint: None };
            let (joint, property, fields) = r.channel(&field, &self.joints, &timelines)?;
            let at = slot(joint, property);
            match fields {
                ChannelFields::Constant(v) => {
                    let n = if property == Property::Rotation { 4 } else { 3 };
                    decoder.fixed[at..at + n].iter_mut().zip(v).for_each(|(o, v)| *o = v as f32);
                }
                ChannelFields::Curve(curve, largest) => {
                    let times = timelines[curve.line];
                    let bytes = &self.bytes[..];
                    match (largest, curve.form) {
                        (Some(largest), Form::Cubic) => {
                            let points = Ahead::new(Rotations::new(bytes, &curve, largest));
                            decoder.cubic_rotations.push(Cubic::new(at, bytes, times, &curve, points));
                        }
                        (Some(largest), Form::Keys) => {
                            let points = Ahead::new(Rotations::new(bytes, &curve, largest));
                            decoder.slerps.push(Slerp { keys: Keys::new(at, bytes, times, &curve, points), arc: None });
                        }
                        (None, Form::Cubic) => {
                            decoder.cubic_vectors.push(Cubic::new(
                                at,
                                bytes,
                                times,
                                &curve,
                                Ahead::new(Vectors::new(bytes, &curve)),
                            ));
                        }
                        (None, Form::Keys) => {
                            let keys = Keys::new(at, bytes, times, &curve, Ahead::new(Vectors::new(bytes, &curve)));
                            decoder.lerps.push(Lerp { keys });
                        }
                    }
                }
            }
        }
        decoder.groups = vec![Group::default(); decoder.cubic_rotations.len().div_ceil(LANES)];
        Ok(decoder)
    }
}

/// One fitted clip being decoded: its rest-and-constant pose, and a cursor per curve on the
/// decoder's runtime form.
#[derive(Clone, Debug)]
pub struct ClipDecoder<'a> {
    /// The source clip's name.
    pub name: &'a str,
    /// The source's frames a second ([`super::fitted::FittedClip::source_rate`]).
    pub rate: f64,
    /// The clip's first and last key times.
    span: [f64; 2],
    /// Every joint's rest pose with the clip's constant channels written over it.
    fixed: Vec<f32>,
    cubic_rotations: Vec<Cubic<'a, Ahead<Rotations<'a>, 4>, 4>>,
    /// The cubic rotations' current spans, [`LANES`] channels a group, a group sampled at once.
    groups: Vec<Group>,
    cubic_vectors: Vec<Cubic<'a, Ahead<Vectors<'a>, 3>, 3>>,
    slerps: Vec<Slerp<'a>>,
    lerps: Vec<Lerp<'a>>,
}

impl ClipDecoder<'_> {
    /// Floats of one pose: [`POSE_FLOATS`] per joint.
    #[must_use]
    pub fn pose_floats(&self) -> usize {
        self.fixed.len()
    }

    /// Bytes this decoding holds besides the decoder's: its fixed pose, its cursors (each a
    /// span's knots and control points and where its streams are) and the cubic rotations'
    /// groups, what every clip played at once costs.
    #[must_use]
    pub fn state_bytes(&self) -> usize {
        use std::mem::size_of_val as size;
        size(&self.fixed[..])
            + size(&self.cubic_rotations[..])
            + size(&self.groups[..])
            + size(&self.cubic_vectors[..])
            + size(&self.slerps[..])
            + size(&self.lerps[..])
    }

    /// The clip's first and last key times, seconds.
    #[must_use]
    pub fn span(&self) -> [f64; 2] {
        self.span
    }

    /// The local pose at `t` (clamped to the clip's span) into `pose` ([`Self::pose_floats`]
    /// floats). Fastest at times taken in order: a cursor steps forward from its span, reading
    /// its next knot and control point, and starts over at its first span for an earlier time.
    ///
    /// # Errors
    /// `t` is not finite, or `pose` is not [`Self::pose_floats`] long; `pose` is left as it was.
    pub fn pose(&mut self, t: f64, pose: &mut [f32]) -> Result<(), PoseError> {
        if !t.is_finite() {
            return Err(PoseError::Time { clip: self.name.to_string(), time: t });
        }
        if pose.len() != self.fixed.len() {
            return Err(PoseError::Length { clip: self.name.to_string(), floats: self.fixed.len(), given: pose.len() });
        }
        let t = t.clamp(self.span[0], self.span[1]);
        pose.copy_from_slice(&self.fixed);
        // The cubic rotations: each cursor stepped to its span, which it copies into its
        // group's lane; then each group's four sampled at once (a third of a pose, one at a time).
        for (i, c) in self.cubic_rotations.iter_mut().enumerate() {
            if t >= c.end || t < c.origin {
                c.seek(t);
                self.groups[i / LANES].set(i % LANES, c);
            }
        }
        for (group, cursors) in self.groups.iter().zip(self.cubic_rotations.chunks(LANES)) {
            let q = group.sample(t);
            for (lane, c) in cursors.iter().enumerate() {
                pose[c.slot..c.slot + 4].copy_from_slice(&[q[0][lane], q[1][lane], q[2][lane], q[3][lane]]);
            }
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
            return Err(PoseError::Length { clip: self.name.to_string(), floats: times.len() * n, given: poses.len() });
        }
        for (&t, pose) in times.iter().zip(poses.chunks_exact_mut(n.max(1))) {
            self.pose(t, pose)?;
        }
        Ok(())
    }
}

/// Cubic rotations sampled at once: four `f32` lanes, one register at the build's baseline
/// (SSE2 on x86-64, NEON on aarch64).
const LANES: usize = 4;

/// The current spans of [`LANES`] cubic rotations, field by field, each field's four values in
/// one register: what their samples need besides the time. A cursor copies its span into its
/// lane when it enters it.
#[derive(Clone, Debug, Default)]
struct Group {
    /// Each span's first knot, the origin of its time `u`.
    origin: [f64; LANES],
    /// `a2, a3` (the left differences), `b1, b2, b3` (the right ones), the Cox-de Boor
    /// triangle's six reciprocals, then the four control points' components, point after point.
    fields: [f32x4; 27],
}

impl Group {
    /// Lane `lane`'s span, from its cursor.
    #[inline(always)]
    fn set<P>(&mut self, lane: usize, c: &Cubic<'_, P, 4>) {
        self.origin[lane] = c.origin;
        // Each field written by name: an iterator chaining them cost a quarter of a pose.
        let f = &mut self.fields;
        f[0].as_array_mut()[lane] = c.a[0];
        f[1].as_array_mut()[lane] = c.a[1];
        for j in 0..3 {
            f[2 + j].as_array_mut()[lane] = c.b[j];
        }
        for j in 0..6 {
            f[5 + j].as_array_mut()[lane] = c.inv[j];
        }
        for (k, point) in c.p.iter().enumerate() {
            for (component, &v) in point.iter().enumerate() {
                f[11 + 4 * k + component].as_array_mut()[lane] = v;
            }
        }
    }

    /// Each lane's rotation at `t`, `[component][lane]`: the basis by Cox-de Boor (The NURBS
    /// Book, A2.2, unrolled for order 4) on the span's offsets, the weighted sum of its four
    /// control points, and the sum normalized (the processor's reciprocal square root and one
    /// Newton step, within 2 ulp: the sum is near unit, its points a few degrees apart).
    #[inline(always)]
    fn sample(&self, t: f64) -> [[f32; LANES]; 4] {
        let (f, o) = (&self.fields, &self.origin);
        let u = f32x4::from([(t - o[0]) as f32, (t - o[1]) as f32, (t - o[2]) as f32, (t - o[3]) as f32]);
        let (l1, l2, l3) = (u, u + f[0], u + f[1]);
        let (r1, r2, r3) = (f[2] - u, f[3] - u, f[4] - u);
        let inv = |j: usize| f[5 + j];
        let (n0, n1) = (r1 * inv(0), l1 * inv(0));
        let (t0, t1) = (n0 * inv(1), n1 * inv(2));
        let (n0, n1, n2) = (r1 * t0, l2 * t0 + r2 * t1, l1 * t1);
        let (t0, t1, t2) = (n0 * inv(3), n1 * inv(4), n2 * inv(5));
        let w = [r1 * t0, l3 * t0 + r2 * t1, l2 * t1 + r3 * t2, l1 * t2];
        let component = |c: usize| w[0] * f[11 + c] + w[1] * f[15 + c] + w[2] * f[19 + c] + w[3] * f[23 + c];
        let q = [component(0), component(1), component(2), component(3)];
        let length = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
        let y = length.recip_sqrt();
        let scale = y * (f32x4::splat(1.5) - f32x4::splat(0.5) * length * y * y);
        q.map(|q| (q * scale).to_array())
    }
}

/// Why a clip was not opened.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OpenError {
    /// The index is past the last clip.
    #[error("clip {index} is not one of the container's {clips} clips")]
    NoClip {
        /// The index asked for.
        index: usize,
        /// How many clips there are.
        clips: usize,
    },
    /// A field of the clip's runtime form did not read.
    #[error(transparent)]
    Container(#[from] ContainerError),
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

/// A curve's control points, read from its codes one after another as its cursor steps.
trait Points<const C: usize> {
    /// The next control point.
    fn next(&mut self) -> [f32; C];
    /// Back to the first.
    fn restart(&mut self);
}

/// A stream read one point ahead of its cursor: the point a step takes was decoded at the step
/// before, so that its codes, square root and alignment are in no sample's wait, and the
/// processor decodes it beside other channels' samples.
#[derive(Clone, Debug)]
struct Ahead<P, const C: usize> {
    stream: P,
    ahead: [f32; C],
}

impl<P: Points<C>, const C: usize> Ahead<P, C> {
    fn new(stream: P) -> Self {
        Self { stream, ahead: [0.0; C] }
    }
}

impl<P: Points<C>, const C: usize> Points<C> for Ahead<P, C> {
    #[inline(always)]
    fn next(&mut self) -> [f32; C] {
        // Past the last point the stream reads the bytes after it, which no span takes.
        std::mem::replace(&mut self.ahead, self.stream.next())
    }

    fn restart(&mut self) {
        self.stream.restart();
        self.ahead = self.stream.next();
    }
}

/// A translation's or scale's control points.
#[derive(Clone, Debug)]
struct Vectors<'a> {
    codes: FixedCodes<'a>,
    low: [f64; 3],
    step: f64,
}

impl<'a> Vectors<'a> {
    fn new(bytes: &'a [u8], curve: &CurveFields<'a>) -> Self {
        let codes = FixedCodes::new(bytes, curve.codes_at, curve.bits);
        Self { codes, low: curve.low, step: step(curve.span, curve.bits) }
    }
}

impl Points<3> for Vectors<'_> {
    #[inline(always)]
    fn next(&mut self) -> [f32; 3] {
        value(&self.low, self.step, &self.codes.next()).map(|v| v as f32)
    }

    fn restart(&mut self) {
        self.codes.restart();
    }
}

/// A rotation's control points, each on the side of the one before it, as the batch packs
/// them: the sign flips where a point's dot with the one before, as decoded, is negative, so
/// that no point waits for the one before it to be aligned.
#[derive(Clone, Debug)]
struct Rotations<'a> {
    vectors: Vectors<'a>,
    largest: Largest<'a>,
    /// The next point's index, the point before it as decoded, and the sign it took.
    index: usize,
    previous: [f32; 4],
    sign: f32,
}

impl<'a> Rotations<'a> {
    fn new(bytes: &'a [u8], curve: &CurveFields<'a>, largest: Largest<'a>) -> Self {
        Self { vectors: Vectors::new(bytes, curve), largest, index: 0, previous: [0.0; 4], sign: 1.0 }
    }
}

impl Points<4> for Rotations<'_> {
    #[inline(always)]
    fn next(&mut self) -> [f32; 4] {
        let Vectors { codes, low, step } = &mut self.vectors;
        let rest = value(low, *step, &codes.next()).map(|v| v as f32);
        let q = rotation(rest, self.largest.at(self.index));
        self.index += 1;
        let dot = q[0] * self.previous[0] + q[1] * self.previous[1] + q[2] * self.previous[2] + q[3] * self.previous[3];
        if dot < 0.0 {
            self.sign = -self.sign;
        }
        self.previous = q;
        q.map(|v| self.sign * v)
    }

    fn restart(&mut self) {
        self.vectors.restart();
        (self.index, self.previous, self.sign) = (0, [0.0; 4], 1.0);
    }
}

/// A curve's knot times, read one after another from its knots' stream as its cursor steps:
/// its clamped ends, then each interior knot at its sample (a cubic's) or key (keys').
#[derive(Clone, Debug)]
struct KnotTimes<'a> {
    times: KeyTimes<'a>,
    form: Form,
    stream: FixedKnots<'a>,
    interior: usize,
    unread: usize,
}

impl<'a> KnotTimes<'a> {
    fn new(bytes: &'a [u8], times: KeyTimes<'a>, curve: &CurveFields<'a>) -> Self {
        let stream = FixedKnots::new(bytes, curve.knots_at, curve.knot_parameter, least_delta(curve.form));
        Self { times, form: curve.form, stream, interior: curve.knot_count, unread: curve.knot_count }
    }

    fn first(&self) -> f64 {
        self.times.key(0)
    }

    /// The next interior knot's time, or the last key's once every interior knot is read.
    #[inline(always)]
    fn next(&mut self) -> f64 {
        if self.unread == 0 {
            return self.times.key(self.times.keys() - 1);
        }
        self.unread -= 1;
        let at = self.stream.next() as usize;
        match self.form {
            Form::Cubic => self.times.sample(at),
            Form::Keys => self.times.key(at),
        }
    }

    fn restart(&mut self) {
        self.stream.restart();
        self.unread = self.interior;
    }
}

/// A clamped cubic B-spline's cursor: its span `l` (`knots[l] <= t < knots[l + 1]`, the last
/// span taking its end), that span's knots and control points, and what its basis needs
/// besides the time. Interior knots lie strictly inside the timeline, so neither end span is
/// empty; an empty span inside is stepped over.
#[derive(Clone, Debug)]
struct Cubic<'a, P, const C: usize> {
    slot: usize,
    knots: KnotTimes<'a>,
    points: P,
    /// Control points: the last span is `points - 1`.
    count: usize,
    /// The span; 0 before the cursor first starts.
    l: usize,
    /// Knots `l - 2..=l + 3`.
    window: [f64; 6],
    /// Control points `l - 3..=l`.
    p: [[f32; C]; ORDER],
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

impl<'a, P: Points<C>, const C: usize> Cubic<'a, P, C> {
    fn new(slot: usize, bytes: &'a [u8], times: KeyTimes<'a>, curve: &CurveFields<'a>, points: P) -> Self {
        Self {
            slot,
            knots: KnotTimes::new(bytes, times, curve),
            points,
            count: curve.points,
            l: 0,
            window: [0.0; 6],
            p: [[0.0; C]; ORDER],
            origin: f64::INFINITY,
            end: f64::NEG_INFINITY,
            a: [0.0; 2],
            b: [0.0; 3],
            inv: [0.0; 6],
        }
    }

    /// Onto the first span: its knots and control points read from the streams' starts.
    fn start(&mut self) {
        self.knots.restart();
        self.points.restart();
        let first = self.knots.first();
        self.window = [first, first, first, self.knots.next(), self.knots.next(), self.knots.next()];
        self.p = std::array::from_fn(|_| self.points.next());
        self.l = ORDER - 1;
    }

    /// Onto the next span: one more knot and control point read.
    #[inline(always)]
    fn step(&mut self) {
        self.l += 1;
        self.window.rotate_left(1);
        self.window[5] = self.knots.next();
        self.p.rotate_left(1);
        self.p[ORDER - 1] = self.points.next();
    }

    /// Moves to the span of `t`, from the start when `t` is before the current one.
    #[inline(always)]
    fn seek(&mut self, t: f64) {
        if self.l == 0 || (t < self.origin && self.l > ORDER - 1) {
            self.start();
        }
        let last = self.count - 1;
        while self.l < last && t >= self.window[3] {
            self.step();
        }
        let k = &self.window;
        self.origin = k[2];
        self.end = if self.l == last { f64::INFINITY } else { k[3] };
        let d = |i: usize, j: usize| (k[i] - k[j]) as f32;
        let ([a2, a3], [b1, b2, b3]) = ([d(2, 1), d(2, 0)], [d(3, 2), d(4, 2), d(5, 2)]);
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
        let p = &self.p;
        let mut sum = [0.0f32; C];
        for (c, s) in sum.iter_mut().enumerate() {
            *s = w[0] * p[0][c] + w[1] * p[1][c] + w[2] * p[2][c] + w[3] * p[3][c];
        }
        sum
    }
}

/// An order-2 B-spline's cursor on its keys: span `l` from control point `l - 1` to `l`, the
/// two and their knots held.
#[derive(Clone, Debug)]
struct Keys<'a, P, const C: usize> {
    slot: usize,
    knots: KnotTimes<'a>,
    points: P,
    count: usize,
    /// The span; 0 before the cursor first starts.
    l: usize,
    /// Knots `l` and `l + 1`, and control points `l - 1` and `l`.
    k: [f64; 2],
    p: [[f32; C]; 2],
    origin: f64,
    end: f64,
    /// `1 / (knots[l + 1] - knots[l])`.
    inv: f64,
}

impl<'a, P: Points<C>, const C: usize> Keys<'a, P, C> {
    fn new(slot: usize, bytes: &'a [u8], times: KeyTimes<'a>, curve: &CurveFields<'a>, points: P) -> Self {
        Self {
            slot,
            knots: KnotTimes::new(bytes, times, curve),
            points,
            count: curve.points,
            l: 0,
            k: [0.0; 2],
            p: [[0.0; C]; 2],
            origin: f64::INFINITY,
            end: f64::NEG_INFINITY,
            inv: 0.0,
        }
    }

    /// The span of `t` and `t`'s fraction of it; whether the span changed.
    #[inline]
    fn seek(&mut self, t: f64) -> (f32, bool) {
        let moved = t >= self.end || t < self.origin;
        if moved {
            if self.l == 0 || (t < self.origin && self.l > 1) {
                self.knots.restart();
                self.points.restart();
                self.k = [self.knots.first(), self.knots.next()];
                self.p = [self.points.next(), self.points.next()];
                self.l = 1;
            }
            let last = self.count - 1;
            while self.l < last && t >= self.k[1] {
                self.l += 1;
                self.k = [self.k[1], self.knots.next()];
                self.p = [self.p[1], self.points.next()];
            }
            self.origin = self.k[0];
            self.end = if self.l == last { f64::INFINITY } else { self.k[1] };
            self.inv = 1.0 / (self.k[1] - self.k[0]);
        }
        (((t - self.origin) * self.inv).min(1.0) as f32, moved)
    }
}

/// A fraction of a keys span within which a time is taken to be on its key: `2^-24`, f32's
/// rounding, which moves a slerp by at most that times its angle (at most `pi / 2`), 1e-7 rad.
const ON_KEY: f32 = f32::EPSILON / 2.0;

/// Rotation keys slerped (KKS's order 2).
#[derive(Clone, Debug)]
struct Slerp<'a> {
    keys: Keys<'a, Ahead<Rotations<'a>, 4>, 4>,
    /// The span's angle between its keys and its sine's reciprocal (0 for keys too close to
    /// part, which are lerped), once a time inside the span asked for them.
    arc: Option<[f32; 2]>,
}

impl Slerp<'_> {
    #[inline]
    fn at(&mut self, t: f64) -> [f32; 4] {
        let (h, moved) = self.keys.seek(t);
        let [a, b] = self.keys.p;
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
struct Lerp<'a> {
    keys: Keys<'a, Ahead<Vectors<'a>, 3>, 3>,
}

impl Lerp<'_> {
    #[inline]
    fn at(&mut self, t: f64) -> [f32; 3] {
        let (h, _) = self.keys.seek(t);
        let [a, b] = self.keys.p;
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
        let decoded = Decoder::from_bytes(&container.to_bytes()).unwrap();
        let mut decoder = decoded.open(0).unwrap();
        assert_eq!((decoder.name, decoder.rate), ("turn", container.clips[0].source_rate()));
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
        let decoded = Decoder::from_bytes(&container().to_bytes()).unwrap();
        let mut decoder = decoded.open(0).unwrap();
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
    fn a_clip_past_the_last_is_named() {
        let decoded = Decoder::from_bytes(&container().to_bytes()).unwrap();
        let e = decoded.open(1).unwrap_err();
        assert_eq!(e, OpenError::NoClip { index: 1, clips: 1 });
        assert_eq!(e.to_string(), "clip 1 is not one of the container's 1 clips");
    }

    #[test]
    fn a_time_that_is_not_finite_or_an_output_of_another_length_is_named() {
        let decoded = Decoder::from_bytes(&container().to_bytes()).unwrap();
        let mut decoder = decoded.open(0).unwrap();
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
