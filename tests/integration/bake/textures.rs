//! `bake --texture local|model|skin`, `--precision`, `--atlas` and `--preview` (DESIGN section
//! 5b), checked against forward kinematics written here in f64: from the baked glTF's own
//! nodes and samplers, from the baked BVH's text, and from the local texture and sidecar.

use super::{bake, data_dir, json, read_npy, stderr, tiny_gltf_value};
use base64::Engine;
use quatcurve::formats::bvh::{self, BvhChannel};
use std::collections::HashMap;
use std::path::Path;

type M4 = [[f64; 4]; 4];

fn mul(a: &M4, b: &M4) -> M4 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..4).map(|k| a[i][k] * b[k][j]).sum()))
}

fn identity() -> M4 {
    std::array::from_fn(|i| std::array::from_fn(|j| if i == j { 1.0 } else { 0.0 }))
}

/// `T * R * S` from glTF's translation, rotation `x, y, z, w` (normalized here) and scale.
fn trs(t: [f64; 3], q: [f64; 4], s: [f64; 3]) -> M4 {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let [x, y, z, w] = q.map(|v| v / n);
    let r = [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)],
        [2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)],
        [2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)],
    ];
    let mut m = identity();
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = r[i][j] * s[j];
        }
        m[i][3] = t[i];
    }
    m
}

/// Largest `|texture - expected|` over a frame's joints, relative to the largest expected
/// value (at least 1): the texture rows are 3x4 row-major.
fn worst(texture: &[f32], expected: &[M4]) -> f64 {
    let scale = expected.iter().flat_map(|m| m[..3].iter().flatten()).fold(1.0f64, |a, v| a.max(v.abs()));
    expected
        .iter()
        .enumerate()
        .flat_map(|(j, m)| (0..12).map(move |i| (f64::from(texture[j * 12 + i]) - m[i / 4][i % 4]).abs()))
        .fold(0.0, f64::max)
        / scale
}

/// World matrices of every node of `doc` (a glTF read back), local transforms from `local`.
fn world_matrices(parents: &[Option<usize>], local: &[M4]) -> Vec<M4> {
    fn world(j: usize, parents: &[Option<usize>], local: &[M4], memo: &mut Vec<Option<M4>>) -> M4 {
        if let Some(m) = memo[j] {
            return m;
        }
        let m = match parents[j] {
            Some(p) => mul(&world(p, parents, local, memo), &local[j]),
            None => local[j],
        };
        memo[j] = Some(m);
        m
    }
    let mut memo = vec![None; local.len()];
    (0..local.len()).map(|j| world(j, parents, local, &mut memo)).collect()
}

fn read_glb(path: &Path) -> gltf::Gltf {
    let bytes = std::fs::read(path).unwrap();
    // BrainStem's meshes are Draco-compressed, which the crate's validation flags.
    gltf::Gltf::from_slice(&bytes).unwrap_or_else(|_| gltf::Gltf::from_slice_without_validation(&bytes).unwrap())
}

/// Per frame of `clip` in the baked GLB: every node's world matrix, by the test's own FK over
/// the file's nodes (rest TRS, `matrix` nodes decomposed by the crate) and the clip's LINEAR
/// samplers, whose keys are the frames.
fn gltf_fk(gltf: &gltf::Gltf, clip: &str) -> Vec<Vec<M4>> {
    let blob = gltf.blob.clone().unwrap();
    let nodes: Vec<_> = gltf.nodes().collect();
    let mut parents = vec![None; nodes.len()];
    for n in &nodes {
        for c in n.children() {
            parents[c.index()] = Some(n.index());
        }
    }
    let rest: Vec<([f64; 3], [f64; 4], [f64; 3])> = nodes
        .iter()
        .map(|n| {
            let (t, r, s) = n.transform().decomposed();
            (t.map(f64::from), r.map(f64::from), s.map(f64::from))
        })
        .collect();
    let anim = gltf
        .animations()
        .find(|a| a.name().map_or_else(|| format!("animation{}", a.index()), str::to_string) == clip)
        .expect("clip in the GLB");
    // (node, path) -> values per frame.
    let mut tracks: HashMap<(usize, &str), Vec<[f64; 4]>> = HashMap::new();
    let mut frames = 0;
    for channel in anim.channels() {
        let reader = channel.reader(|_| Some(&blob[..]));
        frames = reader.read_inputs().unwrap().count();
        let (path, values): (&str, Vec<[f64; 4]>) = match reader.read_outputs().unwrap() {
            gltf::animation::util::ReadOutputs::Rotations(r) => {
                ("rotation", r.into_f32().map(|v| v.map(f64::from)).collect())
            }
            gltf::animation::util::ReadOutputs::Translations(v) => {
                ("translation", v.map(|[x, y, z]| [x, y, z, 0.0].map(f64::from)).collect())
            }
            gltf::animation::util::ReadOutputs::Scales(v) => {
                ("scale", v.map(|[x, y, z]| [x, y, z, 0.0].map(f64::from)).collect())
            }
            gltf::animation::util::ReadOutputs::MorphTargetWeights(_) => continue,
        };
        tracks.insert((channel.target().node().index(), path), values);
    }
    (0..frames)
        .map(|f| {
            let local: Vec<M4> = (0..nodes.len())
                .map(|j| {
                    let (mut t, mut r, mut s) = rest[j];
                    if let Some(v) = tracks.get(&(j, "translation")) {
                        t = [v[f][0], v[f][1], v[f][2]];
                    }
                    if let Some(v) = tracks.get(&(j, "rotation")) {
                        r = v[f];
                    }
                    if let Some(v) = tracks.get(&(j, "scale")) {
                        s = [v[f][0], v[f][1], v[f][2]];
                    }
                    trs(t, r, s)
                })
                .collect();
            world_matrices(&parents, &local)
        })
        .collect()
}

