//! `CurvePalettes` through the GPU crate's own API on an adapter (lavapipe in CI): a two-joint
//! arm whose rotations are B-spline tracks, played by instances at their own times and blends,
//! against the f64 reference's rotations and the skeleton's forward kinematics. Skipped
//! without an adapter unless `QUATCURVE_REQUIRE_GPU=1`.

use quatcurve_core::curve::{Curve, CurveSpec};
use quatcurve_core::quat::QuatF64;
use quatcurve_eval::batch::BatchBuilder;
use quatcurve_eval::output::{LOCAL_CHANNELS, MATRIX_CHANNELS};
use quatcurve_eval::reference::evaluate_rotation;
use quatcurve_eval::skeleton::{forward_kinematics, PoseCurves, PoseSource, PoseTimes};
use quatcurve_eval::track::Track;
use quatcurve_gpu::{CurvePalettes, GpuContext};

/// The test's context, or None (skip) when there is no adapter and none is required.
fn context() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(context) => Some(context),
        Err(e) if std::env::var("QUATCURVE_REQUIRE_GPU").as_deref() == Ok("1") => {
            panic!("QUATCURVE_REQUIRE_GPU=1 but {e}")
        }
        Err(e) => {
            eprintln!("skipped: no GPU adapter ({e})");
            None
        }
    }
}

/// A unit quaternion `[x, y, z, w]` of `angle` radians about `axis` (normalized here).
fn about(axis: [f64; 3], angle: f64) -> [f64; 4] {
    let n = axis.iter().map(|a| a * a).sum::<f64>().sqrt();
    let (s, c) = (angle / 2.0).sin_cos();
    [axis[0] / n * s, axis[1] / n * s, axis[2] / n * s, c]
}

#[test]
fn instances_play_the_reference_s_poses_at_their_own_times_and_blends() {
    let Some(context) = context() else { return };
    // Two clips of two joints; each joint's rotation a track of five keys over 2 s.
    let times: Vec<f64> = (0..5).map(|k| 0.5 * k as f64).collect();
    let track = |axis: [f64; 3], turn: f64| Track {
        times: Some(times.clone()),
        rotations: (0..5).map(|k| about(axis, turn * k as f64 * (1.0 + 0.2 * k as f64))).collect(),
        ..Track::default()
    };
    let tracks = [
        track([0.0, 0.0, 1.0], 0.4),
        track([1.0, 0.0, 0.0], -0.3),
        track([0.3, 1.0, 0.0], 0.7),
        track([0.0, 1.0, 1.0], 0.2),
    ];
    let spec = CurveSpec::new(Curve::BSplineInterp);
    let mut builder = BatchBuilder::new();
    for t in &tracks {
        builder.add(t, &spec).unwrap();
    }
    let batch = builder.build().unwrap();
    // Per clip, per joint: rotation track, translation, scale. The child hangs one unit up.
    let offsets = [[0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]];
    let scale = PoseSource::Value([1.0, 1.0, 1.0, 0.0]);
    let mut sources = Vec::new();
    for clip in 0..2 {
        for (joint, offset) in offsets.iter().enumerate() {
            sources.extend([PoseSource::Rotation(2 * clip + joint), PoseSource::Value(*offset), scale]);
        }
    }
    let parents = [None, Some(0)];
    let order = [0, 1];
    let curves =
        PoseCurves { batch: Some(&batch), vectors: Vec::new(), sources, parents: &parents, order: &order, skin: None };
    let palettes = CurvePalettes::new(&context, &curves).unwrap();
    let instances = [
        PoseTimes { clips: [0, 0], times: [0.3, 0.3], weight: 0.0 },
        PoseTimes { clips: [1, 0], times: [1.7, 0.9], weight: 0.0 },
        PoseTimes { clips: [0, 1], times: [1.1, 0.4], weight: 0.35 },
    ];
    let got = palettes.run(&instances).unwrap();
    assert_eq!(got.len(), instances.len() * 2 * MATRIX_CHANNELS);
    for (i, instance) in instances.iter().enumerate() {
        // The blend of the two poses (shorter arc) as the skeleton's local rows, then FK.
        let mut local = vec![0.0f32; 2 * LOCAL_CHANNELS];
        for joint in 0..2 {
            let rotation = |pose: usize| {
                let view = batch.view(2 * instance.clips[pose] + joint);
                evaluate_rotation(view, instance.times[pose])
            };
            let (a, b): (QuatF64, QuatF64) = (rotation(0), rotation(1));
            let b = if a.to_array().iter().zip(b.to_array()).map(|(x, y)| x * y).sum::<f64>() < 0.0 { -b } else { b };
            let q = a.slerp(b, f64::from(instance.weight)).to_array();
            let row = &mut local[joint * LOCAL_CHANNELS..(joint + 1) * LOCAL_CHANNELS];
            row[..4].copy_from_slice(&q.map(|v| v as f32));
            row[4..7].copy_from_slice(&[0.0, offsets[joint][1], 0.0]);
            row[7..10].copy_from_slice(&[1.0; 3]);
        }
        let want = forward_kinematics(&parents, &order, &local);
        let mine = &got[i * 2 * MATRIX_CHANNELS..(i + 1) * 2 * MATRIX_CHANNELS];
        let worst = mine.iter().zip(&want).map(|(g, w)| (g - w).abs()).fold(0.0f32, f32::max);
        // f32 curves and blends on the device against f64 rotations (about 2.4e-7 on lavapipe):
        // entries of unit rotations and one-unit offsets.
        assert!(worst < 2e-6, "instance {i}: largest difference {worst}\n{mine:?}\n{want:?}");
    }
}
