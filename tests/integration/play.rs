//! The playback runtime (`quatcurve::play`, DESIGN section 17) held to what it must equal:
//! the bake's skin textures at their frame times (every clip of the real files, on the
//! reference, the CPU path and the GPU), the single clips at blend weights 0 and 1, and at
//! 0.25 and 0.5 a local-space blend, forward kinematics and skinning computed here with glam; and
//! `quatcurve play` end to end: the schedule, its file, bad requests refused before work.

use crate::bake::{data_dir, json, read_npy, stderr};
use assert_cmd::Command;
use glam::{DMat4, DQuat, DVec3};
use quatcurve::anim::curves::CurveChoice;
use quatcurve::anim::loops::LoopMode;
use quatcurve::curve::{Curve, CurveSpec};
use quatcurve::formats::source::Source;
use quatcurve::play::schedule::{Schedule, PHASE_STEP};
use quatcurve::play::{ClipTime, Instance, Playback, PALETTE_CHANNELS};
use quatcurve::{Device, DeviceChoice};
use std::path::Path;

/// Palettes agree with the bake's textures within this, relative to the largest entry.
const TOLERANCE: f64 = 1e-5;

/// The devices to play on: the reference, the CPU path, and the GPU when there is one.
fn devices() -> Vec<(&'static str, Device)> {
    let mut devices = vec![
        ("reference", Device::open(DeviceChoice::Reference).unwrap()),
        ("cpu", Device::open(DeviceChoice::Cpu).unwrap()),
    ];
    if let Some(gpu) = crate::shared_gpu() {
        devices.push(("gpu", Device::Gpu(Box::new(gpu.share_device()))));
    }
    devices
}

fn play(args: &[&str]) -> std::process::Output {
    Command::cargo_bin("quatcurve").unwrap().arg("play").args(args).output().unwrap()
}

/// `quatcurve bake --texture skin --rate 30 --exact-rate` of `input` into `output`, and more.
fn bake_skin(input: &Path, output: &Path, more: &[&str]) {
    let result = Command::cargo_bin("quatcurve")
        .unwrap()
        .args(["bake", "--input", input.to_str().unwrap(), "--output", output.to_str().unwrap()])
        .args(["--texture", "skin", "--rate", "30", "--exact-rate"])
        .args(more)
        .output()
        .unwrap();
    assert!(result.status.success(), "{}: {}", input.display(), stderr(&result));
}

/// `path`'s clips played with `curve` (`None`: the source's own interpolation, the default).
fn playback(path: &Path, curve: Option<Curve>) -> Playback {
    let source = Source::read(path, Default::default()).unwrap();
    let curve = CurveChoice::new(curve, &quatcurve::options::CurveOptions::DEFAULT);
    Playback::new(source.animation().clone(), &curve, LoopMode::Auto, None).unwrap()
}

/// The largest difference between two palettes, relative to the largest entry of `expected`.
fn relative_gap(got: &[f32], expected: &[f32]) -> f64 {
    assert_eq!(got.len(), expected.len());
    let scale = expected.iter().map(|v| f64::from(v.abs())).fold(1e-30, f64::max);
    got.iter().zip(expected).map(|(a, b)| f64::from((a - b).abs())).fold(0.0, f64::max) / scale
}

#[test]
fn palettes_equal_the_bakes_skin_texture_at_its_frame_times_on_every_device() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    for (name, curve) in [
        ("CesiumMan.glb", Curve::BSplineInterp),
        ("Fox.glb", Curve::BSplineInterp),
        ("cmu_131_03.bvh", Curve::Slerp),
        // Equally spaced knots: rotations and the root's translation on the polynomial table.
        ("cmu_131_03.bvh", Curve::BSpline),
        ("Fox.fbx", Curve::Squad),
    ] {
        let input = data.join(name);
        let playback = playback(&input, Some(curve));
        for (device_name, device) in devices() {
            let out = dir.path().join(format!("{name}.{curve}.{device_name}"));
            bake_skin(&input, &out, &["--curve", &curve.to_string(), "--device", device_name]);
            let stem = input.file_stem().unwrap().to_str().unwrap();
            let sidecar = json(&out.join(format!("{stem}.json")));
            for (c, clip) in sidecar["clips"].as_array().unwrap().iter().enumerate() {
                let (shape, texture) = read_npy(&out.join(clip["file"].as_str().unwrap()));
                let rate = clip["rate"].as_f64().unwrap();
                let instances: Vec<Instance> =
                    (0..shape[0] as usize).map(|f| Instance::single(c, f as f64 / rate)).collect();
                let palettes = playback.palettes(&device, &instances).unwrap();
                let gap = relative_gap(&palettes, &texture);
                assert!(gap < TOLERANCE, "{name} clip {c} on {device_name}: {gap:.2e}");
                eprintln!("{name} clip {c} on {device_name}: {} frames within {gap:.1e}", shape[0]);
            }
        }
    }
}