/// Bakes `input` into `dir` (on the CPU path unless `extra` names a device); the sidecar.
pub(super) fn bake_into(dir: &Path, input: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec!["--input", input.to_str().unwrap(), "--output", dir.to_str().unwrap()];
    if !extra.contains(&"--device") {
        args.extend(["--device", "cpu"]);
    }
    args.extend_from_slice(extra);
    let result = bake(&args);
    assert!(result.status.success(), "{}: {}", input.display(), stderr(&result));
    json(&dir.join(format!("{}.json", input.file_stem().unwrap().to_string_lossy())))
}

#[test]
fn model_textures_match_forward_kinematics_of_the_baked_files() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    for name in ["Fox", "CesiumMan", "BrainStem"] {
        let out = dir.path().join(name);
        let sidecar = bake_into(&out, &data.join(format!("{name}.glb")), &["--texture", "model"]);
        assert_eq!(sidecar["texture"], "model");
        assert_eq!(sidecar["channels"].as_array().unwrap().len(), 12);
        let gltf = read_glb(&out.join(format!("{name}.glb")));
        let joints = gltf.nodes().count();
        for clip in sidecar["clips"].as_array().unwrap() {
            let (shape, texture) = read_npy(&out.join(clip["file"].as_str().unwrap()));
            let expected = gltf_fk(&gltf, clip["name"].as_str().unwrap());
            assert_eq!(shape, [expected.len() as u64, joints as u64, 12], "{name}");
            let frame = joints * 12;
            let err = expected
                .iter()
                .enumerate()
                .map(|(f, m)| worst(&texture[f * frame..(f + 1) * frame], m))
                .fold(0.0, f64::max);
            assert!(err <= 1e-5, "{name} clip {}: model texture off by {err} (relative)", clip["name"]);
        }
    }
    // On the GPU (lavapipe in CI): curves and forward kinematics in f32 there.
    if crate::shared_gpu().is_some() {
        let out = dir.path().join("gpu");
        let sidecar = bake_into(&out, &data.join("Fox.glb"), &["--texture", "model", "--device", "gpu"]);
        assert!(sidecar["device"].as_str().unwrap().starts_with("gpu:"));
        let gltf = read_glb(&out.join("Fox.glb"));
        let joints = gltf.nodes().count() * 12;
        for clip in sidecar["clips"].as_array().unwrap() {
            let (_, texture) = read_npy(&out.join(clip["file"].as_str().unwrap()));
            let expected = gltf_fk(&gltf, clip["name"].as_str().unwrap());
            let err = expected
                .iter()
                .enumerate()
                .map(|(f, m)| worst(&texture[f * joints..(f + 1) * joints], m))
                .fold(0.0, f64::max);
            assert!(err <= 1e-5, "Fox on the GPU, clip {}: model texture off by {err} (relative)", clip["name"]);
        }
    } else {
        assert!(
            std::env::var_os("QUATCURVE_REQUIRE_GPU").is_none(),
            "QUATCURVE_REQUIRE_GPU is set but there is no adapter"
        );
    }
    // BVH: the baked text's OFFSETs, positions and Euler angles, composed here.
    let out = dir.path().join("bvh");
    let sidecar = bake_into(&out, &data.join("cmu_131_01.bvh"), &["--texture", "model"]);
    let file = bvh::read(&out.join("cmu_131_01.bvh")).unwrap();
    let (shape, texture) = read_npy(&out.join(sidecar["clips"][0]["file"].as_str().unwrap()));
    let joints = file.joints.len();
    assert_eq!(shape, [file.frames.len() as u64, joints as u64, 12]);
    let mut err = 0.0f64;
    for (f, row) in file.frames.iter().enumerate() {
        let mut column = 0;
        let local: Vec<M4> = file
            .joints
            .iter()
            .map(|j| {
                let mut m = identity();
                let mut t = j.offset;
                for &c in &j.channels {
                    let v = row[column];
                    column += 1;
                    match c {
                        BvhChannel::Position(axis) => t[axis] += v,
                        BvhChannel::Rotation(axis) => m = mul(&m, &axis_rotation(axis, v)),
                    }
                }
                for (i, t) in t.iter().enumerate() {
                    m[i][3] = *t;
                }
                m
            })
            .collect();
        let parents: Vec<Option<usize>> = file.joints.iter().map(|j| j.parent).collect();
        err = err.max(worst(&texture[f * joints * 12..(f + 1) * joints * 12], &world_matrices(&parents, &local)));
    }
    // The text holds angles to 1e-6 degrees and positions to 1e-6 units.
    assert!(err <= 1e-5, "BVH model texture off by {err} (relative)");
}

