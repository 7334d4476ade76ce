//! What a bake tells its user besides the files: output faults found before the work (and
//! reported as output faults when they happen during it), source keys that are probably
//! broken, and the clip end an exact rate leaves unbaked.

use super::{bake, data_dir, json, read_npy, stderr, tiny_gltf};

const Q: [f32; 4] = [0.0, 0.0, 0.0, 1.0];
const TURN: [f32; 4] = [0.0, 0.38268343, 0.0, 0.9238795];

/// Two good inputs in a fresh directory.
fn two_inputs() -> (tempfile::TempDir, String, String) {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("walk.gltf"), dir.path().join("wave.gltf"));
    std::fs::write(&a, tiny_gltf(&[0.0, 0.5, 1.0], &[Q, TURN, Q])).unwrap();
    std::fs::write(&b, tiny_gltf(&[0.0, 0.5, 1.0], &[TURN, Q, TURN])).unwrap();
    let (a, b) = (a.display().to_string(), b.display().to_string());
    (dir, a, b)
}

#[test]
fn an_output_directory_that_cannot_be_written_fails_before_any_input_is_baked() {
    let (dir, a, b) = two_inputs();
    // A directory that exists but takes no file (as root too), one that cannot be created,
    // and one where a baked file's name is a directory.
    let in_the_way = dir.path().join("in-the-way");
    std::fs::create_dir_all(in_the_way.join("wave.glb")).unwrap();
    let mut cases = vec![
        (in_the_way.clone(), "a directory is where a baked file goes"),
        (dir.path().join("walk.gltf").join("out"), "cannot create the directory"),
    ];
    if cfg!(target_os = "linux") {
        cases.push(("/proc".into(), "cannot write into the directory"));
    }
    for (output, why) in cases {
        let result = bake(&["--input", &a, &b, "--output", output.to_str().unwrap()]);
        let message = stderr(&result);
        assert_eq!(result.status.code(), Some(2), "{}: {message}", output.display());
        assert!(
            message.contains("--output") && message.contains(why) && message.contains("nothing was baked"),
            "{}: {message}",
            output.display()
        );
        // No input was baked: no summary, nothing written.
        assert!(result.stdout.is_empty(), "{}: {}", output.display(), String::from_utf8_lossy(&result.stdout));
    }
    assert_eq!(std::fs::read_dir(&in_the_way).unwrap().count(), 1, "nothing written beside the directory in the way");
}

#[test]
fn an_output_that_fails_during_the_job_is_reported_as_an_output_failure() {
    let (dir, a, b) = two_inputs();
    let out = dir.path().join("out");
    // A texture's name (known only once the clips are read) taken by a directory.
    std::fs::create_dir_all(out.join("walk.wave.npy")).unwrap();
    let result = bake(&["--input", &a, &b, "--output", out.to_str().unwrap()]);
    let (summary, message) = (String::from_utf8_lossy(&result.stdout).into_owned(), stderr(&result));
    assert_eq!(result.status.code(), Some(1), "an output fault is the machine's (exit 1): {message}");
    let walk = summary.lines().find(|l| l.contains("walk.gltf")).unwrap();
    assert!(walk.contains("FAILED (output)"), "{summary}");
    assert!(summary.lines().find(|l| l.contains("wave.gltf")).unwrap().contains("ok"), "{summary}");
    assert!(message.contains("1 of 2 inputs failed (1 output not written); the other was baked"), "{message}");
    let mut left: Vec<String> =
        std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    left.sort();
    assert_eq!(
        left,
        ["manifest.0-of-1.json", "walk.wave.npy", "wave.glb", "wave.json", "wave.wave.npy"],
        "the failed input's other outputs are removed"
    );
    // Both inputs failing say so, not "the others were baked".
    let out = dir.path().join("out2");
    for texture in ["walk.wave.npy", "wave.wave.npy"] {
        std::fs::create_dir_all(out.join(texture)).unwrap();
    }
    let result = bake(&["--input", &a, &b, "--output", out.to_str().unwrap()]);
    assert!(
        stderr(&result).contains("2 of 2 inputs failed (2 output not written); nothing was baked"),
        "{}",
        stderr(&result)
    );
}

/// Steps a hair either side of `SOURCE_STEP_WARNING_DEGREES` are told apart: the cheap
/// screen that spares most steps the exact angle must not move the limit.
#[test]
fn source_steps_just_over_the_warning_limit_are_counted_and_those_just_under_are_not() {
    use quatcurve::anim::{Animation, Channel, Clip, Joint, Property};
    use quatcurve::bake::{source_step_warnings, SOURCE_STEP_WARNING_DEGREES};
    let about_z = |degrees: f64| {
        let half = degrees.to_radians() / 2.0;
        [0.0, 0.0, half.sin(), half.cos()]
    };
    let (under, over) = (SOURCE_STEP_WARNING_DEGREES - 1e-6, SOURCE_STEP_WARNING_DEGREES + 1e-6);
    let values = vec![about_z(0.0), about_z(under), about_z(0.0), about_z(over), about_z(0.0), about_z(-under)];
    let channel = Channel::keys(0, Property::Rotation, (0..6).map(f64::from).collect(), values);
    let animation = Animation {
        joints: vec![Joint::at("bone".into(), None, [0.0; 3])],
        clips: vec![Clip { name: "edge".into(), channels: vec![channel] }],
        skins: Vec::new(),
    };
    let warnings = source_step_warnings(&animation);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("2 steps between consecutive keys"), "{warnings:?}");
    assert!(warnings[0].contains("the first is key 2 to key 3 at 3 s"), "{warnings:?}");
}