/// glTF's node transform of a local row: `T * R * S`.
fn trs(row: &[f32]) -> DMat4 {
    let q = DQuat::from_xyzw(row[0].into(), row[1].into(), row[2].into(), row[3].into()).normalize();
    let v = |i: usize| DVec3::new(row[i].into(), row[i + 1].into(), row[i + 2].into());
    DMat4::from_scale_rotation_translation(v(7), q, v(4))
}

/// Skin palettes of one instance's local rows, by glam: parents' matrices first, then the
/// skin's joints' model matrices times their inverse binds, as 3x4 rows.
fn independent_palette(playback: &Playback, local: &[f32]) -> Vec<f32> {
    let animation = playback.animation();
    let mut model: Vec<Option<DMat4>> = vec![None; animation.joints.len()];
    fn world(j: usize, animation: &quatcurve::anim::Animation, local: &[f32], model: &mut [Option<DMat4>]) -> DMat4 {
        if let Some(m) = model[j] {
            return m;
        }
        let own = trs(&local[j * 10..j * 10 + 10]);
        let m = match animation.joints[j].parent {
            Some(p) => world(p, animation, local, model) * own,
            None => own,
        };
        model[j] = Some(m);
        m
    }
    let skin = playback.skin().unwrap();
    let mut out = Vec::new();
    for (&j, ibm) in skin.joints.iter().zip(&skin.inverse_bind) {
        let inverse_bind = DMat4::from_cols_array(&[
            ibm[0], ibm[4], ibm[8], 0.0, ibm[1], ibm[5], ibm[9], 0.0, ibm[2], ibm[6], ibm[10], 0.0, ibm[3], ibm[7],
            ibm[11], 1.0,
        ]);
        let m = world(j, animation, local, &mut model) * inverse_bind;
        for r in 0..3 {
            out.extend((0..4).map(|c| m.col(c)[r] as f32));
        }
    }
    out
}

#[test]
fn blends_are_the_single_clips_at_their_ends_and_a_local_space_blend_between() {
    let Some(data) = data_dir() else { return };
    let playback = playback(&data.join("Fox.glb"), Some(Curve::BSplineInterp));
    let joints = playback.animation().joints.len();
    // Survey (clip 0) at 1.3 s with Run (clip 2) at 0.4 s; Walk with itself half a cycle on.
    let pairs = [
        (ClipTime { clip: 0, time: 1.3 }, ClipTime { clip: 2, time: 0.4 }),
        (ClipTime { clip: 1, time: 0.2 }, ClipTime { clip: 1, time: 0.2 + playback.duration(1) / 2.0 }),
    ];
    for (device_name, device) in devices() {
        for (a, b) in pairs {
            let single = |p: ClipTime| playback.palettes(&device, &[Instance::single(p.clip, p.time)]).unwrap();
            let blended = |w: f32| playback.palettes(&device, &[Instance { first: a, second: Some((b, w)) }]).unwrap();
            assert!(relative_gap(&blended(0.0), &single(a)) < TOLERANCE, "{device_name}: weight 0");
            assert!(relative_gap(&blended(1.0), &single(b)) < TOLERANCE, "{device_name}: weight 1");
            // The poses differ, so a blend that ignored its weight or its second pose fails.
            assert!(relative_gap(&single(a), &single(b)) > 100.0 * TOLERANCE, "{device_name}: the poses differ");
            // Weights 0.25 and 0.5: slerp and lerp of the two local poses, then FK and
            // skinning, by glam (at 0.25 slerp and a normalized lerp differ).
            let la = playback.local_poses(&device, &[Instance::single(a.clip, a.time)]).unwrap();
            let lb = playback.local_poses(&device, &[Instance::single(b.clip, b.time)]).unwrap();
            for w in [0.25f32, 0.5] {
                let mut mixed = vec![0.0f32; la.len()];
                for j in 0..joints {
                    let (ra, rb) = (&la[j * 10..j * 10 + 10], &lb[j * 10..j * 10 + 10]);
                    let q =
                        |r: &[f32]| DQuat::from_xyzw(r[0].into(), r[1].into(), r[2].into(), r[3].into()).normalize();
                    let s = q(ra).slerp(q(rb), f64::from(w));
                    mixed[j * 10..j * 10 + 4].copy_from_slice(&[s.x as f32, s.y as f32, s.z as f32, s.w as f32]);
                    for i in 4..10 {
                        mixed[j * 10 + i] = ra[i] + (rb[i] - ra[i]) * w;
                    }
                }
                let gap = relative_gap(&blended(w), &independent_palette(&playback, &mixed));
                assert!(gap < TOLERANCE, "{device_name}: weight {w} {gap:.2e}");
            }
        }
    }
}