/// The 4x4 rotation by `degrees` about an axis.
fn axis_rotation(axis: usize, degrees: f64) -> M4 {
    let (s, c) = degrees.to_radians().sin_cos();
    let r = match axis {
        0 => [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
        1 => [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
        _ => [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
    };
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            if i < 3 && j < 3 {
                r[i][j]
            } else if i == j {
                1.0
            } else {
                0.0
            }
        })
    })
}

/// Inverse bind matrices of every skin of a GLB, row-major.
fn inverse_binds(gltf: &gltf::Gltf) -> Vec<(Vec<usize>, Vec<M4>)> {
    let blob = gltf.blob.clone().unwrap();
    gltf.skins()
        .map(|skin| {
            let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
            let ibm: Vec<M4> = match skin.reader(|_| Some(&blob[..])).read_inverse_bind_matrices() {
                Some(m) => m.map(|m| std::array::from_fn(|i| std::array::from_fn(|j| f64::from(m[j][i])))).collect(),
                None => vec![identity(); joints.len()],
            };
            (joints, ibm)
        })
        .collect()
}

/// Checks every skin texture of `sidecar`'s clips against model * IBM, the model texture from
/// `model_dir` (a `--texture model` bake of the same input).
fn assert_skins(out: &Path, model_dir: &Path, stem: &str, sidecar: &serde_json::Value) {
    let gltf = read_glb(&out.join(format!("{stem}.glb")));
    let skins = inverse_binds(&gltf);
    let joints = gltf.nodes().count();
    assert_eq!(sidecar["skins"].as_array().unwrap().len(), skins.len());
    for (c, clip) in sidecar["clips"].as_array().unwrap().iter().enumerate() {
        let files = clip["files"].as_array().unwrap();
        assert_eq!(files.len(), skins.len());
        let model_file =
            json(&model_dir.join(format!("{stem}.json")))["clips"][c]["file"].as_str().unwrap().to_string();
        let (_, model) = read_npy(&model_dir.join(&model_file));
        for (k, (file, (skin_joints, ibm))) in files.iter().zip(&skins).enumerate() {
            // The model texture's name with the skin's suffix: `<stem>.<clip>.skin<k>.npy`.
            assert_eq!(file.as_str().unwrap(), model_file.replace(".npy", &format!(".skin{k}.npy")));
            // The sidecar carries the inverse bind matrices (3x4 rows), so a renderer needs no glTF.
            let recorded: Vec<f64> = sidecar["skins"][k]["inverse_bind"]
                .as_array()
                .unwrap()
                .iter()
                .flat_map(|m| m.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()))
                .collect();
            let expected: Vec<f64> =
                ibm.iter().flat_map(|m| (0..3).flat_map(move |i| (0..4).map(move |j| m[i][j]))).collect();
            assert_eq!(recorded.len(), expected.len());
            assert!(recorded.iter().zip(&expected).all(|(a, b)| (a - b).abs() < 1e-6), "{stem}: inverse bind matrices");
            let (shape, texture) = read_npy(&out.join(file.as_str().unwrap()));
            let frames = shape[0] as usize;
            assert_eq!(shape, [frames as u64, skin_joints.len() as u64, 12]);
            let mut err = 0.0f64;
            for f in 0..frames {
                let expected: Vec<M4> = skin_joints
                    .iter()
                    .zip(ibm)
                    .map(|(&j, ibm)| {
                        let row = &model[(f * joints + j) * 12..(f * joints + j + 1) * 12];
                        let m: M4 = std::array::from_fn(|i| {
                            std::array::from_fn(|jj| {
                                if i < 3 {
                                    f64::from(row[i * 4 + jj])
                                } else if jj == 3 {
                                    1.0
                                } else {
                                    0.0
                                }
                            })
                        });
                        mul(&m, ibm)
                    })
                    .collect();
                err = err.max(worst(&texture[f * skin_joints.len() * 12..(f + 1) * skin_joints.len() * 12], &expected));
            }
            assert!(err <= 1e-5, "{stem} clip {c} skin {k}: off by {err}");
        }
    }
}

