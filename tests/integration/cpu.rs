//! The fast CPU path against the f64 reference (DESIGN section 18 bars): the same suites as the
//! GPU, plus layouts and matrices checked against the GPU-independent reference directly.

use crate::common::*;
use crate::fast::*;
use quatcurve::cpu::{CpuEvaluator, Isa};
use quatcurve::FloatOutput;
use quatcurve::{Batch, Curve, CurveSpec, KnotMode, Layout, QuatF64, SampleTimes, Sampling};
use quatcurve::{EvalJob, JobOptions};

fn on_cpu(batch: &Batch, times: &SampleTimes, layout: Layout, derivatives: bool) -> FloatOutput {
    CpuEvaluator::new()
        .evaluate(&EvalJob::new(batch, times).with(JobOptions { layout, derivatives, ..JobOptions::default() }))
        .unwrap()
}

fn on_portable_lanes(batch: &Batch, times: &SampleTimes, layout: Layout, derivatives: bool) -> FloatOutput {
    let cpu = CpuEvaluator::with_isa(Isa::Portable).expect("the baseline runs everywhere");
    cpu.evaluate(&EvalJob::new(batch, times).with(JobOptions { layout, derivatives, ..JobOptions::default() })).unwrap()
}

/// The lane type is chosen at run time (AVX2 where the CPU has it): the suites above run the
/// chosen one; here the baseline (`wide` at the build's target) meets the same bars, so a
/// machine without AVX2 runs tested code.
#[test]
fn the_baseline_lanes_meet_the_same_bars() {
    assert_eq!(CpuEvaluator::new().isa(), Isa::detect());
    every_family_order_and_knot_mode(&on_portable_lanes)
        .assert_within_bars("cpu portable: all families, 4 kinds, both layouts");
    interp_and_loops(&on_portable_lanes).assert_within_bars("cpu portable: bspline-interp and loops");
    samples_on_knots_and_domain_ends(&on_portable_lanes)
        .assert_within_bars("cpu portable: samples on knots and domain ends");
    let (batch, times) = mixed_batch_with_repeated_knots();
    compare_output(
        &on_portable_lanes(&batch, &times, Layout::Track, true),
        &batch,
        &times,
        Layout::Track,
        true,
        "mixed",
    )
    .assert_within_bars("cpu portable: mixed batch with repeated knots");
    odd_sizes(&on_portable_lanes);
}

#[test]
fn every_family_order_and_knot_mode_matches_the_reference() {
    every_family_order_and_knot_mode(&on_cpu).assert_within_bars("cpu: all families, 4 kinds, both layouts");
}

#[test]
fn bspline_interp_and_loops_match_the_reference() {
    interp_and_loops(&on_cpu).assert_within_bars("cpu: bspline-interp and loops");
}

#[test]
fn samples_exactly_on_knots_and_at_domain_ends() {
    samples_on_knots_and_domain_ends(&on_cpu).assert_within_bars("cpu: samples on knots and domain ends");
}

#[test]
fn repeated_knots_and_mixed_families_in_one_batch() {
    let (batch, times) = mixed_batch_with_repeated_knots();
    compare_output(&on_cpu(&batch, &times, Layout::Track, true), &batch, &times, Layout::Track, true, "mixed")
        .assert_within_bars("cpu: mixed batch with repeated knots");
}

