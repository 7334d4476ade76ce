//! Errors of the library: every message names the track, the key (or sample) and the rule.

use std::fmt;

/// Identifies a track in messages: its index in the batch and, when it has one, its name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TrackId {
    /// Position in the batch (0-based).
    pub index: usize,
    /// The track's `name`, if given.
    pub name: Option<String>,
}

impl fmt::Display for TrackId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.name {
            Some(name) => write!(f, "track {} \"{}\"", self.index, name),
            None => write!(f, "track {}", self.index),
        }
    }
}

/// Choices as messages list them: `a`, `a or b`, `a, b or c`.
pub fn one_of<T: fmt::Display>(items: impl IntoIterator<Item = T>) -> String {
    let names: Vec<String> = items.into_iter().map(|i| i.to_string()).collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => names.concat(),
    }
}

/// A number as messages print it: plain decimals for everyday magnitudes (`0`, `0.25`,
/// `12.35`), scientific notation with four digits for the rest (`3.172e-7`), never `0e0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Number(pub f64);

impl fmt::Display for Number {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        if x == 0.0 || !x.is_finite() {
            write!(f, "{x}")
        } else if (1e-3..1e6).contains(&x.abs()) {
            // Four significant digits, trailing zeros dropped.
            let decimals = (3 - x.abs().log10().floor() as i32).max(0) as usize;
            let text = format!("{x:.decimals$}");
            let text = if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.') } else { &text };
            f.write_str(text)
        } else {
            // Four significant digits, trailing zeros of the mantissa dropped (1e-6, 3.172e-7).
            let text = format!("{x:.3e}");
            let (mantissa, exponent) = text.split_once('e').unwrap_or((&text, "0"));
            let mantissa =
                if mantissa.contains('.') { mantissa.trim_end_matches('0').trim_end_matches('.') } else { mantissa };
            write!(f, "{mantissa}e{exponent}")
        }
    }
}

