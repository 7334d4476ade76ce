//! What the GPU and CPU accuracy tests share: DESIGN section 18's bars, the comparison with
//! the reference, and batch generators within the bars' domain. Included by path.

use crate::common::*;
use quatcurve::FloatOutput;
use quatcurve::{
    Batch, BatchBuilder, Curve, CurveSpec, EvalJob, KnotMode, Layout, QuatF64, SampleTimes, Sampling, Track, Vec3F64,
};

/// DESIGN section 18: rotation error bar (rad) and derivative relative error bar.
pub const ROTATION_BAR: f64 = 1e-5;
pub const DERIVATIVE_BAR: f64 = 1e-4;

/// Worst errors of a fast path vs reference, with where they happened.
#[derive(Debug, Default)]
pub struct Worst {
    pub rotation: (f64, String),
    pub derivative: (f64, String),
}

impl Worst {
    pub fn merge(&mut self, other: Worst) {
        if other.rotation.0 > self.rotation.0 {
            self.rotation = other.rotation;
        }
        if other.derivative.0 > self.derivative.0 {
            self.derivative = other.derivative;
        }
    }

    pub fn assert_within_bars(&self, what: &str) {
        eprintln!(
            "{what}: worst rotation {:.2e} rad at {}; worst derivative {:.2e} at {}",
            self.rotation.0, self.rotation.1, self.derivative.0, self.derivative.1
        );
        assert!(self.rotation.0 <= ROTATION_BAR, "{what}: rotation {:?}", self.rotation);
        assert!(self.derivative.0 <= DERIVATIVE_BAR, "{what}: derivative {:?}", self.derivative);
    }
}

/// Nam-Kim's blend runs along the unfolded geodesic from C1(s) to C2(s); where those are
/// nearly antipodal (the same rotation with opposite sign) the blend is a near-full turn about
/// an ill-defined axis, and its derivatives are ill-conditioned in any precision. DESIGN
/// section 6 excludes the analogous key pairs; this is the same exclusion for the blend:
/// `1 + dot(C1, C2) >= 1.25e-3` (blend half-angle at most pi - 0.05).
pub const BLEND_ANTIPODE_MARGIN: f64 = 1.25e-3;

/// `1 + dot(C1(s), C2(s))` at time `t` of a Nam-Kim track (f64), or infinity for others.
fn blend_margin(batch: &Batch, track: usize, t: f64) -> f64 {
    let view = batch.view(track);
    if view.track.curve() != Curve::NamKim {
        return f64::INFINITY;
    }
    let k = view.knots;
    let t = t.clamp(k[0], k[k.len() - 1]);
    let i = (0..k.len() - 1).rev().find(|&i| k[i] <= t).unwrap_or(0).min(k.len() - 2);
    let u = (t - k[i]) / (k[i + 1] - k[i]);
    let v = |c: [f64; 4]| Vec3F64::new(c[0], c[1], c[2]);
    let c1 = view.points[i] * QuatF64::exp(v(view.coefs[2 * i]).scale(u));
    let c2 = view.points[i + 1] * QuatF64::exp(v(view.coefs[2 * i + 1]).scale(u - 1.0));
    1.0 + c1.dot(c2)
}

/// (track, sample) of an output slot.
fn slot_sample(times: &SampleTimes, layout: Layout, slot: usize) -> (usize, usize) {
    match layout {
        Layout::Track => {
            let track = times.offsets().partition_point(|&o| o <= slot) - 1;
            (track, slot - times.offsets()[track])
        }
        Layout::Frame => (slot % times.track_count(), slot / times.track_count()),
    }
}