#[test]
fn skin_textures_are_model_times_inverse_bind() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let input = data.join("CesiumMan.glb");
    let (skin_dir, model_dir) = (dir.path().join("skin"), dir.path().join("model"));
    let sidecar = bake_into(&skin_dir, &input, &["--texture", "skin"]);
    bake_into(&model_dir, &input, &["--texture", "model"]);
    assert_skins(&skin_dir, &model_dir, "CesiumMan", &sidecar);
}

/// A glTF with a `matrix` root, non-uniform scales, a joint no clip animates, a second root
/// and two skins over overlapping joints; node 1's rotation is keyed at 0 and 1 s.
pub(super) fn rig() -> String {
    let (mut doc, mut bytes) = tiny_gltf_value(&[0.0, 1.0], &[[0.0, 0.0, 0.0, 1.0], [0.0, 0.38268343, 0.0, 0.9238795]]);
    let m4 = |t: [f32; 3], s: [f32; 3]| -> Vec<f32> {
        // Column-major: a quarter turn about z with scale s, then translation t.
        vec![0.0, s[0], 0.0, 0.0, -s[1], 0.0, 0.0, 0.0, 0.0, 0.0, s[2], 0.0, t[0], t[1], t[2], 1.0]
    };
    let ibm_offset = bytes.len();
    let ibms: Vec<f32> = [
        m4([0.1, -0.2, 0.3], [1.0, 1.0, 1.0]),
        m4([0.0, 0.0, -1.0], [0.5, 0.5, 0.5]),
        m4([1.0, 2.0, 3.0], [1.0, 1.0, 1.0]),
    ]
    .concat();
    bytes.extend(ibms.iter().flat_map(|v| v.to_le_bytes()));
    doc["buffers"][0] = serde_json::json!({"byteLength": bytes.len(), "uri": format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bytes))});
    doc["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"buffer": 0, "byteOffset": ibm_offset, "byteLength": 3 * 64}));
    let accessors = doc["accessors"].as_array_mut().unwrap();
    accessors.push(serde_json::json!({"bufferView": 2, "componentType": 5126, "count": 2, "type": "MAT4"}));
    accessors.push(
        serde_json::json!({"bufferView": 2, "byteOffset": 128, "componentType": 5126, "count": 1, "type": "MAT4"}),
    );
    doc["nodes"] = serde_json::json!([
        {"name": "root", "matrix": m4([1.0, 0.0, 2.0], [2.0, 1.0, 1.0]), "children": [1]},
        {"name": "bone", "translation": [0.0, 1.0, 0.0], "scale": [1.0, 2.0, 0.5], "children": [2]},
        {"name": "tip", "translation": [0.5, 0.0, 0.0], "rotation": [0.0, 0.0, 0.38268343, 0.9238795]},
        {"name": "other", "translation": [-3.0, 0.0, 0.0], "scale": [0.5, 0.5, 0.5]}
    ]);
    doc["animations"][0]["channels"][0]["target"]["node"] = serde_json::json!(1);
    doc["scenes"] = serde_json::json!([{"nodes": [0, 3]}]);
    doc["skins"] = serde_json::json!([{"joints": [1, 2], "inverseBindMatrices": 2}, {"name": "second", "joints": [3], "inverseBindMatrices": 3}]);
    doc.to_string()
}