/// Why a batch could not be built or an evaluation job could not run.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// The batch holds no track.
    #[error("the batch is empty: at least one track is required")]
    EmptyBatch,
    /// A key quaternion has a NaN or infinite component.
    #[error("{track}: key {key} is not finite ({value:?}); rotations must be finite numbers")]
    NonFiniteKey {
        /// The track, by index and name.
        track: TrackId,
        /// The key's index in the track.
        key: usize,
        /// The value given.
        value: [f64; 4],
    },
    /// A key quaternion is (nearly) zero and has no direction.
    #[error(
        "{track}: key {key} has norm {}, below {}; a rotation key must be a non-zero quaternion",
        Number(*.norm),
        Number(*.min)
    )]
    ZeroKey {
        /// The track, by index and name.
        track: TrackId,
        /// The key's index in the track.
        key: usize,
        /// The key's norm.
        norm: f64,
        /// The least norm allowed.
        min: f64,
    },
    /// Fewer keys than the curve needs.
    #[error("{track}: {curve} needs at least {min} keys, got {found}")]
    TooFewKeys {
        /// The track, by index and name.
        track: TrackId,
        /// The curve as messages name it.
        curve: String,
        /// The least the curve needs.
        min: usize,
        /// How many were given.
        found: usize,
    },
    /// `times` has a different length from `rotations`.
    #[error("{track}: times has {found} entries but there are {expected} keys; give one time per key")]
    TimesCount {
        /// The track, by index and name.
        track: TrackId,
        /// How many the rule asks for.
        expected: usize,
        /// How many were given.
        found: usize,
    },
    /// A key time is NaN or infinite.
    #[error("{track}: time of key {key} is not finite ({value})")]
    NonFiniteTime {
        /// The track, by index and name.
        track: TrackId,
        /// The key's index in the track.
        key: usize,
        /// The value given.
        value: f64,
    },
    /// Key times do not strictly increase.
    #[error("{track}: time of key {key} ({value}) is not greater than the time of key {} ({previous}); key times \
        must strictly increase", key - 1)]
    TimesNotIncreasing {
        /// The track, by index and name.
        track: TrackId,
        /// The key's index in the track.
        key: usize,
        /// The key's time.
        value: f64,
        /// The previous key's time.
        previous: f64,
    },
    /// The knot mode needs uniformly spaced key times and they are not.
    #[error("{track}: key {key} is at time {value} but {mode} knots need uniform times (expected {expected} within \
        {} of the step)", Number(*.tolerance))]
    NonUniformTimes {
        /// The track, by index and name.
        track: TrackId,
        /// The key's index in the track.
        key: usize,
        /// The key's time.
        value: f64,
        /// The time uniform spacing puts the key at.
        expected: f64,
        /// The knot mode.
        mode: String,
        /// The most the rule allows.
        tolerance: f64,
    },
    /// An order outside 2..=8, or phantom knots with an order other than 4.
    #[error("{track}: {reason}")]
    BadOrder {
        /// The track, by index and name.
        track: TrackId,
        /// What is wrong, in words.
        reason: String,
    },
    /// Two control points of one span of a normalized B-spline are a half turn or more apart.
    #[error(
        "{track}: control points {first} and {second} of one span of a normalized-bspline of order {order} are \
         {angle} rad apart{}; a span's control points must lie less than a half turn (pi rad) apart, or their \
         normalized sum can vanish: add keys between them, or use bspline",
        if *phantom { " (with phantom knots control point i is key i - 1, and the first and last are the mirrored ends)" } else { "" }
    )]
    ControlPointsApart {
        /// The track, by index and name.
        track: TrackId,
        /// The first control point's index.
        first: usize,
        /// The second's.
        second: usize,
        /// The turn from one to the other along the aligned control points, radians (at least
        /// pi).
        angle: f64,
        /// Whether the knots are phantom (the control points are the keys shifted by one).
        phantom: bool,
        /// The B-spline order (control points a span holds).
        order: usize,
    },
    /// Explicit knots are missing or their count is wrong.
    #[error(
        "{track}: explicit knots for order {order} with {keys} keys need {expected} knots (n + k + 1), got {found}"
    )]
    KnotCount {
        /// The track, by index and name.
        track: TrackId,
        /// The B-spline order.
        order: usize,
        /// Keys of the track.
        keys: usize,
        /// Knots the rule asks for (n + k + 1).
        expected: usize,
        /// Knots given.
        found: usize,
    },
    /// A knot is NaN or infinite.
    #[error("{track}: knot {knot} is not finite ({value})")]
    NonFiniteKnot {
        /// The track, by index and name.
        track: TrackId,
        /// The knot's index.
        knot: usize,
        /// The knot.
        value: f64,
    },
    /// Knots decrease.
    #[error(
        "{track}: knot {knot} ({value}) is smaller than knot {} ({previous}); knots must be non-decreasing",
        knot - 1
    )]
    KnotsDecreasing {
        /// The track, by index and name.
        track: TrackId,
        /// The knot's index.
        knot: usize,
        /// The knot.
        value: f64,
        /// The knot before it.
        previous: f64,
    },
    /// A knot value repeats too often.
    #[error(
        "{track}: knot {knot} (value {value}) has multiplicity {multiplicity}, more than {max} allowed {place} \
        for order {order}"
    )]
    KnotMultiplicity {
        /// The track, by index and name.
        track: TrackId,
        /// The first knot of the run.
        knot: usize,
        /// The knot's value.
        value: f64,
        /// How often the value repeats.
        multiplicity: usize,
        /// The most allowed there.
        max: usize,
        /// The B-spline order.
        order: usize,
        /// Inside the domain, or at or outside its ends.
        place: &'static str,
    },
    /// The B-spline domain `[t_{k-1}, t_{n+1}]` is empty.
    #[error("{track}: the curve's domain [knot {first}, knot {last}] = [{start}, {end}] is empty")]
    EmptyDomain {
        /// The track, by index and name.
        track: TrackId,
        /// The first knot's index.
        first: usize,
        /// The last knot's index.
        last: usize,
        /// Where the domain starts.
        start: f64,
        /// Where the domain ends.
        end: f64,
    },
    /// `angular_velocities` is needed and missing, or its length is wrong.
    #[error(
        "{track}: angular_velocities has {found} entries but there are {expected} keys (tangents = given needs \
        one body angular velocity per key)"
    )]
    VelocityCount {
        /// The track, by index and name.
        track: TrackId,
        /// How many the rule asks for.
        expected: usize,
        /// How many were given.
        found: usize,
    },
    /// An angular velocity is NaN or infinite.
    #[error("{track}: angular velocity of key {key} is not finite ({value:?})")]
    NonFiniteVelocity {
        /// The track, by index and name.
        track: TrackId,
        /// The key's index in the track.
        key: usize,
        /// The value given.
        value: [f64; 3],
    },
    /// `extra_turns` has the wrong length.
    #[error(
        "{track}: extra_turns has {found} entries but there are {expected} segments; give one integer per segment"
    )]
    ExtraTurnsCount {
        /// The track, by index and name.
        track: TrackId,
        /// How many the rule asks for.
        expected: usize,
        /// How many were given.
        found: usize,
    },
    /// An extra turn was asked on a segment whose middle coefficient has no axis.
    #[error("{track}: segment {segment} (keys {segment}..{}) asks for {turns} extra turns but its middle rotation \
        w2 is zero, so the turn axis is undefined", segment + 1)]
    ExtraTurnOnZeroArc {
        /// The track, by index and name.
        track: TrackId,
        /// The segment's index.
        segment: usize,
        /// The extra turns asked for.
        turns: i64,
    },
    /// A translation or scale value is NaN or infinite.
    #[error("{track}: value of key {key} is not finite ({value:?})")]
    NonFiniteValue {
        /// The track, by index and name.
        track: TrackId,
        /// The key's index in the track.
        key: usize,
        /// The value given.
        value: [f64; 3],
    },
    /// `tangents = given` on a vector channel, which has no per-key velocities.
    #[error(
        "{track}: tangents = given needs per-key velocities, which translation and scale channels do not carry; \
        use catmull-rom or zero"
    )]
    VectorTangents {
        /// The track, by index and name.
        track: TrackId,
    },
    /// `--loop` with a family that cannot loop.
    #[error("{track}: {curve} cannot loop; the curves that loop are {looping}")]
    LoopUnsupported {
        /// The track, by index and name.
        track: TrackId,
        /// The curve as messages name it.
        curve: String,
        /// The curves that loop.
        looping: String,
    },
    /// A looping track whose last key is not its first rotation.
    #[error("{track}: a looping track must end on its first rotation, but key {last} is {} rad from key 0 (at most \
        {} allowed)", Number(*.angle), Number(*.tolerance))]
    LoopNotClosed {
        /// The track, by index and name.
        track: TrackId,
        /// The last key's index.
        last: usize,
        /// Angle between the last key and the first (rad).
        angle: f64,
        /// The most the rule allows.
        tolerance: f64,
    },
    /// The `bspline-interp` solve did not reach its key tolerance.
    #[error(
        "{track}: bspline-interp did not converge after {iterations} Newton iterations: the curve misses key \
         {key} by {} (at most {} rad allowed); keys this far apart have no stable C2 interpolant, try hermite",
        Number(*.error),
        Number(*.tolerance)
    )]
    NoConvergence {
        /// The track, by index and name.
        track: TrackId,
        /// The key the curve misses most.
        key: usize,
        /// The worst key's error (rad).
        error: f64,
        /// Newton iterations run.
        iterations: usize,
        /// The most the rule allows.
        tolerance: f64,
    },
    /// A sample time is NaN or infinite.
    #[error("{track}: sample time {sample} is not finite ({value})")]
    NonFiniteSampleTime {
        /// The track, by index and name.
        track: TrackId,
        /// The sample's index.
        sample: usize,
        /// The value given.
        value: f64,
    },
    /// A sampling request that cannot produce samples.
    #[error(transparent)]
    BadSampling(#[from] SamplingError),
    /// Output buffers or per-track sample lists do not match the batch.
    #[error(transparent)]
    BadJob(#[from] JobError),
}

/// Why a sampling request (`Sampling::Count`, `Sampling::Rate`) gives no samples.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SamplingError {
    /// `Count(0)`.
    #[error("a sample count must be at least 1")]
    ZeroCount,
    /// A count above the per-track limit.
    #[error("{count} samples is more than {limit} per track")]
    TooMany {
        /// The count asked for.
        count: usize,
        /// The most allowed.
        limit: usize,
    },
    /// A rate that is not finite and positive.
    #[error("a sample rate must be a positive number of samples per second, got {0}")]
    BadRate(f64),
    /// A rate that gives more samples over the domain than the per-track limit.
    #[error("a rate of {hz} Hz gives {count} samples over a domain of {span}, more than {limit} per track")]
    RateTooHigh {
        /// The rate asked for.
        hz: f64,
        /// The samples it gives.
        count: f64,
        /// The domain's length.
        span: f64,
        /// The most allowed.
        limit: usize,
    },
}

