//! SMPL-family pose archives (AMASS's layouts, docs/DATASETS.md) resampled into their own
//! layout. The fixtures are generated here from the documented layout; frames are held to
//! a slerp of the keys in glam (scipy's `Slerp` holds them in the Python tests); split fields and
//! per-frame coefficients follow the poses; other fields are copied byte for byte; hostile
//! archives are refused by name with nothing written.

use super::{assert_rejected, bake, json, stderr};
use crate::common::{f64_bytes, npy_bytes, npz_bytes, write_npz};
use glam::{DQuat, DVec3};
use std::io::Read;
use std::path::Path;

/// Joints of SMPL-H and SMPL-X.
const SMPL_H: usize = 52;
const SMPL_X: usize = 55;

/// `[frames, joints * 3]` axis-angles: a smooth wander of every joint, up to about 2 rad.
fn poses(frames: usize, joints: usize) -> Vec<f64> {
    (0..frames)
        .flat_map(|f| {
            (0..3 * joints).map(move |c| {
                let (t, c) = (f as f64 / 20.0, c as f64);
                0.7 * (1.3 * t + 0.37 * c).sin() + 0.4 * (0.5 * t * (1.0 + c % 5.0) + c).cos()
            })
        })
        .collect()
}

fn f32_bytes(values: &[f64]) -> Vec<u8> {
    values.iter().flat_map(|&v| (v as f32).to_le_bytes()).collect()
}

/// A numpy unicode scalar (`<U{n}`) as `np.array("female")` saves it.
fn unicode(text: &str) -> Vec<u8> {
    let data: Vec<u8> = text.chars().flat_map(|c| (c as u32).to_le_bytes()).collect();
    npy_bytes(&format!("<U{}", text.chars().count()), &[], &data)
}

/// A pickle that would run code if it were unpickled.
const PICKLE: &[u8] = b"\x80\x02cbuiltins\neval\nq\x00.";

/// An archive's members: name and `.npy` bytes.
type Members = Vec<(&'static str, Vec<u8>)>;

/// An AMASS SMPL-H archive: 61 frames at 60 Hz (one second), with betas, gender and DMPLs.
fn smpl_h() -> (Vec<f64>, Vec<f64>, Vec<f64>, Members) {
    let frames = 61;
    let (poses, trans) = (poses(frames, SMPL_H), (0..frames * 3).map(|i| 0.01 * i as f64).collect::<Vec<_>>());
    let dmpls: Vec<f64> = (0..frames * 8).map(|i| (i as f64 * 0.1).sin()).collect();
    let members = vec![
        ("trans", npy_bytes("<f8", &[frames as u64, 3], &f64_bytes(&trans))),
        ("gender", unicode("female")),
        ("mocap_framerate", npy_bytes("<f8", &[], &f64_bytes(&[60.0]))),
        ("betas", npy_bytes("<f8", &[16], &f64_bytes(&[0.25; 16]))),
        ("poses", npy_bytes("<f8", &[frames as u64, 3 * SMPL_H as u64], &f64_bytes(&poses))),
        ("dmpls", npy_bytes("<f8", &[frames as u64, 8], &f64_bytes(&dmpls))),
    ];
    (poses, trans, dmpls, members)
}

/// Every member of an archive: name (without `.npy`) and bytes, in the archive's order.
fn members(path: &Path) -> Vec<(String, Vec<u8>)> {
    let mut zip = zip::ZipArchive::new(std::fs::File::open(path).unwrap()).unwrap();
    (0..zip.len())
        .map(|i| {
            let mut entry = zip.by_index(i).unwrap();
            // Stamped with the zip epoch, not the time of the bake: the same bake, the same bytes.
            let stamp = entry.last_modified();
            assert_eq!((stamp.year(), stamp.month(), stamp.day()), (1980, 1, 1), "{}", entry.name());
            let mut bytes = Vec::new();
            entry.read_to_end(&mut bytes).unwrap();
            (entry.name().trim_end_matches(".npy").to_string(), bytes)
        })
        .collect()
}

/// A member's shape and values as f64.
fn floats(members: &[(String, Vec<u8>)], name: &str) -> (Vec<u64>, Vec<f64>) {
    let (_, bytes) = members.iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("no {name}"));
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    let shape = npy.shape().to_vec();
    let values = match npy.dtype() {
        npyz::DType::Plain(t) if t.size_field() == 4 => {
            npy.into_vec::<f32>().unwrap().into_iter().map(f64::from).collect()
        }
        _ => npy.into_vec::<f64>().unwrap(),
    };
    (shape, values)
}

