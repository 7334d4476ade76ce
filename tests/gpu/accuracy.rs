//! GPU against the f64 reference: every family, order and knot mode, with and without
//! derivatives, both layouts, random and adversarial tracks (DESIGN section 6 bars).

use crate::common::*;
use quatcurve::gpu::{GpuEvaluator, GpuOptions};
use quatcurve::{Batch, BatchBuilder, Curve, CurveSpec, DQuat, DVec3, EvalJob, KnotMode, Layout, SampleTimes, Sampling, Track};
use std::sync::OnceLock;

/// DESIGN section 6: rotation error bar (rad) and derivative relative error bar.
pub const ROTATION_BAR: f64 = 1e-5;
pub const DERIVATIVE_BAR: f64 = 1e-4;

/// The shared evaluator, or None (skip) when there is no adapter and none is required.
pub fn gpu() -> Option<&'static GpuEvaluator> {
    static GPU: OnceLock<Option<GpuEvaluator>> = OnceLock::new();
    GPU.get_or_init(|| match GpuEvaluator::new() {
        Ok(g) => {
            eprintln!("GPU tests on: {}", g.adapter_name());
            Some(g)
        }
        Err(e) if std::env::var("QUATCURVE_REQUIRE_GPU").as_deref() == Ok("1") => {
            panic!("QUATCURVE_REQUIRE_GPU=1 but {e}")
        }
        Err(e) => {
            eprintln!("skipped: no GPU adapter ({e})");
            None
        }
    })
    .as_ref()
}

/// Worst errors of GPU vs reference, with where they happened.
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
        eprintln!("{what}: worst rotation {:.2e} rad at {}; worst derivative {:.2e} at {}", self.rotation.0, self.rotation.1, self.derivative.0, self.derivative.1);
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
    if view.track.curve != Curve::NamKim {
        return f64::INFINITY;
    }
    let k = view.knots;
    let t = t.clamp(k[0], k[k.len() - 1]);
    let i = (0..k.len() - 1).rev().find(|&i| k[i] <= t).unwrap_or(0).min(k.len() - 2);
    let u = (t - k[i]) / (k[i + 1] - k[i]);
    let v = |c: [f64; 4]| DVec3::new(c[0], c[1], c[2]);
    let c1 = view.points[i] * DQuat::exp(v(view.coefs[2 * i]).scale(u));
    let c2 = view.points[i + 1] * DQuat::exp(v(view.coefs[2 * i + 1]).scale(u - 1.0));
    1.0 + c1.dot(c2)
}

/// (track, sample) of an output slot.
fn slot_sample(times: &SampleTimes, layout: Layout, slot: usize) -> (usize, usize) {
    match layout {
        Layout::Track => {
            let track = times.offsets.partition_point(|&o| o <= slot) - 1;
            (track, slot - times.offsets[track])
        }
        Layout::Frame => (slot % times.track_count(), slot / times.track_count()),
    }
}

/// Samples left out of the bars by [`BLEND_ANTIPODE_MARGIN`], over the whole test run.
pub static EXCLUDED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Evaluates `batch` on both paths and returns the worst differences.
pub fn compare(gpu: &GpuEvaluator, batch: &Batch, times: &SampleTimes, options: GpuOptions, label: &str) -> Worst {
    let reference = EvalJob { batch, times, layout: options.layout, derivatives: options.derivatives }.run().unwrap();
    let out = gpu.evaluate(batch, times, &options).unwrap().to_output(options.derivatives);
    assert_eq!(out.rotations.len(), reference.rotations.len(), "{label}");
    let mut worst = Worst::default();
    for i in 0..out.rotations.len() {
        let (track, j) = slot_sample(times, options.layout, i);
        if blend_margin(batch, track, times.time(track, j)) < BLEND_ANTIPODE_MARGIN {
            EXCLUDED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            continue;
        }
        let rot = DQuat::from_array(out.rotations[i]).angle_to(DQuat::from_array(reference.rotations[i]));
        if rot > worst.rotation.0 || rot.is_nan() {
            worst.rotation = (if rot.is_nan() { f64::INFINITY } else { rot }, format!("{label} slot {i}"));
        }
        if options.derivatives {
            let a = DVec3::from_array;
            let der = rel_err(a(out.angular_velocity[i]), a(reference.angular_velocity[i]))
                .max(rel_err(a(out.angular_acceleration[i]), a(reference.angular_acceleration[i])));
            if der > worst.derivative.0 || der.is_nan() {
                worst.derivative = (if der.is_nan() { f64::INFINITY } else { der }, format!("{label} slot {i}"));
            }
        }
    }
    worst
}

/// A track within DESIGN section 6's domain: consecutive key dots >= 1e-3 (the half-turn
/// choice is ill-conditioned below), velocities up to 20 rad/s.
fn accurate_track(g: &mut Gen, spec: &CurveSpec, count: usize, kind: Kind) -> Track {
    loop {
        let t = track(g, spec, count, kind);
        let keys: Vec<DQuat> = t.rotations.iter().map(|&k| DQuat::from_array(k).normalize()).collect();
        if keys.windows(2).all(|w| w[0].dot(w[1]).abs() >= 1e-3) {
            return t;
        }
    }
}

