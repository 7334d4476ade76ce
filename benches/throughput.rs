//! Throughput of the evaluation paths in samples per second (criterion).
//!
//! Workload of the GPU issue: uniform cubic B-spline, 10,000 tracks x 1,000 samples (32 keys
//! per track), value only and with derivatives; GPU end to end (upload, dispatch, readback)
//! and dispatch only; specialized vs generic (switching) kernel. The f64 reference runs a
//! 1,000-track slice of the same workload (it is the oracle, not a fast path).
//!
//! Run: `cargo bench --bench throughput`. Inputs are deterministic (`synthetic::walk_tracks`).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use quatcurve::gpu::{GpuEvaluator, GpuOptions};
use quatcurve::{synthetic, Batch, CurveSpec, EvalJob, KnotMode, Layout, SampleTimes};

const TRACKS: usize = 10_000;
const SAMPLES: usize = 1_000;

fn workload(tracks: usize) -> (Batch, SampleTimes) {
    let spec = CurveSpec { knots: KnotMode::Uniform, ..CurveSpec::default() };
    synthetic::workload(tracks, SAMPLES, &spec).expect("valid synthetic workload")
}

fn reference(c: &mut Criterion) {
    let (batch, times) = workload(TRACKS / 10);
    let mut group = c.benchmark_group("reference_bspline4_uniform");
    group.sample_size(10).throughput(Throughput::Elements(times.total() as u64));
    for derivatives in [false, true] {
        group.bench_function(if derivatives { "derivatives" } else { "value" }, |b| {
            b.iter(|| EvalJob { batch: &batch, times: &times, layout: Layout::Track, derivatives }.run().unwrap())
        });
    }
    group.finish();
}

fn gpu(c: &mut Criterion) {
    let Ok(gpu) = GpuEvaluator::new() else {
        eprintln!("skipped: no GPU adapter");
        return;
    };
    eprintln!("GPU: {}", gpu.adapter_name());
    let (batch, times) = workload(TRACKS);
    let mut group = c.benchmark_group("gpu_bspline4_uniform_10k_x_1k");
    group.sample_size(10).throughput(Throughput::Elements(times.total() as u64));
    for derivatives in [false, true] {
        let name = if derivatives { "derivatives" } else { "value" };
        let options = GpuOptions { derivatives, ..GpuOptions::default() };
        group.bench_function(format!("{name}/end_to_end"), |b| b.iter(|| gpu.evaluate(&batch, &times, &options).unwrap()));
        let prepared = gpu.prepare(&batch, &times, &options).unwrap();
        group.bench_function(format!("{name}/dispatch_only"), |b| b.iter(|| gpu.dispatch(&prepared).unwrap()));
        let generic = gpu.prepare(&batch, &times, &GpuOptions { generic_kernel: true, ..options }).unwrap();
        group.bench_function(format!("{name}/dispatch_only_generic_kernel"), |b| b.iter(|| gpu.dispatch(&generic).unwrap()));
    }
    group.finish();
}

criterion_group!(benches, reference, gpu);
criterion_main!(benches);