/// `evaluate_into` writes every float of the caller's buffer (a kept buffer is not cleared
/// between jobs, `Device::evaluate_into`): into NaNs, every family in both layouts, with
/// and without derivatives, short tracks and tracks split into pieces, it equals a fresh output
/// to the bit.
#[test]
fn evaluate_into_writes_every_float_of_the_buffer() {
    let cpu = CpuEvaluator::new();
    let (batch, per_rate) = mixed_batch_with_repeated_knots();
    let [short, long] = [13, 5000].map(|n| SampleTimes::uniform(&batch, Sampling::Count(n)).unwrap());
    // A frame-major layout needs every track's count the same.
    let runs = [
        (&per_rate, &[Layout::Track][..]),
        (&short, &[Layout::Track, Layout::Frame]),
        (&long, &[Layout::Track, Layout::Frame]),
    ];
    for (times, layouts) in runs {
        for &layout in layouts {
            for derivatives in [false, true] {
                let job = EvalJob::new(&batch, times).with(JobOptions { layout, derivatives, ..JobOptions::default() });
                let fresh = cpu.evaluate(&job).unwrap();
                let mut kept = vec![f32::NAN; fresh.data.len()];
                cpu.evaluate_into(&job, &mut kept).unwrap();
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert!(
                    bits(&kept) == bits(&fresh.data),
                    "{layout:?} derivatives={derivatives}, {} samples: a float left unwritten or different",
                    times.total()
                );
            }
        }
    }
}

#[test]
fn sizes_that_are_not_multiples_of_the_simd_width() {
    odd_sizes(&on_cpu);
}

#[test]
fn bezier_curves_of_every_degree() {
    // Degrees 1..=7 take the SIMD de Casteljau basis, 8 and 9 the reference per sample.
    let spec = CurveSpec::new(Curve::Bezier);
    let mut all = Worst::default();
    for (degree, kind) in
        (1..=9).zip([Kind::Random, Kind::NearIdentical, Kind::NearAntipodal, Kind::SignFlipped].into_iter().cycle())
    {
        let mut g = Gen::new(degree as u64);
        let mut builder = quatcurve::BatchBuilder::new();
        for _ in 0..3 {
            builder.add(&accurate_track(&mut g, &spec, degree + 1, kind), &spec).unwrap();
        }
        let batch = builder.build().unwrap();
        let times = SampleTimes::uniform(&batch, Sampling::Count(101)).unwrap();
        for derivatives in [false, true] {
            let out = on_cpu(&batch, &times, Layout::Track, derivatives);
            all.merge(compare_output(
                &out,
                &batch,
                &times,
                Layout::Track,
                derivatives,
                &format!("bezier degree {degree} {kind:?}"),
            ));
        }
    }
    all.assert_within_bars("cpu: bezier degrees 1..=9");
}

#[test]
fn long_clips_keep_full_time_precision() {
    long_clip(&on_cpu).assert_within_bars("cpu: long clip at t = 1000..1037 s");
}

#[test]
fn tracks_longer_than_one_work_piece_and_matrices() {
    // 10,000 samples per track cross several parallel pieces; the matrix columns must be the
    // rotation's own matrix, frame-major must be the transpose of track-major.
    let spec = CurveSpec { knots: KnotMode::Uniform, ..CurveSpec::new(Curve::BSpline) };
    let batch = batch_for(3, &spec, Kind::Random, 3);
    let times = SampleTimes::uniform(&batch, Sampling::Count(10_000)).unwrap();
    let cpu = CpuEvaluator::new();
    let by_track = cpu
        .evaluate(&EvalJob::new(&batch, &times).with(JobOptions {
            layout: Layout::Track,
            derivatives: true,
            matrix: true,
            ..JobOptions::default()
        }))
        .unwrap();
    let by_frame = cpu
        .evaluate(&EvalJob::new(&batch, &times).with(JobOptions {
            layout: Layout::Frame,
            derivatives: true,
            matrix: true,
            ..JobOptions::default()
        }))
        .unwrap();
    assert_eq!(by_track.channels, 19);
    compare_output(&by_track, &batch, &times, Layout::Track, true, "long tracks").assert_within_bars("cpu: 3 x 10,000");
    for track in 0..3 {
        for j in (0..10_000).step_by(37) {
            let a = &by_track.data[(track * 10_000 + j) * 19..][..19];
            let b = &by_frame.data[(j * 3 + track) * 19..][..19];
            assert_eq!(a, b, "track {track} sample {j}");
            let m = QuatF64::from_array([a[0], a[1], a[2], a[3]].map(f64::from)).to_mat3();
            for (got, want) in a[10..].iter().zip(m.iter().flatten()) {
                assert!((f64::from(*got) - want).abs() < 1e-6, "matrix entry {got} vs {want}");
            }
        }
    }
}