fn rotation(poses: &[f64], width: usize, frame: usize, joint: usize) -> DQuat {
    let v = &poses[frame * width + 3 * joint..][..3];
    DQuat::from_scaled_axis(DVec3::new(v[0], v[1], v[2]))
}

/// Slerp on the shorter arc as scipy's `Slerp` computes it, `a * (a^-1 b)^h`, with glam's
/// axis-angle (glam's own `slerp` turns to a normalized lerp for close rotations, 1e-8 rad off).
fn slerp(a: DQuat, b: DQuat, h: f64) -> DQuat {
    let step = a.inverse() * b;
    let step = if step.w < 0.0 { -step } else { step };
    a * DQuat::from_scaled_axis(step.to_scaled_axis() * h)
}

/// The angle between two rotations, resolved to 1e-16 rad (glam's `angle_between` takes the
/// arccosine of their dot product, which cannot tell angles under about 2e-8 from 0).
fn angle(a: DQuat, b: DQuat) -> f64 {
    let d = a.inverse() * b;
    2.0 * DVec3::new(d.x, d.y, d.z).length().atan2(d.w.abs())
}

#[test]
fn smpl_h_poses_resample_at_exact_times_into_their_own_layout() {
    let dir = tempfile::tempdir().unwrap();
    let (source, trans, dmpls, written) = smpl_h();
    let input = dir.path().join("walk.npz");
    write_npz(&input, &written);
    let out = dir.path().join("out");
    let args = ["--input", input.to_str().unwrap(), "--output", out.to_str().unwrap(), "--device", "cpu"];
    let result = bake(&[&args[..], &["--rate", "24", "--exact-rate"]].concat());
    assert!(result.status.success(), "{}", stderr(&result));
    let baked = members(&out.join("walk.npz"));
    // Every member, in the archive's order; the per-sequence ones byte for byte.
    let names: Vec<&str> = baked.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["trans", "gender", "mocap_framerate", "betas", "poses", "dmpls"]);
    for copied in ["gender", "betas"] {
        let original = &written.iter().find(|(n, _)| *n == copied).unwrap().1;
        assert_eq!(&baked.iter().find(|(n, _)| n == copied).unwrap().1, original, "{copied}");
    }
    assert_eq!(floats(&baked, "mocap_framerate"), (vec![], vec![24.0]));
    // Frames at exactly k / 24 over the second: 25, the last on the last key.
    let (shape, poses) = floats(&baked, "poses");
    assert_eq!(shape, [25, 156]);
    let width = 3 * SMPL_H;
    let mut worst = 0.0f64;
    for f in 0..25 {
        let at = f as f64 / 24.0 * 60.0;
        let (key, h) = ((at.floor() as usize).min(59), at - (at.floor()).min(59.0));
        for j in 0..SMPL_H {
            let expected = slerp(rotation(&source, width, key, j), rotation(&source, width, key + 1, j), h);
            worst = worst.max(angle(rotation(&poses, width, f, j), expected));
        }
        // The root's translation and the soft-tissue coefficients, linearly.
        let (_, baked_trans) = floats(&baked, "trans");
        let (_, baked_dmpls) = floats(&baked, "dmpls");
        for c in 0..3 {
            let expected = trans[key * 3 + c] + h * (trans[(key + 1) * 3 + c] - trans[key * 3 + c]);
            assert!((baked_trans[f * 3 + c] - expected).abs() < 1e-12, "trans frame {f}");
        }
        for c in 0..8 {
            let expected = dmpls[key * 8 + c] + h * (dmpls[(key + 1) * 8 + c] - dmpls[key * 8 + c]);
            assert!((baked_dmpls[f * 8 + c] - expected).abs() < 1e-12, "dmpls frame {f}");
        }
    }
    // In f64 from the f64 archive, not through the device's f32 rows.
    assert!(worst < 1e-12, "frames {worst:e} rad from the slerp of the keys");
    // The source's own frames slerped unless asked otherwise, and the sidecar says so; the
    // local texture is the same frames.
    let sidecar = json(&out.join("walk.json"));
    assert_eq!((&sidecar["curve"], &sidecar["interpolation"]), (&"source".into(), &serde_json::json!(["LINEAR"])));
    // The sidecar says what the archive holds of each array.
    let arrays: Vec<(String, String)> = sidecar["arrays"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| (a["name"].as_str().unwrap().to_string(), a["written"].as_str().unwrap().to_string()))
        .collect();
    let expected = [
        ("trans", "resampled"),
        ("gender", "copied"),
        ("mocap_framerate", "rate"),
        ("betas", "copied"),
        ("poses", "resampled"),
        ("dmpls", "resampled"),
    ];
    assert_eq!(arrays, expected.map(|(n, w)| (n.to_string(), w.to_string())));
    assert_eq!(sidecar["joints"].as_array().unwrap().len(), SMPL_H);
    assert_eq!(sidecar["joints"][37], "right_index1");
    let asked = dir.path().join("c2");
    let result =
        bake(&["--input", input.to_str().unwrap(), "--output", asked.to_str().unwrap(), "--curve", "bspline-interp"]);
    assert!(result.status.success(), "{}", stderr(&result));
    assert_eq!(json(&asked.join("walk.json"))["curve"], "bspline-interp");
}

