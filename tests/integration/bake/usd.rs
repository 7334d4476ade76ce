//! `bake --usd`'s stage as text: what Pixar's library makes of it is held by the Python test
//! (`python/tests/test_usd.py`, usd-core); here, the rules a stage is written by.

use super::{bake, data_dir, stderr};

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
