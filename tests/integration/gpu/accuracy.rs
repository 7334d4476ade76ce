//! GPU against the f64 reference: every family, order and knot mode, with and without
//! derivatives, both layouts, random and adversarial tracks (DESIGN section 18 bars).

use crate::common::*;
use crate::fast::*;
use crate::shared_gpu as gpu;
use quatcurve::gpu::GpuDevice;
use quatcurve::FloatOutput;
use quatcurve::{Batch, Curve, CurveSpec, KnotMode, Layout, QuatF64, SampleTimes, Sampling};
use quatcurve::{EvalJob, JobOptions};

/// Evaluates `batch` on the GPU and compares with the reference.
pub fn compare(gpu: &GpuDevice, batch: &Batch, times: &SampleTimes, options: JobOptions, label: &str) -> Worst {
    let out = gpu.evaluate(&EvalJob::new(batch, times).with(options)).unwrap();
    compare_output(&out, batch, times, options.layout, options.derivatives, label)
}

/// The GPU as a fast path under test.
fn on_gpu(gpu: &GpuDevice, generic_kernel: bool) -> impl Fn(&Batch, &SampleTimes, Layout, bool) -> FloatOutput + '_ {
    move |batch, times, layout, derivatives| {
        gpu.evaluate(&EvalJob::new(batch, times).with(JobOptions {
            layout,
            derivatives,
            generic_kernel,
            ..JobOptions::default()
        }))
        .unwrap()
    }
}

#[test]
fn every_family_order_and_knot_mode_matches_the_reference() {
    let Some(gpu) = gpu() else { return };
    every_family_order_and_knot_mode(&on_gpu(gpu, false)).assert_within_bars("all families, 4 kinds, both layouts");
    eprintln!(
        "samples excluded by the Nam-Kim blend antipode margin so far: {}",
        EXCLUDED.load(std::sync::atomic::Ordering::Relaxed)
    );
}

#[test]
fn bspline_interp_and_loops_match_the_reference() {
    let Some(gpu) = gpu() else { return };
    interp_and_loops(&on_gpu(gpu, false)).assert_within_bars("bspline-interp and loops");
}

#[test]
fn samples_exactly_on_knots_and_at_domain_ends() {
    let Some(gpu) = gpu() else { return };
    samples_on_knots_and_domain_ends(&on_gpu(gpu, false)).assert_within_bars("samples on knots and domain ends");
}

#[test]
fn repeated_knots_and_mixed_families_in_one_batch() {
    let Some(gpu) = gpu() else { return };
    let (batch, times) = mixed_batch_with_repeated_knots();
    let mut all = Worst::default();
    for generic_kernel in [false, true] {
        let out = on_gpu(gpu, generic_kernel)(&batch, &times, Layout::Track, true);
        all.merge(compare_output(
            &out,
            &batch,
            &times,
            Layout::Track,
            true,
            &format!("mixed generic={generic_kernel}"),
        ));
    }
    all.assert_within_bars("mixed batch with repeated knots");
}

#[test]
fn bspline_batches_mixing_orders_and_knot_spacings() {
    let Some(gpu) = gpu() else { return };
    let uniform = [KnotMode::Uniform, KnotMode::Phantom];
    for (orders, modes, what) in [
        (
            &[4, 2, 4, 5, 3, 8][..],
            &[KnotMode::Uniform, KnotMode::Phantom, KnotMode::Clamped][..],
            "mixed orders and spacings",
        ),
        (&[3, 4, 7][..], &uniform[..], "mixed orders, equally spaced"),
        (&[5][..], &[KnotMode::Clamped, KnotMode::Uniform][..], "one order, mixed spacings"),
        (&[4][..], &uniform[..], "one order, equally spaced (both specializations)"),
    ] {
        // One form (the kernel of one family), and both side by side (a fitted clip's: the
        // kernel of the two forms alone).
        for forms in [&[Curve::BSpline][..], &[Curve::NormalizedBSpline, Curve::BSpline]] {
            let (batch, times) = bspline_batch(orders, modes, forms);
            let what = format!("{what}, {forms:?}");
            for layout in [Layout::Track, Layout::Frame] {
                compare_output(&on_gpu(gpu, false)(&batch, &times, layout, true), &batch, &times, layout, true, &what)
                    .assert_within_bars(&what);
            }
        }
    }
}

#[test]
fn sizes_that_are_not_multiples_of_the_workgroup() {
    let Some(gpu) = gpu() else { return };
    odd_sizes(&on_gpu(gpu, false));
}

