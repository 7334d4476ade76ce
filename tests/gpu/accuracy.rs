//! GPU against the f64 reference: every family, order and knot mode, with and without
//! derivatives, both layouts, random and adversarial tracks (DESIGN section 6 bars).

use crate::common::*;
use crate::fast::*;
use quatcurve::gpu::{GpuEvaluator, GpuOptions};
use quatcurve::job::FloatOutput;
use quatcurve::{Batch, Curve, CurveSpec, DQuat, KnotMode, Layout, SampleTimes, Sampling};
use std::sync::OnceLock;

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

/// Evaluates `batch` on the GPU and compares with the reference.
pub fn compare(gpu: &GpuEvaluator, batch: &Batch, times: &SampleTimes, options: GpuOptions, label: &str) -> Worst {
    let out = gpu.evaluate(batch, times, &options).unwrap();
    compare_output(&out, batch, times, options.layout, options.derivatives, label)
}

/// The GPU as a fast path under test.
fn on_gpu(gpu: &GpuEvaluator, generic_kernel: bool) -> impl Fn(&Batch, &SampleTimes, Layout, bool) -> FloatOutput + '_ {
    move |batch, times, layout, derivatives| gpu.evaluate(batch, times, &GpuOptions { layout, derivatives, generic_kernel, ..GpuOptions::default() }).unwrap()
}

#[test]
fn every_family_order_and_knot_mode_matches_the_reference() {
    let Some(gpu) = gpu() else { return };
    every_family_order_and_knot_mode(&on_gpu(gpu, false)).assert_within_bars("all families, 4 kinds, both layouts");
    eprintln!("samples excluded by the Nam-Kim blend antipode margin so far: {}", EXCLUDED.load(std::sync::atomic::Ordering::Relaxed));
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
        all.merge(compare_output(&out, &batch, &times, Layout::Track, true, &format!("mixed generic={generic_kernel}")));
    }
    all.assert_within_bars("mixed batch with repeated knots");
}

#[test]
fn sizes_that_are_not_multiples_of_the_workgroup() {
    let Some(gpu) = gpu() else { return };
    odd_sizes(&on_gpu(gpu, false));
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
    let Some(gpu) = gpu() else { return };
    long_clip(&on_gpu(gpu, false)).assert_within_bars("long clip at t = 1000..1037 s");
}