#[test]
fn bad_poses_are_refused_naming_the_instance() {
    let Some(data) = data_dir() else { return };
    let playback = playback(&data.join("CesiumMan.glb"), Some(Curve::BSplineInterp));
    let device = Device::open(DeviceChoice::Cpu).unwrap();
    let cases = [
        (Instance::single(3, 0.0), "instance 1: clip 3 asked for, but the file has 1 clip(s)"),
        (Instance::single(0, f64::NAN), "instance 1: time NaN is not finite"),
        (
            Instance { first: ClipTime { clip: 0, time: 0.0 }, second: Some((ClipTime { clip: 0, time: 0.5 }, 1.5)) },
            "instance 1: blend weight 1.5 is outside [0, 1]",
        ),
    ];
    for (bad, message) in cases {
        let err = playback.palettes(&device, &[Instance::single(0, 0.0), bad]).unwrap_err();
        assert_eq!(err.to_string(), message);
    }
}

#[test]
fn play_writes_the_schedule_and_its_first_instance_is_the_bake() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let input = data.join("Fox.glb");
    let output = dir.path().join("palettes.npy");
    let args = ["--input", input.to_str().unwrap(), "--output", output.to_str().unwrap(), "--device", "cpu"];
    let result =
        play(&[&args[..], &["--instances", "5", "--rate", "30", "--seconds", "2", "--blend-weight", "0.25"]].concat());
    assert!(result.status.success(), "{}", stderr(&result));
    let (shape, data_) = read_npy(&output);
    let playback = playback(&input, None);
    let joints = playback.palette_joints();
    assert_eq!(shape, [61, 5, joints as u64, PALETTE_CHANNELS as u64]);
    // Frame by frame, the schedule's instances through the library.
    let device = Device::open(DeviceChoice::Cpu).unwrap();
    let schedule = Schedule { instances: 5, rate: 30.0, blend: Some(0.25), blend_clip: None };
    let frame = 5 * joints * PALETTE_CHANNELS;
    for f in [0, 17, 60] {
        let instances = schedule.frame(&playback, f);
        // Instance i plays clip i mod 3 from phase frac(i * PHASE_STEP); the next clip blended.
        for (i, instance) in instances.iter().enumerate() {
            let clip = i % 3;
            let phase = (i as f64 * PHASE_STEP).fract() * playback.duration(clip);
            assert_eq!(instance.first.clip, clip);
            let t = phase + f as f64 / 30.0;
            let expected =
                if playback.looping(clip) || t <= playback.duration(clip) { t } else { t % playback.duration(clip) };
            assert!((instance.first.time - expected).abs() < 1e-12, "frame {f} instance {i}");
            // The viewer's rule: the next clip at the same fraction of its span (Fox's loop).
            let (second, next) = (instance.second.unwrap().0, (clip + 1) % 3);
            assert_eq!(second.clip, next);
            let fraction = expected / playback.duration(clip);
            assert!((second.time - fraction * playback.duration(next)).abs() < 1e-9, "frame {f} instance {i}");
        }
        let palettes = playback.palettes(&device, &instances).unwrap();
        assert_eq!(palettes, &data_[f * frame..(f + 1) * frame], "frame {f}");
    }
    // One instance, no blend: clip 0 from its start, the bake's exact-rate frames (CesiumMan
    // is open; a loop's bake fits its rate to whole frames, so only its rate-fitted times are
    // the bake's, as the test above holds).
    let input = data.join("CesiumMan.glb");
    let bake_dir = dir.path().join("bake");
    bake_skin(&input, &bake_dir, &["--device", "cpu"]);
    let args = ["--input", input.to_str().unwrap(), "--output", output.to_str().unwrap(), "--device", "cpu"];
    let result = play(&[&args[..], &["--rate", "30", "--seconds", "1.5"]].concat());
    assert!(result.status.success(), "{}", stderr(&result));
    let (shape, played) = read_npy(&output);
    let (baked_shape, baked) = read_npy(&bake_dir.join("CesiumMan.animation0.skin0.npy"));
    assert_eq!(shape[..2], [46, 1]);
    assert!(baked_shape[0] >= 46);
    let gap = relative_gap(&played, &baked[..played.len()]);
    assert!(gap < TOLERANCE, "{gap:.2e}");
}