#[test]
fn probably_broken_source_keys_are_warned_per_channel_without_failing() {
    let dir = tempfile::tempdir().unwrap();
    // Key 2 turns 170 degrees from key 1, then back.
    let flip = [0.0, 0.9961947, 0.0, 0.0871557];
    let input = dir.path().join("flip.gltf");
    std::fs::write(&input, tiny_gltf(&[0.0, 0.5, 1.0, 1.5], &[Q, Q, flip, Q])).unwrap();
    let out = dir.path().join("out");
    let result = bake(&["--input", input.to_str().unwrap(), "--output", out.to_str().unwrap()]);
    let message = stderr(&result);
    assert!(result.status.success(), "{message}");
    let expected = [
        "warning:",
        "flip.gltf",
        "clip 'wave', bone rotation",
        "2 steps between consecutive keys turn more than 90 degrees",
        "key 1 to key 2 at 1 s, 170 degrees",
    ];
    for part in expected {
        assert!(message.contains(part), "lacks {part:?}: {message}");
    }
    let manifest = json(&out.join("manifest.0-of-1.json"));
    let warnings = manifest["inputs"][0]["warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{manifest}");
    assert!(warnings[0].as_str().unwrap().contains("bone rotation"), "{manifest}");
    // A clip without such steps has none.
    let (_, a, _) = two_inputs();
    let result = bake(&["--input", &a, "--output", out.to_str().unwrap()]);
    assert!(!stderr(&result).contains("warning"), "{}", stderr(&result));
    // The real takes' flipping thumbs are named.
    let Some(data) = data_dir() else { return };
    let result = bake(&["--input", data.join("cmu_131_03.bvh").to_str().unwrap(), "--output", out.to_str().unwrap()]);
    assert!(stderr(&result).contains("clip 'cmu_131_03', RThumb rotation: 14 steps"), "{}", stderr(&result));
}

#[test]
fn clips_bake_from_first_to_last_key_unless_an_exact_rate_is_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("walk.gltf");
    // 1.07 s at 10 Hz: 10.7 intervals, fitted to 11.
    std::fs::write(&input, tiny_gltf(&[0.0, 0.5, 1.07], &[Q, TURN, Q])).unwrap();
    let out = dir.path().join("out");
    for (exact, frames, end, rate) in [(false, 12, 1.07, 11.0 / 1.07), (true, 11, 1.0, 10.0)] {
        let mut args = vec![
            "--input",
            input.to_str().unwrap(),
            "--rate",
            "10",
            "--loop",
            "off",
            "--output",
            out.to_str().unwrap(),
        ];
        if exact {
            args.push("--exact-rate");
        }
        let result = bake(&args);
        let message = stderr(&result);
        assert!(result.status.success(), "{message}");
        let clip = &json(&out.join("walk.json"))["clips"][0];
        assert_eq!(clip["frames"], frames, "exact rate {exact}: {clip}");
        assert!((clip["end"].as_f64().unwrap() - end).abs() < 1e-6, "exact rate {exact}: {clip}");
        assert!((clip["rate"].as_f64().unwrap() - rate).abs() < 1e-5, "exact rate {exact}: {clip}");
        let (shape, _) = read_npy(&out.join("walk.wave.npy"));
        assert_eq!(shape[0], frames as u64);
        let warned = message.contains(
            "clip 'wave': at exactly 10 Hz the last frame is at 1 s, so the last 0.07 s \
            before its last key at 1.07 s are not baked",
        );
        assert_eq!(warned, exact, "{message}");
    }
    // Loops too: every clip of RobotExpressive at exactly 30 Hz (fitting gave 29.65-30.32 Hz),
    // a loop of whole frames ending on its seam, another (Jump: 0.7083 s, 21.25 frames) with
    // its last frame not its seam, and said so.
    if let Some(data) = data_dir() {
        let robot = dir.path().join("robot");
        let input = data.join("RobotExpressive.glb");
        let args = ["--input", input.to_str().unwrap(), "--output", robot.to_str().unwrap(), "--rate", "30"];
        let result = bake(&[&args[..], &["--exact-rate"]].concat());
        assert!(result.status.success(), "{}", stderr(&result));
        let sidecar = json(&robot.join("RobotExpressive.json"));
        let clips = sidecar["clips"].as_array().unwrap();
        assert!(clips.iter().all(|c| c["rate"] == 30.0), "{clips:?}");
        let clip = |name: &str| clips.iter().find(|c| c["name"] == name).unwrap();
        assert_eq!(
            (&clip("Idle")["frames"], &clip("Idle")["loop"]),
            (&serde_json::json!(101), &serde_json::json!(true))
        );
        assert_eq!(
            (&clip("Jump")["frames"], &clip("Jump")["loop"]),
            (&serde_json::json!(22), &serde_json::json!(false))
        );
        assert!(
            stderr(&result).contains("clip 'Jump': at exactly 30 Hz the last frame is at 0.7 s"),
            "{}",
            stderr(&result)
        );
        assert!(stderr(&result).contains("a loop, its frames on its looping curve, but its last frame is not its seam"));
    }
    // CesiumMan's walk (2 s) at 30 Hz ends on its last key.
    let Some(data) = data_dir() else { return };
    let result = bake(&[
        "--input",
        data.join("CesiumMan.glb").to_str().unwrap(),
        "--rate",
        "30",
        "--output",
        out.to_str().unwrap(),
    ]);
    assert!(result.status.success(), "{}", stderr(&result));
    let clip = &json(&out.join("CesiumMan.json"))["clips"][0];
    let (start, end) = (clip["start"].as_f64().unwrap(), clip["end"].as_f64().unwrap());
    assert!((end - 2.0).abs() < 1e-6 && clip["frames"] == ((end - start) * 30.0).round() as u64 + 1, "{clip}");
}

