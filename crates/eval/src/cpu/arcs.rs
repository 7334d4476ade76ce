//! Squad and Nam-Kim rotations, eight samples at a time. Both are two great arcs followed at
//! the same parameter and a geodesic between the two points (Peisa's squad: `slerp(slerp(q_i,
//! q_i+1, h), slerp(s_i, s_i+1, h), 2h(1 - h))`; NK eq. 4-5: `C_1(s)` from `q_i`, `C_2(s)` from
//! `q_i+1`, blended by `f(s)`). Each segment's arcs are fixed, so they are set up once per
//! piece in f64; per sample this leaves two `sin_cos`, one log (an `atan2`) and one exp.
//!
//! Values only: derivatives keep the reference's jets, per sample (see [`super::track`]).

use super::lanes::{write_columns, LANES, Q8};
use super::simd::{Isa, Lanes};
use crate::batch::TrackView;
use crate::sampling::SampleTimes;
use quatcurve_core::curve::{Blend, Curve};
use quatcurve_core::quat::{QuatF64, Vec3F64};
use quatcurve_core::segment::locate;

/// The great arc `start * exp(x v)`, written `cos(x theta) start + sin(x theta) lead` with
/// `lead = start * (axis, 0)`: no quaternion product per sample.
#[derive(Clone, Copy, Debug, Default)]
struct Arc {
    start: [f32; 4],
    lead: [f32; 4],
    theta: f32,
}

impl Arc {
    /// The arc from `start` along the half-angle vector `v`.
    fn new(start: QuatF64, v: Vec3F64) -> Self {
        let theta = v.length();
        let axis = if theta > 0.0 { v.scale(1.0 / theta) } else { Vec3F64::new(0.0, 0.0, 0.0) };
        let lead = start * QuatF64::from_xyzw(axis.x, axis.y, axis.z, 0.0);
        let f = |q: QuatF64| q.to_array().map(|c| c as f32);
        Self { start: f(start), lead: f(lead), theta: theta as f32 }
    }

    /// The unfolded geodesic from `a` to `b` (parameter 0 to 1), as the reference's.
    fn between(a: QuatF64, b: QuatF64) -> Self {
        Self::new(a, (a.conjugate() * b).log())
    }
}

/// Eight lanes of one [`Arc`] (the same arc broadcast, or gathered per lane).
struct Arc8<S> {
    start: Q8<S>,
    lead: Q8<S>,
    theta: S,
}

impl<S: Lanes> Arc8<S> {
    #[inline(always)]
    fn gather(arcs: &[Arc; LANES]) -> Self {
        Self {
            start: Q8::gather(&arcs.map(|a| a.start)),
            lead: Q8::gather(&arcs.map(|a| a.lead)),
            theta: S::new(arcs.map(|a| a.theta)),
        }
    }

    #[inline(always)]
    fn splat(a: &Arc) -> Self {
        Self { start: Q8::splat(a.start), lead: Q8::splat(a.lead), theta: S::splat(a.theta) }
    }

    /// The point at parameter `x`.
    #[inline(always)]
    fn at(&self, x: S) -> Q8<S> {
        let (sin, cos) = (x * self.theta).sin_cos();
        self.start.along(self.lead, sin, cos)
    }
}

/// `p * exp(g log(p^-1 q))`, as the reference's `geodesic`: past the middle from the other
/// end, `q * exp((1 - g) log(q^-1 p))`, and about the `x` axis where the log has no axis
/// (`p^-1 q = (-1, 0, 0, 0)` exactly).
#[inline(always)]
fn geodesic<S: Lanes>(p: Q8<S>, q: Q8<S>, g: S) -> Q8<S> {
    let flip = g.cmp_gt(S::splat(0.5));
    #[inline(always)]
    fn pick<S: Lanes>(flip: S, a: Q8<S>, b: Q8<S>) -> Q8<S> {
        Q8 { x: flip.blend(b.x, a.x), y: flip.blend(b.y, a.y), z: flip.blend(b.z, a.z), w: flip.blend(b.w, a.w) }
    }
    let (p, q, g) = (pick(flip, p, q), pick(flip, q, p), flip.blend(S::ONE - g, g));
    let r = p.conjugate() * q;
    let n = (r.x * r.x + r.y * r.y + r.z * r.z).sqrt();
    let angle = n.atan2(r.w);
    let (sin, cos) = (g * angle).sin_cos();
    let some = n.cmp_gt(S::ZERO);
    let k = some.blend(sin / n, S::ZERO);
    let x_axis = r.w.cmp_lt(S::ZERO) & !some & S::ONE;
    p * Q8 { x: r.x.mul_add(k, x_axis * sin), y: r.y * k, z: r.z * k, w: cos }
}

/// Each segment's two arcs, for one track.
fn segment_arcs(view: TrackView<'_>) -> Vec<[Arc; 2]> {
    let (points, coefs) = (view.points, view.coefs);
    let vec = |c: [f64; 4]| Vec3F64::new(c[0], c[1], c[2]);
    (0..points.len() - 1)
        .map(|i| match view.track.curve() {
            Curve::Squad => [
                Arc::between(points[i], points[i + 1]),
                Arc::between(QuatF64::from_array(coefs[i]), QuatF64::from_array(coefs[i + 1])),
            ],
            // C_2(s) = q_i+1 exp(b (s - 1)): the second arc is followed at s - 1.
            _ => [Arc::new(points[i], vec(coefs[2 * i])), Arc::new(points[i + 1], vec(coefs[2 * i + 1]))],
        })
        .collect()
}

