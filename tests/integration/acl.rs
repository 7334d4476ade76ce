//! `examples/acl/`, the side-by-side with ACL 2.1.0 (DESIGN section 16), smoke-tested: its
//! harness builds against the vendored headers as `run.sh` builds it and compresses and
//! decompresses a clip in `examples/acl_raw.rs`'s format. Timings stay benchmarks (`run.sh`).

use std::path::Path;
use std::process::Command;

/// A clip of `joints` joints in a chain, each turning about its own axis, in the raw layout:
/// `u32` joints, `u32` frames, `f32` rate, an `i32` parent per joint, then per frame per joint
/// rotation `x, y, z, w` and translation `x, y, z` as `f32`.
fn raw_clip(joints: u32, frames: u32, rate: f32) -> Vec<u8> {
    let mut bytes = Vec::new();
    bytes.extend(joints.to_le_bytes());
    bytes.extend(frames.to_le_bytes());
    bytes.extend(rate.to_le_bytes());
    for j in 0..joints as i32 {
        bytes.extend((j - 1).to_le_bytes());
    }
    for f in 0..frames {
        for j in 0..joints {
            let half = 0.4 * (f as f32 / rate * (1.0 + j as f32)).sin();
            let axis = [(j % 3 == 0) as u32 as f32, (j % 3 == 1) as u32 as f32, (j % 3 == 2) as u32 as f32];
            let values = [axis[0] * half.sin(), axis[1] * half.sin(), axis[2] * half.sin(), half.cos(), 0.0, 10.0, 0.0];
            bytes.extend(values.iter().flat_map(|v| v.to_le_bytes()));
        }
    }
    bytes
}

#[test]
fn the_acl_harness_builds_against_the_vendored_headers_and_round_trips_a_clip() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let acl = root.join("../shared/vendor/acl-2.1.0");
    if !acl.join("includes/acl").exists() {
        eprintln!("skipped: ACL's headers are not at {}", acl.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let harness = dir.path().join("harness");
    // run.sh's build, at -O1: this is about building and running, not speed.
    let built = Command::new("g++")
        .args(["-O1", "-std=c++14", "-DNDEBUG", "-mavx"])
        .arg(format!("-I{}", acl.join("includes").display()))
        .arg(format!("-I{}", acl.join("external/rtm/includes").display()))
        .arg(root.join("examples/acl/harness.cpp"))
        .arg("-o")
        .arg(&harness)
        .output();
    let built = match built {
        Ok(out) => out,
        Err(e) => {
            eprintln!("skipped: no C++ compiler (g++: {e})");
            return;
        }
    };
    assert!(built.status.success(), "{}", String::from_utf8_lossy(&built.stderr));
    let clip = dir.path().join("clip.raw");
    std::fs::write(&clip, raw_clip(8, 120, 30.0)).unwrap();
    let out = Command::new(&harness).arg(&clip).args(["1", "1"]).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("8 joints, 120 frames at 30 Hz; ACL "), "{stdout}");
    let first = stdout.lines().next().unwrap_or_default();
    let ratio: f64 = first
        .rsplit(", ")
        .next()
        .and_then(|r| r.strip_suffix(":1"))
        .and_then(|r| r.parse().ok())
        .unwrap_or_else(|| panic!("no ratio in {stdout}"));
    assert!(ratio > 1.0, "{stdout}");
    assert!(stdout.contains("ns a bone-pose"), "{stdout}");
    // Not a raw clip: named, exit non-zero.
    std::fs::write(&clip, b"nope").unwrap();
    let out = Command::new(&harness).arg(&clip).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a raw clip"));
}