/// Why an evaluation job's parts do not fit together.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum JobError {
    /// The sample times were made for another batch.
    #[error("sample times cover {times} tracks but the batch has {batch}")]
    TrackCount {
        /// Tracks the sample times cover.
        times: usize,
        /// Tracks of the batch.
        batch: usize,
    },
    /// A looping track's uniform grid leaves its period (fast paths do not wrap grids).
    #[error(
        "{track}: a looping track's uniform sample times must stay within its period [{lo}, {hi}]; give other \
        times as an explicit list (SampleTimes::new wraps them)"
    )]
    GridOutsidePeriod {
        /// The track, by index and name.
        track: TrackId,
        /// Start of the period.
        lo: f64,
        /// End of the period.
        hi: f64,
    },
    /// Tracks with different sample counts where one array holds them all (a frame-major
    /// layout, an `.npy` file, a numpy array): `needed_by` says which.
    #[error("{needed_by} needs the same sample count in every track: {first} has {count}, {other} has {other_count}")]
    UnequalCounts {
        /// The first track.
        first: TrackId,
        /// Its sample count.
        count: usize,
        /// The first track with another count.
        other: TrackId,
        /// That track's sample count.
        other_count: usize,
        /// What needs one count.
        needed_by: &'static str,
    },
    /// A grid given as a list (`SampleTimes::per_track`).
    #[error("{track}: a sample grid must be uniform")]
    GridNotUniform {
        /// The track, by index and name.
        track: TrackId,
    },
    /// A caller's output buffer of the wrong size.
    #[error("output buffer holds {floats} floats but {samples} samples x {channels} channels are needed")]
    BufferSize {
        /// Floats the buffer holds.
        floats: usize,
        /// Samples the job writes.
        samples: usize,
        /// Floats per sample.
        channels: usize,
    },
}

/// Short-hand result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::Number;

    #[test]
    fn numbers_read_naturally() {
        let cases = [
            (0.0, "0"),
            (0.25, "0.25"),
            (1.0, "1"),
            (1234.0, "1234"),
            (12.345678, "12.35"),
            (-0.0123456, "-0.01235"),
            (3.1717e-7, "3.172e-7"),
            (1e-6, "1e-6"),
            (1.5e-12, "1.5e-12"),
            (2.5e9, "2.5e9"),
            (f64::NAN, "NaN"),
        ];
        for (x, text) in cases {
            assert_eq!(Number(x).to_string(), text, "{x}");
        }
    }
}