#[test]
fn bad_requests_are_refused_before_anything_is_written() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let input = data.join("CesiumMan.glb");
    let output = dir.path().join("p.npy");
    let base = ["--input", input.to_str().unwrap(), "--output", output.to_str().unwrap(), "--device", "cpu"];
    for (extra, message) in [
        (&["--rate", "0"][..], "--rate 0 must be a positive number"),
        (&["--seconds", "-1"][..], "--seconds -1 must be a number of seconds"),
        (&["--blend-weight", "2"][..], "--blend-weight 2 must be a weight in [0, 1]"),
        (&["--instances", "0"][..], "--instances must be 1 or more"),
        (&["--instances", "100000", "--seconds", "1000"][..], "floats of palettes"),
        (&["--skin", "4"][..], "skin 4 asked for, but the file has 1 skin(s)"),
        (&["--skin-from", input.to_str().unwrap(), "--skin", "2"][..], "skin 2 asked for, but the file has 1"),
        (&["--blend-weight", "0.5", "--blend-clip", "Run"][..], "no clip 'Run': the clips are 0 'animation0'"),
        (&["--blend-weight", "0.5", "--blend-clip", "1"][..], "no clip '1': the clips are 0 'animation0'"),
    ] {
        let result = play(&[&base[..], extra].concat());
        assert_eq!(result.status.code(), Some(2), "{extra:?}");
        assert!(stderr(&result).contains(message), "{extra:?}: {}", stderr(&result));
        assert!(!output.exists(), "{extra:?}");
    }
    // A file without skins refuses a skin asked for by number.
    let bvh = data.join("cmu_131_03.bvh");
    let result = play(&["--input", bvh.to_str().unwrap(), "--output", output.to_str().unwrap(), "--skin", "0"]);
    assert_eq!(result.status.code(), Some(2));
    assert!(stderr(&result).contains("skin 0 asked for, but the file has 0 skin(s)"), "{}", stderr(&result));
    let missing = dir.path().join("missing.glb");
    let result = play(&["--input", missing.to_str().unwrap(), "--output", output.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2));
    assert!(stderr(&result).contains("missing.glb"), "{}", stderr(&result));
    assert!(std::fs::read_dir(dir.path()).unwrap().next().is_none(), "nothing written");
}