/// Samples left out of the bars by [`BLEND_ANTIPODE_MARGIN`], over the whole test run.
pub static EXCLUDED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Compares a fast path's output for `batch` at `times` (in `layout`) with the reference
/// and returns the worst differences.
pub fn compare_output(
    out: &FloatOutput,
    batch: &Batch,
    times: &SampleTimes,
    layout: Layout,
    derivatives: bool,
    label: &str,
) -> Worst {
    let reference = EvalJob::new(batch, times).layout(layout).derivatives(derivatives).run().unwrap();
    let out = out.to_output(derivatives);
    assert_eq!(out.rotations.len(), reference.rotations.len(), "{label}");
    let mut worst = Worst::default();
    for i in 0..out.rotations.len() {
        let (track, j) = slot_sample(times, layout, i);
        if blend_margin(batch, track, times.time(track, j)) < BLEND_ANTIPODE_MARGIN {
            EXCLUDED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            continue;
        }
        let rot = QuatF64::from_array(out.rotations[i]).angle_to(QuatF64::from_array(reference.rotations[i]));
        if rot > worst.rotation.0 || rot.is_nan() {
            worst.rotation = (if rot.is_nan() { f64::INFINITY } else { rot }, format!("{label} slot {i}"));
        }
        if derivatives {
            let a = Vec3F64::from_array;
            let der = rel_err(a(out.angular_velocity[i]), a(reference.angular_velocity[i]))
                .max(rel_err(a(out.angular_acceleration[i]), a(reference.angular_acceleration[i])));
            if der > worst.derivative.0 || der.is_nan() {
                worst.derivative = (if der.is_nan() { f64::INFINITY } else { der }, format!("{label} slot {i}"));
            }
        }
    }
    worst
}

/// A track within DESIGN section 18's domain: consecutive key dots >= 1e-3 (the half-turn
/// choice is ill-conditioned below), velocities up to 20 rad/s.
pub fn accurate_track(g: &mut Gen, spec: &CurveSpec, count: usize, kind: Kind) -> Track {
    loop {
        let t = track(g, spec, count, kind);
        let keys: Vec<QuatF64> = t.rotations.iter().map(|&k| QuatF64::from_array(k).normalize()).collect();
        if keys.windows(2).all(|w| w[0].dot(w[1]).abs() >= 1e-3) {
            return t;
        }
    }
}

/// A batch of `tracks` tracks of different lengths for `spec`.
pub fn batch_for(seed: u64, spec: &CurveSpec, kind: Kind, tracks: usize) -> Batch {
    let mut g = Gen::new(seed);
    let mut builder = BatchBuilder::new();
    for i in 0..tracks {
        let extra = if spec.curve == Curve::Bezier { i % 4 } else { i % 6 };
        let t = accurate_track(&mut g, spec, spec.min_keys().max(2) + extra, kind);
        builder.add(&t, spec).unwrap();
    }
    builder.build().unwrap()
}

/// A fast path under test: evaluates a batch at its times in a layout, with or without
/// derivatives.
pub type Eval<'a> = &'a dyn Fn(&Batch, &SampleTimes, Layout, bool) -> FloatOutput;

/// Every spec x 4 kinds, on grids that do not line up with knots (where C0/C1 derivatives
/// jump): a rate of 29.97 Hz track-major, and 38 samples (37 intervals) frame-major; with and
/// without derivatives.
pub fn every_family_order_and_knot_mode(eval: Eval<'_>) -> Worst {
    let mut all = Worst::default();
    for (k, kind) in KINDS.into_iter().enumerate() {
        for spec in all_specs() {
            let batch = batch_for(17 + k as u64, &spec, kind, 5);
            let per_rate = SampleTimes::uniform(&batch, Sampling::Rate(29.97)).unwrap();
            let per_count = SampleTimes::uniform(&batch, Sampling::Count(38)).unwrap();
            for (times, layout) in [(&per_rate, Layout::Track), (&per_count, Layout::Frame)] {
                for derivatives in [false, true] {
                    let label = format!("{} {kind:?} {layout:?} derivatives={derivatives}", describe(&spec));
                    all.merge(compare_output(
                        &eval(&batch, times, layout, derivatives),
                        &batch,
                        times,
                        layout,
                        derivatives,
                        &label,
                    ));
                }
            }
        }
    }
    all
}

/// Every knot, the domain ends, and times outside the domain (clamped), for every spec.
pub fn samples_on_knots_and_domain_ends(eval: Eval<'_>) -> Worst {
    let mut all = Worst::default();
    for spec in all_specs() {
        let batch = batch_for(5, &spec, Kind::Random, 3);
        let overrides: Vec<Vec<f64>> = (0..batch.len())
            .map(|i| {
                let view = batch.view(i);
                let [lo, hi] = view.track.domain();
                let mut t: Vec<f64> = view.knots.to_vec();
                t.extend([lo, hi, lo - 1.0, hi + 2.5]);
                t
            })
            .collect();
        let refs: Vec<Option<&[f64]>> = overrides.iter().map(|t| Some(t.as_slice())).collect();
        let times = SampleTimes::new(&batch, &refs, Sampling::Count(2)).unwrap();
        all.merge(compare_output(
            &eval(&batch, &times, Layout::Track, true),
            &batch,
            &times,
            Layout::Track,
            true,
            &describe(&spec),
        ));
    }
    all
}

