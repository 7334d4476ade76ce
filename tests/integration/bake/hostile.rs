//! Hostile and newcomer cases, one test each: crafted counts that would size allocations,
//! buffer URIs reaching outside the input's directory, output permissions, stray output
//! directories, clashing output names, flags read the wrong way. Each asserts the exit code,
//! the message and that nothing was written (and no byte of an outside file was read).

use super::{assert_rejected, bake, stderr, tiny_gltf, tiny_gltf_value};
use assert_cmd::Command;
use std::path::Path;

const Q: [f32; 4] = [0.0, 0.0, 0.0, 1.0];
const TURN: [f32; 4] = [0.0, 0.382_683_43, 0.0, 0.923_879_5];

fn quatcurve(args: &[&str]) -> std::process::Output {
    Command::cargo_bin("quatcurve").unwrap().args(args).output().unwrap()
}

const BVH_HEAD: &str = "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n End \
    Site\n {\n  OFFSET 0 1 0\n }\n}\nMOTION\n";

#[test]
fn bvh_counts_are_checked_against_the_text_before_any_allocation() {
    // Four billion frames announced, two present: a 96 GB allocation before the fix.
    let text = format!("{BVH_HEAD}Frames: 4000000000\nFrame Time: 0.1\n0 0 0\n0 0 10\n");
    assert_rejected("frames.bvh", text.as_bytes(), &["frames.bvh", "Frames: 4000000000 but 2 frame lines follow"]);
    let text = BVH_HEAD.replace("CHANNELS 3", "CHANNELS 99999999999");
    assert_rejected(
        "channels.bvh",
        format!("{text}Frames: 1\nFrame Time: 0.1\n0 0 0\n").as_bytes(),
        &["channels.bvh", "99999999999 channels", "at most 6"],
    );
    // A frame time of a century: two frames at 30 Hz would be 3e9 output frames.
    let text = format!("{BVH_HEAD}Frames: 2\nFrame Time: 3e9\n0 0 0\n0 0 10\n");
    assert_rejected("century.bvh", text.as_bytes(), &["century.bvh", "lower rate"]);
}

#[test]
fn gltf_accessors_must_fit_their_bytes() {
    let (mut doc, _) = tiny_gltf_value(&[0.0, 1.0], &[Q, TURN]);
    doc["accessors"][0]["count"] = 4_000_000_000u64.into();
    doc["accessors"][0]["max"] = serde_json::json!([1.0]);
    assert_rejected(
        "count.gltf",
        doc.to_string().as_bytes(),
        &["count.gltf", "clip 'wave', bone rotation", "key times (accessor 0)", "count 4000000000"],
    );
    let (mut doc, _) = tiny_gltf_value(&[0.0, 1.0], &[Q, TURN]);
    doc["bufferViews"][1]["byteStride"] = 252.into();
    assert_rejected(
        "stride.gltf",
        doc.to_string().as_bytes(),
        &["stride.gltf", "key values (accessor 1)", "stride 252"],
    );
    let (mut doc, _) = tiny_gltf_value(&[0.0, 1.0], &[Q, TURN]);
    doc["bufferViews"][1]["byteLength"] = 1_000_000.into();
    assert_rejected(
        "view.gltf",
        doc.to_string().as_bytes(),
        &["view.gltf", "bufferViews[1]: bytes 8+1000000 lie outside buffer 0"],
    );
    // Two keys a year apart at 30 Hz: a billion frames.
    assert_rejected(
        "year.gltf",
        tiny_gltf(&[0.0, 3.2e7], &[Q, TURN]).as_bytes(),
        &["year.gltf", "clip 'wave'", "lower rate"],
    );
    // A GLB whose JSON chunk claims more bytes than the file has.
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend(40u32.to_le_bytes());
    glb.extend(0xFFFF_FFF0u32.to_le_bytes());
    glb.extend(b"JSON{}");
    assert_rejected("chunk.glb", &glb, &["chunk.glb", "not a valid g"]);
}

/// A .gltf in `dir` whose buffer is at `uri`, with the buffer's bytes returned.
fn gltf_with_uri(dir: &Path, uri: &str) -> (std::path::PathBuf, Vec<u8>) {
    let (mut doc, bytes) = tiny_gltf_value(&[0.0, 0.5, 1.0], &[Q, TURN, Q]);
    doc["buffers"][0]["uri"] = uri.into();
    let path = dir.join("outside.gltf");
    std::fs::write(&path, doc.to_string()).unwrap();
    (path, bytes)
}

