//! `quatcurve fit` end to end: a real CMU clip fitted within ACL's error, its container baked
//! back to BVH at the source rate on every device, and the error measured again from the
//! decoded BVH alone (parsed, posed and compared with the source, frame by frame), which must
//! be the report's; and the faults a fit or a bad container meets, named.

use super::{bake, data_dir, stderr};
use assert_cmd::Command;
use quatcurve::analysis::vertex_error::{pose_errors, Transform};
use quatcurve::anim::loops::LoopMode;
use quatcurve::anim::{Animation, Property};
use quatcurve::bake::{self as bake_lib, ClipRate, Reuse};
use quatcurve::formats::bvh;
use quatcurve::qcf::decoder::{Decoder, POSE_FLOATS};
use quatcurve::qcf::fitted::{Fitted, Form};
use quatcurve::qcf::Container;
use std::path::{Path, PathBuf};

/// CMU's BVH unit in cm.
const CMU_UNIT_CM: f64 = 5.644;

/// `quatcurve ARGS`, run to the end.
fn quatcurve(args: &[&str]) -> std::process::Output {
    Command::cargo_bin("quatcurve").unwrap().args(args).output().unwrap()
}

fn fit(args: &[&str]) -> std::process::Output {
    quatcurve(&[&["fit"][..], args].concat())
}

/// Every `every`th of the first `frames` frames of `source` as a BVH file at `path`.
fn first_frames(source: &Path, frames: usize, every: usize, path: &Path) {
    let text = std::fs::read_to_string(source).unwrap();
    let (hierarchy, motion) = text.split_at(text.find("MOTION").unwrap());
    let lines = motion.lines().skip(3).filter(|l| !l.trim().is_empty());
    let frame_time: f64 = motion.lines().nth(2).unwrap().split(':').nth(1).unwrap().trim().parse().unwrap();
    let rows: Vec<&str> = lines.take(frames).step_by(every).collect();
    let frame_time = frame_time * every as f64;
    std::fs::write(
        path,
        format!("{hierarchy}MOTION\nFrames: {}\nFrame Time: {frame_time}\n{}\n", rows.len(), rows.join("\n")),
    )
    .unwrap();
}

/// Each frame's local transforms: the rest pose with the clip's keys at frame `f`.
fn pose(animation: &Animation, f: usize) -> Vec<Transform> {
    let mut local: Vec<Transform> = animation
        .joints
        .iter()
        .map(|j| Transform { rotation: j.rotation, translation: j.translation, scale: j.scale })
        .collect();
    for c in &animation.clips[0].channels {
        let v = c.keyed().expect("keys").1[f];
        match c.property {
            Property::Rotation => local[c.joint].rotation = v,
            Property::Translation => local[c.joint].translation = [v[0], v[1], v[2]],
            Property::Scale => local[c.joint].scale = [v[0], v[1], v[2]],
        }
    }
    local
}

/// The worst virtual-vertex error (file units) over the frames of `decoded` against `source`.
fn worst_error(source: &Animation, decoded: &Animation, distance: f64) -> f64 {
    let parents = source.parents();
    let order = source.parents_first().unwrap();
    let frames = source.clips[0].channels[0].len();
    assert_eq!(decoded.clips[0].channels[0].len(), frames, "every source frame decoded");
    (0..frames)
        .map(|f| pose_errors(&parents, &order, &pose(source, f), &pose(decoded, f), distance))
        .flat_map(|errors| errors.into_iter())
        .fold(0.0, f64::max)
}

#[test]
fn a_fitted_bvh_bakes_back_to_its_frames_within_the_error_the_report_gives() {
    bakes_back_within_the_reported_error(1);
}

#[test]
fn a_fitted_bvh_at_24_hz_keeps_keys_and_bakes_back_within_the_reported_error() {
    let Some(container) = bakes_back_within_the_reported_error(5) else { return };
    // Noisy frames at a low rate: keys are cheaper than a cubic, and the GPU decodes them.
    let container = Container::from_bytes(&container).unwrap();
    let keyed = container.clips[0]
        .channels
        .iter()
        .filter(|c| {
            matches!(&c.curve, Fitted::Rotation(s, _) if s.form == Form::Keys)
                || matches!(&c.curve, Fitted::Vector(s, _) if s.form == Form::Keys)
        })
        .count();
    assert!(keyed * 2 > container.clips[0].channels.len(), "{keyed} channels kept as keys");
}

