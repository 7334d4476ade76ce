//! How smooth a curve is and how much effort it asks of a rigid body (DESIGN section 14):
//! energy `integral |alpha|^2 dt`, torque energy `integral |tau|^2 dt` with the body torque
//! `tau = I alpha + omega x (I omega)` (Euler's equations, body frame), peak rates, arc length
//! and the jump of alpha at the curve's joints.
//!
//! Everything comes from the exact derivatives any [`Device`] returns, sampled at the nodes of
//! composite Simpson rules laid **per span** (between consecutive knots): a C1 curve's alpha
//! jumps at its joints, and a Simpson rule straddling a jump would be first-order accurate
//! instead of fourth. Each span's last node sits just inside the span (its left limit) and the
//! next span's first node on the knot (its right limit), so the same samples give both the
//! integrals and the jumps.
//!
//! [`paper`] reruns KKS section 6.1's torque comparison on random key sequences;
//! [`vertex_error`] measures how far a lossy motion is from its source, as ACL does.

pub mod paper;
pub mod vertex_error;

use quatcurve_device::{Device, DeviceError};
use quatcurve_eval::batch::{Batch, TrackView};
use quatcurve_eval::error::Number;
use quatcurve_eval::job::EvalJob;
use quatcurve_eval::output::Output;
use quatcurve_eval::sampling::{PerTrack, SampleTimes};

/// Simpson steps per span when no step is given: 1/1000 of the shortest span.
pub const DEFAULT_STEPS_PER_SPAN: f64 = 1000.0;
/// The default step is never finer than the domain over this many steps, so one very short
/// span does not multiply the work of a long track.
pub const MAX_DEFAULT_STEPS: f64 = 1e6;
/// At most this many nodes per track: a guard against `--step 1e-12`.
pub const MAX_NODES_PER_TRACK: usize = 50_000_000;
/// Nodes evaluated at once: bounds the memory of a large analysis (about 80 bytes per node).
const NODES_PER_PIECE: usize = 1 << 22;

/// What to measure with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnalysisOptions {
    /// Principal moments of inertia `[Ixx, Iyy, Izz]` in the body frame (all 1: the torque is
    /// the angular acceleration).
    pub inertia: [f64; 3],
    /// Simpson step in time units; `None`: 1/1000 of each track's shortest span, and no finer
    /// than its domain over 10^6.
    pub step: Option<f64>,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        Self { inertia: [1.0; 3], step: None }
    }
}

/// Why an analysis could not run.
#[derive(Debug, thiserror::Error)]
pub enum AnalysisError {
    /// An inertia moment that is not a finite positive number.
    #[error("inertia moments must be finite and positive, got {0:?}")]
    BadInertia([f64; 3]),
    /// A step that is not a finite positive number.
    #[error("the integration step must be a finite positive time, got {0}")]
    BadStep(f64),
    /// The step asks for more than [`MAX_NODES_PER_TRACK`] samples of one track.
    #[error("{track}: a step of {} s needs {nodes} samples over its domain, more than {MAX_NODES_PER_TRACK}; give a \
        larger step", Number(*.step))]
    TooManyNodes {
        /// The track, as messages name it.
        track: String,
        /// The step asked for.
        step: f64,
        /// Samples it would need.
        nodes: usize,
    },
    /// The tracks or sample times break a rule of the builder (named track and key).
    #[error(transparent)]
    Keys(#[from] quatcurve_eval::error::Error),
    /// The device rejected the job or failed.
    #[error(transparent)]
    Device(#[from] DeviceError),
}

/// One curve's figures over one track (or totals over many: [`Metrics::total`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Metrics {
    /// `integral |alpha|^2 dt` (rad^2 / s^3).
    pub energy: f64,
    /// `integral |tau|^2 dt` with `tau = I alpha + omega x (I omega)`.
    pub torque_energy: f64,
    /// Largest `|omega|` (rad/s).
    pub max_omega: f64,
    /// Largest `|alpha|` (rad/s^2).
    pub max_alpha: f64,
    /// `integral |omega| dt`: the angle turned through (rad).
    pub arc_length: f64,
    /// Largest `|alpha(t+) - alpha(t-)|` over the joints inside the domain and, for a looping
    /// track, its seam; 0 for a C2 curve.
    pub alpha_jump: f64,
    /// Largest `|omega(t+) - omega(t-)|` likewise; 0 for a C1 curve. Where it is not 0 (slerp)
    /// alpha holds an impulse at the joint that no energy integral counts.
    pub omega_jump: f64,
}

impl Metrics {
    /// Totals over tracks: integrals add, maxima take the largest.
    #[must_use]
    pub fn total<'a>(items: impl IntoIterator<Item = &'a Metrics>) -> Metrics {
        items.into_iter().fold(Metrics::default(), |a, m| Metrics {
            energy: a.energy + m.energy,
            torque_energy: a.torque_energy + m.torque_energy,
            max_omega: a.max_omega.max(m.max_omega),
            max_alpha: a.max_alpha.max(m.max_alpha),
            arc_length: a.arc_length + m.arc_length,
            alpha_jump: a.alpha_jump.max(m.alpha_jump),
            omega_jump: a.omega_jump.max(m.omega_jump),
        })
    }
}