#[test]
fn a_fitted_container_plays_the_characters_skin_within_the_fits_budget() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let glb = data.join("CesiumMan.glb");
    let result = Command::cargo_bin("quatcurve")
        .unwrap()
        .args(["fit", "--input", glb.to_str().unwrap(), "--output", dir.path().to_str().unwrap()])
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", stderr(&result));
    let source = Source::read(&glb, Default::default()).unwrap();
    let fitted = Source::read(&dir.path().join("CesiumMan.qcf"), Default::default()).unwrap();
    let mut animation = fitted.animation().clone();
    assert!(animation.skins.is_empty(), "a container keeps no skin");
    animation.skins = vec![quatcurve::play::skin_by_name(&animation, source.animation(), 0).unwrap()];
    let fitted =
        Playback::new(animation, &CurveChoice::Family(CurveSpec::new(Curve::Slerp)), LoopMode::Auto, Some(0)).unwrap();
    // The fit is held to the source's LINEAR keys: 0.01 cm at them on vertices 3 cm out, a
    // rotation of 1/300 rad, which moves an entry of a rotation matrix by at most sqrt 2 times
    // that (4.7e-3); the palettes' largest entries are about 1.
    let original = playback(&glb, Some(Curve::Slerp));
    let device = Device::open(DeviceChoice::Cpu).unwrap();
    let keys: Vec<Instance> = (0..48).map(|f| Instance::single(0, f as f64 / 24.0)).collect();
    let gap = relative_gap(&fitted.palettes(&device, &keys).unwrap(), &original.palettes(&device, &keys).unwrap());
    eprintln!("fitted CesiumMan at its keys: within {gap:.2e} of the glb's palettes");
    assert!(gap < std::f64::consts::SQRT_2 / 300.0, "{gap:.2e}");
    // A joint the played file lacks is named.
    let mut other = source.animation().clone();
    other.joints[other.skins[0].joints[3]].name = "elsewhere".into();
    let err = quatcurve::play::skin_by_name(fitted.animation(), &other, 0).unwrap_err();
    assert!(err.to_string().contains("joint 'elsewhere' is not a joint of the played file"), "{err}");
}

#[test]
fn a_crowd_larger_than_a_binding_plays_a_part_at_a_time_on_the_gpu() {
    let Some(data) = data_dir() else { return };
    let Some(gpu) = crate::shared_gpu() else { return };
    let playback = playback(&data.join("Fox.glb"), Some(Curve::BSplineInterp));
    let schedule = Schedule { instances: 200, rate: 30.0, blend: Some(0.3), blend_clip: None };
    let instances = schedule.frame(&playback, 11);
    let whole = Device::Gpu(Box::new(gpu.share_device()));
    let expected = playback.palettes(&whole, &instances).unwrap();
    let cpu = playback.palettes(&Device::open(DeviceChoice::Cpu).unwrap(), &instances).unwrap();
    assert!(relative_gap(&expected, &cpu) < TOLERANCE);
    // From resident curves: Fox's curves fit 128 KiB, a palette of its 24 joints is 1,152
    // bytes, so 200 instances take two submissions.
    let parts = Device::Gpu(Box::new(gpu.share_device().with_binding_limit(128 << 10)));
    assert_eq!(playback.palettes(&parts, &instances).unwrap(), expected);
    // Curves larger than a binding are refused by name on `gpu`.
    let tiny = Device::Gpu(Box::new(gpu.share_device().with_binding_limit(4096)));
    let err = playback.palettes(&tiny, &instances).unwrap_err().to_string();
    assert!(err.contains("storage bindings of 4096 bytes; playback keeps them in one"), "{err}");
    // Given poses (two of 1,920 bytes an instance): two instances a submission.
    let (instances, expected) = (&instances[..7], &expected[..7 * expected.len() / instances.len()]);
    let animation = playback.animation();
    let local = playback.local_poses(&whole, instances).unwrap();
    let row = local.len() / instances.len();
    let poses: Vec<f32> = local.chunks(row).flat_map(|r| [r, r]).flatten().copied().collect();
    let weights = vec![0.0; instances.len()];
    let (parents, order) = (animation.parents(), animation.parents_first().unwrap());
    let skin =
        playback.skin().map(|s| quatcurve::skeleton::PaletteSkin { joints: &s.joints, inverse_binds: &s.inverse_bind });
    let given = whole.play_palettes(&parents, &order, &poses, &weights, skin).unwrap();
    assert!(relative_gap(&given, expected) < TOLERANCE);
    assert_eq!(tiny.play_palettes(&parents, &order, &poses, &weights, skin).unwrap(), given);
}

