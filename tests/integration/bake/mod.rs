//! `quatcurve bake` end to end on the real files in `../shared/data` (skipped with a message
//! when absent), on crafted bad inputs, and the BVH Euler conventions against hand-computed
//! rotations; hostile files one by one ([`hostile`]) and mutated at random ([`mutations`]);
//! sharded jobs and resume ([`shards`]).

mod babylon;
mod clients;
mod documented_names;
mod fbx;
mod fitted;
mod hostile;
mod images;
mod interpolation;
mod mutations;
mod reporting;
mod rigid;
mod root_motion;
mod shader;
mod shards;
mod smpl;
mod textures;
mod three;
mod usd;
mod vertex;
mod vertex_shader;
mod viewer;

use assert_cmd::Command;
use base64::Engine;
use quatcurve::formats::bvh::{self, BvhChannel};
use quatcurve::QuatF64;
use std::path::{Path, PathBuf};

pub(crate) fn data_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if dir.join("Fox.glb").exists() {
        Some(dir)
    } else {
        // CI sets QUATCURVE_REQUIRE_DATA=1, so a green run proves the real files were baked.
        assert!(
            std::env::var_os("QUATCURVE_REQUIRE_DATA").is_none(),
            "../shared/data is absent and QUATCURVE_REQUIRE_DATA is set"
        );
        eprintln!("skipped: ../shared/data is absent");
        None
    }
}

/// `../shared/data` as one motion library to bake whole: its glTF and BVH files, linked into a
/// directory of their own. Its FBX files are Blender's exports of two of its glTFs, with the
/// same stems, which one bake of a directory refuses to write twice.
fn library() -> Option<PathBuf> {
    static LIBRARY: std::sync::OnceLock<Option<PathBuf>> = std::sync::OnceLock::new();
    LIBRARY
        .get_or_init(|| {
            let data = data_dir()?;
            let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("library");
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
            for entry in std::fs::read_dir(&data).unwrap() {
                let path = entry.unwrap().path();
                if matches!(path.extension().and_then(|e| e.to_str()), Some("glb" | "gltf" | "bvh")) {
                    std::os::unix::fs::symlink(&path, dir.join(path.file_name().unwrap())).unwrap();
                }
            }
            Some(dir)
        })
        .clone()
}

fn bake(args: &[&str]) -> std::process::Output {
    Command::cargo_bin("quatcurve").unwrap().arg("bake").args(args).output().unwrap()
}

pub(crate) fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

pub(crate) fn read_npy(path: &Path) -> (Vec<u64>, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    let shape = npy.shape().to_vec();
    (shape, npy.into_vec::<f32>().unwrap())
}