/// A batch of `tracks` tracks of different lengths for `spec`.
fn batch_for(seed: u64, spec: &CurveSpec, kind: Kind, tracks: usize) -> Batch {
    let mut g = Gen::new(seed);
    let mut builder = BatchBuilder::new();
    for i in 0..tracks {
        let extra = if spec.curve == Curve::Bezier { i % 4 } else { i % 6 };
        let t = accurate_track(&mut g, spec, spec.min_keys().max(2) + extra, kind);
        builder.add(&t, spec).unwrap();
    }
    builder.build().unwrap()
}

#[test]
fn every_family_order_and_knot_mode_matches_the_reference() {
    let Some(gpu) = gpu() else { return };
    let mut all = Worst::default();
    for (k, kind) in KINDS.into_iter().enumerate() {
        for spec in all_specs() {
            let batch = batch_for(17 + k as u64, &spec, kind, 5);
            // Grids that do not line up with knots (where C0/C1 derivatives jump): a rate
            // of 29.97 Hz, and 38 samples (37 intervals) for the equal counts frame-major needs.
            let per_rate = SampleTimes::uniform(&batch, Sampling::Rate(29.97)).unwrap();
            let per_count = SampleTimes::uniform(&batch, Sampling::Count(38)).unwrap();
            for (times, layout) in [(&per_rate, Layout::Track), (&per_count, Layout::Frame)] {
                for derivatives in [false, true] {
                    let options = GpuOptions { layout, derivatives, ..GpuOptions::default() };
                    let label = format!("{} {kind:?} {layout:?} derivatives={derivatives}", describe(&spec));
                    all.merge(compare(gpu, &batch, times, options, &label));
                }
            }
        }
    }
    all.assert_within_bars("all families, 4 kinds, both layouts");
    eprintln!("samples excluded by the Nam-Kim blend antipode margin so far: {}", EXCLUDED.load(std::sync::atomic::Ordering::Relaxed));
}

#[test]
fn samples_exactly_on_knots_and_at_domain_ends() {
    let Some(gpu) = gpu() else { return };
    let mut all = Worst::default();
    for spec in all_specs() {
        let batch = batch_for(5, &spec, Kind::Random, 3);
        // Every knot, the domain ends, and times outside the domain (clamped).
        let overrides: Vec<Vec<f64>> = (0..batch.len())
            .map(|i| {
                let view = batch.view(i);
                let [lo, hi] = view.track.domain;
                let mut t: Vec<f64> = view.knots.to_vec();
                t.extend([lo, hi, lo - 1.0, hi + 2.5]);
                t
            })
            .collect();
        let refs: Vec<Option<&[f64]>> = overrides.iter().map(|t| Some(t.as_slice())).collect();
        let times = SampleTimes::new(&batch, &refs, Sampling::Count(2)).unwrap();
        let options = GpuOptions { derivatives: true, ..GpuOptions::default() };
        all.merge(compare(gpu, &batch, &times, options, &describe(&spec)));
    }
    all.assert_within_bars("samples on knots and domain ends");
}

#[test]
fn repeated_knots_and_mixed_families_in_one_batch() {
    let Some(gpu) = gpu() else { return };
    let mut g = Gen::new(99);
    let mut builder = BatchBuilder::new();
    for spec in all_specs() {
        let count = spec.min_keys().max(2) + 2;
        let mut t = accurate_track(&mut g, &spec, count, Kind::SignFlipped);
        if spec.knots == KnotMode::Explicit && spec.curve == Curve::BSpline && spec.order >= 3 {
            // Force an interior knot of multiplicity k - 1.
            let k = spec.order;
            let mut knots = explicit_knots(&mut g, k, count);
            let mid = knots[k];
            for knot in knots.iter_mut().skip(k).take(k - 1) {
                *knot = mid;
            }
            for i in (2 * k - 1)..knots.len() {
                knots[i] = knots[i].max(mid + 0.1 * (i + 2 - 2 * k) as f64);
            }
            t.knots = Some(knots);
        }
        builder.add(&t, &spec).unwrap();
    }
    let batch = builder.build().unwrap();
    let times = SampleTimes::uniform(&batch, Sampling::Rate(31.3)).unwrap();
    let mut all = Worst::default();
    for generic_kernel in [false, true] {
        let options = GpuOptions { derivatives: true, generic_kernel, ..GpuOptions::default() };
        all.merge(compare(gpu, &batch, &times, options, &format!("mixed generic={generic_kernel}")));
    }
    all.assert_within_bars("mixed batch with repeated knots");
}