/// Writes the rotations of samples `from..from + n` of squad or Nam-Kim track `index` into
/// `out` (rows of `channels` floats, rotation first).
#[allow(clippy::too_many_arguments)]
pub fn evaluate(
    isa: Isa,
    view: TrackView<'_>,
    times: &SampleTimes,
    index: usize,
    from: usize,
    n: usize,
    channels: usize,
    out: &mut [f32],
) {
    match isa {
        // SAFETY: `Isa::Avx2` is only chosen where the CPU has AVX2 and FMA.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { evaluate_avx2(view, times, index, from, n, channels, out) },
        _ => evaluate_lanes::<wide::f32x8>(view, times, index, from, n, channels, out),
    }
}

/// [`evaluate_lanes`] on AVX2 registers, compiled for them.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn evaluate_avx2(
    view: TrackView<'_>,
    times: &SampleTimes,
    index: usize,
    from: usize,
    n: usize,
    channels: usize,
    out: &mut [f32],
) {
    evaluate_lanes::<super::simd::Avx2>(view, times, index, from, n, channels, out);
}

/// [`evaluate`] on lanes of type `S`.
#[inline(always)]
fn evaluate_lanes<S: Lanes>(
    view: TrackView<'_>,
    times: &SampleTimes,
    index: usize,
    from: usize,
    n: usize,
    channels: usize,
    out: &mut [f32],
) {
    let knots = view.knots;
    let last = knots.len() - 2;
    let arcs = segment_arcs(view);
    let (squad, blend) = (view.track.curve() == Curve::Squad, view.track.blend());
    let second_offset = S::splat(if squad { 0.0 } else { 1.0 });
    let mut hint = 0;
    for g in (0..n).step_by(LANES) {
        let valid = LANES.min(n - g);
        let (mut spans, mut h) = ([0usize; LANES], [0.0f32; LANES]);
        for lane in 0..LANES {
            // Lanes past the end repeat the last sample and are not written.
            let t = times.time(index, from + g + lane.min(valid - 1));
            let (span, t) = if knots[hint] <= t && t < knots[hint + 1] { (hint, t) } else { locate(knots, 0, last, t) };
            hint = span;
            spans[lane] = span;
            h[lane] = ((t - knots[span]) / (knots[span + 1] - knots[span])) as f32;
        }
        let h = S::new(h);
        let (first, second) = if spans.iter().all(|&s| s == spans[0]) {
            let [a, b] = &arcs[spans[0]];
            (Arc8::splat(a), Arc8::splat(b))
        } else {
            (Arc8::gather(&spans.map(|s| arcs[s][0])), Arc8::gather(&spans.map(|s| arcs[s][1])))
        };
        let weight = if squad { (h - h * h) * S::splat(2.0) } else { blend_weight(blend, h) };
        let q = geodesic(first.at(h), second.at(h - second_offset), weight);
        write_columns([q.x, q.y, q.z, q.w], &mut out[g * channels..(g + valid) * channels], channels, 0, 4, valid);
    }
}

/// Nam-Kim's blend ratio `f(s)`, as [`quatcurve_core::curve::Blend::ratio`].
#[inline(always)]
fn blend_weight<S: Lanes>(kind: Blend, s: S) -> S {
    match kind {
        Blend::Cubic => s * s * (S::splat(3.0) - s * S::splat(2.0)),
        Blend::Quadratic => {
            let r = s - S::ONE;
            s.cmp_le(S::splat(0.5)).blend(s * s * S::splat(2.0), S::ONE - r * r * S::splat(2.0))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{geodesic, Q8};
    use quatcurve_core::quat::QuatF64;
    use wide::f32x8;

    /// Where the log has no axis, the SIMD geodesic does what the reference's does: stays
    /// put between equal points, turns about x between exact opposites.
    #[test]
    fn geodesic_between_equal_and_opposite_points_follows_the_reference() {
        let p = QuatF64::from_xyzw(0.5, -0.5, 0.5, 0.5);
        for q in [p, p.mul_scalar(-1.0), QuatF64::from_xyzw(0.5, 0.5, -0.5, 0.5)] {
            for g in [0.0, 0.3, 0.5, 0.9] {
                let want = p.geodesic(q, g).to_array();
                let got = geodesic(
                    Q8::splat(p.to_array().map(|c| c as f32)),
                    Q8::splat(q.to_array().map(|c| c as f32)),
                    f32x8::splat(g as f32),
                );
                let got = [got.x, got.y, got.z, got.w].map(|c| f64::from(c.to_array()[0]));
                for (w, g) in want.iter().zip(got) {
                    assert!((w - g).abs() < 1e-6, "p={p:?} q={q:?}: want {want:?}, got {got:?}");
                }
            }
        }
    }
}
