//! The fit through its own API ([`FitJob`]): a file fitted into a container within the budget,
//! which the runtime decoder (`quatcurve_qcf::decoder`) plays back near the source's frames.

use quatcurve_fit::job::{FitJob, FitOptions};
use quatcurve_formats::source::{ReadOptions, Source};
use quatcurve_qcf::decoder::{Decoder, POSE_FLOATS};
use std::fmt::Write;

/// A two-joint BVH of `frames` frames at 30 Hz: the root still, its child swinging by up to
/// 40 degrees about Z.
fn swinging_arm(frames: usize) -> String {
    let mut text = String::from(
        "HIERARCHY\nROOT hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n  \
         JOINT arm\n  {\n    OFFSET 0 10 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n    End Site\n    {\n      \
         OFFSET 0 10 0\n    }\n  }\n}\nMOTION\n",
    );
    writeln!(text, "Frames: {frames}\nFrame Time: 0.0333333").unwrap();
    for f in 0..frames {
        let angle = 40.0 * (f as f64 / frames as f64 * std::f64::consts::TAU).sin();
        writeln!(text, "0 0 0 0 0 0 {angle:.4} 0 0").unwrap();
    }
    text
}

#[test]
fn a_fitted_container_decodes_to_poses_within_the_budget_of_its_source_frames() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("arm.bvh");
    std::fs::write(&input, swinging_arm(60)).unwrap();
    let options = FitOptions { unit_cm: Some(1.0), ..FitOptions::DEFAULT };
    let job = FitJob { inputs: vec![input.clone()], output: dir.path().join("out"), options: options.clone() };
    let report = job.run(&|_, _| {}).unwrap();
    assert_eq!(report.failed(), 0, "{:?}", report.inputs[0].error);
    let fitted = &report.inputs[0].clips[0];
    assert!(fitted.at_frames.error_cm <= options.max_error_cm, "{fitted:?}");

    let container = std::fs::read(dir.path().join("out/arm.qcf")).unwrap();
    let decoder = Decoder::from_bytes(&container).unwrap();
    let clip = &mut decoder.open(0).unwrap();
    let source = Source::read(&input, ReadOptions::default()).unwrap();
    let keys = source.animation().clips[0].channels.iter().find(|c| c.joint == 1).unwrap().keyed().unwrap();
    let mut pose = vec![0.0f32; clip.pose_floats()];
    for (&t, key) in keys.0.iter().zip(keys.1) {
        clip.pose(t, &mut pose).unwrap();
        // Joint 1's rotation, `x, y, z, w`, after joint 0's local row.
        let row = POSE_FLOATS;
        let q: Vec<f64> = pose[row..row + 4].iter().map(|&v| f64::from(v)).collect();
        let dot = (0..4).map(|i| q[i] * key[i]).sum::<f64>().abs().min(1.0);
        let degrees = 2.0 * dot.acos().to_degrees();
        // A virtual vertex `vertex_distance` from the joint moves at most `max_error`: the
        // rotation is within that chord's angle (the root is still).
        let bound = (2.0 * (options.max_error_cm / (2.0 * options.vertex_distance_cm)).asin()).to_degrees() * 1.001;
        assert!(degrees <= bound, "at {t} s the decoded arm is {degrees} degrees from its key (bound {bound})");
    }
}

#[test]
fn a_bvh_without_its_unit_is_refused_before_any_input_is_fitted() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("arm.bvh");
    std::fs::write(&input, swinging_arm(10)).unwrap();
    let job = FitJob { inputs: vec![input], output: dir.path().join("out"), options: FitOptions::DEFAULT };
    let error = job.run(&|_, _| {}).unwrap_err();
    assert!(matches!(error, quatcurve_files::FileJobError::Option { option: "unit_cm", .. }), "{error}");
    assert!(!dir.path().join("out").exists());
}