#[test]
fn matrix_nodes_scales_rest_joints_and_two_skins() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rig.gltf");
    std::fs::write(&input, rig()).unwrap();
    let [local_dir, model_dir, skin_dir] = ["local", "model", "skin"].map(|k| dir.path().join(k));
    let sidecar = bake_into(&local_dir, &input, &["--rate", "4"]);
    assert_eq!(sidecar["parents"], serde_json::json!([-1, 0, 1, -1]));
    assert_eq!(sidecar["rest"][1]["scale"], serde_json::json!([1.0, 2.0, 0.5]));
    // The matrix node's decomposition: scale 2, 1, 1 and a quarter turn about z.
    let rest0 = &sidecar["rest"][0];
    assert!(
        (rest0["scale"][0].as_f64().unwrap() - 2.0).abs() < 1e-6
            && (rest0["rotation"][2].as_f64().unwrap() - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-6,
        "{rest0}"
    );
    let (shape, local) = read_npy(&local_dir.join("rig.wave.npy"));
    assert_eq!(shape, [5, 4, 10]);
    // Scale columns: rest values, for every frame.
    for f in 0..5 {
        assert_eq!(&local[(f * 4 + 1) * 10 + 7..(f * 4 + 2) * 10], &[1.0, 2.0, 0.5]);
        assert_eq!(&local[(f * 4 + 3) * 10 + 7..(f * 4 + 4) * 10], &[0.5, 0.5, 0.5]);
    }
    bake_into(&model_dir, &input, &["--rate", "4", "--texture", "model"]);
    let (_, model) = read_npy(&model_dir.join("rig.wave.npy"));
    let gltf = read_glb(&model_dir.join("rig.glb"));
    for (f, expected) in gltf_fk(&gltf, "wave").iter().enumerate() {
        let err = worst(&model[f * 48..(f + 1) * 48], expected);
        assert!(err <= 1e-6, "frame {f}: {err}");
    }
    let sidecar = bake_into(&skin_dir, &input, &["--rate", "4", "--texture", "skin"]);
    assert_eq!(sidecar["skins"][1]["name"], "second");
    assert_skins(&skin_dir, &model_dir, "rig", &sidecar);
}

#[test]
fn half_precision_atlas_holds_every_clip_within_2e_3() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let input = data.join("Fox.glb");
    let (full, half) = (dir.path().join("f32"), dir.path().join("f16"));
    let per_clip = bake_into(&full, &input, &["--texture", "model"]);
    let atlas = bake_into(&half, &input, &["--texture", "model", "--atlas", "--precision", "f16"]);
    assert_eq!(atlas["precision"], "f16");
    let bytes = std::fs::read(half.join("Fox.npy")).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    assert_eq!(npy.dtype(), npyz::DType::Plain("<f2".parse().unwrap()));
    let shape = npy.shape().to_vec();
    let rows: Vec<f32> = npy.into_vec::<half::f16>().unwrap().into_iter().map(half::f16::to_f32).collect();
    let width = (shape[1] * shape[2]) as usize;
    let mut next = 0;
    for (a, c) in atlas["clips"].as_array().unwrap().iter().zip(per_clip["clips"].as_array().unwrap()) {
        assert_eq!(a["file"], "Fox.npy");
        let (first, frames) = (a["first_row"].as_u64().unwrap() as usize, a["frames"].as_u64().unwrap() as usize);
        assert_eq!(first, next, "clips stacked in order");
        next += frames;
        let (_, exact) = read_npy(&full.join(c["file"].as_str().unwrap()));
        let part = &rows[first * width..(first + frames) * width];
        let err = part.iter().zip(&exact).map(|(h, f)| (h - f).abs() / f.abs().max(1.0)).fold(0.0f32, f32::max);
        assert!(err <= 2e-3, "clip {}: f16 off by {err} (relative)", a["name"]);
    }
    assert_eq!(shape[0] as usize, next);
}