/// One span's Simpson nodes: `steps + 1` nodes from `first` on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// Index of the span's first node in [`Nodes::times`].
    pub first: usize,
    /// Number of Simpson steps (even, at least 2).
    pub steps: usize,
    /// The span's length in time.
    pub length: f64,
}

/// Where one track is sampled: the spans between its knots and their Simpson nodes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Nodes {
    /// Node times, span after span; each span's last node just inside it.
    pub times: Vec<f64>,
    /// The spans, in time order.
    pub spans: Vec<Span>,
    /// Whether the track loops (its seam counts as a joint).
    pub looping: bool,
}

/// The distinct knot values in a track's domain, both ends included: the joints where
/// continuity may break (the key times for every family through keys).
#[must_use]
pub fn joints(view: TrackView<'_>) -> Vec<f64> {
    let [lo, hi] = view.track.domain();
    let mut out: Vec<f64> = vec![lo];
    out.extend(view.knots.iter().copied().filter(|&k| k > lo && k < hi));
    out.push(hi);
    out.dedup();
    out
}

/// The Simpson nodes of one track for `step` (see [`AnalysisOptions::step`]).
///
/// # Errors
/// [`AnalysisError::BadStep`], [`AnalysisError::TooManyNodes`].
pub fn nodes(view: TrackView<'_>, name: &str, step: Option<f64>) -> Result<Nodes, AnalysisError> {
    let joints = joints(view);
    let [lo, hi] = view.track.domain();
    let step = match step {
        Some(s) if !(s.is_finite() && s > 0.0) => return Err(AnalysisError::BadStep(s)),
        Some(s) => s,
        None => {
            let shortest = joints.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min);
            (shortest / DEFAULT_STEPS_PER_SPAN).max((hi - lo) / MAX_DEFAULT_STEPS)
        }
    };
    // Even, at least 2; counted in f64 so that an absurd step cannot overflow.
    let steps_f = |length: f64| 2.0 * (0.5 * (length / step)).ceil().max(1.0);
    let total: f64 = joints.windows(2).map(|w| steps_f(w[1] - w[0]) + 1.0).sum();
    if total > MAX_NODES_PER_TRACK as f64 {
        return Err(AnalysisError::TooManyNodes {
            track: name.to_string(),
            step,
            nodes: total.min(usize::MAX as f64) as usize,
        });
    }
    let steps_of = |length: f64| steps_f(length) as usize;
    let mut out = Nodes {
        times: Vec::with_capacity(total as usize),
        spans: Vec::with_capacity(joints.len()),
        looping: view.track.looping(),
    };
    for w in joints.windows(2) {
        let (a, b) = (w[0], w[1]);
        let length = b - a;
        let steps = steps_of(length);
        out.spans.push(Span { first: out.times.len(), steps, length });
        out.times.extend((0..steps).map(|j| a + length * j as f64 / steps as f64));
        out.times.push(b - left_limit_offset(b, length));
    }
    Ok(out)
}

/// How far inside a span its last node sits: close enough that alpha there is the span's left
/// limit to ~1e-9 relative, far enough that every device resolves it as before the knot
/// (the GPU reads times in 32.32 fixed point, 2^-32 s).
fn left_limit_offset(end: f64, length: f64) -> f64 {
    (f64::from(2.0f32.powi(-30)) * end.abs().max(1.0)).min(1e-6 * length)
}