#[test]
fn batches_forced_through_many_chunks_match_one_chunk() {
    let Some(full) = gpu() else { return };
    let small = gpu().unwrap().share_device().with_binding_limit(32 * 1024);
    for spec in [
        CurveSpec::new(Curve::BSpline),
        CurveSpec { knots: KnotMode::Explicit, order: 5, ..CurveSpec::new(Curve::BSpline) },
        CurveSpec::new(Curve::NamKim),
    ] {
        let batch = batch_for(3, &spec, Kind::Random, 40);
        for (times, layout) in [
            (SampleTimes::uniform(&batch, Sampling::Rate(40.0)).unwrap(), Layout::Track),
            (SampleTimes::uniform(&batch, Sampling::Count(50)).unwrap(), Layout::Frame),
        ] {
            let options = JobOptions { layout, derivatives: true, ..JobOptions::default() };
            let one = full.evaluate(&EvalJob::new(&batch, &times).with(options)).unwrap();
            let many = small.evaluate(&EvalJob::new(&batch, &times).with(options)).unwrap();
            assert_eq!(one, many, "{layout:?}: chunked result differs");
            compare(&small, &batch, &times, options, "chunked").assert_within_bars("chunked");
        }
    }
    // Tracks whose samples overflow a binding are cut into pieces, bit for bit the same:
    // uniform times (rate), uniform with the exact last sample (count), explicit times, in
    // both layouts.
    let pieces = gpu().unwrap().share_device().with_binding_limit(4096);
    let batch = batch_for(3, &CurveSpec::new(Curve::BSpline), Kind::Random, 6);
    let explicit: Vec<f64> = (0..700).map(|i| 0.05 + f64::from(i) * 0.0007).collect();
    let overrides = vec![Some(&explicit[..]); 3];
    for (times, layout) in [
        (SampleTimes::uniform(&batch, Sampling::Rate(400.0)).unwrap(), Layout::Track),
        (SampleTimes::uniform(&batch, Sampling::Count(777)).unwrap(), Layout::Track),
        (SampleTimes::uniform(&batch, Sampling::Count(777)).unwrap(), Layout::Frame),
        (SampleTimes::new(&batch, &overrides, Sampling::Count(1)).unwrap(), Layout::Track),
    ] {
        let options = JobOptions { layout, derivatives: true, ..JobOptions::default() };
        assert!(
            pieces.prepare(&EvalJob::new(&batch, &times).with(options)).unwrap().chunk_count() > 3 * 5,
            "{layout:?}: tracks were not cut"
        );
        assert_eq!(
            pieces.evaluate(&EvalJob::new(&batch, &times).with(options)).unwrap(),
            full.evaluate(&EvalJob::new(&batch, &times).with(options)).unwrap(),
            "{layout:?}: pieces differ"
        );
    }
    // A track whose keys alone overflow a binding is an error naming it, not a crash.
    let tiny = gpu().unwrap().share_device().with_binding_limit(64);
    let batch = batch_for(1, &CurveSpec::new(Curve::BSpline), Kind::Random, 1);
    let times = SampleTimes::uniform(&batch, Sampling::Count(100)).unwrap();
    let err = tiny.evaluate(&EvalJob::new(&batch, &times).with(JobOptions::default())).unwrap_err().to_string();
    assert!(err.contains("track 0") && err.contains("binding"), "{err}");
}

/// Runs of tracks keyed at the same times share one knot vector in the batch and in each GPU
/// chunk. Every track must read its own run's knots: runs with different times follow each
/// other (one crossing a packing task of 4,096 tracks), in one chunk and cut at arbitrary
/// tracks by a small binding limit, where a run's tracks past a cut pack the knots again.
#[test]
fn tracks_sharing_knot_vectors_read_their_own_in_every_chunk() {
    let Some(full) = gpu() else { return };
    let small = gpu().unwrap().share_device().with_binding_limit(48 * 1024);
    let mut g = Gen::new(17);
    // (tracks, keys, first key time, key spacing within the accuracy tests' 0.2..1.5 s): the
    // first run's times come back last, apart. Key counts - 1 are prime to the 6 sample steps,
    // so no inner sample lands on a key (where slerp's angular velocity jumps).
    let runs = [(3, 8, 0.0, 0.5), (4200, 12, 0.35, 0.3), (2, 6, -2.0, 0.7), (5, 8, 0.0, 0.5)];
    for spec in [CurveSpec::new(Curve::BSpline), CurveSpec::new(Curve::Slerp)] {
        let mut builder = quatcurve::BatchBuilder::new();
        for &(tracks, keys, start, step) in &runs {
            let times: Vec<f64> = (0..keys).map(|j| start + step * j as f64).collect();
            for _ in 0..tracks {
                let track = quatcurve::Track {
                    times: Some(times.clone()),
                    ..accurate_track(&mut g, &spec, keys, Kind::Random)
                };
                builder.add(&track, &spec).unwrap();
            }
        }
        let batch = builder.build().unwrap();
        let vectors: std::collections::BTreeSet<usize> = batch.tracks().iter().map(|t| t.knot_offset()).collect();
        assert_eq!(vectors.len(), runs.len(), "{}: one knot vector per run", describe(&spec));
        let times = SampleTimes::uniform(&batch, Sampling::Count(7)).unwrap();
        let options = JobOptions { derivatives: true, ..JobOptions::default() };
        assert!(
            small.prepare(&EvalJob::new(&batch, &times).with(options)).unwrap().chunk_count() > 10,
            "the small limit cuts the runs"
        );
        let one = full.evaluate(&EvalJob::new(&batch, &times).with(options)).unwrap();
        assert_eq!(
            one,
            small.evaluate(&EvalJob::new(&batch, &times).with(options)).unwrap(),
            "{}: chunked result differs",
            describe(&spec)
        );
        compare(full, &batch, &times, options, "shared knots")
            .assert_within_bars(&format!("{}: shared knots", describe(&spec)));
    }
}