/// 200 characters at 30 Hz: textures of 58 MB (local) and 69 MB (model), so each is computed
/// and written in several 32 MiB blocks of frames; the model rows must be the forward
/// kinematics of the local rows of the same frame, the frames in time order (each hips walks
/// forward), and the manifest must hold each streamed file's own size and SHA-256.
#[test]
fn the_crowd_bakes_a_model_texture_of_its_hierarchy_and_previews() {
    let dir = tempfile::tempdir().unwrap();
    let [local_dir, model_dir] = ["local", "model"].map(|k| dir.path().join(k));
    let run = |out: &Path, texture: &str| {
        let result = bake(&[
            "--characters",
            "200",
            "--texture",
            texture,
            "--rate",
            "30",
            "--preview",
            "--output",
            out.to_str().unwrap(),
        ]);
        assert!(result.status.success(), "{}", stderr(&result));
        json(&out.join("crowd.json"))
    };
    let sidecar = run(&local_dir, "local");
    run(&model_dir, "model");
    let parents: Vec<Option<usize>> =
        sidecar["parents"].as_array().unwrap().iter().map(|p| usize::try_from(p.as_i64().unwrap()).ok()).collect();
    assert_eq!(parents.iter().filter(|p| p.is_none()).count(), 200, "one root per character");
    let (shape, local) = read_npy(&local_dir.join("crowd.walk.npy"));
    let (_, model) = read_npy(&model_dir.join("crowd.walk.npy"));
    let joints = shape[1] as usize;
    assert_eq!(shape, [301, 200 * 24, 10]);
    for out in [&local_dir, &model_dir] {
        let bytes = std::fs::read(out.join("crowd.walk.npy")).unwrap();
        let manifest = json(&out.join("manifest.0-of-1.json"));
        let outputs = manifest["inputs"][0]["outputs"].as_array().unwrap();
        let recorded = outputs.iter().find(|o| o["file"] == "crowd.walk.npy").unwrap();
        assert_eq!(
            (recorded["size"].as_u64().unwrap(), recorded["sha256"].as_str().unwrap()),
            (bytes.len() as u64, super::shards::sha256(&bytes).as_str())
        );
    }
    // Every character's hips move forward (z) from frame to frame, in both textures.
    for c in 0..200 {
        let hips = c * 24;
        let z = |f: usize| (local[(f * joints + hips) * 10 + 6], model[(f * joints + hips) * 12 + 11]);
        for f in 1..shape[0] as usize {
            assert!(
                z(f).0 > z(f - 1).0 && z(f).1 > z(f - 1).1,
                "character {c}, frame {f}: hips z {:?} after {:?}",
                z(f),
                z(f - 1)
            );
        }
    }
    for f in 0..shape[0] as usize {
        let rows: Vec<M4> = (0..joints)
            .map(|j| {
                let r = |i: usize| f64::from(local[(f * joints + j) * 10 + i]);
                trs([r(4), r(5), r(6)], [r(0), r(1), r(2), r(3)], [r(7), r(8), r(9)])
            })
            .collect();
        let err = worst(&model[f * joints * 12..(f + 1) * joints * 12], &world_matrices(&parents, &rows));
        assert!(err <= 1e-6, "frame {f}: {err}");
    }
    let png = image::open(model_dir.join("crowd.walk.preview.png")).unwrap().to_rgb8();
    let coloured = png.pixels().filter(|p| p.0.iter().max().unwrap() - p.0.iter().min().unwrap() > 60).count();
    assert!(coloured > 1000, "the preview shows no skeleton ({coloured} coloured pixels)");
    assert_eq!(json(&model_dir.join("crowd.json"))["clips"][0]["preview"], "crowd.walk.preview.png");
}

#[test]
fn hierarchies_with_two_parents_or_a_cycle_are_refused() {
    let (mut doc, _) = tiny_gltf_value(&[0.0, 1.0], &[[0.0, 0.0, 0.0, 1.0]; 2]);
    doc["nodes"] = serde_json::json!([{"children": [2]}, {"children": [2]}, {}]);
    super::assert_rejected("two.gltf", doc.to_string().as_bytes(), &["node 2 is a child of both node 0 and node 1"]);
    doc["nodes"] = serde_json::json!([{"children": [1]}, {"children": [0]}]);
    super::assert_rejected("cycle.gltf", doc.to_string().as_bytes(), &["cycle"]);
    // --texture skin on a file without a skin says what to use instead.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("plain.gltf");
    std::fs::write(&input, tiny_gltf_value(&[0.0, 1.0], &[[0.0, 0.0, 0.0, 1.0]; 2]).0.to_string()).unwrap();
    let result = bake(&[
        "--input",
        input.to_str().unwrap(),
        "--output",
        dir.path().join("out").to_str().unwrap(),
        "--texture",
        "skin",
    ]);
    assert_eq!(result.status.code(), Some(2));
    assert!(
        stderr(&result).contains("has no skin to bake a skin texture for; bake a model texture instead"),
        "{}",
        stderr(&result)
    );
}