/// The figures of one track from its derivatives at `nodes` (`omega[i]`, `alpha[i]` at
/// `nodes.times[i]`).
#[must_use]
pub fn measure(nodes: &Nodes, omega: &[[f64; 3]], alpha: &[[f64; 3]], inertia: [f64; 3]) -> Metrics {
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let torque = |w: [f64; 3], a: [f64; 3]| {
        let iw = [inertia[0] * w[0], inertia[1] * w[1], inertia[2] * w[2]];
        let gyro = [w[1] * iw[2] - w[2] * iw[1], w[2] * iw[0] - w[0] * iw[2], w[0] * iw[1] - w[1] * iw[0]];
        [inertia[0] * a[0] + gyro[0], inertia[1] * a[1] + gyro[1], inertia[2] * a[2] + gyro[2]]
    };
    let mut m = Metrics::default();
    for span in &nodes.spans {
        let h = span.length / span.steps as f64;
        let simpson = |f: &dyn Fn(usize) -> f64| {
            let inner: f64 = (1..span.steps).map(|j| if j % 2 == 1 { 4.0 } else { 2.0 } * f(span.first + j)).sum();
            h / 3.0 * (f(span.first) + inner + f(span.first + span.steps))
        };
        m.energy += simpson(&|i| norm(alpha[i]).powi(2));
        m.torque_energy += simpson(&|i| norm(torque(omega[i], alpha[i])).powi(2));
        m.arc_length += simpson(&|i| norm(omega[i]));
    }
    for i in 0..nodes.times.len() {
        m.max_omega = m.max_omega.max(norm(omega[i]));
        m.max_alpha = m.max_alpha.max(norm(alpha[i]));
    }
    let jump = |v: &[[f64; 3]], after: usize, before: usize| norm(std::array::from_fn(|c| v[after][c] - v[before][c]));
    let mut joint = |after: usize, before: usize| {
        m.alpha_jump = m.alpha_jump.max(jump(alpha, after, before));
        m.omega_jump = m.omega_jump.max(jump(omega, after, before));
    };
    for pair in nodes.spans.windows(2) {
        joint(pair[1].first, pair[0].first + pair[0].steps);
    }
    if let (true, Some(first), Some(last)) = (nodes.looping, nodes.spans.first(), nodes.spans.last()) {
        joint(first.first, last.first + last.steps);
    }
    m
}

/// Checks the options before any work.
///
/// # Errors
/// [`AnalysisError::BadInertia`], [`AnalysisError::BadStep`].
pub fn validate(options: &AnalysisOptions) -> Result<(), AnalysisError> {
    if !options.inertia.iter().all(|&i| i.is_finite() && i > 0.0) {
        return Err(AnalysisError::BadInertia(options.inertia));
    }
    match options.step {
        Some(s) if !(s.is_finite() && s > 0.0) => Err(AnalysisError::BadStep(s)),
        _ => Ok(()),
    }
}

/// The figures of every track of `batch`, from derivatives evaluated on `device` (in pieces
/// of bounded memory).
///
/// # Errors
/// The options' errors, [`AnalysisError::TooManyNodes`], and the device's.
pub fn analyze(batch: &Batch, device: &Device, options: &AnalysisOptions) -> Result<Vec<Metrics>, AnalysisError> {
    validate(options)?;
    let nodes = (0..batch.len())
        .map(|i| nodes(batch.view(i), &batch.id(i).to_string(), options.step))
        .collect::<Result<Vec<_>, _>>()?;
    let mut out = Vec::with_capacity(batch.len());
    let mut start = 0;
    while start < batch.len() {
        let mut end = start + 1;
        let mut count = nodes[start].times.len();
        while end < batch.len() && count + nodes[end].times.len() <= NODES_PER_PIECE {
            count += nodes[end].times.len();
            end += 1;
        }
        let piece = &nodes[start..end];
        let sampled = derivatives_at(&batch.subset(start..end), piece, device)?;
        let mut offset = 0;
        for n in piece {
            let len = n.times.len();
            let (omega, alpha) =
                (&sampled.angular_velocity[offset..offset + len], &sampled.angular_acceleration[offset..offset + len]);
            out.push(measure(n, omega, alpha, options.inertia));
            offset += len;
        }
        start = end;
    }
    Ok(out)
}

/// `|omega|` and `|alpha|` of track `index` at about `points` times over its domain, both
/// sides of every joint included (a jump shows as a vertical step): `(times, |omega|,
/// |alpha|)`, for plots.
///
/// # Errors
/// The device's.
pub fn profile(batch: &Batch, index: usize, device: &Device, points: usize) -> Result<[Vec<f64>; 3], AnalysisError> {
    let view = batch.view(index);
    let [lo, hi] = view.track.domain();
    let nodes = nodes(view, &batch.id(index).to_string(), Some((hi - lo) / points.max(2) as f64))?;
    let sampled = derivatives_at(&batch.subset(index..index + 1), std::slice::from_ref(&nodes), device)?;
    let norm = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    Ok([
        nodes.times,
        sampled.angular_velocity.iter().map(norm).collect(),
        sampled.angular_acceleration.iter().map(norm).collect(),
    ])
}

/// Rotations and derivatives of `batch`'s tracks at their nodes, track after track.
fn derivatives_at(batch: &Batch, nodes: &[Nodes], device: &Device) -> Result<Output, AnalysisError> {
    let times = SampleTimes::per_track(batch, |i, _| Ok(PerTrack::List(&nodes[i].times)))?;
    let job = EvalJob::new(batch, &times).derivatives(true);
    Ok(device.evaluate(&job)?)
}
