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

#[test]
fn a_library_holds_every_input_s_clips_on_one_skeleton_stored_once_and_refuses_another_skeleton() {
    let dir = tempfile::tempdir().unwrap();
    let mut inputs = Vec::new();
    for (stem, frames) in [("swing", 60), ("sway", 45)] {
        let input = dir.path().join(format!("{stem}.bvh"));
        std::fs::write(&input, swinging_arm(frames)).unwrap();
        inputs.push(input);
    }
    let options = FitOptions { unit_cm: Some(1.0), ..FitOptions::DEFAULT };
    let apart = FitJob { inputs: inputs.clone(), output: dir.path().join("apart"), options: options.clone() };
    let apart = apart.run(&|_, _| {}).unwrap();
    let library = FitOptions { clip_library: Some("arm".into()), ..options.clone() };
    let job = FitJob { inputs: inputs.clone(), output: dir.path().join("library"), options: library.clone() };
    let report = job.run(&|_, _| {}).unwrap();
    assert_eq!(report.failed(), 0, "{report:?}");
    let written = report.clip_library.as_ref().unwrap();
    let path = dir.path().join("library/arm.qcf");
    assert_eq!(written.output.as_deref(), Some(path.to_str().unwrap()));
    assert_eq!(std::fs::read_dir(dir.path().join("library")).unwrap().count(), 1, "the library alone");
    // The clips as each input's own container holds them, the skeleton and hierarchy once.
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(written.container_bytes, bytes.len());
    let apart_bytes: usize = apart.inputs.iter().map(|i| i.container_bytes).sum();
    let clip_bytes: usize = apart.inputs.iter().flat_map(|i| &i.clips).map(|c| c.compressed_bytes).sum();
    assert_eq!(written.clip_bytes, clip_bytes);
    assert!(bytes.len() < apart_bytes, "{} bytes, {apart_bytes} apart", bytes.len());
    assert!(written.whole_file_ratio > apart.inputs[0].whole_file_ratio, "{written:?}");
    let decoder = Decoder::from_bytes(&bytes).unwrap();
    let names: Vec<&str> = decoder.clips().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["sway", "swing"], "in the inputs' order, by path");
    for (index, apart) in apart.inputs.iter().enumerate() {
        let alone = Decoder::from_bytes(&std::fs::read(apart.output.as_ref().unwrap()).unwrap()).unwrap();
        let (mut one, mut other) = (decoder.open(index).unwrap(), alone.open(0).unwrap());
        let (mut a, mut b) = (vec![0.0; one.pose_floats()], vec![0.0; other.pose_floats()]);
        for f in 0..40 {
            one.pose(f64::from(f) / 30.0, &mut a).unwrap();
            other.pose(f64::from(f) / 30.0, &mut b).unwrap();
            assert_eq!(a, b, "clip {index} frame {f}");
        }
    }
    // Another skeleton: refused before any fit, naming both files and the joint.
    let other = dir.path().join("other.bvh");
    std::fs::write(&other, swinging_arm(30).replace("JOINT arm", "JOINT leg")).unwrap();
    let job = FitJob {
        inputs: vec![inputs[0].clone(), other.clone()],
        output: dir.path().join("mixed"),
        options: library.clone(),
    };
    let error = job.run(&|_, _| {}).unwrap_err().to_string();
    assert!(
        error.starts_with("clip_library holds clips of one skeleton: ")
            && error.contains("swing.bvh's is not")
            && error.contains("other.bvh's (joint 1: 'arm' is not 'leg' as it hangs and rests)"),
        "{error}"
    );
    assert!(!dir.path().join("mixed").exists(), "nothing written");
    let job = FitJob {
        inputs,
        output: dir.path().join("named"),
        options: FitOptions { clip_library: Some("a/b".into()), ..library },
    };
    let error = job.run(&|_, _| {}).unwrap_err().to_string();
    assert_eq!(error, "clip_library 'a/b' is not a file name: the library is <output>/<NAME>.qcf");
}