/// The first 240 frames of CMU 131_01 at 120 Hz, every `every`th of them, fitted within 0.01
/// cm, baked back at their rate on every device and measured from the BVH; the container's
/// bytes.
fn bakes_back_within_the_reported_error(every: usize) -> Option<Vec<u8>> {
    let data = data_dir()?;
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("walk.bvh");
    first_frames(&data.join("cmu_131_01.bvh"), 240, every, &source);
    let fitted = dir.path().join("fitted");
    let unit = CMU_UNIT_CM.to_string();
    let result = fit(&[
        "--input",
        source.to_str().unwrap(),
        "--output",
        fitted.to_str().unwrap(),
        "--max-error-cm",
        "0.01",
        "--unit-cm",
        &unit,
        "--json",
    ]);
    assert!(result.status.success(), "{}", stderr(&result));
    let report: serde_json::Value = serde_json::from_slice(&result.stdout).unwrap();
    let input = &report["inputs"][0];
    let clip = &input["clips"][0];
    let at_frames_cm = clip["at_frames"]["error_cm"].as_f64().unwrap();
    assert!(at_frames_cm <= 0.01, "{clip}");
    assert!(clip["between_frames"]["error_cm"].as_f64().unwrap() <= 0.3, "{clip}");
    let frames = 240 / every;
    assert_eq!(clip["frames"], frames);
    assert_eq!(clip["raw_bytes"].as_u64().unwrap(), 40 * 31 * frames as u64, "ACL's raw bytes: 40 per joint per frame");
    let (raw, compressed) = (clip["raw_bytes"].as_f64().unwrap(), clip["compressed_bytes"].as_f64().unwrap());
    assert!(raw / compressed > 8.0 / every as f64, "{clip}");
    let container = fitted.join("walk.qcf");
    // The clip's bytes are in the container, beside the skeleton and the BVH hierarchy.
    let file_bytes = std::fs::metadata(&container).unwrap().len();
    assert_eq!(input["container_bytes"].as_u64().unwrap(), file_bytes);
    assert!(compressed < file_bytes as f64);
    let source_animation = bvh::read(&source).unwrap().animation("walk");
    let devices: &[&str] =
        if crate::shared_gpu().is_some() { &["cpu", "gpu", "reference"] } else { &["cpu", "reference"] };
    let rate = (120 / every).to_string();
    for device in devices {
        let out = dir.path().join(device);
        let baked = bake(&[
            "--input",
            container.to_str().unwrap(),
            "--rate",
            &rate,
            "--device",
            device,
            "--output",
            out.to_str().unwrap(),
        ]);
        assert!(baked.status.success(), "{device}: {}", stderr(&baked));
        let sidecar = super::json(&out.join("walk.json"));
        assert_eq!(sidecar["curve"], "fitted-bspline", "{device}");
        let decoded = bvh::read(&out.join("walk.bvh")).unwrap();
        assert!((decoded.frame_time - every as f64 / 120.0).abs() < 1e-9, "{device}: {}", decoded.frame_time);
        let again_cm = worst_error(&source_animation, &decoded.animation("walk"), 3.0 / CMU_UNIT_CM) * CMU_UNIT_CM;
        eprintln!("{device}: the decoded BVH is within {again_cm} cm; the report says {at_frames_cm} cm");
        assert!((again_cm - at_frames_cm).abs() <= 2e-5, "{device}: {again_cm} cm decoded, {at_frames_cm} reported");
    }
    // The runtime decoder, frame after frame from the bytes, poses the skeleton as the bake does.
    let bytes = std::fs::read(&container).unwrap();
    let decoder = Decoder::from_bytes(&bytes).unwrap();
    let mut clip = decoder.open(0).unwrap();
    let [start, end] = clip.span();
    assert!(
        (clip.rate - 120.0 / every as f64).abs() < 1e-9
            && ((end - start) * clip.rate - (frames - 1) as f64).abs() < 1e-6
    );
    let (parents, order) = (source_animation.parents(), source_animation.parents_first().unwrap());
    let mut floats = vec![0.0; clip.pose_floats()];
    let mut worst = 0.0f64;
    for f in 0..frames {
        clip.pose(start + f as f64 / clip.rate, &mut floats).unwrap();
        let decoded: Vec<Transform> = floats
            .chunks_exact(POSE_FLOATS)
            .map(|p| {
                let v: Vec<f64> = p.iter().map(|&v| f64::from(v)).collect();
                Transform {
                    rotation: [v[0], v[1], v[2], v[3]],
                    translation: [v[4], v[5], v[6]],
                    scale: [v[7], v[8], v[9]],
                }
            })
            .collect();
        let errors = pose_errors(&parents, &order, &pose(&source_animation, f), &decoded, 3.0 / CMU_UNIT_CM);
        worst = errors.into_iter().fold(worst, f64::max);
    }
    let decoder_cm = worst * CMU_UNIT_CM;
    eprintln!("decoder: within {decoder_cm} cm; the report says {at_frames_cm} cm");
    assert!((decoder_cm - at_frames_cm).abs() <= 2e-5, "decoder: {decoder_cm} cm, {at_frames_cm} reported");
    // What the decoder holds: the clip's body as the container stores it, its streams at fixed
    // widths instead of Rice codes (a few percent more), and the rest pose; a clip being
    // decoded adds its pose and a cursor of at most 600 bytes a channel.
    let section = quatcurve::qcf::clip_bytes(&Container::from_bytes(&bytes).unwrap().clips[0]);
    let channels = Container::from_bytes(&bytes).unwrap().clips[0].channels.len();
    let held = decoder.bytes() - 4 * clip.pose_floats();
    assert!(held < section * 5 / 4 && held > section / 2, "{held} bytes held for a clip of {section}");
    let state = clip.state_bytes();
    assert!(state <= 4 * clip.pose_floats() + 600 * channels, "{state} bytes for {channels} channels");
    Some(bytes)
}