/// One batch of every spec with sign-flipped keys, explicit B-spline knots with an interior
/// knot of multiplicity k - 1.
pub fn mixed_batch_with_repeated_knots() -> (Batch, SampleTimes) {
    let mut g = Gen::new(99);
    let mut builder = BatchBuilder::new();
    for spec in all_specs() {
        let count = spec.min_keys().max(2) + 2;
        let mut t = accurate_track(&mut g, &spec, count, Kind::SignFlipped);
        if spec.knots == KnotMode::Explicit
            && matches!(spec.curve, Curve::BSpline | Curve::NormalizedBSpline)
            && spec.order >= 3
        {
            let k = spec.order;
            let mut knots = explicit_knots(&mut g, k, count);
            let mid = knots[k];
            for knot in knots.iter_mut().skip(k).take(k - 1) {
                *knot = mid;
            }
            for (i, knot) in knots.iter_mut().enumerate().skip(2 * k - 1) {
                *knot = knot.max(mid + 0.1 * (i + 2 - 2 * k) as f64);
            }
            t.knots = Some(knots);
        }
        builder.add(&t, &spec).unwrap();
    }
    let batch = builder.build().unwrap();
    let times = SampleTimes::uniform(&batch, Sampling::Rate(31.3)).unwrap();
    (batch, times)
}

/// B-splines only, of each order, knot mode and form given, several of each side by side: a
/// kernel specialized to the family (or to both forms) must still take each track's form,
/// order and knot spacing.
pub fn bspline_batch(orders: &[usize], knot_modes: &[KnotMode], forms: &[Curve]) -> (Batch, SampleTimes) {
    let mut g = Gen::new(7);
    let mut builder = BatchBuilder::new();
    for &order in orders {
        // Phantom knots exist for the cubic only.
        for &knots in knot_modes.iter().filter(|&&m| m != KnotMode::Phantom || order == 4) {
            for &curve in forms {
                let spec = CurveSpec { order, knots, ..CurveSpec::new(curve) };
                let t = accurate_track(&mut g, &spec, spec.min_keys().max(2) + 3, Kind::SignFlipped);
                builder.add(&t, &spec).unwrap();
            }
        }
    }
    let batch = builder.build().unwrap();
    // 97 intervals (a prime): no sample lands on an inner knot, where C0 and C1 curves'
    // derivatives jump and f32 times may pick either side.
    let times = SampleTimes::uniform(&batch, Sampling::Count(98)).unwrap();
    (batch, times)
}

/// Batch sizes and sample counts that are not multiples of a workgroup or SIMD width.
pub fn odd_sizes(eval: Eval<'_>) {
    let spec = CurveSpec::new(Curve::BSpline);
    for (tracks, samples) in [(1usize, 1usize), (1, 7), (1, 9), (1, 63), (1, 65), (3, 21), (7, 129), (13, 1)] {
        let batch = batch_for(tracks as u64, &spec, Kind::Random, tracks);
        let times = SampleTimes::uniform(&batch, Sampling::Count(samples)).unwrap();
        for layout in [Layout::Track, Layout::Frame] {
            compare_output(
                &eval(&batch, &times, layout, true),
                &batch,
                &times,
                layout,
                true,
                &format!("{tracks}x{samples}"),
            )
            .assert_within_bars(&format!("{tracks} tracks x {samples}"));
        }
    }
}

/// 1,400 keys at 37.5 Hz (BrainStem-like) starting at t = 1000 s, where an f32 time alone
/// is off by up to 6e-5 s. Steps up to 30 degrees keep velocities within 20 rad/s; the
/// 119.3 Hz grid never lands on a key (where C1 curves' alpha jumps).
pub fn long_clip(eval: Eval<'_>) -> Worst {
    let mut g = Gen::new(4);
    let count = 1400;
    let mut q = g.rotation();
    let rotations = (0..count)
        .map(|_| {
            q = q * QuatF64::exp(g.direction().scale(g.range(0.0, 30f64.to_radians()) / 2.0));
            q.to_array()
        })
        .collect();
    let t = Track {
        times: Some((0..count).map(|i| 1000.0 + i as f64 / 37.5).collect()),
        ..Track::from_rotations(rotations)
    };
    let mut all = Worst::default();
    for spec in [
        CurveSpec::new(Curve::Hermite),
        CurveSpec::new(Curve::Squad),
        CurveSpec { knots: KnotMode::Uniform, order: 6, ..CurveSpec::new(Curve::BSpline) },
    ] {
        let batch = Batch::from_tracks(std::slice::from_ref(&t), &spec).unwrap();
        let times = SampleTimes::uniform(&batch, Sampling::Rate(119.3)).unwrap();
        all.merge(compare_output(
            &eval(&batch, &times, Layout::Track, true),
            &batch,
            &times,
            Layout::Track,
            true,
            &describe(&spec),
        ));
    }
    all
}

