//! `bake --texture model-trs|skin-trs` (DESIGN section 6): the model and skin matrices as
//! rotation, translation and scale, checked against the matrix bakes of the same real files,
//! with quaternions that keep to one side from frame to frame, and sheared joints refused.

use super::textures::{bake_into, rig};
use super::{bake, data_dir, json, read_npy, stderr};

/// 3x4 row-major `T * R * S` of a rigid row (`x, y, z, w`, translation, scale), in f64.
fn matrix(row: &[f32]) -> [f64; 12] {
    quatcurve::skeleton::trs_row(row)
}

/// Every file of `sidecar`'s clips (one per clip, or one per clip and skin).
fn files(sidecar: &serde_json::Value) -> Vec<String> {
    let mut out = Vec::new();
    for clip in sidecar["clips"].as_array().unwrap() {
        match clip["files"].as_array() {
            Some(files) => out.extend(files.iter().map(|f| f.as_str().unwrap().to_string())),
            None => out.push(clip["file"].as_str().unwrap().to_string()),
        }
    }
    out
}

#[test]
fn rigid_textures_are_the_matrices_and_their_quaternions_keep_to_one_side() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    for name in ["CesiumMan.glb", "Fox.glb", "SimpleSkin.gltf", "cmu_131_03.bvh"] {
        let input = data.join(name);
        let stem = input.file_stem().unwrap().to_string_lossy().into_owned();
        for (matrices, rigid) in [("model", "model-trs"), ("skin", "skin-trs")] {
            let [m_dir, r_dir] = [matrices, rigid].map(|k| dir.path().join(format!("{stem}.{k}")));
            let m_side = bake_into(&m_dir, &input, &["--texture", matrices]);
            let r_side = bake_into(&r_dir, &input, &["--texture", rigid]);
            assert_eq!(
                r_side["channels"],
                serde_json::json!(["qx", "qy", "qz", "qw", "tx", "ty", "tz", "sx", "sy", "sz"])
            );
            let (m_files, r_files) = (files(&m_side), files(&r_side));
            assert_eq!(m_files.len(), r_files.len(), "{name} {rigid}");
            for (m_file, r_file) in m_files.iter().zip(&r_files) {
                let (m_shape, m) = read_npy(&m_dir.join(m_file));
                let (r_shape, r) = read_npy(&r_dir.join(r_file));
                assert_eq!((m_shape[0], m_shape[1], m_shape[2], r_shape[2]), (r_shape[0], r_shape[1], 12, 10));
                let joints = r_shape[1] as usize;
                let (mut worst, mut flips) = (0.0f64, 0);
                for (k, (m, row)) in m.chunks_exact(12).zip(r.chunks_exact(10)).enumerate() {
                    let scale = m.iter().fold(1.0f32, |a, v| a.max(v.abs()));
                    let back = matrix(row);
                    worst = worst
                        .max((0..12).map(|i| (back[i] - f64::from(m[i])).abs()).fold(0.0, f64::max) / f64::from(scale));
                    if k < joints {
                        assert!(row[3] >= 0.0, "{r_file}: the first frame's joint {k} has w < 0");
                    } else {
                        let previous = &r[(k - joints) * 10..(k - joints) * 10 + 4];
                        let dot: f32 = (0..4).map(|i| row[i] * previous[i]).sum();
                        flips += usize::from(dot < 0.0);
                    }
                }
                assert!(worst <= 2e-6, "{r_file}: the rigid transform differs from the matrix by {worst:e}");
                assert_eq!(flips, 0, "{r_file}: {flips} quaternions turn to the other side from the frame before");
            }
            // The sidecar says how much shear each clip dropped; the matrix kinds drop none.
            for (m_clip, r_clip) in m_side["clips"].as_array().unwrap().iter().zip(r_side["clips"].as_array().unwrap())
            {
                assert!(m_clip.get("dropped_shear").is_none(), "{name} {matrices}: {m_clip}");
                let dropped = r_clip["dropped_shear"].as_f64().unwrap();
                assert!((0.0..=2e-6).contains(&dropped), "{name} {rigid}: {dropped:e}");
            }
        }
    }
}

/// BrainStem's skin matrices shear a little (2.0e-5 of their scale, measured independently
/// from its `skin` bake): the rigid kind drops it, and its sidecar says so.
#[test]
fn the_shear_a_rigid_texture_drops_is_in_its_sidecar() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let sidecar = bake_into(dir.path(), &data.join("BrainStem.glb"), &["--texture", "skin-trs", "--rate", "30"]);
    let dropped = sidecar["clips"][0]["dropped_shear"].as_f64().unwrap();
    assert!((1e-5..=quatcurve::bake::texture::SHEAR_TOLERANCE).contains(&dropped), "{dropped:e}");
}

#[test]
fn sheared_joints_are_refused_by_the_rigid_kinds_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rig.gltf");
    // The root scales x by 2 and the bone turns about y under it: its model matrix shears.
    std::fs::write(&input, rig()).unwrap();
    for kind in ["model-trs", "skin-trs"] {
        let out = dir.path().join(kind);
        let args = ["--input", input.to_str().unwrap(), "--output", out.to_str().unwrap(), "--device", "cpu"];
        let result = bake(&[&args[..], &["--rate", "4", "--texture", kind]].concat());
        assert!(!result.status.success(), "{kind}: a sheared joint was baked");
        let message = stderr(&result);
        let instead = format!("bake a {} texture (matrices) instead", kind.trim_end_matches("-trs"));
        for needle in ["clip 'wave'", "frame ", "sheared", "SHEAR_TOLERANCE", &instead] {
            assert!(message.contains(needle), "{kind}: {needle:?} missing from: {message}");
        }
        let written: Vec<String> = std::fs::read_dir(&out)
            .map(|d| d.map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect())
            .unwrap_or_default();
        assert!(written.iter().all(|f| !f.starts_with("rig.")), "{kind}: wrote {written:?}");
    }
    // The matrix kinds hold it.
    let sidecar = bake_into(&dir.path().join("model"), &input, &["--rate", "4", "--texture", "model"]);
    assert_eq!(json(&dir.path().join("model/rig.json"))["texture"], sidecar["texture"]);
}