#[test]
fn smpl_x_split_fields_follow_the_resampled_poses_in_their_dtype() {
    let dir = tempfile::tempdir().unwrap();
    let frames = 31;
    let source = poses(frames, SMPL_X);
    let width = 3 * SMPL_X;
    let part = |joints: std::ops::Range<usize>| -> Vec<f64> {
        (0..frames).flat_map(|f| source[f * width + 3 * joints.start..f * width + 3 * joints.end].to_vec()).collect()
    };
    let f32_part = |name, joints: std::ops::Range<usize>| {
        (name, npy_bytes("<f4", &[frames as u64, 3 * joints.len() as u64], &f32_bytes(&part(joints))))
    };
    let written = vec![
        ("poses", npy_bytes("<f4", &[frames as u64, width as u64], &f32_bytes(&source))),
        ("mocap_frame_rate", npy_bytes("<i8", &[], &30i64.to_le_bytes())),
        ("mocap_time_length", npy_bytes("<f8", &[], &f64_bytes(&[1.0]))),
        f32_part("root_orient", 0..1),
        f32_part("pose_body", 1..22),
        f32_part("pose_jaw", 22..23),
        f32_part("pose_eye", 23..25),
        f32_part("pose_hand", 25..55),
        // A dict saved by numpy (an object array): copied as its bytes, never unpickled.
        ("markers_latent_vids", npy_bytes("|O", &[], PICKLE)),
    ];
    let input = dir.path().join("talk.npz");
    write_npz(&input, &written);
    let out = dir.path().join("out");
    let result = bake(&["--input", input.to_str().unwrap(), "--output", out.to_str().unwrap(), "--rate", "10"]);
    assert!(result.status.success(), "{}", stderr(&result));
    let baked = members(&out.join("talk.npz"));
    let (shape, poses) = floats(&baked, "poses");
    assert_eq!(shape, [11, width as u64]);
    assert_eq!(baked.iter().find(|(n, _)| n == "markers_latent_vids").unwrap().1, written[8].1);
    assert!(baked.iter().find(|(n, _)| n == "poses").unwrap().1.windows(3).any(|w| w == b"<f4"), "poses stay float32");
    assert_eq!(floats(&baked, "mocap_frame_rate").1, [10.0]);
    // Every third key is a frame: the keys themselves, to float32.
    for f in 0..11 {
        for j in 0..SMPL_X {
            let angle = rotation(&poses, width, f, j).angle_between(rotation(&source, width, 3 * f, j));
            assert!(angle < 1e-5, "frame {f} joint {j}: {angle}");
        }
    }
    for (name, joints) in
        [("root_orient", 0..1), ("pose_body", 1..22), ("pose_jaw", 22..23), ("pose_eye", 23..25), ("pose_hand", 25..55)]
    {
        let (shape, values) = floats(&baked, name);
        assert_eq!(shape, [11, 3 * joints.len() as u64], "{name}");
        let expected: Vec<f64> =
            (0..11).flat_map(|f| poses[f * width + 3 * joints.start..f * width + 3 * joints.end].to_vec()).collect();
        assert!(values == expected, "{name} is not its part of poses");
    }
}

/// An SMPL-H archive with `change` applied to its members.
fn hostile(change: impl FnOnce(&mut Members)) -> Vec<u8> {
    let (_, _, _, mut members) = smpl_h();
    change(&mut members);
    npz_bytes(&members)
}