/// A small BVH: a root that moves and turns, a child that bends, 61 frames at 30 Hz.
fn small_bvh(path: &Path) {
    let mut text = String::from(
        "HIERARCHY\nROOT hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation \
         Yrotation\n  JOINT knee\n  {\n    OFFSET 0 -10 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n    End Site\n    \
         {\n      OFFSET 0 -10 0\n    }\n  }\n}\nMOTION\nFrames: 61\nFrame Time: 0.0333333\n",
    );
    for f in 0..61 {
        let t = f64::from(f) / 30.0;
        let row = [
            t,
            1.0 + (2.0 * t).sin(),
            0.0,
            20.0 * t,
            5.0 * (3.0 * t).sin(),
            0.0,
            30.0 * (2.0 * t).sin(),
            0.0,
            10.0 * t,
        ];
        text.push_str(&row.map(|v| format!("{v:.6}")).join(" "));
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

/// `bend.bvh` (`small_bvh`) written in `dir`, and the output directory a fit of it would make.
fn bend(dir: &Path) -> (PathBuf, PathBuf) {
    let source = dir.join("bend.bvh");
    small_bvh(&source);
    (source, dir.join("out"))
}

/// `bend.bvh` in `dir` and its fit, `out/bend.qcf`: (the source, the container).
fn fitted_bend(dir: &Path) -> (PathBuf, PathBuf) {
    let (source, out) = bend(dir);
    let result = fit(&["--input", source.to_str().unwrap(), "--output", out.to_str().unwrap(), "--unit-cm", "1"]);
    assert!(result.status.success(), "{}", stderr(&result));
    (source, out.join("bend.qcf"))
}

#[test]
fn a_fit_refuses_what_it_cannot_do_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let (source, out) = bend(dir.path());
    let (src, dst) = (source.to_str().unwrap(), out.to_str().unwrap());
    // A BVH does not say its unit: refused before anything is read or made.
    let result = fit(&["--input", src, "--output", dst]);
    assert_eq!(result.status.code(), Some(2));
    assert!(stderr(&result).contains("--unit-cm is needed for"), "{}", stderr(&result));
    assert!(!out.exists(), "nothing made for a refused job");
    let result = fit(&["--input", src, "--output", dst, "--unit-cm", "1", "--max-error-cm", "0"]);
    assert_eq!(result.status.code(), Some(2));
    assert!(stderr(&result).contains("--max-error-cm is 0; it must be a positive length"), "{}", stderr(&result));
    // The container's place taken by a directory: refused before the fit.
    std::fs::create_dir_all(out.join("bend.qcf")).unwrap();
    let result = fit(&["--input", src, "--output", dst, "--unit-cm", "1"]);
    assert_eq!(result.status.code(), Some(2));
    assert!(stderr(&result).contains("is a directory (nothing was fitted)"), "{}", stderr(&result));
}

#[test]
fn a_budget_no_fit_meets_names_the_closest_fit_and_what_loosens_it() {
    let dir = tempfile::tempdir().unwrap();
    let (source, out) = bend(dir.path());
    let (src, dst) = (source.to_str().unwrap(), out.to_str().unwrap());
    // (Rounding a control point to f32 alone moves it by more than 1e-9 cm.)
    let tight = ["--max-error-cm", "1e-9", "--between-error-cm", "1e-9"];
    let result = fit(&[&["--input", src, "--output", dst, "--unit-cm", "1"][..], &tight].concat());
    assert_eq!(result.status.code(), Some(2));
    for part in [
        "bend.bvh: clip 'bend': no fit within 1e-9 cm (the maximum error) at every frame and 1e-9 cm between them \
         (the between-frames error); the closest came to ",
        " cm at frames (knee at ",
        "; a larger between-frames error, or none, loosens the check between frames",
    ] {
        assert!(stderr(&result).contains(part), "{}\nlacks: {part}", stderr(&result));
    }
    assert!(!out.join("bend.qcf").exists(), "no container for a clip over its budget");
}

#[test]
fn bench_fitted_times_every_copy_of_every_clip_on_each_device() {
    let dir = tempfile::tempdir().unwrap();
    let (_, container) = fitted_bend(dir.path());
    // Decompression timed: every clip, copied, at its source rate (61 frames of 2 joints).
    let bench = quatcurve(&[
        "bench",
        "--fitted",
        container.to_str().unwrap(),
        "--copies",
        "3",
        "--runs",
        "1",
        "--devices",
        "cpu,reference",
        "--json",
    ]);
    assert!(bench.status.success(), "{}", stderr(&bench));
    let timed: serde_json::Value = serde_json::from_slice(&bench.stdout).unwrap();
    assert_eq!((timed["clips"].as_u64(), timed["poses"].as_u64()), (Some(3), Some(3 * 61)), "{timed}");
    assert_eq!(timed["bone_poses"].as_u64(), Some(3 * 61 * 2));
    for row in timed["results"].as_array().unwrap() {
        assert!(row["ns_per_bone_pose"].as_f64().unwrap() > 0.0, "{row}");
    }
    for row in ["load", "check", "decoder"] {
        assert!(timed[row]["ns_per_bone_pose"].as_f64().unwrap() > 0.0, "{row}: {timed}");
    }
    for field in ["open_us_per_clip", "held_bytes_per_bone_pose"] {
        assert!(timed[field].as_f64().unwrap() > 0.0, "{field}: {timed}");
    }
    assert!(timed["state_bytes_per_clip"].as_u64().unwrap() > 0, "{timed}");
    // Each clip alone: the one clip of 61 frames of 2 joints, what it holds and its rate.
    let per_clip = timed["per_clip"].as_array().unwrap();
    assert_eq!(per_clip.len(), 1, "{timed}");
    assert_eq!((per_clip[0]["frames"].as_u64(), per_clip[0]["joints"].as_u64()), (Some(61), Some(2)));
    assert!(per_clip[0]["held_bytes"].as_u64().unwrap() > 0 && per_clip[0]["ns_per_bone_pose"].as_f64().unwrap() > 0.0);
    let one_thread =
        |row: &serde_json::Value| row["device"].as_str().unwrap().starts_with("cpu") && row["threads"] == 1;
    assert!(timed["results"].as_array().unwrap().iter().any(one_thread), "the CPU path on one thread: {timed}");
    for row in timed["results"].as_array().unwrap() {
        // Host threads bake on the CPU rows; a GPU's row has none, and a name says one thread so.
        let device = row["device"].as_str().unwrap();
        assert_eq!(row["threads"].is_null(), device.starts_with("gpu"), "{row}");
        assert!(!device.contains(" 1 threads"), "{row}");
    }
}

#[test]
fn buffers_kept_from_bake_to_bake_give_what_fresh_ones_give() {
    let dir = tempfile::tempdir().unwrap();
    let (source, container) = fitted_bend(dir.path());
    // The fitted clip, then its source's keys (another kind of batch, of other sizes), then the
    // fitted clip again.
    let fitted = Container::from_bytes(&std::fs::read(&container).unwrap()).unwrap().animation();
    let keyed = bvh::read(&source).unwrap().animation("bend");
    let device = quatcurve::Device::open(quatcurve::DeviceChoice::Cpu).unwrap();
    let (spec, rates) = (
        quatcurve::anim::curves::CurveChoice::Family(quatcurve::CurveSpec::new(quatcurve::Curve::BSpline)),
        [ClipRate::Fit(30.0)],
    );
    let mut reuse = Reuse::default();
    for animation in [&fitted, &keyed, &fitted] {
        let fresh = bake_lib::bake_each(animation, &spec, &rates, LoopMode::Off, &device).unwrap();
        let kept = bake_lib::bake_reusing(animation, &spec, &rates, LoopMode::Off, &device, &mut reuse).unwrap();
        assert_eq!(kept, fresh);
        reuse.keep(kept);
    }
}

#[test]
fn a_fitted_clip_is_refused_as_a_loop_and_under_an_error_budget() {
    let dir = tempfile::tempdir().unwrap();
    let (_, container) = fitted_bend(dir.path());
    // Fitted clips are open curves of control points: no loop, no rate budget over keys.
    let baked = dir.path().join("baked");
    for (flags, message) in [
        (&["--loop", "on"][..], "is fitted (an open curve of control points); loop mode on needs keys"),
        (&["--max-error-deg", "1"][..], "is fitted (control points, not keys)"),
    ] {
        let result =
            bake(&[&["--input", container.to_str().unwrap(), "--output", baked.to_str().unwrap()][..], flags].concat());
        assert_eq!(result.status.code(), Some(2), "{flags:?}");
        assert!(stderr(&result).contains(message), "{flags:?}: {}", stderr(&result));
    }
}

#[test]
fn a_damaged_container_is_refused_naming_its_field() {
    let dir = tempfile::tempdir().unwrap();
    let (_, container) = fitted_bend(dir.path());
    let bytes = std::fs::read(&container).unwrap();
    let baked = dir.path().join("baked");
    // Truncated, or not a container at all: exit 2, the field named.
    for (name, cut, field) in [
        ("cut.qcf", bytes.len() - 3, "checksum: the bytes before it hash to "),
        ("header.qcf", 9, "byte 9: version: truncated: 1 bytes needed, 0 left"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let result = bake(&["--input", path.to_str().unwrap(), "--output", baked.to_str().unwrap()]);
        assert_eq!(result.status.code(), Some(2), "{name}");
        assert!(stderr(&result).contains("fitted container byte"), "{name}: {}", stderr(&result));
        assert!(stderr(&result).contains(field), "{name}: {}", stderr(&result));
    }
    let text = dir.path().join("text.qcf");
    std::fs::write(&text, "HIERARCHY").unwrap();
    let result = bake(&["--input", text.to_str().unwrap(), "--output", baked.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2));
    assert!(
        stderr(&result).contains("byte 0: magic: not a quatcurve fitted-clip container (those start with QCURVFIT)"),
        "{}",
        stderr(&result)
    );
}

#[test]
fn eval_reads_a_container_and_samples_what_the_bake_decodes() {
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("bend.bvh");
    small_bvh(&source);
    let fitted = dir.path().join("fitted");
    let result = fit(&["--input", source.to_str().unwrap(), "--output", fitted.to_str().unwrap(), "--unit-cm", "1"]);
    assert!(result.status.success(), "{}", stderr(&result));
    let container = fitted.join("bend.qcf");
    let baked = dir.path().join("baked");
    let result = bake(&["--input", container.to_str().unwrap(), "--rate", "30", "--output", baked.to_str().unwrap()]);
    assert!(result.status.success(), "{}", stderr(&result));
    let decoded = bvh::read(&baked.join("bend.bvh")).unwrap().animation("bend");
    let frames = decoded.clips[0].channels[0].len();
    assert_eq!(frames, 61);
    let devices: &[&str] =
        if crate::shared_gpu().is_some() { &["cpu", "gpu", "reference"] } else { &["cpu", "reference"] };
    for device in devices {
        let samples = frames.to_string();
        let eval =
            quatcurve(&["eval", "--input", container.to_str().unwrap(), "--samples", &samples, "--device", device]);
        assert!(eval.status.success(), "{device}: {}", stderr(&eval));
        let out: serde_json::Value = serde_json::from_slice(&eval.stdout).unwrap();
        assert_eq!(out["curve"], "normalized-bspline");
        let tracks = out["tracks"].as_array().unwrap();
        let names: Vec<&str> = tracks.iter().map(|t| t["name"].as_str().unwrap()).collect();
        assert_eq!(names, ["bend/hips", "bend/knee"], "every rotation channel, named <clip>/<joint>");
        for (track, joint) in tracks.iter().zip(0..) {
            let channel = decoded.clips[0]
                .channels
                .iter()
                .find(|c| c.joint == joint && c.property == Property::Rotation)
                .and_then(|c| c.keyed())
                .unwrap()
                .1;
            for (f, q) in track["rotations"].as_array().unwrap().iter().enumerate() {
                let q: Vec<f64> = q.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
                let dot: f64 = q.iter().zip(channel[f]).map(|(a, b)| a * b).sum();
                let off = q.iter().zip(channel[f]).map(|(a, b)| (a - b * dot.signum()).abs()).fold(0.0, f64::max);
                // Both are f32 samples of one curve (the BVH's Euler angles printed to 1e-6 degrees).
                assert!(off < 1e-6, "{device}: joint {joint} frame {f}: {q:?} vs {:?}", channel[f]);
            }
        }
    }
    // The container's curves are its own; analyze reads keys, not curves.
    let refused = quatcurve(&["eval", "--input", container.to_str().unwrap(), "--curve", "slerp"]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(stderr(&refused).contains("--curve: a fitted container's curves are its own"), "{}", stderr(&refused));
    let refused = quatcurve(&["analyze", "--input", container.to_str().unwrap()]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(stderr(&refused).contains("a fitted container holds curves, not keys"), "{}", stderr(&refused));
}

/// A clip library of two copies of CesiumMan: one container, the skeleton once, each clip named
/// by its input's stem as both inputs name theirs alike; `bake` and the decoder read it.
#[test]
fn a_library_of_one_skeleton_s_files_is_one_container_that_bakes_and_decodes_every_clip() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    for stem in ["walk", "stroll"] {
        std::fs::copy(data.join("CesiumMan.glb"), dir.path().join(format!("{stem}.glb"))).unwrap();
    }
    let out = dir.path().join("fitted");
    let fitted = quatcurve(&[
        "fit",
        "--input",
        dir.path().join("stroll.glb").to_str().unwrap(),
        dir.path().join("walk.glb").to_str().unwrap(),
        "--clip-library",
        "men",
        "--output",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(fitted.status.success(), "{}", stderr(&fitted));
    let report: serde_json::Value = serde_json::from_slice(&fitted.stdout).unwrap();
    let library = &report["clip_library"];
    let bytes = std::fs::read(out.join("men.qcf")).unwrap();
    assert_eq!(library["container_bytes"].as_u64(), Some(bytes.len() as u64), "{report}");
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 1);
    let clip = report["inputs"][0]["clips"][0]["clip"].as_str().unwrap().to_string();
    assert!(clip.starts_with("stroll/"), "{clip}");
    let names: Vec<String> = Decoder::from_bytes(&bytes).unwrap().clips().iter().map(|c| c.name.clone()).collect();
    assert_eq!(names, [clip.clone(), clip.replacen("stroll/", "walk/", 1)]);
    assert!(library["whole_file_ratio"].as_f64().unwrap() < library["ratio"].as_f64().unwrap(), "{report}");
    let baked = dir.path().join("baked");
    let result = bake(&["--input", out.join("men.qcf").to_str().unwrap(), "--output", baked.to_str().unwrap()]);
    assert!(result.status.success(), "{}", stderr(&result));
    let sidecar = super::json(&baked.join("men.json"));
    let baked_names: Vec<&str> =
        sidecar["clips"].as_array().unwrap().iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(baked_names, names);
}