/// Every bake's summary gives the rig's size at rest, so a rig read at the wrong scale shows at
/// a glance (Mixamo's dancer, in centimetres in its file: 1.5 to 1.9 m tall, not 0.18); and the
/// meshes a texture does not draw are named in the summary and the sidecar, never dropped
/// silently: RobotExpressive's rigid parts (hung from bones without a skin) are drawn by its
/// skin textures, bound to their bones, but not by Babylon's baked vertex animation.
#[test]
fn the_summary_gives_the_rig_s_size_and_names_the_meshes_a_texture_does_not_draw() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, texture: &str, more: &[&str]| {
        let (out, input) = (dir.path().join(format!("{name}.{texture}{}", more.join(""))), data.join(name));
        let args = ["--input", input.to_str().unwrap(), "--output", out.to_str().unwrap(), "--texture", texture];
        let result = bake(&[&args[..], more].concat());
        assert!(result.status.success(), "{name}: {}", stderr(&result));
        (String::from_utf8_lossy(&result.stdout).into_owned(), stderr(&result), out)
    };
    let (summary, _, _) = run("Samba_Dancing.fbx", "model", &[]);
    let tall: f64 = summary
        .split_once("rig at rest ")
        .and_then(|(_, rest)| rest.split_whitespace().next())
        .and_then(|h| h.parse().ok())
        .unwrap_or_else(|| panic!("no rig in the summary: {summary}"));
    assert!((1.5..1.9).contains(&tall), "Samba_Dancing's rig is {tall} m tall");
    let sidecar = |out: &std::path::Path| json(&out.join("RobotExpressive.json"));
    // Skin textures draw the rigid parts: the sidecar binds each to its bone.
    let (_, warnings, out) = run("RobotExpressive.glb", "skin-trs", &[]);
    assert!(!warnings.contains("not drawn"), "{warnings}");
    let side = sidecar(&out);
    assert!(side.get("not_drawn").is_none(), "{side}");
    let primitives = side["primitives"].as_array().unwrap();
    let rigid: Vec<&serde_json::Value> = primitives.iter().filter(|p| p["rigid"].is_object()).collect();
    // 12 rigid meshes of 15 primitives (the torso has two, the head three), and the two hands.
    assert_eq!((rigid.len(), primitives.len() - rigid.len()), (15, 4), "{primitives:?}");
    let torso = rigid.iter().find(|p| p["name"].as_str().unwrap().starts_with("node 'Torso'")).unwrap();
    let body = side["joints"].as_array().unwrap().iter().position(|j| j == "Body").unwrap();
    let skin = &side["skins"][torso["skin"].as_u64().unwrap() as usize]["joints"];
    assert_eq!(skin[torso["rigid"]["joint"].as_u64().unwrap() as usize], body, "the torso hangs from Body");
    // Babylon's baked vertex animation moves skinned meshes alone: the rigid parts are named.
    let (_, warnings, out) = run("RobotExpressive.glb", "skin", &["--format", "babylon"]);
    assert!(
        warnings.contains("12 meshes are not drawn") && warnings.contains("node 'Torso', mesh 'Torso': a rigid"),
        "{warnings}"
    );
    assert_eq!(sidecar(&out)["not_drawn"].as_array().unwrap().len(), 12);
    // A model texture draws no mesh: nothing is left out of it.
    let (_, warnings, out) = run("RobotExpressive.glb", "model", &[]);
    assert!(!warnings.contains("not drawn"), "{warnings}");
    assert!(sidecar(&out).get("not_drawn").is_none());
}