#[test]
fn loops_play_on_for_a_thousand_cycles_each_track_wrapping_its_own_time() {
    let Some(data) = data_dir() else { return };
    // Fox's loops, clip 0's translations given a steady travel: a loop whose root moves on
    // by its per-cycle offset every period.
    let source = Source::read(&data.join("Fox.glb"), Default::default()).unwrap();
    let mut animation = source.animation().clone();
    for channel in &mut animation.clips[0].channels {
        if let (quatcurve::anim::Property::Translation, quatcurve::anim::ChannelCurve::Keys { times, values, .. }) =
            (channel.property, &mut channel.curve)
        {
            for (t, v) in times.iter().zip(values.iter_mut()) {
                v[0] += 70.0 * t;
                v[2] -= 30.0 * t;
            }
        }
    }
    let playback =
        Playback::new(animation, &CurveChoice::Family(CurveSpec::new(Curve::BSplineInterp)), LoopMode::Auto, None)
            .unwrap();
    assert!(playback.looping(0) && playback.looping(1));
    let period = playback.duration(0);
    let instances: Vec<Instance> = [-3.0, 0.0, 1.0, 7.0, 250.0, 1000.0]
        .iter()
        .map(|k| Instance {
            first: ClipTime { clip: 0, time: 0.37 + k * period },
            second: Some((ClipTime { clip: 1, time: 0.11 + k * playback.duration(1) }, 0.4)),
        })
        .collect();
    let mut others = devices();
    let (_, reference) = others.remove(0);
    let expected = playback.palettes(&reference, &instances).unwrap();
    let per = expected.len() / instances.len();
    // The travel is there: the root's palette moves by the offset each cycle.
    assert!(relative_gap(&expected[per..2 * per], &expected[..per]) > 0.01);
    for (name, device) in others {
        let got = playback.palettes(&device, &instances).unwrap();
        for (i, (g, e)) in got.chunks(per).zip(expected.chunks(per)).enumerate() {
            let gap = relative_gap(g, e);
            assert!(gap < TOLERANCE, "{name} instance {i}: {gap:.2e}");
        }
    }
}

#[test]
fn a_frame_stays_on_the_gpu_for_a_vertex_shader_and_reads_back_as_the_palettes() {
    let Some(data) = data_dir() else { return };
    let Some(gpu) = crate::shared_gpu() else { return };
    let playback = playback(&data.join("Fox.glb"), Some(Curve::BSplineInterp));
    let instances = Schedule { instances: 30, rate: 30.0, blend: Some(0.3), blend_clip: None }.frame(&playback, 5);
    let device = Device::Gpu(Box::new(gpu.share_device()));
    let player = playback.player(&device).unwrap();
    let times = player.pose_times(&instances).unwrap();
    let resident = player.resident().expect("the GPU keeps the curves").gpu();
    let frame = resident.frame(&times).unwrap();
    assert!(frame.buffer().usage().contains(wgpu::BufferUsages::STORAGE), "a vertex shader binds it");
    assert_eq!(frame.floats(), 30 * 24 * PALETTE_CHANNELS);
    assert_eq!(resident.read(&frame).unwrap(), player.palettes(&instances).unwrap());
    // One buffer holds what one binding does; more is refused, not cut.
    let small = Device::Gpu(Box::new(gpu.share_device().with_binding_limit(128 << 10)));
    let player = playback.player(&small).unwrap();
    let resident = player.resident().unwrap().gpu();
    assert!(resident.max_frame_instances() < 200);
    let many = Schedule { instances: 200, rate: 30.0, blend: None, blend_clip: None }.frame(&playback, 0);
    let err = resident.frame(&player.pose_times(&many).unwrap()).unwrap_err().to_string();
    assert!(err.contains("200 instances are more than one binding of palettes holds"), "{err}");
}

