//! Throughput of every evaluation path in samples per second (criterion), on the same
//! deterministic workloads (`synthetic::workload`: 32 keys per track at 30 Hz).
//!
//! Workloads: uniform cubic B-spline 10,000 tracks x 1,000 samples (the GPU issue's), a
//! non-uniform (clamped) order-5 B-spline, Hermite and squad, each value only and with
//! derivatives. Paths: the f64 reference on a 1,000-track slice (it is the oracle, not a fast
//! path), the fast CPU path end to end and into a reused buffer, the GPU end to end (upload,
//! dispatch, readback) and dispatch only, and for the cubic B-spline the GPU's generic
//! (switching) kernel.
//!
//! Run: `cargo bench --bench throughput` (filter with e.g. `-- cpu`).

// criterion_group! generates an undocumented public function.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use quatcurve::cpu::CpuEvaluator;
use quatcurve::gpu::GpuDevice;
use quatcurve::{synthetic, Curve, CurveSpec, EvalJob, JobOptions, KnotMode};

const TRACKS: usize = 10_000;
const SAMPLES: usize = 1_000;

fn workloads() -> Vec<(&'static str, CurveSpec)> {
    vec![
        ("bspline4_uniform", CurveSpec { knots: KnotMode::Uniform, ..CurveSpec::new(Curve::BSpline) }),
        ("bspline5_clamped", CurveSpec { knots: KnotMode::Clamped, order: 5, ..CurveSpec::new(Curve::BSpline) }),
        ("hermite", CurveSpec::new(Curve::Hermite)),
        ("squad", CurveSpec::new(Curve::Squad)),
    ]
}

fn paths(c: &mut Criterion) {
    let gpu = GpuDevice::new().map_err(|e| eprintln!("GPU rows skipped: no GPU adapter ({e})")).ok();
    let cpu = CpuEvaluator::new();
    eprintln!("CPU: {}; GPU: {}", cpu.name(), gpu.as_ref().map_or("none", |g| g.adapter_name()));
    for (name, spec) in workloads() {
        let (batch, times) =
            synthetic::workload(TRACKS, SAMPLES, synthetic::WORKLOAD_KEYS, &spec).expect("valid workload");
        let (slice, slice_times) =
            synthetic::workload(TRACKS / 10, SAMPLES, synthetic::WORKLOAD_KEYS, &spec).expect("valid workload");
        for derivatives in [false, true] {
            let what = if derivatives { "derivatives" } else { "value" };
            let mut group = c.benchmark_group(format!("{name}/{what}"));
            group.sample_size(10);
            group.throughput(Throughput::Elements(slice_times.total() as u64));
            group.bench_function("reference_1k_tracks", |b| {
                b.iter(|| EvalJob::new(&slice, &slice_times).derivatives(derivatives).run().unwrap())
            });
            group.throughput(Throughput::Elements(times.total() as u64));
            let job = EvalJob::new(&batch, &times).derivatives(derivatives);
            group.bench_function("cpu", |b| b.iter(|| cpu.evaluate(&job).unwrap()));
            let mut buffer = vec![0.0f32; times.total() * job.options.row().channels()];
            group.bench_function("cpu_reused_buffer", |b| b.iter(|| cpu.evaluate_into(&job, &mut buffer).unwrap()));
            if let Some(gpu) = &gpu {
                group.bench_function("gpu_end_to_end", |b| b.iter(|| gpu.evaluate(&job).unwrap()));
                let prepared = gpu.prepare(&job).unwrap();
                group.bench_function("gpu_dispatch_only", |b| b.iter(|| gpu.dispatch(&prepared).unwrap()));
                if name == "bspline4_uniform" {
                    let generic = gpu.prepare(&job.with(JobOptions { generic_kernel: true, ..job.options })).unwrap();
                    group.bench_function("gpu_dispatch_only_generic_kernel", |b| {
                        b.iter(|| gpu.dispatch(&generic).unwrap())
                    });
                }
            }
            group.finish();
        }
    }
}

/// `bspline-interp`: the builder's Newton solve in keys per second (2,000 walk tracks of 32
/// keys, open, and whole gait cycles looping), and build plus CPU evaluation of 1,000 samples per track (the
/// end-to-end figure compared with scipy's RotationSpline in the README).
fn interp(c: &mut Criterion) {
    let open = synthetic::walk_tracks(2_000, synthetic::WORKLOAD_KEYS, 30.0);
    let closed = synthetic::walk_cycles(2_000, synthetic::WORKLOAD_KEYS, 30.0);
    let keys = (open.len() * synthetic::WORKLOAD_KEYS) as u64;
    let cpu = CpuEvaluator::new();
    let mut group = c.benchmark_group("bspline_interp");
    group.sample_size(10);
    for (name, tracks, looping) in [("solve_open", &open, false), ("solve_loop", &closed, true)] {
        let spec = CurveSpec { looping, ..CurveSpec::new(Curve::BSplineInterp) };
        group.throughput(Throughput::Elements(keys));
        group.bench_function(name, |b| b.iter(|| quatcurve::Batch::from_tracks(tracks, &spec).unwrap()));
    }
    let spec = CurveSpec::new(Curve::BSplineInterp);
    group.throughput(Throughput::Elements(open.len() as u64 * 1_000));
    group.bench_function("build_and_evaluate_cpu_1000_samples", |b| {
        b.iter(|| {
            let batch = quatcurve::Batch::from_tracks(&open, &spec).unwrap();
            let times = quatcurve::SampleTimes::uniform(&batch, quatcurve::Sampling::Count(1_000)).unwrap();
            cpu.evaluate(&EvalJob::new(&batch, &times)).unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, interp, paths);
criterion_main!(benches);