#[test]
fn gltf_buffer_uris_stay_inside_the_input_directory_unless_allowed() {
    let root = tempfile::tempdir().unwrap();
    let inner = root.path().join("clips");
    std::fs::create_dir(&inner).unwrap();
    let out = root.path().join("out");
    let (input, bytes) = gltf_with_uri(&inner, "x");
    // The buffer's bytes outside the input's directory, plus a secret-looking file.
    std::fs::write(root.path().join("keys.bin"), &bytes).unwrap();
    let refused = |uri: &str, why: &str| {
        gltf_with_uri(&inner, uri);
        let result = bake(&["--input", input.to_str().unwrap(), "--output", out.to_str().unwrap(), "--device", "cpu"]);
        assert_eq!(result.status.code(), Some(2), "{uri}: {}", stderr(&result));
        assert!(
            stderr(&result).contains(&format!("uri {uri}")) && stderr(&result).contains(why),
            "{uri}: {}",
            stderr(&result)
        );
        assert!(!out.exists(), "{uri}: output written");
    };
    refused("/etc/passwd", "absolute path");
    refused("../../../../../../../../etc/passwd", "leaves the file's directory");
    refused("../keys.bin", "leaves the file's directory");
    refused("file:///etc/passwd", "absolute path");
    refused("https://example.com/keys.bin", "https URIs are not read");
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(root.path().join("keys.bin"), inner.join("link.bin")).unwrap();
        refused("link.bin", "leaves the file's directory");
    }
    // A relative, percent-encoded name inside the directory is read.
    std::fs::write(inner.join("my keys.bin"), &bytes).unwrap();
    gltf_with_uri(&inner, "my%20keys.bin");
    let result = bake(&["--input", input.to_str().unwrap(), "--output", out.to_str().unwrap(), "--device", "cpu"]);
    assert!(result.status.success(), "{}", stderr(&result));
    // --allow-external-uris reads outside files.
    std::fs::remove_dir_all(&out).unwrap();
    gltf_with_uri(&inner, "../keys.bin");
    let result = bake(&[
        "--input",
        input.to_str().unwrap(),
        "--output",
        out.to_str().unwrap(),
        "--device",
        "cpu",
        "--allow-external-uris",
    ]);
    assert!(result.status.success(), "{}", stderr(&result));
}

#[cfg(unix)]
#[test]
fn outputs_get_the_permissions_of_a_plain_file_create() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("wave.gltf");
    std::fs::write(&input, tiny_gltf(&[0.0, 0.5, 1.0], &[Q, TURN, Q])).unwrap();
    for (umask, mode) in [("022", 0o644), ("027", 0o640), ("002", 0o664)] {
        let out = dir.path().join(format!("out{umask}"));
        let bin = assert_cmd::cargo::cargo_bin("quatcurve");
        let script = format!(
            "umask {umask} && exec '{}' bake --input '{}' --output '{}' --device cpu",
            bin.display(),
            input.display(),
            out.display()
        );
        let result = std::process::Command::new("sh").arg("-c").arg(&script).output().unwrap();
        assert!(result.status.success(), "{}", stderr(&result));
        for entry in std::fs::read_dir(&out).unwrap() {
            let entry = entry.unwrap();
            let got = entry.metadata().unwrap().permissions().mode() & 0o777;
            assert_eq!(got, mode, "umask {umask}: {} has mode {got:o}", entry.path().display());
        }
    }
}