#[test]
fn dispatches_beyond_65535_workgroups_use_two_dimensions() {
    let Some(gpu) = gpu() else { return };
    // 65,535 x 64 = 4,194,240 samples fit one dimension; go past it.
    let spec = CurveSpec { knots: KnotMode::Uniform, ..CurveSpec::new(Curve::BSpline) };
    let batch = batch_for(8, &spec, Kind::Random, 2);
    let times = SampleTimes::uniform(&batch, Sampling::Count(2_150_000)).unwrap();
    let out = gpu.evaluate(&EvalJob::new(&batch, &times).with(JobOptions::default())).unwrap();
    assert_eq!(out.data.len(), 4_300_000 * 4);
    let mut worst = 0.0f64;
    for slot in (0..4_300_000).step_by(997).chain([4_299_999]) {
        let (track, j) = if slot < 2_150_000 { (0, slot) } else { (1, slot - 2_150_000) };
        let reference = quatcurve::evaluate(batch.view(track), times.time(track, j)).rotation;
        let q = &out.data[slot * 4..slot * 4 + 4];
        let got = QuatF64::from_xyzw(f64::from(q[0]), f64::from(q[1]), f64::from(q[2]), f64::from(q[3]));
        worst = worst.max(got.angle_to(reference));
    }
    assert!(worst <= ROTATION_BAR, "{worst}");
}

#[test]
fn long_clips_keep_full_time_precision() {
    let Some(gpu) = gpu() else { return };
    long_clip(&on_gpu(gpu, false)).assert_within_bars("long clip at t = 1000..1037 s");
}

/// One 20 M-sample track with derivatives (800 MB of output), through bindings of 100 MiB:
/// the GPU cuts it into pieces and agrees with the CPU path (checked on every 997th sample and
/// the last, within the bars against the reference too).
#[test]
fn a_track_longer_than_a_binding_is_evaluated_in_pieces() {
    if gpu().is_none() {
        return;
    }
    let gpu = gpu().unwrap().share_device().with_binding_limit(100 << 20);
    // A 6.3 s walk keyed at 10 Hz, sampled at 3.2 MHz.
    let batch =
        Batch::from_tracks(&quatcurve::synthetic::walk_tracks(1, 64, 10.0), &CurveSpec::new(Curve::BSplineInterp))
            .unwrap();
    let times = SampleTimes::uniform(&batch, Sampling::Count(20_000_000)).unwrap();
    let options = JobOptions { derivatives: true, ..JobOptions::default() };
    let out = gpu.evaluate(&EvalJob::new(&batch, &times).with(options)).unwrap();
    assert!(out.data.len() * 4 > 7 * (100 << 20), "the output must overflow seven bindings");
    drop(gpu);
    let cpu = quatcurve::cpu::CpuEvaluator::new()
        .evaluate(
            &quatcurve::EvalJob::new(&batch, &times)
                .with(quatcurve::JobOptions { derivatives: true, ..Default::default() }),
        )
        .unwrap();
    let (mut rotation, mut omega) = (0.0f32, 0.0f32);
    for slot in (0..20_000_000).step_by(997).chain([19_999_999]) {
        let (g, c) = (&out.data[slot * 10..slot * 10 + 10], &cpu.data[slot * 10..slot * 10 + 10]);
        let sign = if g[..4].iter().zip(&c[..4]).map(|(a, b)| a * b).sum::<f32>() < 0.0 { -1.0 } else { 1.0 };
        rotation = rotation.max(g[..4].iter().zip(&c[..4]).map(|(a, b)| (a - sign * b).abs()).fold(0.0, f32::max));
        omega =
            omega.max(g[4..].iter().zip(&c[4..]).map(|(a, b)| (a - b).abs() / b.abs().max(1.0)).fold(0.0, f32::max));
    }
    assert!(rotation < 1e-5 && omega < 1e-3, "GPU pieces vs CPU: rotation {rotation}, derivatives {omega}");
}
