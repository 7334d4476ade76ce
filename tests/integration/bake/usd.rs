//! `bake --usd`'s stage as text: what Pixar's library makes of it is held by the Python test
//! (`python/tests/test_usd.py`, usd-core); here, the rules a stage is written by, and a stage
//! read as an input (`quatcurve_formats::usd`) baking as the file it was written from.

use super::{bake, data_dir, json, read_npy, stderr};

#[test]
fn a_stage_says_its_unit_and_a_bvh_needs_it_given() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let bvh = data.join("cmu_131_01.bvh");
    let out = dir.path().join("out");
    let args = ["--input", bvh.to_str().unwrap(), "--output", out.to_str().unwrap(), "--usd"];
    let result = bake(&args);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(stderr(&result).contains("--unit-cm is needed for"), "{}", stderr(&result));
    assert!(!out.exists(), "nothing written");
    let result = bake(&[&args[..], &["--unit-cm", "5.644"]].concat());
    assert!(result.status.success(), "{}", stderr(&result));
    let stage = std::fs::read_to_string(out.join("cmu_131_01.usda")).unwrap();
    assert!(stage.contains("metersPerUnit = 0.05644"), "{}", &stage[..400]);
    let glb = dir.path().join("glb");
    let result = bake(&["--input", data.join("Fox.glb").to_str().unwrap(), "--output", glb.to_str().unwrap(), "--usd"]);
    assert!(result.status.success(), "{}", stderr(&result));
    let stage = std::fs::read_to_string(glb.join("Fox.usda")).unwrap();
    assert!(stage.contains("metersPerUnit = 1\n"), "glTF's metre");
}

#[test]
fn a_stage_s_joints_are_paths_of_identifiers_parents_first_and_each_clip_a_variant() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let input = data.join("Samba_Dancing.fbx");
    let result = bake(&["--input", input.to_str().unwrap(), "--output", out.to_str().unwrap(), "--usd"]);
    assert!(result.status.success(), "{}", stderr(&result));
    let stage = std::fs::read_to_string(out.join("Samba_Dancing.usda")).unwrap();
    let joints = stage.lines().find_map(|l| l.trim().strip_prefix("uniform token[] joints = [")).unwrap();
    let paths: Vec<&str> = joints.trim_end_matches(']').split(", ").map(|p| p.trim_matches('"')).collect();
    // Mixamo's `mixamorig:Hips`: a colon is no part of a prim name.
    assert_eq!(paths[0], "mixamorig_Hips");
    for (k, path) in paths.iter().enumerate() {
        let (parent, name) = path.rsplit_once('/').unwrap_or(("", path));
        assert!(name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'), "{path}");
        assert!(parent.is_empty() || paths[..k].contains(&parent), "{path}: its parent after it");
    }
    assert!(stage.contains("variantSet \"clip\" = {\n            \"mixamo_com\" {"), "the clip 'mixamo.com' a variant");
    assert!(stage.contains("rel skel:animationSource = </Samba_Dancing/Animations/mixamo_com>"));
}

/// `bake --usd`'s stage baked again is the bake of the file it was written from: CesiumMan's
/// skinned vertices (the mesh, its skin and its clip through USD) and each of Fox's three
/// clips as model matrices (every joint by name; the stage adds its skeleton's node and the
/// mesh's), within 1e-5 of the extent. Stages written by Pixar's library read back in
/// `python/tests/test_usd.py`.
#[test]
fn a_stage_bakes_as_the_file_it_was_written_from() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    for (file, texture) in [("CesiumMan.glb", "vertex"), ("Fox.glb", "model")] {
        let stem = file.trim_end_matches(".glb");
        let (first, again) = (dir.path().join(format!("{stem}-a")), dir.path().join(format!("{stem}-b")));
        let input = data.join(file);
        let args =
            ["--input", input.to_str().unwrap(), "--texture", texture, "--output", first.to_str().unwrap(), "--usd"];
        let result = bake(&args);
        assert!(result.status.success(), "{}", stderr(&result));
        let stage = first.join(format!("{stem}.usda"));
        let result =
            bake(&["--input", stage.to_str().unwrap(), "--texture", texture, "--output", again.to_str().unwrap()]);
        assert!(result.status.success(), "{}", stderr(&result));
        let (sidecar, read_back) =
            (json(&first.join(format!("{stem}.json"))), json(&again.join(format!("{stem}.json"))));
        let names = |s: &serde_json::Value| -> Vec<String> {
            s["joints"].as_array().unwrap().iter().map(|n| n.as_str().unwrap().to_string()).collect()
        };
        let (joints, joints_again) = (names(&sidecar), names(&read_back));
        let clips = sidecar["clips"].as_array().unwrap();
        assert_eq!(clips.len(), read_back["clips"].as_array().unwrap().len());
        for (clip, clip_again) in clips.iter().zip(read_back["clips"].as_array().unwrap()) {
            assert_eq!(clip["name"], clip_again["name"]);
            let files = |c: &serde_json::Value| -> Vec<String> {
                match c.get("files") {
                    Some(list) => list.as_array().unwrap().iter().map(|f| f.as_str().unwrap().to_string()).collect(),
                    None => vec![c["file"].as_str().unwrap().to_string()],
                }
            };
            for (name, name_again) in files(clip).iter().zip(files(clip_again)) {
                let ((shape, values), (shape_again, values_again)) =
                    (read_npy(&first.join(name)), read_npy(&again.join(name_again)));
                // Vertex textures match row for row; model textures joint by joint.
                let columns: Vec<usize> = if texture == "vertex" {
                    (0..shape[1] as usize).collect()
                } else {
                    joints.iter().map(|j| joints_again.iter().position(|a| a == j).unwrap()).collect()
                };
                let width = shape[2] as usize;
                let (frames, rows, rows_again) = (shape[0] as usize, shape[1] as usize, shape_again[1] as usize);
                assert_eq!((frames, width), (shape_again[0] as usize, shape_again[2] as usize), "{name}");
                // The positions' extent: a vertex's first three channels, a matrix's last column.
                let axes = if texture == "vertex" { [0, 1, 2] } else { [3, 7, 11] };
                let extent = axes
                    .iter()
                    .map(|&axis| {
                        let along = values.iter().skip(axis).step_by(width);
                        let (lo, hi) = along.fold((f32::MAX, f32::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
                        hi - lo
                    })
                    .fold(0.0f32, f32::max);
                let mut worst = 0.0f32;
                for f in 0..frames {
                    for (row, &row_again) in columns.iter().enumerate() {
                        for c in 0..width {
                            let a = values[(f * rows + row) * width + c];
                            let b = values_again[(f * rows_again + row_again) * width + c];
                            worst = worst.max((a - b).abs());
                        }
                    }
                }
                assert!(worst <= 1e-5 * extent, "{file} {name}: {worst} against an extent of {extent}");
            }
        }
    }
}
