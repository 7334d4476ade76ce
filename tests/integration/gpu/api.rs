//! The evaluator's API: embedding in an existing device, writing into a caller's buffer,
//! specialized and generic kernels, and errors as values.

use crate::common::*;
use crate::shared_gpu as gpu;
use quatcurve::gpu::{GpuDevice, GpuError};
use quatcurve::{Batch, Curve, CurveSpec, Layout, SampleTimes, Sampling};
use quatcurve::{EvalJob, JobOptions};

fn small_batch(spec: &CurveSpec) -> Batch {
    let mut g = Gen::new(2);
    let tracks: Vec<_> = (0..4).map(|i| track(&mut g, spec, spec.min_keys().max(2) + i, Kind::Random)).collect();
    Batch::from_tracks(&tracks, spec).unwrap()
}

#[test]
fn evaluate_into_a_caller_buffer_without_readback() {
    let Some(gpu) = gpu() else { return };
    let batch = small_batch(&CurveSpec::new(Curve::BSpline));
    let times = SampleTimes::uniform(&batch, Sampling::Count(33)).unwrap();
    let options = JobOptions { derivatives: true, ..JobOptions::default() };
    let expected = gpu.evaluate(&EvalJob::new(&batch, &times).with(options)).unwrap();
    let bytes = (expected.data.len() * 4) as u64;
    let target = gpu.device().create_buffer(&wgpu::BufferDescriptor {
        label: Some("engine buffer"),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    gpu.evaluate_into(&EvalJob::new(&batch, &times).with(options), &target).unwrap();
    // Read it back here only to check it.
    let staging = gpu.device().create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: bytes,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = gpu.device().create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(&target, 0, &staging, 0, bytes);
    gpu.queue().submit([encoder.finish()]);
    staging.map_async(wgpu::MapMode::Read, .., |r| r.unwrap());
    gpu.device().poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let data: Vec<f32> = bytemuck::cast_slice(&staging.get_mapped_range(..).unwrap()).to_vec();
    assert_eq!(data, expected.data);

    let too_small = gpu.device().create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 64,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let err = gpu.evaluate_into(&EvalJob::new(&batch, &times).with(options), &too_small).unwrap_err();
    assert!(matches!(err, GpuError::Job(_)), "{err}");
}

#[test]
fn with_device_embeds_in_an_existing_application() {
    let Some(gpu) = gpu() else { return };
    let (device, queue) = pollster::block_on(async {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = instance.request_adapter(&wgpu::RequestAdapterOptions::default()).await.unwrap();
        adapter.request_device(&wgpu::DeviceDescriptor::default()).await.unwrap()
    });
    let evaluator = GpuDevice::with_device(device, queue, "host application").unwrap();
    assert_eq!(evaluator.adapter_name(), "host application");
    let batch = small_batch(&CurveSpec::new(Curve::Squad));
    let times = SampleTimes::uniform(&batch, Sampling::Count(9)).unwrap();
    let out = evaluator.evaluate(&EvalJob::new(&batch, &times).with(JobOptions::default())).unwrap();
    assert_eq!(out.data.len(), times.total() * 4);
    // A device without MAPPABLE_PRIMARY_BUFFERS reads back through a staging copy; where
    // `GpuDevice::new` mapped its outputs directly (unified memory, as lavapipe), the
    // two paths must agree bit for bit, also over several chunks.
    assert_eq!(out.data, gpu.evaluate(&EvalJob::new(&batch, &times).with(JobOptions::default())).unwrap().data);
    let evaluator = evaluator.with_binding_limit(1024);
    let frame = JobOptions { layout: Layout::Frame, derivatives: true, ..JobOptions::default() };
    assert!(evaluator.prepare(&EvalJob::new(&batch, &times).with(frame)).unwrap().chunk_count() > 1);
    assert_eq!(
        evaluator.evaluate(&EvalJob::new(&batch, &times).with(frame)).unwrap().data,
        gpu.evaluate(&EvalJob::new(&batch, &times).with(frame)).unwrap().data
    );
}

#[test]
fn specialized_and_generic_kernels_agree() {
    let Some(gpu) = gpu() else { return };
    for spec in all_specs() {
        let batch = small_batch(&spec);
        let times = SampleTimes::uniform(&batch, Sampling::Rate(17.0)).unwrap();
        let special = gpu
            .evaluate(&EvalJob::new(&batch, &times).with(JobOptions { derivatives: true, ..JobOptions::default() }))
            .unwrap();
        let generic = gpu
            .evaluate(&EvalJob::new(&batch, &times).with(JobOptions {
                derivatives: true,
                generic_kernel: true,
                ..JobOptions::default()
            }))
            .unwrap();
        // Same code, different specialization: allow only f32 rounding differences.
        let diff = special
            .data
            .iter()
            .zip(&generic.data)
            .map(|(a, b)| (a - b).abs() / b.abs().max(1.0))
            .fold(0.0f32, f32::max);
        assert!(diff < 1e-5, "{}: {diff}", describe(&spec));
    }
}

#[test]
fn matrix_output_matches_the_rotation() {
    let Some(gpu) = gpu() else { return };
    let batch = small_batch(&CurveSpec::new(Curve::Hermite));
    let times = SampleTimes::uniform(&batch, Sampling::Count(11)).unwrap();
    let out =
        gpu.evaluate(&EvalJob::new(&batch, &times).with(JobOptions { matrix: true, ..JobOptions::default() })).unwrap();
    assert_eq!(out.channels, 13);
    for row in out.data.chunks_exact(13) {
        let q = quatcurve::QuatF64::from_xyzw(row[0].into(), row[1].into(), row[2].into(), row[3].into()).normalize();
        let m = q.to_mat3();
        for r in 0..3 {
            for c in 0..3 {
                assert!((m[r][c] - f64::from(row[4 + 3 * r + c])).abs() < 1e-6);
            }
        }
    }
}

#[test]
fn unsupported_batches_are_errors_naming_the_track() {
    let Some(gpu) = gpu() else { return };
    let spec = CurveSpec::new(Curve::Bezier);
    let mut g = Gen::new(1);
    let track = track(&mut g, &spec, 40, Kind::Random);
    let batch = Batch::from_tracks(&[track], &spec).unwrap();
    let times = SampleTimes::uniform(&batch, Sampling::Count(3)).unwrap();
    let err = gpu.evaluate(&EvalJob::new(&batch, &times).with(JobOptions::default())).unwrap_err().to_string();
    assert!(err.contains("track 0") && err.contains("degree 39"), "{err}");
}

/// Key times closer than the kernel's 32.32 fixed-point resolution would give zero-length
/// spans there and NaN samples: refused, naming the track and the knots; `auto` takes the
/// CPU path, which evaluates them.
#[test]
fn knots_closer_than_the_gpu_time_resolution_are_refused() {
    let Some(gpu) = gpu() else { return };
    let keys: Vec<[f64; 4]> = (0..5)
        .map(|i| quatcurve::QuatF64::exp(quatcurve::Vec3F64::new(0.1 * f64::from(i), 0.0, 0.0)).to_array())
        .collect();
    let times: Vec<f64> = (0..5).map(|i| 1e-11 * f64::from(i)).collect();
    let mut tiny = quatcurve::Track::from_rotations(keys.clone());
    tiny.times = Some(times);
    tiny.name = Some("tiny".into());
    let normal = quatcurve::Track::from_rotations(keys);
    for curve in [Curve::Slerp, Curve::Hermite, Curve::BSpline] {
        let batch = Batch::from_tracks(&[normal.clone(), tiny.clone()], &CurveSpec::new(curve)).unwrap();
        let times = SampleTimes::uniform(&batch, Sampling::Count(4)).unwrap();
        let err = gpu.evaluate(&EvalJob::new(&batch, &times)).unwrap_err().to_string();
        assert!(err.contains("tiny") && err.contains("time resolution"), "{curve}: {err}");
        let device = quatcurve::Device::Auto(Box::new(gpu.share_device()), quatcurve::cpu::CpuEvaluator::new());
        let mut out = quatcurve::Output::default();
        let name = device.evaluate_into(&EvalJob::new(&batch, &times), &mut out).unwrap();
        assert!(name.starts_with("cpu:") && out.rotations.iter().flatten().all(|v| v.is_finite()), "{curve}: {name}");
    }
}

#[test]
fn a_reused_output_buffer_gives_the_same_samples_as_a_fresh_one() {
    let Some(_) = gpu() else { return };
    // An evaluator of its own: the shared one is used by other tests in parallel.
    let evaluator = gpu().unwrap().share_device();
    let batch = small_batch(&CurveSpec::new(Curve::Hermite));
    let (big, small) = (
        SampleTimes::uniform(&batch, Sampling::Count(500)).unwrap(),
        SampleTimes::uniform(&batch, Sampling::Count(7)).unwrap(),
    );
    let options = JobOptions { derivatives: true, ..JobOptions::default() };
    let fresh = evaluator.evaluate(&EvalJob::new(&batch, &small).with(options)).unwrap();
    evaluator.evaluate(&EvalJob::new(&batch, &big).with(options)).unwrap();
    // Now the kept buffer is larger than this output and holds the big batch's samples.
    let reused = evaluator.evaluate(&EvalJob::new(&batch, &small).with(options)).unwrap();
    assert_eq!(reused.data, fresh.data);
    evaluator.release_buffers();
    assert_eq!(evaluator.evaluate(&EvalJob::new(&batch, &small).with(options)).unwrap().data, fresh.data);
}

/// The input buffers `evaluate` keeps (where inputs are mappable, as on lavapipe) are packed
/// again for the next chunk and the next call: a small batch packed into a larger batch's
/// buffers, whose tails still hold the larger batch's keys and knots, gives the bits of a
/// fresh evaluator, in one chunk and across chunks.
#[test]
fn reused_input_buffers_give_the_same_samples_as_fresh_ones() {
    let Some(_) = gpu() else { return };
    let small = crate::fast::batch_for(4, &CurveSpec::new(Curve::BSpline), Kind::Random, 5);
    let large = crate::fast::batch_for(9, &CurveSpec::new(Curve::Hermite), Kind::Random, 60);
    let times = |batch: &Batch| SampleTimes::uniform(batch, Sampling::Count(33)).unwrap();
    let options = JobOptions { derivatives: true, ..JobOptions::default() };
    for limit in [u64::MAX, 8 * 1024] {
        let fresh = gpu()
            .unwrap()
            .share_device()
            .with_binding_limit(limit)
            .evaluate(&EvalJob::new(&small, &times(&small)).with(options))
            .unwrap();
        // An evaluator of its own: the shared one is used by other tests in parallel.
        let evaluator = gpu().unwrap().share_device().with_binding_limit(limit);
        evaluator.evaluate(&EvalJob::new(&large, &times(&large)).with(options)).unwrap();
        let reused = evaluator.evaluate(&EvalJob::new(&small, &times(&small)).with(options)).unwrap();
        assert_eq!(reused.data, fresh.data, "binding limit {limit}");
    }
}

/// The roofline kernel writes what `bench` says it does: the same bytes as the evaluation
/// (every channel of every sample of every chunk), here the sample index in each.
#[test]
fn the_roofline_kernel_writes_every_output_float() {
    let Some(gpu) = gpu() else { return };
    let evaluator = gpu.share_device().with_binding_limit(4096);
    let batch = small_batch(&CurveSpec::new(Curve::BSpline));
    let times = SampleTimes::uniform(&batch, Sampling::Count(70)).unwrap();
    let options = JobOptions { derivatives: true, ..JobOptions::default() };
    let prepared = evaluator.prepare(&EvalJob::new(&batch, &times).with(options)).unwrap();
    assert!(prepared.chunk_count() > 1);
    evaluator.roofline(&prepared).unwrap();
    let out = evaluator.read(&prepared).unwrap();
    // Chunk-local sample indices 0, 1, 2, ... restarting at each chunk; every float written.
    let (mut next, mut chunks) = (0.0f32, 0);
    for row in out.data.chunks_exact(10) {
        assert!(row.iter().all(|&v| v == row[0]), "{row:?}");
        if row[0] == 0.0 {
            chunks += 1;
        } else {
            assert_eq!(row[0], next);
        }
        next = row[0] + 1.0;
    }
    assert_eq!(chunks, prepared.chunk_count());
    let _ = gpu;
}

/// `Device::Auto` (what `--device auto` opens over a hardware adapter; over lavapipe it opens
/// the CPU path) hands a batch the kernel cannot take to the CPU path and names it.
#[test]
fn auto_hands_batches_the_kernel_refuses_to_the_cpu_path() {
    let Some(_) = gpu() else { return };
    let evaluator = gpu().unwrap().share_device();
    let software = evaluator.is_software();
    let device = quatcurve::Device::Auto(Box::new(evaluator), quatcurve::cpu::CpuEvaluator::new());
    let keys: Vec<[f64; 4]> = (0..40)
        .map(|i| quatcurve::QuatF64::exp(quatcurve::Vec3F64::new(0.0, 0.0, 0.05 * f64::from(i))).to_array())
        .collect();
    let batch = Batch::from_tracks(&[quatcurve::Track::from_rotations(keys)], &CurveSpec::new(Curve::Bezier)).unwrap();
    let times = SampleTimes::uniform(&batch, Sampling::Count(5)).unwrap();
    let job = quatcurve::EvalJob::new(&batch, &times).layout(Layout::Track).derivatives(false);
    let name = device.evaluate_into(&job, &mut quatcurve::Output::default()).unwrap();
    assert!(name.starts_with("cpu:"), "{name}");
    let small = small_batch(&CurveSpec::new(Curve::BSpline));
    let times = SampleTimes::uniform(&small, Sampling::Count(5)).unwrap();
    let job = quatcurve::EvalJob::new(&small, &times).layout(Layout::Track).derivatives(false);
    let name = device.evaluate_into(&job, &mut quatcurve::Output::default()).unwrap();
    assert!(name.starts_with("gpu:"), "{name}");
    // lavapipe is a software adapter: plain `auto` opens the CPU path there.
    if software {
        assert!(quatcurve::Device::open(quatcurve::DeviceChoice::Auto).unwrap().name().starts_with("cpu:"));
    }
}

/// The forward-kinematics kernel against its CPU twin (f64) on the crowd's hierarchy and a
/// deep chain with scales.
#[test]
fn forward_kinematics_on_the_gpu_matches_the_cpu_twin() {
    let Some(gpu) = gpu() else { return };
    use quatcurve::anim::Joint;
    use quatcurve::bake::texture;
    use quatcurve::formats::crowd;
    let mut animation = crowd::crowd(3);
    // A 40-joint chain under the crowd's first root, scaled unevenly, not animated.
    for k in 0..40 {
        let parent = if k == 0 { 0 } else { animation.joints.len() - 1 };
        let mut joint = Joint::at(format!("chain{k}"), Some(parent), [0.05, 0.1, -0.02]);
        joint.rotation = quatcurve::QuatF64::exp(quatcurve::Vec3F64::new(0.05, -0.1, 0.2)).to_array();
        joint.scale = [1.01, 0.99, 1.02];
        animation.joints.push(joint);
    }
    let device = quatcurve::Device::open(quatcurve::DeviceChoice::Cpu).unwrap();
    let baked = quatcurve::bake::bake(
        &animation,
        &quatcurve::anim::curves::CurveChoice::Family(CurveSpec::new(Curve::BSplineInterp)),
        quatcurve::bake::ClipRate::Fit(30.0),
        quatcurve::anim::loops::LoopMode::Auto,
        &device,
    )
    .unwrap();
    let order = animation.parents_first().unwrap();
    let local = texture::local(&animation, &baked, 0);
    let parents = animation.parents();
    let cpu = quatcurve::skeleton::forward_kinematics(&parents, &order, &local);
    let on_gpu = gpu.forward_kinematics(&parents, &order, &local).unwrap();
    assert_eq!(on_gpu.len(), cpu.len());
    let scale = cpu.iter().fold(1.0f32, |a, v| a.max(v.abs()));
    let worst = on_gpu.iter().zip(&cpu).map(|(g, c)| (g - c).abs()).fold(0.0f32, f32::max) / scale;
    assert!(worst <= 1e-5, "GPU forward kinematics off by {worst} (relative to {scale})");
    // A parent listed after its child is refused, not computed wrong.
    let mut bad = order.clone();
    bad.reverse();
    assert!(gpu.forward_kinematics(&parents, &bad, &local).is_err());
}

/// The child of [`opening_a_gpu_prints_nothing_without_a_runtime_directory`]: opens a device.
#[test]
#[ignore = "run by opening_a_gpu_prints_nothing_without_a_runtime_directory, in a process of its own"]
fn open_a_gpu_device() {
    GpuDevice::new().unwrap();
}

#[test]
fn opening_a_gpu_prints_nothing_without_a_runtime_directory() {
    if crate::shared_gpu().is_none() {
        return;
    }
    // A library user's process on a server: no XDG_RUNTIME_DIR (Mesa's drivers would print
    // "XDG_RUNTIME_DIR is invalid or not set" twice per device).
    let child = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "gpu::api::open_a_gpu_device", "--ignored", "--nocapture", "--test-threads", "1"])
        .env_remove("XDG_RUNTIME_DIR")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&child.stderr);
    assert!(child.status.success() && String::from_utf8_lossy(&child.stdout).contains("1 passed"), "{stderr}");
    assert!(!stderr.contains("XDG_RUNTIME_DIR"), "{stderr}");
}