pub(crate) fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Frames of a clip spanning `[start, end]` baked at `rate` (DESIGN section 6: the rate fitted
/// to a whole number of intervals, so the first and last frames are the first and last keys;
/// for a loop the last frame is the seam).
fn fitted_frames(start: f64, end: f64, rate: f64) -> usize {
    ((end - start) * rate).round().max(1.0) as usize + 1
}

/// The viewer reads sidecars through the types that write them: every field a bake writes
/// (budgets, root tracks, PNG16 ranges, vertex records) reads back and writes again to the
/// same bytes.
#[test]
fn sidecars_read_back_through_the_types_that_write_them() {
    let Some(data) = data_dir() else { return };
    let out = tempfile::tempdir().unwrap();
    let input = data.join("CesiumMan.glb");
    let cases: [&[&str]; 2] = [
        &["--texture", "skin-trs", "--format", "png16", "--max-error-deg", "2", "--root-motion", "extract"],
        &["--texture", "vertex", "--format", "exr", "--rate", "5"],
    ];
    for (k, extra) in cases.iter().enumerate() {
        let dir = out.path().join(k.to_string());
        let args =
            [&["--input", input.to_str().unwrap(), "--output", dir.to_str().unwrap(), "--device", "cpu"], *extra];
        let result = bake(&args.concat());
        assert!(result.status.success(), "{extra:?}: {}", stderr(&result));
        let text = std::fs::read_to_string(dir.join("CesiumMan.json")).unwrap();
        let sidecar: quatcurve::bake::sidecar::Sidecar = serde_json::from_str(&text).unwrap();
        assert!(sidecar.clips.iter().all(|c| c.frames > 1), "{extra:?}");
        assert_eq!(serde_json::to_string_pretty(&sidecar).unwrap(), text, "{extra:?}");
    }
}

#[test]
fn real_files_bake_to_files_that_read_back() {
    let Some(data) = library() else { return };
    let out = tempfile::tempdir().unwrap();
    let result = bake(&["--input", data.to_str().unwrap(), "--rate", "30", "--output", out.path().to_str().unwrap()]);
    assert!(result.status.success(), "{}", stderr(&result));
    let summary = String::from_utf8_lossy(&result.stdout);
    for name in ["Fox", "CesiumMan", "BrainStem", "SimpleSkin", "cmu_131_01", "cmu_131_03"] {
        assert!(summary.contains(name), "{summary}");
        let sidecar = json(&out.path().join(format!("{name}.json")));
        let error = sidecar["max_key_error_rad"].as_f64().unwrap();
        assert!(error <= 1e-5, "{name}: keys reproduced to {error} rad");
        let joints = sidecar["joints"].as_array().unwrap().len() as u64;
        for clip in sidecar["clips"].as_array().unwrap() {
            let (shape, data) = read_npy(&out.path().join(clip["file"].as_str().unwrap()));
            let (start, end) = (clip["start"].as_f64().unwrap(), clip["end"].as_f64().unwrap());
            assert_eq!(shape, [clip["frames"].as_u64().unwrap(), joints, 10], "{name}");
            assert_eq!(shape[0] as usize, fitted_frames(start, end, 30.0), "{name}: {start}..{end}");
            for row in data.chunks_exact(10) {
                let norm = row[..4].iter().map(|v| v * v).sum::<f32>().sqrt();
                assert!((norm - 1.0).abs() < 1e-5, "{name}: rotation norm {norm}");
            }
        }
    }
    // The GLBs parse again, with LINEAR samplers at 30 Hz and unit rotations.
    for name in ["Fox", "CesiumMan", "BrainStem", "SimpleSkin"] {
        let bytes = std::fs::read(out.path().join(format!("{name}.glb"))).unwrap();
        let gltf = match gltf::Gltf::from_slice(&bytes) {
            Ok(g) => g,
            Err(_) => gltf::Gltf::from_slice_without_validation(&bytes).unwrap(), // BrainStem: Draco
        };
        let blob = gltf.blob.clone().unwrap();
        let original = gltf::Gltf::from_slice_without_validation(
            &std::fs::read(data.join(if name == "SimpleSkin" {
                "SimpleSkin.gltf".into()
            } else {
                format!("{name}.glb")
            }))
            .unwrap(),
        )
        .unwrap();
        assert_eq!(gltf.meshes().count(), original.meshes().count(), "{name}: meshes kept");
        assert_eq!(gltf.skins().count(), original.skins().count(), "{name}: skins kept");
        for anim in gltf.animations() {
            for channel in anim.channels() {
                assert_eq!(channel.sampler().interpolation(), gltf::animation::Interpolation::Linear);
                let reader = channel.reader(|_| Some(&blob[..]));
                let times: Vec<f32> = reader.read_inputs().unwrap().collect();
                // Uniform frames at 30 Hz, or (loops) at the nearest rate with whole frames per period.
                let step = f64::from(times[times.len() - 1] - times[0]) / (times.len() - 1).max(1) as f64;
                assert!(times.len() == 1 || (step * 30.0 - 1.0).abs() < 0.02, "{name}: frame step {step}");
                for (i, t) in times.iter().enumerate() {
                    assert!(
                        (f64::from(*t) - (f64::from(times[0]) + i as f64 * step)).abs() < 1e-4,
                        "{name}: frame {i} at {t}"
                    );
                }
                if let gltf::animation::util::ReadOutputs::Rotations(r) = reader.read_outputs().unwrap() {
                    let values: Vec<[f32; 4]> = r.into_f32().collect();
                    assert_eq!(values.len(), times.len());
                    assert!(values.iter().all(|q| (q.iter().map(|v| v * v).sum::<f32>() - 1.0).abs() < 1e-5));
                }
            }
        }
    }
    // The BVHs parse again with the hierarchy unchanged and frames at the new rate.
    for name in ["cmu_131_01", "cmu_131_03"] {
        let original = bvh::read(&data.join(format!("{name}.bvh"))).unwrap();
        let baked = bvh::read(&out.path().join(format!("{name}.bvh"))).unwrap();
        assert_eq!(baked.joints, original.joints);
        let duration = (original.frames.len() - 1) as f64 * original.frame_time;
        assert_eq!(baked.frames.len(), fitted_frames(0.0, duration, 30.0));
        // The clip's own rate, fitted to its span, as the sidecar records it.
        let rate = json(&out.path().join(format!("{name}.json")))["clips"][0]["rate"].as_f64().unwrap();
        assert!(
            (baked.frame_time - 1.0 / rate).abs() < 1e-15
                && (duration * rate - (baked.frames.len() - 1) as f64).abs() < 1e-9,
            "{name}: {rate} Hz"
        );
    }
}

/// Angle between two rotations, sign-blind.
fn angle(a: QuatF64, b: QuatF64) -> f64 {
    a.angle_to(b)
}

#[test]
fn baking_at_the_source_rate_reproduces_the_keys_in_the_written_files() {
    let Some(data) = data_dir() else { return };
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().to_str().unwrap();
    // CesiumMan is keyed at 24 Hz, the CMU takes at 120 Hz.
    let glb = data.join("CesiumMan.glb");
    let result = bake(&["--input", glb.to_str().unwrap(), "--rate", "24", "--output", dir]);
    assert!(result.status.success(), "{}", stderr(&result));
    let read = |path: &Path| {
        let g = gltf::Gltf::from_slice(&std::fs::read(path).unwrap()).unwrap();
        let blob = g.blob.clone().unwrap();
        let mut rotations = Vec::new();
        for channel in g.animations().flat_map(|a| a.channels().collect::<Vec<_>>()) {
            let reader = channel.reader(|_| Some(&blob[..]));
            if let Some(gltf::animation::util::ReadOutputs::Rotations(r)) = reader.read_outputs() {
                let times: Vec<f32> = reader.read_inputs().unwrap().collect();
                rotations.push((channel.target().node().index(), times, r.into_f32().collect::<Vec<_>>()));
            }
        }
        rotations
    };
    let (before, after) = (read(&glb), read(&out.path().join("CesiumMan.glb")));
    assert_eq!(before.len(), after.len());
    let mut worst = 0.0f64;
    for ((node, t0, keys), (node1, t1, baked)) in before.iter().zip(&after) {
        assert_eq!(node, node1);
        assert_eq!(t0.len(), t1.len(), "24 Hz keys baked at 24 Hz");
        for (k, b) in keys.iter().zip(baked) {
            worst = worst.max(angle(QuatF64::from_array(k.map(f64::from)), QuatF64::from_array(b.map(f64::from))));
        }
    }
    assert!(worst <= 1e-5, "CesiumMan keys reproduced to {worst} rad");
    // The CMU takes write their frame time rounded (0.0083333 s for 1/120 s): baked at 120 Hz,
    // every frame is its source frame (no drift), slerp and the C2 curve alike.
    for (name, curve) in [("cmu_131_01", "slerp"), ("cmu_131_03", "slerp"), ("cmu_131_01", "bspline-interp")] {
        let bvh_in = data.join(format!("{name}.bvh"));
        let result = bake(&["--input", bvh_in.to_str().unwrap(), "--rate", "120", "--curve", curve, "--output", dir]);
        assert!(result.status.success(), "{}", stderr(&result));
        let baked = out.path().join(format!("{name}.bvh"));
        let text = std::fs::read_to_string(&baked).unwrap();
        let written: f64 = text.lines().find_map(|l| l.strip_prefix("Frame Time:")).unwrap().trim().parse().unwrap();
        assert_eq!(written, 1.0 / 120.0, "{name}: the frame time is written to round-trip");
        let (before, after) = (bvh::read(&bvh_in).unwrap(), bvh::read(&baked).unwrap());
        assert_eq!(before.frames.len(), after.frames.len());
        let mut worst = (0.0f64, 0, "");
        let mut worst_position = 0.0f64;
        for (f, (a, b)) in before.frames.iter().zip(&after.frames).enumerate() {
            let mut column = 0;
            for joint in &before.joints {
                let range = column..column + joint.channels.len();
                column = range.end;
                let error = angle(
                    bvh::euler_to_quat(&joint.channels, &a[range.clone()]),
                    bvh::euler_to_quat(&joint.channels, &b[range.clone()]),
                );
                if error > worst.0 {
                    worst = (error, f, &joint.name);
                }
                for (i, c) in joint.channels.iter().enumerate() {
                    if matches!(c, BvhChannel::Position(_)) {
                        worst_position = worst_position.max((a[range.start + i] - b[range.start + i]).abs());
                    }
                }
            }
        }
        eprintln!("{name} with {curve} at 120 Hz: worst frame {:.2e} rad (frame {}, {})", worst.0, worst.1, worst.2);
        // Angles are written with 6 decimals of a degree (1.7e-8 rad).
        assert!(
            worst.0 <= 1e-4,
            "{name} with {curve}: source frames reproduced to {} rad (frame {}, {})",
            worst.0,
            worst.1,
            worst.2
        );
        assert!(worst_position <= 1e-5, "{name}: positions reproduced to {worst_position}");
    }
}

fn axis_matrix(axis: usize, degrees: f64) -> [[f64; 3]; 3] {
    let (s, c) = degrees.to_radians().sin_cos();
    match axis {
        0 => [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
        1 => [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
        _ => [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
    }
}

fn mat_mul(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

#[test]
fn bvh_euler_channels_compose_in_file_order_for_every_axis_order() {
    // Hand-computed: "Zrotation Xrotation Yrotation" = 90, 90, 0 maps x -> y and y -> z
    // (Rx(90) takes y to z, then Rz(90) leaves z alone; x is kept by Rx, then Rz takes it to y).
    let zxy = [BvhChannel::Rotation(2), BvhChannel::Rotation(0), BvhChannel::Rotation(1)];
    let q = bvh::euler_to_quat(&zxy, &[90.0, 90.0, 0.0]);
    let x = q.rotate(quatcurve::Vec3F64::new(1.0, 0.0, 0.0)).to_array();
    let y = q.rotate(quatcurve::Vec3F64::new(0.0, 1.0, 0.0)).to_array();
    for (got, want) in [(x, [0.0, 1.0, 0.0]), (y, [0.0, 0.0, 1.0])] {
        assert!(got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-12), "{got:?} vs {want:?}");
    }
    // Position channels between rotations are skipped; every order matches the matrix product.
    let orders = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let angles = [[30.0, -50.0, 120.0], [-170.0, 80.0, 10.0], [5.0, 0.0, -95.0], [0.0, 89.0, 0.0]];
    for order in orders {
        let channels: Vec<BvhChannel> = order.iter().map(|&a| BvhChannel::Rotation(a)).collect();
        for a in angles {
            let expected =
                mat_mul(mat_mul(axis_matrix(order[0], a[0]), axis_matrix(order[1], a[1])), axis_matrix(order[2], a[2]));
            let q = bvh::euler_to_quat(&channels, &a);
            let m = q.to_mat3();
            for i in 0..3 {
                for j in 0..3 {
                    assert!(
                        (m[i][j] - expected[i][j]).abs() < 1e-12,
                        "order {order:?} angles {a:?}: {m:?} vs {expected:?}"
                    );
                }
            }
            // Back to angles in the same order: the same rotation, near the previous frame.
            let back = bvh::quat_to_euler(&order, q, &a);
            assert!(
                bvh::euler_to_quat(&channels, &back).angle_to(q) < 1e-9,
                "order {order:?} angles {a:?} -> {back:?}"
            );
            if a[1].abs() < 85.0 {
                assert!(back.iter().zip(a).all(|(b, a)| (b - a).abs() < 1e-9), "order {order:?}: {a:?} -> {back:?}");
            }
        }
    }
    // Unwrapping: 179 then -179 degrees about one axis is written as 181.
    let back = bvh::quat_to_euler(&[2], bvh::euler_to_quat(&[BvhChannel::Rotation(2)], &[-179.0]), &[179.0]);
    assert!((back[0] - 181.0).abs() < 1e-9, "{back:?}");
}

/// At gimbal lock (the middle angle at or within a hair of 90 degrees, every channel order),
/// angles taken from an f32 quaternion (unit only to ~1e-7, as a decoded clip's are) give the
/// normalized quaternion back to 1e-12 rad: what BVH written from a decoded clip needs to stay
/// within the container's bound.
#[test]
fn euler_angles_at_gimbal_lock_give_the_rotation_back_for_every_channel_order() {
    let orders = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let mut worst = 0.0f64;
    for order in orders {
        let channels: Vec<BvhChannel> = order.iter().map(|&a| BvhChannel::Rotation(a)).collect();
        for middle in [90.0, -90.0, 89.96, -89.96, 90.0 - 1e-6, 89.0] {
            for (first, last) in [(0.0, 0.0), (30.0, -50.0), (-170.0, 120.0)] {
                let exact = bvh::euler_to_quat(&channels, &[first, middle, last]);
                let q = QuatF64::from_array(exact.to_array().map(|c| f64::from(c as f32)));
                let back = bvh::quat_to_euler(&order, q, &[first, middle, last]);
                let error = bvh::euler_to_quat(&channels, &back).angle_to(q.normalize());
                worst = worst.max(error);
                assert!(error < 1e-12, "order {order:?}, {middle} degrees: {back:?} is {error:e} rad off");
            }
        }
    }
    eprintln!("worst {worst:e} rad");
}

/// A minimal .gltf (one node, one rotation channel) with its buffer as a data URI.
fn tiny_gltf(times: &[f32], rotations: &[[f32; 4]]) -> String {
    tiny_gltf_value(times, rotations).0.to_string()
}

/// [`tiny_gltf`]'s document, and its buffer's bytes (for tests that move them to a file).
fn tiny_gltf_value(times: &[f32], rotations: &[[f32; 4]]) -> (serde_json::Value, Vec<u8>) {
    let mut bytes: Vec<u8> = times.iter().flat_map(|t| t.to_le_bytes()).collect();
    let offset = bytes.len();
    bytes.extend(rotations.iter().flatten().flat_map(|v| v.to_le_bytes()));
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bytes));
    let document = serde_json::json!({
        "asset": {"version": "2.0"},
        "nodes": [{"name": "bone"}],
        "scenes": [{"nodes": [0]}],
        "buffers": [{"byteLength": bytes.len(), "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": offset},
            {"buffer": 0, "byteOffset": offset, "byteLength": bytes.len() - offset}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": times.len(), "type": "SCALAR",
             "min": [times[0]], "max": [times[times.len() - 1]]},
            {"bufferView": 1, "componentType": 5126, "count": rotations.len(), "type": "VEC4"}
        ],
        "animations": [{"name": "wave", "samplers": [{"input": 0, "output": 1, "interpolation": "LINEAR"}],
                        "channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}]}]
    });
    (document, bytes)
}

/// Runs bake on one bad file; checks exit 2, the message, and that nothing was written.
fn assert_rejected(name: &str, contents: &[u8], expected: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join(name);
    std::fs::write(&input, contents).unwrap();
    let out_dir = dir.path().join("out");
    let result =
        bake(&["--input", input.to_str().unwrap(), "--output", out_dir.to_str().unwrap(), "--device", "reference"]);
    assert_eq!(result.status.code(), Some(2), "{name}: {}", stderr(&result));
    let msg = stderr(&result);
    for part in expected {
        assert!(msg.contains(part), "{name}: message lacks {part:?}: {msg}");
    }
    assert!(!out_dir.exists(), "{name}: output directory left behind");
}

#[test]
fn bad_inputs_exit_2_naming_file_clip_channel_and_key_and_leave_nothing() {
    let q = [0.0, 0.0, 0.0, 1.0];
    let turn = [0.0, 0.38268343, 0.0, 0.9238795];
    assert_rejected(
        "stuck.gltf",
        tiny_gltf(&[0.0, 1.0, 1.0], &[q, turn, q]).as_bytes(),
        &["stuck.gltf", "clip 'wave', bone rotation", "key 2"],
    );
    assert_rejected(
        "zero.gltf",
        tiny_gltf(&[0.0, 1.0, 2.0], &[q, [0.0; 4], q]).as_bytes(),
        &["zero.gltf", "bone rotation", "key 1", "norm"],
    );
    assert_rejected(
        "nan.gltf",
        tiny_gltf(&[0.0, 1.0, 2.0], &[q, q, [f32::NAN, 0.0, 0.0, 1.0]]).as_bytes(),
        &["nan.gltf", "key 2", "not finite"],
    );
    assert_rejected("broken.glb", b"glTF\x02\x00\x00\x00garbage", &["broken.glb", "not a valid glTF"]);
    assert_rejected("broken.gltf", b"{\"asset\": ", &["broken.gltf", "not a valid glTF"]);
    let png = b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR";
    assert_rejected(
        "picture.glb",
        png,
        &["picture.glb", "not a glTF file", "starts with 89 50 4e 47 0d 0a 1a 0a (a PNG image)"],
    );
    let bvh_text = "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation \
        Xrotation Yrotation\n End Site\n {\n  OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 3\nFrame Time: 0.1\n";
    let good = "0 0 0 0 0 0\n0 0 0 10 0 0\n";
    assert_rejected(
        "nan.bvh",
        format!("{bvh_text}{good}0 0 0 nan 0 0\n").as_bytes(),
        &["nan.bvh", "Hips rotation", "key 2"],
    );
    assert_rejected(
        "short.bvh",
        format!("{bvh_text}{good}0 0 0\n").as_bytes(),
        &["short.bvh", "line 16", "frame 2 has 3 values"],
    );
    assert_rejected(
        "word.bvh",
        format!("{bvh_text}{good}0 0 0 x 0 0\n").as_bytes(),
        &["word.bvh", "line 16", "x is not a number"],
    );
    assert_rejected("notes.txt", b"hello", &["notes.txt", "unknown format"]);
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("absent.glb");
    let result = bake(&["--input", missing.to_str().unwrap(), "--output", dir.path().join("out").to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2));
    assert!(stderr(&result).contains("absent.glb") && stderr(&result).contains("cannot read"), "{}", stderr(&result));
}

#[test]
fn a_job_over_many_files_finishes_the_good_ones_and_reports_the_bad() {
    let dir = tempfile::tempdir().unwrap();
    let q = [0.0, 0.0, 0.0, 1.0];
    let turn = [0.0, 0.38268343, 0.0, 0.9238795];
    std::fs::write(dir.path().join("good.gltf"), tiny_gltf(&[0.0, 0.5, 1.0], &[q, turn, q])).unwrap();
    std::fs::write(dir.path().join("bad.gltf"), tiny_gltf(&[0.0, 0.5, 0.25], &[q, turn, q])).unwrap();
    let out = dir.path().join("out");
    let result = bake(&["--input", dir.path().to_str().unwrap(), "--output", out.to_str().unwrap(), "--rate", "10"]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    let summary = String::from_utf8_lossy(&result.stdout);
    assert!(summary.contains("bad.gltf") && summary.contains("FAILED (input)"), "{summary}");
    assert!(stderr(&result).contains("1 of 2 inputs failed"), "{}", stderr(&result));
    let mut written: Vec<String> =
        std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    written.sort();
    assert_eq!(written, ["good.glb", "good.json", "good.wave.npy", "manifest.0-of-1.json"]);
    let (shape, _) = read_npy(&out.join("good.wave.npy"));
    assert_eq!(shape, [11, 1, 10]);
    // The manifest records both: the bad one failed, with its message.
    let manifest = json(&out.join("manifest.0-of-1.json"));
    let inputs = manifest["inputs"].as_array().unwrap();
    assert_eq!(inputs.iter().map(|i| i["status"].as_str().unwrap()).collect::<Vec<_>>(), ["failed", "ok"]);
    assert!(inputs[0]["error"].as_str().unwrap().contains("key 2"), "{}", inputs[0]);
}

#[test]
fn the_built_in_crowd_bakes_with_every_curve() {
    let dir = tempfile::tempdir().unwrap();
    for curve in ["hermite", "bspline", "squad", "nam-kim", "slerp", "bezier"] {
        let out = dir.path().join(curve);
        // Bezier's degree is the key count less one (100 here), above the GPU's 32: auto
        // bakes it on the CPU path and says so.
        let result = bake(&[
            "--characters",
            "3",
            "--curve",
            curve,
            "--output",
            out.to_str().unwrap(),
            "--rate",
            "24",
            "--device",
            "auto",
        ]);
        assert!(result.status.success(), "{curve}: {}", stderr(&result));
        if curve == "bezier" {
            assert!(json(&out.join("crowd.json"))["device"].as_str().unwrap().starts_with("cpu:"));
        }
        let (shape, data) = read_npy(&out.join("crowd.walk.npy"));
        assert_eq!(shape, [241, 72, 10], "{curve}");
        assert!(data.iter().all(|v| v.is_finite()));
        let sidecar = json(&out.join("crowd.json"));
        assert_eq!(sidecar["max_key_error_rad"].is_f64(), curve != "bspline" && curve != "bezier", "{curve}");
    }
}

/// Body angular velocity (rad/s, physical) between consecutive frames of one joint's rotations.
fn frame_velocities(rotations: &[QuatF64], dt: f64) -> Vec<[f64; 3]> {
    rotations
        .windows(2)
        .map(|w| {
            let r = w[0].conjugate() * w[1];
            let r = if r.w < 0.0 { -r } else { r };
            r.log().to_array().map(|v| 2.0 * v / dt)
        })
        .collect()
}

/// Fox's Survey, Walk and Run end on their first pose: `--loop auto` bakes them as loops whose
/// last frame is the first, a whole number of frames per period, and with the C2 curve whose
/// angular velocity is continuous across the seam (its jump there no larger than the largest
/// jump between frames inside the clip, measured on a 120 Hz bake); baked open, the seam
/// jumps more. (The source's own slerp turns a corner at every key, the seam's included.)
#[test]
fn looping_clips_close_on_their_first_frame_without_a_velocity_jump() {
    let Some(data) = data_dir() else { return };
    let fox = data.join("Fox.glb");
    let mut seam_ratios = Vec::new();
    for mode in ["auto", "off"] {
        let out = tempfile::tempdir().unwrap();
        let result = bake(&[
            "--input",
            fox.to_str().unwrap(),
            "--rate",
            "120",
            "--curve",
            "bspline-interp",
            "--loop",
            mode,
            "--output",
            out.path().to_str().unwrap(),
        ]);
        assert!(result.status.success(), "{}", stderr(&result));
        let sidecar = json(&out.path().join("Fox.json"));
        let joints = sidecar["joints"].as_array().unwrap().len();
        let mut worst_ratio = 0.0f64;
        for clip in sidecar["clips"].as_array().unwrap() {
            let name = clip["name"].as_str().unwrap();
            assert_eq!(clip["loop"].as_bool().unwrap(), mode == "auto", "{name}");
            let (start, end, rate) =
                (clip["start"].as_f64().unwrap(), clip["end"].as_f64().unwrap(), clip["rate"].as_f64().unwrap());
            let (shape, texture) = read_npy(&out.path().join(clip["file"].as_str().unwrap()));
            let frames = shape[0] as usize;
            if mode == "auto" {
                let periods = (end - start) * rate;
                assert!(
                    (periods - periods.round()).abs() < 1e-9 && frames == periods.round() as usize + 1,
                    "{name}: {frames} frames at {rate} Hz"
                );
                assert!((rate - 120.0).abs() < 120.0 / (frames - 1) as f64, "{name}: rate {rate}");
            }
            let (mut seam, mut inside) = (0.0f64, 0.0f64);
            for joint in 0..joints {
                let q: Vec<QuatF64> = (0..frames)
                    .map(|f| {
                        let v = &texture[(f * joints + joint) * 10..][..4];
                        QuatF64::from_xyzw(v[0].into(), v[1].into(), v[2].into(), v[3].into())
                    })
                    .collect();
                if mode == "auto" {
                    assert!(angle(q[0], q[frames - 1]) < 1e-6, "{name} joint {joint}: last frame is not the first");
                }
                let w = frame_velocities(&q, 1.0 / rate);
                let jump = |a: [f64; 3], b: [f64; 3]| {
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
                };
                seam = seam.max(jump(w[0], w[w.len() - 1]));
                inside = w.windows(2).map(|p| jump(p[0], p[1])).fold(inside, f64::max);
            }
            worst_ratio = worst_ratio.max(seam / inside);
        }
        seam_ratios.push(worst_ratio);
    }
    let [looped, open] = seam_ratios[..] else { unreachable!() };
    assert!(looped <= 1.0, "looping: the seam's velocity jump is {looped:.2}x the largest inside a clip");
    assert!(open > looped, "open: seam jump ratio {open:.2} vs looped {looped:.2}");
}