#[test]
fn no_loader_noise_without_a_runtime_directory() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("demo.json");
    let result = Command::cargo_bin("quatcurve")
        .unwrap()
        .env_remove("XDG_RUNTIME_DIR")
        .args(["eval", "--output", output.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", stderr(&result));
    assert!(!stderr(&result).contains("XDG_RUNTIME_DIR"), "{}", stderr(&result));
}

#[test]
fn negative_numbers_reach_our_checks() {
    let result = quatcurve(&["bake", "--rate", "-1", "--characters", "1"]);
    assert_eq!(result.status.code(), Some(2));
    assert!(stderr(&result).contains("--rate must be a positive number of Hz, not -1"), "{}", stderr(&result));
    let result = quatcurve(&["eval", "--rate", "-1"]);
    assert_eq!(result.status.code(), Some(2));
    assert!(
        stderr(&result).contains("--rate: a sample rate must be a positive number of samples per second, got -1"),
        "{}",
        stderr(&result)
    );
}

#[test]
fn a_directory_without_animation_is_an_error_not_the_crowd() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), "nothing to bake").unwrap();
    let out = dir.path().join("out");
    let result = bake(&["--input", dir.path().to_str().unwrap(), "--output", out.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(
        stderr(&result).contains("holds no file of .gltf, .glb, .fbx, .usd, .usda, .usdc, .usdz, .bvh, .npz, .qcf"),
        "{}",
        stderr(&result)
    );
    assert!(!out.exists());
}

#[test]
fn inputs_with_one_name_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    for sub in ["walk", "run"] {
        std::fs::create_dir(dir.path().join(sub)).unwrap();
        std::fs::write(dir.path().join(sub).join("idle.gltf"), tiny_gltf(&[0.0, 0.5, 1.0], &[Q, TURN, Q])).unwrap();
    }
    let out = dir.path().join("out");
    let walk = dir.path().join("walk");
    let run = dir.path().join("run").join("idle.gltf");
    let result = bake(&["--input", walk.to_str().unwrap(), run.to_str().unwrap(), "--output", out.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(stderr(&result).contains("would both write") && stderr(&result).contains("idle.*"), "{}", stderr(&result));
    assert!(!out.exists());
}

#[test]
fn unusable_output_directories_are_exit_2_and_failed_jobs_leave_none() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("plain");
    std::fs::write(&file, "a file, not a directory").unwrap();
    let under = file.join("out");
    let result = bake(&["--characters", "1", "--output", under.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(stderr(&result).contains("cannot create the directory"), "{}", stderr(&result));
    // A failed bake into new nested directories removes them all again.
    let bad = dir.path().join("bad.gltf");
    std::fs::write(&bad, tiny_gltf(&[0.0, 1.0, 0.5], &[Q, TURN, Q])).unwrap();
    let nested = dir.path().join("a").join("b");
    let result = bake(&["--input", bad.to_str().unwrap(), "--output", nested.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(!dir.path().join("a").exists(), "empty output directories left behind");
}

#[test]
fn flags_a_subcommand_does_not_have_are_rejected() {
    let result = quatcurve(&["bench", "--device", "cpu", "--tracks", "1", "--samples", "1"]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(stderr(&result).contains("unexpected argument '--device'"), "{}", stderr(&result));
}

#[test]
fn messages_print_numbers_naturally_and_long_names_fit() {
    let dir = tempfile::tempdir().unwrap();
    let name = format!("{}.gltf", "é".repeat(30));
    let input = dir.path().join(&name);
    std::fs::write(&input, tiny_gltf(&[0.0, 1.0, 2.0], &[Q, [0.0; 4], Q])).unwrap();
    let result = bake(&["--input", input.to_str().unwrap(), "--output", dir.path().join("out").to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(stderr(&result).contains("has norm 0, below 1e-6"), "{}", stderr(&result));
    assert!(String::from_utf8_lossy(&result.stdout).contains("FAILED (input)"));
}

/// Inputs the mutation run (`mutations.rs`) found crashing the reader, kept as regressions:
/// each was a panic (in the `gltf` crate or in our GLB writer) before its guard existed.
#[test]
fn crashers_found_by_the_mutation_run_are_input_errors() {
    let crafted = |edit: &dyn Fn(&mut serde_json::Value)| {
        let (mut doc, _) = tiny_gltf_value(&[0.0, 0.5, 1.0], &[Q, TURN, Q]);
        edit(&mut doc);
        doc.to_string()
    };
    // An unknown channel target path (the crate unwraps it).
    let doc = crafted(&|d| d["animations"][0]["channels"][0]["target"]["path"] = "rot-1ation".into());
    assert_rejected("path.gltf", doc.as_bytes(), &["path.gltf", "target", "path"]);
    // A mesh whose POSITION accessor does not exist (the crate's validation indexes it).
    let doc = crafted(&|d| d["meshes"] = serde_json::json!([{"primitives": [{"attributes": {"POSITION": 9}}]}]));
    assert_rejected(
        "position.gltf",
        doc.as_bytes(),
        &["position.gltf", "attributes.POSITION: accessor 9 does not exist"],
    );
    // Key times stored as VEC2 (the crate's reader asserts the element size).
    let doc = crafted(&|d| d["accessors"][0]["type"] = "VEC2".into());
    assert_rejected(
        "vec2.gltf",
        doc.as_bytes(),
        &["vec2.gltf", "key times (accessor 0)", "Vec2 of F32 is not an element type glTF allows here"],
    );
    // A channel targeting a node that does not exist (the crate unwraps the lookup).
    let doc = crafted(&|d| d["animations"][0]["channels"][0]["target"]["node"] = 99.into());
    assert_rejected(
        "node.gltf",
        doc.as_bytes(),
        &["node.gltf", "animations[0].channels[0].target.node: index 99 does not exist"],
    );
    // An unused buffer view at byte offset 2^64 - 1 (our GLB writer re-based it with an add).
    let doc = crafted(&|d| {
        d["bufferViews"]
            .as_array_mut()
            .unwrap()
            .push(serde_json::json!({"buffer": 0, "byteOffset": u64::MAX, "byteLength": 4}))
    });
    assert_rejected("offset.gltf", doc.as_bytes(), &["offset.gltf", "bufferViews[2]", "lie outside buffer 0"]);
    // Found by `cargo fuzz run bvh`: four rotation channels, or one axis twice, crashed the
    // BVH writer (it solves for the angles of 1 or 3 distinct axes).
    for (channels, found) in [
        ("CHANNELS 4 Zrotation Zrotation Yrotation Xrotation", "4 rotation channels about 3 distinct axes"),
        ("CHANNELS 3 Zrotation Zrotation Xrotation", "3 rotation channels about 2 distinct axes"),
    ] {
        let text = format!(
            "{}Frames: 2\nFrame Time: 0.1\n0 0 0 0\n0 0 10 0\n",
            BVH_HEAD.replace("CHANNELS 3 Zrotation Xrotation Yrotation", channels)
        );
        let text =
            if channels.starts_with("CHANNELS 3") { text.replace("0 0 0 0\n0 0 10 0", "0 0 0\n0 0 10") } else { text };
        assert_rejected("axes.bvh", text.as_bytes(), &["axes.bvh", found, "0, 1 or 3 distinct axes"]);
    }
}