/// bspline-interp (open and looping) and every family that loops, on random, near-identical
/// and sign-flipped keys (near-antipodal too for the piecewise loops), looping keys closed
/// with either sign; uniform grids in both layouts and explicit times on every key, at the
/// domain ends and one and two periods outside (wrapped), with derivatives.
pub fn interp_and_loops(eval: Eval<'_>) -> Worst {
    use quatcurve::{Blend, Tangents};
    let interp = CurveSpec::new(Curve::BSplineInterp);
    let specs = [
        interp,
        CurveSpec { looping: true, ..interp },
        CurveSpec { looping: true, ..CurveSpec::new(Curve::Slerp) },
        CurveSpec { looping: true, ..CurveSpec::new(Curve::Squad) },
        CurveSpec { looping: true, ..CurveSpec::new(Curve::Hermite) },
        CurveSpec { looping: true, tangents: Tangents::Zero, ..CurveSpec::new(Curve::Hermite) },
        CurveSpec { looping: true, ..CurveSpec::new(Curve::NamKim) },
        CurveSpec { looping: true, blend: Blend::Quadratic, ..CurveSpec::new(Curve::NamKim) },
        CurveSpec { looping: true, ..CurveSpec::new(Curve::BSpline) },
    ];
    let mut all = Worst::default();
    for (k, kind) in KINDS.into_iter().enumerate() {
        for spec in specs {
            if kind == Kind::NearAntipodal && spec.curve == Curve::BSplineInterp {
                continue; // Near half-turn steps: the C2 interpolant's control steps are ill-conditioned.
            }
            let mut g = Gen::new(300 + k as u64);
            let mut builder = BatchBuilder::new();
            for i in 0..5 {
                let count = 3 + i % 6;
                let t = loop {
                    let mut t = accurate_track(&mut g, &spec, count, kind);
                    if spec.looping {
                        let sign = if g.coin() { 1.0 } else { -1.0 };
                        t.rotations[count - 1] = QuatF64::from_array(t.rotations[0]).mul_scalar(sign).to_array();
                    }
                    let keys: Vec<QuatF64> = t.rotations.iter().map(|&k| QuatF64::from_array(k).normalize()).collect();
                    if keys.windows(2).all(|w| w[0].dot(w[1]).abs() >= 1e-3) {
                        break t;
                    }
                };
                builder.add(&t, &spec).unwrap_or_else(|e| panic!("{} {kind:?}: {e}", describe(&spec)));
            }
            let batch = builder.build().unwrap();
            let per_rate = SampleTimes::uniform(&batch, Sampling::Rate(29.97)).unwrap();
            let per_count = SampleTimes::uniform(&batch, Sampling::Count(38)).unwrap();
            let overrides: Vec<Vec<f64>> = (0..batch.len())
                .map(|i| {
                    let view = batch.view(i);
                    let [lo, hi] = view.track.domain();
                    let mut t: Vec<f64> = view.knots.iter().copied().filter(|&t| t >= lo && t <= hi).collect();
                    let period = hi - lo;
                    t.extend([lo, hi, lo - 0.3 * period, hi + 1.7 * period, lo + 0.41 * period]);
                    t
                })
                .collect();
            let refs: Vec<Option<&[f64]>> = overrides.iter().map(|t| Some(t.as_slice())).collect();
            let explicit = SampleTimes::new(&batch, &refs, Sampling::Count(2)).unwrap();
            for (times, layout) in [(&per_rate, Layout::Track), (&per_count, Layout::Frame), (&explicit, Layout::Track)]
            {
                for derivatives in [false, true] {
                    let label = format!(
                        "{} loop={} {kind:?} {layout:?} derivatives={derivatives}",
                        describe(&spec),
                        spec.looping
                    );
                    all.merge(compare_output(
                        &eval(&batch, times, layout, derivatives),
                        &batch,
                        times,
                        layout,
                        derivatives,
                        &label,
                    ));
                }
            }
        }
    }
    all
}
