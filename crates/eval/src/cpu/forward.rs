//! Nam & Kim's forward-difference generator (NK section 3) for uniformly sampled slerp and
//! Nam-Kim tracks: a great arc `q exp(j v)` is produced by two additions per component,
//! `q_{j+1} = q_j + d_j`, `d_{j+1} = d_j - sigma q_{j+1}` with `sigma = 2 (1 - cos |v|)`,
//! instead of a `sin_cos` and a quaternion product per sample. Slerp is one arc; Nam-Kim
//! blends two and still pays a log and an exp per sample for the blend.
//!
//! In f32 the recurrence drifts (its error grows with the step count), so every
//! `reseed` steps, and at every segment start, the arcs are seeded again from a direct f64
//! evaluation. Values only: derivative requests take the direct path.

use crate::batch::TrackView;
use crate::job::JobOptions;
use crate::sampling::{SampleTimes, TrackTimes};
use glam::{Quat, Vec4};
use quatcurve_core::curve::Curve;
use quatcurve_core::quat::{QuatF64, Vec3F64};
use quatcurve_core::segment::locate;
use std::ops::Range;

/// Whether track `index` can use the generator: slerp or Nam-Kim, uniform times, no
/// derivatives.
#[must_use]
pub fn applies(view: TrackView<'_>, times: &SampleTimes, index: usize, options: &JobOptions) -> bool {
    matches!(view.track.curve(), Curve::Slerp | Curve::NamKim)
        && matches!(times.tracks()[index], TrackTimes::Uniform { .. })
        && !options.derivatives
        && options.forward_difference.is_some()
}

/// One great arc under the recurrence.
struct Arc {
    q: Vec4,
    d: Vec4,
    sigma: f32,
}

impl Arc {
    /// Starts at `q` with step `v` (half-angle vector per sample), seeded in f64.
    fn seed(q: QuatF64, v: Vec3F64) -> Self {
        let next = q * QuatF64::exp(v);
        let half = 0.5 * v.length();
        // 2 (1 - cos |v|) written 4 sin^2(|v| / 2): no cancellation for small steps.
        let sigma = (4.0 * half.sin() * half.sin()) as f32;
        // The difference is taken in f64: rounding both ends to f32 first would leave d with
        // the absolute error of a unit quaternion, a large relative error for small steps.
        let f = |q: QuatF64| Vec4::from_array(q.to_array().map(|c| c as f32));
        Self { q: f(q), d: f(next - q), sigma }
    }

    fn step(&mut self) {
        self.q += self.d;
        self.d -= self.sigma * self.q;
    }

    fn value(&self) -> Quat {
        Quat::from_vec4(self.q).normalize()
    }
}

/// The unfolded geodesic from `a` to `b` at `h`, from the nearer end (as the reference).
fn geodesic(a: Quat, b: Quat, h: f32) -> Quat {
    let (from, to, h) = if h <= 0.5 { (a, b, h) } else { (b, a, 1.0 - h) };
    let rel = from.conjugate() * to;
    let s = rel.xyz().length();
    if s == 0.0 {
        return from;
    }
    let theta = s.atan2(rel.w);
    let (sin, cos) = (h * theta).sin_cos();
    from * Quat::from_vec4((rel.xyz() * (sin / s)).extend(cos))
}

/// Samples `range` of track `index` into `out`'s rows.
pub fn evaluate(
    view: TrackView<'_>,
    times: &SampleTimes,
    index: usize,
    range: Range<usize>,
    options: &JobOptions,
    out: &mut [f32],
) {
    let layout = options.row();
    let TrackTimes::Uniform { step, count, .. } = times.tracks()[index] else { return };
    let reseed = options.forward_difference.unwrap_or(usize::MAX).max(1);
    let knots = view.knots;
    let coef = |c: [f64; 4]| Vec3F64::new(c[0], c[1], c[2]);
    let (mut segment, mut since, mut s, mut h) = (usize::MAX, 0, 0.0f64, 0.0f64);
    let mut arcs: Vec<Arc> = Vec::with_capacity(2);
    for (row, j) in out.chunks_exact_mut(layout.channels()).zip(range) {
        let t = times.time(index, j);
        let (i, clamped) = locate(knots, 0, knots.len() - 2, t);
        // Seed at segment changes, every `reseed` steps, where clamping or the exact last
        // sample breaks the uniform step, and where the next step would leave the segment.
        if i != segment || since >= reseed || clamped != t || j + 1 == count {
            let len = knots[i + 1] - knots[i];
            (segment, since, s, h) = (i, 0, (clamped - knots[i]) / len, step / len);
            arcs.clear();
            match view.track.curve() {
                Curve::Slerp => {
                    let w = coef(view.coefs[i]);
                    arcs.push(Arc::seed(view.points[i] * QuatF64::exp(w.scale(s)), w.scale(h)));
                }
                _ => {
                    let (a, b) = (coef(view.coefs[2 * i]), coef(view.coefs[2 * i + 1]));
                    arcs.push(Arc::seed(view.points[i] * QuatF64::exp(a.scale(s)), a.scale(h)));
                    arcs.push(Arc::seed(view.points[i + 1] * QuatF64::exp(b.scale(s - 1.0)), b.scale(h)));
                }
            }
        } else {
            arcs.iter_mut().for_each(Arc::step);
            since += 1;
            s += h;
        }
        let q = match view.track.curve() {
            Curve::Slerp => arcs[0].value(),
            _ => geodesic(arcs[0].value(), arcs[1].value(), view.track.blend().ratio(s) as f32),
        };
        layout.write(row, q.to_array(), [0.0; 3], [0.0; 3]);
    }
}