#[test]
fn sizes_that_are_not_multiples_of_the_workgroup() {
    let Some(gpu) = gpu() else { return };
    let spec = CurveSpec::default();
    for (tracks, samples) in [(1usize, 1usize), (1, 63), (1, 65), (3, 21), (7, 129), (13, 1)] {
        let batch = batch_for(tracks as u64, &spec, Kind::Random, tracks);
        let times = SampleTimes::uniform(&batch, Sampling::Count(samples)).unwrap();
        for layout in [Layout::Track, Layout::Frame] {
            let options = GpuOptions { layout, derivatives: true, ..GpuOptions::default() };
            compare(gpu, &batch, &times, options, &format!("{tracks}x{samples}")).assert_within_bars(&format!("{tracks} tracks x {samples}"));
        }
    }
}

#[test]
fn batches_forced_through_many_chunks_match_one_chunk() {
    let Some(full) = gpu() else { return };
    let small = GpuEvaluator::new().unwrap().with_binding_limit(32 * 1024);
    for spec in [CurveSpec::default(), CurveSpec { knots: KnotMode::Explicit, order: 5, ..CurveSpec::default() }, CurveSpec::new(Curve::NamKim)] {
        let batch = batch_for(3, &spec, Kind::Random, 40);
        for (times, layout) in [
            (SampleTimes::uniform(&batch, Sampling::Rate(40.0)).unwrap(), Layout::Track),
            (SampleTimes::uniform(&batch, Sampling::Count(50)).unwrap(), Layout::Frame),
        ] {
            let options = GpuOptions { layout, derivatives: true, ..GpuOptions::default() };
            let one = full.evaluate(&batch, &times, &options).unwrap();
            let many = small.evaluate(&batch, &times, &options).unwrap();
            assert_eq!(one, many, "{layout:?}: chunked result differs");
            compare(&small, &batch, &times, options, "chunked").assert_within_bars("chunked");
        }
    }
    // A track too large for one binding is an error naming it, not a crash.
    let tiny = GpuEvaluator::new().unwrap().with_binding_limit(64);
    let batch = batch_for(1, &CurveSpec::default(), Kind::Random, 1);
    let times = SampleTimes::uniform(&batch, Sampling::Count(100)).unwrap();
    let err = tiny.evaluate(&batch, &times, &GpuOptions::default()).unwrap_err().to_string();
    assert!(err.contains("track 0") && err.contains("binding"), "{err}");
}

#[test]
fn dispatches_beyond_65535_workgroups_use_two_dimensions() {
    let Some(gpu) = gpu() else { return };
    // 65,535 x 64 = 4,194,240 samples fit one dimension; go past it.
    let spec = CurveSpec { knots: KnotMode::Uniform, ..CurveSpec::default() };
    let batch = batch_for(8, &spec, Kind::Random, 2);
    let times = SampleTimes::uniform(&batch, Sampling::Count(2_150_000)).unwrap();
    let out = gpu.evaluate(&batch, &times, &GpuOptions::default()).unwrap();
    assert_eq!(out.data.len(), 4_300_000 * 4);
    let mut worst = 0.0f64;
    for slot in (0..4_300_000).step_by(997).chain([4_299_999]) {
        let (track, j) = if slot < 2_150_000 { (0, slot) } else { (1, slot - 2_150_000) };
        let reference = quatcurve::evaluate(batch.view(track), times.time(track, j)).rotation;
        let q = &out.data[slot * 4..slot * 4 + 4];
        let got = DQuat::from_xyzw(f64::from(q[0]), f64::from(q[1]), f64::from(q[2]), f64::from(q[3]));
        worst = worst.max(got.angle_to(reference));
    }
    assert!(worst <= ROTATION_BAR, "{worst}");
}

#[test]
fn long_clips_keep_full_time_precision() {
    // 1,400 keys at 37.5 Hz (BrainStem-like) starting at t = 1000 s, where an f32 time alone
    // is off by up to 6e-5 s. Steps up to 30 degrees keep velocities within 20 rad/s; the
    // 119.3 Hz grid never lands on a key (where C1 curves' alpha jumps).
    let Some(gpu) = gpu() else { return };
    let mut g = Gen::new(4);
    let count = 1400;
    let mut q = g.rotation();
    let rotations = (0..count)
        .map(|_| {
            q = q * DQuat::exp(g.direction().scale(g.range(0.0, 30f64.to_radians()) / 2.0));
            q.to_array()
        })
        .collect();
    let t = Track { times: Some((0..count).map(|i| 1000.0 + i as f64 / 37.5).collect()), ..Track::from_rotations(rotations) };
    for spec in [CurveSpec::new(Curve::Hermite), CurveSpec::new(Curve::Squad), CurveSpec { knots: KnotMode::Uniform, order: 6, ..CurveSpec::default() }] {
        let batch = Batch::from_tracks(std::slice::from_ref(&t), &spec).unwrap();
        let times = SampleTimes::uniform(&batch, Sampling::Rate(119.3)).unwrap();
        let options = GpuOptions { derivatives: true, ..GpuOptions::default() };
        compare(gpu, &batch, &times, options, &describe(&spec)).assert_within_bars("long clip at t = 1000..1037 s");
    }
}