#[test]
fn forward_differences_match_the_reference_and_reseeding_bounds_their_drift() {
    use quatcurve::Track;
    let cpu = CpuEvaluator::new();
    let fd = |batch: &Batch, times: &SampleTimes, layout: Layout, reseed: usize| {
        cpu.evaluate(&EvalJob::new(batch, times).with(JobOptions {
            layout,
            forward_difference: Some(reseed),
            ..JobOptions::default()
        }))
        .unwrap()
    };
    // The usual sets, both layouts, both samplings (the exact last sample of --samples).
    let mut all = Worst::default();
    for spec in [
        CurveSpec::new(Curve::Slerp),
        CurveSpec::new(Curve::NamKim),
        CurveSpec { blend: quatcurve::Blend::Quadratic, ..CurveSpec::new(Curve::NamKim) },
    ] {
        for (k, kind) in KINDS.into_iter().enumerate() {
            let batch = batch_for(40 + k as u64, &spec, kind, 5);
            for (times, layout) in [
                (SampleTimes::uniform(&batch, Sampling::Rate(293.0)).unwrap(), Layout::Track),
                (SampleTimes::uniform(&batch, Sampling::Count(1001)).unwrap(), Layout::Frame),
            ] {
                let label = format!("{} {kind:?} {layout:?}", describe(&spec));
                all.merge(compare_output(&fd(&batch, &times, layout, 64), &batch, &times, layout, false, &label));
            }
        }
    }
    all.assert_within_bars("cpu forward differences, reseed every 64");
    // Drift over 100,000 steps of one segment: unbounded without reseeding, bounded with it.
    let mut g = Gen::new(8);
    let t = Track {
        times: Some(vec![0.0, 0.4, 1.0]),
        ..Track::from_rotations(vec![g.rotation().to_array(), g.rotation().to_array(), g.rotation().to_array()])
    };
    for spec in [CurveSpec::new(Curve::Slerp), CurveSpec::new(Curve::NamKim)] {
        let batch = Batch::from_tracks(std::slice::from_ref(&t), &spec).unwrap();
        let times = SampleTimes::uniform(&batch, Sampling::Count(100_001)).unwrap();
        let free = compare_output(
            &fd(&batch, &times, Layout::Track, usize::MAX),
            &batch,
            &times,
            Layout::Track,
            false,
            "free",
        );
        let seeded =
            compare_output(&fd(&batch, &times, Layout::Track, 16), &batch, &times, Layout::Track, false, "seeded");
        eprintln!(
            "{}: drift over 60,000 f32 steps {:.2e} rad unseeded, {:.2e} rad reseeded every 16",
            spec.curve, free.rotation.0, seeded.rotation.0
        );
        // f32 rounding of q + d biases every step by up to half an ulp; the recurrence is
        // neutrally stable, so the free-running error stays bounded but several times larger.
        assert!(seeded.rotation.0 <= 2e-6, "{seeded:?}");
        free.assert_within_bars("free-running long segment");
    }
}