/// `--blend-clip` names the clip every instance blends towards, by name or by index, at the
/// same phase of its span as the instance's own clip.
#[test]
fn play_blends_every_instance_towards_the_clip_named_or_numbered() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let input = data.join("Fox.glb");
    let palettes = |name: &str, clip: &str| {
        let output = dir.path().join(name);
        let args = ["--input", input.to_str().unwrap(), "--output", output.to_str().unwrap(), "--device", "cpu"];
        let more = ["--instances", "4", "--seconds", "0.5", "--blend-weight", "0.4", "--blend-clip", clip];
        let result = play(&[&args[..], &more].concat());
        assert!(result.status.success(), "{}", stderr(&result));
        read_npy(&output).1
    };
    let (by_name, by_index) = (palettes("name.npy", "Run"), palettes("index.npy", "2"));
    assert_eq!(by_name, by_index);
    let playback = playback(&input, None);
    let schedule = Schedule { instances: 4, rate: 30.0, blend: Some(0.4), blend_clip: Some(2) };
    let device = Device::open(DeviceChoice::Cpu).unwrap();
    let frame = 4 * playback.palette_joints() * PALETTE_CHANNELS;
    for f in [0, 15] {
        let instances = schedule.frame(&playback, f);
        for instance in &instances {
            let (second, _) = instance.second.unwrap();
            assert_eq!(second.clip, 2);
            let fraction = instance.first.time / playback.duration(instance.first.clip);
            assert!((second.time - fraction * playback.duration(2)).abs() < 1e-9);
        }
        assert_eq!(playback.palettes(&device, &instances).unwrap(), &by_name[f * frame..(f + 1) * frame]);
    }
    assert_ne!(by_name, palettes("next.npy", "Walk"), "another clip, other palettes");
}

/// `play --usd` writes the crowd beside its palettes: the character once (a class prim), each
/// instance an instanceable reference to it bound to its own animation, its clip and phase as
/// the schedule's (instance i plays clip i mod clips from frac(i * PHASE_STEP) of its span).
/// Pixar's library poses each instance as its palette (`python/tests/test_usd.py`). A BVH
/// without its unit, and a crowd too large for a text stage, are refused before anything is
/// written.
#[test]
fn the_crowd_stage_is_one_character_referenced_by_each_instance_playing_its_schedule() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fox = data.join("Fox.glb");
    let output = dir.path().join("crowd.npy");
    let result =
        play(&["--input", fox.to_str().unwrap(), "--instances", "5", "--output", output.to_str().unwrap(), "--usd"]);
    assert!(result.status.success(), "{}", stderr(&result));
    let stage = std::fs::read_to_string(dir.path().join("crowd.usda")).unwrap();
    assert!(stage.contains("\nclass SkelRoot \"Fox\"\n"), "the character once, not drawn itself");
    assert_eq!(stage.matches("prepend references = </Fox>").count(), 5);
    assert_eq!(stage.matches("instanceable = true").count(), 5);
    let playback = playback(&fox, None);
    for i in 0..5 {
        let clip = i % playback.animation().clips.len();
        let phase = (i as f64 * PHASE_STEP).fract() * playback.duration(clip);
        let name = &playback.animation().clips[clip].name;
        let declared = format!("string clip = \"{name}\"\n            double phase = {phase}\n");
        let at = stage.find(&format!("def SkelRoot \"Instance_{i}\"")).unwrap();
        assert!(stage[at..].contains(&declared), "instance {i}: {declared}");
        assert!(stage.contains(&format!("rel skel:animationSource = </Crowd/Motion/Instance_{i}>")));
        assert!(stage.contains(&format!("def SkelAnimation \"Instance_{i}\"")));
    }
    let bvh = data.join("cmu_131_01.bvh");
    let output = dir.path().join("bvh.npy");
    let result = play(&["--input", bvh.to_str().unwrap(), "--output", output.to_str().unwrap(), "--usd"]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(stderr(&result).contains("--unit-cm is needed for --usd"), "{}", stderr(&result));
    assert!(!output.exists() && !dir.path().join("bvh.usda").exists(), "nothing written");
    // A crowd whose poses would make gigabytes of text is refused before any is evaluated.
    let output = dir.path().join("large.npy");
    let large = ["--instances", "2000", "--seconds", "10", "--output", output.to_str().unwrap(), "--usd"];
    let result = play(&[&["--input", fox.to_str().unwrap()], &large[..]].concat());
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(stderr(&result).contains("floats of poses for --usd's text stage"), "{}", stderr(&result));
    assert!(!output.exists() && !dir.path().join("large.usda").exists(), "nothing written");
}