fn set(members: &mut [(&'static str, Vec<u8>)], name: &str, bytes: Vec<u8>) {
    members.iter_mut().find(|(n, _)| *n == name).unwrap().1 = bytes;
}

#[test]
fn hostile_smpl_archives_are_refused_naming_the_file_and_field() {
    let rejected = |name: &str, change: &dyn Fn(&mut Members), expected: &[&str]| {
        let bytes = hostile(change);
        assert_rejected(name, &bytes, &[&[name][..], expected].concat());
    };
    rejected(
        "labels.npz",
        &|m| m.push(("frame_labels", npy_bytes("<i8", &[61], &[0u8; 61 * 8]))),
        &["frame_labels: has the source's 61 rows but is not an array of floats"],
    );
    rejected(
        "norate.npz",
        &|m| m.retain(|(n, _)| *n != "mocap_framerate"),
        &["mocap_framerate: missing", "mocap_frame_rate"],
    );
    rejected(
        "negative.npz",
        &|m| set(m, "mocap_framerate", npy_bytes("<f8", &[], &f64_bytes(&[-60.0]))),
        &["mocap_framerate: -60 is not a positive number"],
    );
    rejected(
        "array_rate.npz",
        &|m| set(m, "mocap_framerate", npy_bytes("<f8", &[2], &f64_bytes(&[60.0, 60.0]))),
        &["mocap_framerate: shape [2]; expected one number"],
    );
    let mut nan = poses(61, SMPL_H);
    nan[3 * 156 + 3 * 4 + 1] = f64::NAN;
    rejected(
        "nan.npz",
        &|m| set(m, "poses", npy_bytes("<f8", &[61, 156], &f64_bytes(&nan))),
        &["poses: frame 3: left_knee value 13 is NaN"],
    );
    rejected(
        "width.npz",
        &|m| set(m, "poses", npy_bytes("<f8", &[61, 100], &f64_bytes(&poses(61, 100)[..6100]))),
        &["poses: shape [61, 100]", "156 for SMPL-H"],
    );
    rejected(
        "huge.npz",
        &|m| set(m, "poses", npy_bytes("<f8", &[4_000_000_000, 156], &f64_bytes(&[0.0; 8]))),
        &["poses: shape [4000000000, 156]", "needs 4992000000000 bytes"],
    );
    // A count whose product overflows u64 (npyz's own product panicked in debug builds).
    rejected(
        "overflow.npz",
        &|m| set(m, "poses", npy_bytes("<f8", &[1 << 32, 1 << 32, 156], &f64_bytes(&[0.0; 8]))),
        &["poses: not a .npy array: shape (4294967296, 4294967296, 156) overflows"],
    );
    rejected(
        "trans.npz",
        &|m| set(m, "trans", npy_bytes("<f8", &[60, 3], &f64_bytes(&[0.0; 180]))),
        &["trans: shape [60, 3]; expected [61, 3]"],
    );
    // numpy's pickle of an object array where a field is read: refused from the header.
    rejected(
        "object.npz",
        &|m| set(m, "trans", npy_bytes("|O", &[], PICKLE)),
        &["trans: an object array", "never unpickles"],
    );
    rejected(
        "split.npz",
        &|m| m.push(("root_orient", npy_bytes("<f8", &[61, 3], &f64_bytes(&[0.0; 183])))),
        &["root_orient: frame 0, value 0", "must be one pose"],
    );
    rejected(
        "duration.npz",
        &|m| m.push(("mocap_time_length", npy_bytes("<f8", &[], &f64_bytes(&[2.0])))),
        &["mocap_framerate: 60 frames per second disagrees with mocap_time_length 2 s over 61 frames"],
    );
    let whole = hostile(|_| {});
    assert_rejected("truncated.npz", &whole[..whole.len() / 2], &["truncated.npz", "file: not a zip archive"]);
    // Model-space products need the body model's offsets, which the file does not hold.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("walk.npz");
    std::fs::write(&input, &whole).unwrap();
    let out = dir.path().join("out");
    for asked in [&["--texture", "model"][..], &["--root-motion", "extract"], &["--max-error-cm", "0.5"]] {
        let result = bake(&[&["--input", input.to_str().unwrap(), "--output", out.to_str().unwrap()], asked].concat());
        assert_eq!(result.status.code(), Some(2), "{asked:?}: {}", stderr(&result));
        assert!(stderr(&result).contains("holds rotations alone"), "{asked:?}: {}", stderr(&result));
        assert!(!out.join("walk.npz").exists(), "{asked:?}");
    }
    // So do `play`'s palettes (matrices of positions): refused before anything is written.
    let palettes = dir.path().join("palettes.npy");
    let result = assert_cmd::Command::cargo_bin("quatcurve")
        .unwrap()
        .args(["play", "--input", input.to_str().unwrap(), "--output", palettes.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(result.status.code(), Some(2), "play: {}", stderr(&result));
    assert!(
        stderr(&result).contains("holds rotations alone") && stderr(&result).contains("walk.npz"),
        "{}",
        stderr(&result)
    );
    assert!(!palettes.exists());
}