/// Many short tracks (0 to 20 samples each: one partial SIMD group, or two) of every spec in
/// blocks of one spec: per-track sample times inside and outside the domain, both layouts,
/// with derivatives and matrices, on the chosen lanes and the baseline.
#[test]
fn many_short_tracks_with_their_own_sample_times_match_the_reference() {
    let mut g = Gen::new(1811);
    let mut builder = quatcurve::BatchBuilder::new();
    let specs = all_specs();
    for i in 0..600 {
        // Blocks of six tracks of one spec.
        let spec = specs[(i / 6) % specs.len()];
        let count = spec.min_keys().max(2) + i % 5;
        builder.add(&accurate_track(&mut g, &spec, count, KINDS[i % 4]), &spec).unwrap();
    }
    let batch = builder.build().unwrap();
    // Track-major: 0 to 20 samples per track; frame-major needs one count: 10.
    let mut lists = |fixed: Option<usize>| -> Vec<Vec<f64>> {
        (0..batch.len())
            .map(|i| {
                let [a, b] = batch.tracks()[i].domain();
                let n = fixed.unwrap_or((g.next_u64() % 21) as usize);
                let mut t: Vec<f64> = (0..n).map(|_| g.range(a - 0.1 * (b - a), b + 0.1 * (b - a))).collect();
                t.sort_by(f64::total_cmp);
                t
            })
            .collect()
    };
    let (ragged, even) = (lists(None), lists(Some(10)));
    let mut all = Worst::default();
    for (layout, lists) in [(Layout::Track, &ragged), (Layout::Frame, &even)] {
        let overrides: Vec<Option<&[f64]>> = lists.iter().map(|l| Some(l.as_slice())).collect();
        let times = SampleTimes::new(&batch, &overrides, Sampling::Count(1)).unwrap();
        assert!(times.total() > 5000, "{}", times.total());
        for (name, eval) in [("chosen", &on_cpu as Eval<'_>), ("portable", &on_portable_lanes)] {
            for derivatives in [false, true] {
                all.merge(compare_output(
                    &eval(&batch, &times, layout, derivatives),
                    &batch,
                    &times,
                    layout,
                    derivatives,
                    &format!("{name} {layout:?} {derivatives}"),
                ));
            }
        }
    }
    all.assert_within_bars("cpu: many short tracks");
    // Matrices ride along: each row's matrix is its quaternion's.
    let overrides: Vec<Option<&[f64]>> = ragged.iter().map(|l| Some(l.as_slice())).collect();
    let times = SampleTimes::new(&batch, &overrides, Sampling::Count(1)).unwrap();
    let out = CpuEvaluator::new()
        .evaluate(&EvalJob::new(&batch, &times).with(JobOptions { matrix: true, ..JobOptions::default() }))
        .unwrap();
    for row in out.data.chunks_exact(out.channels) {
        let m = QuatF64::from_array(std::array::from_fn(|c| f64::from(row[c]))).to_mat3();
        for (r, m) in m.iter().enumerate() {
            for (c, m) in m.iter().enumerate() {
                assert!((f64::from(row[4 + 3 * r + c]) - m).abs() < 1e-5, "{row:?}");
            }
        }
    }
}

/// Short tracks share SIMD groups (lanes run across track ends, `cpu::runs`), so each lane's
/// result must be its own track's whatever shares its group: every track of a batch of short
/// tracks gives the same bits evaluated alone. Blocks of 1 to 8 tracks of one spec (runs
/// that start and stop), 0 to 70 samples each (around the run limit of 64), some Hermite
/// tracks with extra turns so that large and small angles share groups; explicit times and
/// grids; with and without derivatives. The batch also meets the bars.
#[test]
fn short_tracks_sharing_simd_groups_give_the_bits_they_give_alone() {
    use quatcurve::{BatchBuilder, Curve, Track};
    let mut g = Gen::new(2718);
    let specs = all_specs();
    let mut tracks: Vec<(Track, CurveSpec)> = Vec::new();
    while tracks.len() < 400 {
        let spec = specs[(g.next_u64() % specs.len() as u64) as usize];
        for _ in 0..1 + g.next_u64() % 8 {
            let count = spec.min_keys().max(2) + (g.next_u64() % 6) as usize;
            let mut track = accurate_track(&mut g, &spec, count, KINDS[tracks.len() % 4]);
            if spec.curve == Curve::Hermite && g.coin() {
                track.extra_turns = Some((0..count - 1).map(|s| (s % 3) as i64 - 1).collect());
            }
            tracks.push((track, spec));
        }
    }
    let build = |tracks: &[(Track, CurveSpec)]| {
        let mut builder = BatchBuilder::new();
        for (track, spec) in tracks {
            builder.add(track, spec).unwrap();
        }
        builder.build().unwrap()
    };
    let batch = build(&tracks);
    let lists: Vec<Vec<f64>> = (0..batch.len())
        .map(|i| {
            let [a, b] = batch.tracks()[i].domain();
            let mut t: Vec<f64> =
                (0..g.next_u64() % 71).map(|_| g.range(a - 0.1 * (b - a), b + 0.1 * (b - a))).collect();
            t.sort_by(f64::total_cmp);
            t
        })
        .collect();
    let explicit = |i: Option<usize>| -> Vec<Option<&[f64]>> {
        match i {
            Some(i) => vec![Some(lists[i].as_slice())],
            None => lists.iter().map(|l| Some(l.as_slice())).collect(),
        }
    };
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut worst = Worst::default();
    for sampling in [None, Some(10), Some(64), Some(65)] {
        let times_of = |batch: &Batch, i: Option<usize>| match sampling {
            Some(n) => SampleTimes::uniform(batch, Sampling::Count(n)).unwrap(),
            None => SampleTimes::new(batch, &explicit(i), Sampling::Count(1)).unwrap(),
        };
        let times = times_of(&batch, None);
        for derivatives in [false, true] {
            let whole = on_cpu(&batch, &times, Layout::Track, derivatives);
            worst.merge(compare_output(
                &whole,
                &batch,
                &times,
                Layout::Track,
                derivatives,
                &format!("{sampling:?} samples, derivatives {derivatives}"),
            ));
            let channels = whole.channels;
            for (i, (track, spec)) in tracks.iter().enumerate() {
                let alone = build(std::slice::from_ref(&(track.clone(), *spec)));
                let out = on_cpu(&alone, &times_of(&alone, Some(i)), Layout::Track, derivatives);
                let own = &whole.data[times.offsets()[i] * channels..times.offsets()[i + 1] * channels];
                assert!(
                    bits(&out.data) == bits(own),
                    "track {i} ({}, {sampling:?} samples, derivatives {derivatives}) differs alone",
                    describe(spec)
                );
            }
        }
    }
    worst.assert_within_bars("cpu: short tracks sharing SIMD groups");
}

/// Fitted curves have a knot every frame or two, so a group of eight samples straddles
/// several spans, each lane with its own knot constants, and samples on a frame grid land on
/// knots (rounding puts some just before one, so the next skips a span). Orders 2 to 8 on
/// knots 1/120 s apart, some repeated up to k - 1 times, sampled at 120 Hz (on the knots),
/// 47 Hz (several spans skipped per sample) and 400 Hz, with and without derivatives.
#[test]
fn knots_denser_than_the_samples_match_the_reference() {
    use quatcurve::Curve;
    let mut all = Worst::default();
    for (seed, order) in [2usize, 3, 4, 6, 8].into_iter().enumerate() {
        let mut g = Gen::new(40 + seed as u64);
        let spec = CurveSpec { order, knots: KnotMode::Explicit, ..CurveSpec::new(Curve::BSpline) };
        let count = 240;
        let mut track = accurate_track(&mut g, &spec, count, Kind::Random);
        let mut knots = vec![0.0; order];
        let mut frame = 0;
        while knots.len() < count {
            frame += 1;
            let repeats = if g.range(0.0, 1.0) < 0.1 { 1 + (g.next_u64() % (order as u64 - 1)) as usize } else { 1 };
            knots.extend(std::iter::repeat(f64::from(frame) / 120.0).take(repeats.min(count - knots.len())));
        }
        knots.extend(std::iter::repeat(f64::from(frame + 1) / 120.0).take(order));
        track.knots = Some(knots);
        let mut builder = quatcurve::BatchBuilder::new();
        builder.add(&track, &spec).unwrap();
        let batch = builder.build().unwrap();
        for rate in [120.0, 47.0, 400.0] {
            let times = SampleTimes::uniform(&batch, Sampling::Rate(rate)).unwrap();
            for derivatives in [false, true] {
                let label = format!("order {order} at {rate} Hz derivatives={derivatives}");
                all.merge(compare_output(
                    &on_cpu(&batch, &times, Layout::Track, derivatives),
                    &batch,
                    &times,
                    Layout::Track,
                    derivatives,
                    &label,
                ));
            }
        }
    }
    all.assert_within_bars("cpu: knots denser than the samples");
}
