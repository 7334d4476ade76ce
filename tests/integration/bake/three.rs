//! The three.js package (`packages/quatcurve-three/`) in Debian's headless Chromium (WebGL2 on
//! SwiftShader, driven by `tests/browser/engines.mjs`), imported as its README says: one crowd
//! instance's silhouette against three.js's own `AnimationMixer` playing the source .glb as a
//! `SkinnedMesh`, both on one clock (the source's), at five times of every clip, for bakes on
//! the default options (the package README's own among them): EXR float, EXR half and PNG16
//! bone textures, an atlas played per instance, vertex textures (with normals and without),
//! and a rig whose rigid parts hang from bones without a skin (RobotExpressive); a player that ignores the row order or the time fails the same comparison; crowds of 100 draw lit
//! and textured with no page error, and so does `examples/three/`. And the package's shader
//! libraries are what `quatcurve shaders --library` generates today.

use super::viewer::browser;
use super::{bake, data_dir, json, stderr};
use std::path::Path;

/// Silhouettes agree when the pixels inside one but not the other are at most this fraction
/// of the pixels inside either (the issue's 2%: between frames the bake blends two frames
/// where three.js interpolates the keys).
pub(super) const SILHOUETTE_TOLERANCE: f64 = 0.02;

/// Runs `engine`'s test page (`tests/browser/ENGINE/`) at `query` over `dir` (served at
/// `/data/`); its result, with no page error and no request outside the page's origin.
pub(super) fn page(script: &Path, engine: &str, dir: &Path, query: &str, extra: &[&str]) -> serde_json::Value {
    let _one = super::viewer::ONE_BROWSER.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let out = tempfile::NamedTempFile::new().unwrap();
    let status = std::process::Command::new("node")
        .arg(script)
        .arg(engine)
        .arg(dir)
        .arg(query)
        .arg(out.path())
        .args(extra)
        .status()
        .unwrap();
    assert!(status.success(), "engines.mjs failed on {engine} {query}");
    let result = json(out.path());
    assert_eq!(result["errors"], serde_json::json!([]), "page errors on {query}");
    assert_eq!(result["foreign"], serde_json::json!([]), "the page reached outside its origin on {query}");
    result
}

/// `source` baked with `args` into `dir/name`, the source beside it.
pub(super) fn bake_into(dir: &Path, name: &str, source: &Path, args: &[&str]) {
    let output = dir.join(name);
    let out = bake(&[&["--input", source.to_str().unwrap(), "--output", output.to_str().unwrap()], args].concat());
    assert!(out.status.success(), "{name}: {}", stderr(&out));
    let beside = dir.join(source.file_name().unwrap());
    if !beside.exists() {
        std::fs::copy(source, beside).unwrap();
    }
}

/// The silhouettes of `bake`'s clips against `source`'s on `engine`'s test page, with `more` of
/// the page's parameters (`&break=time`: the time broken on the played side): (clip, time,
/// mismatch) each.
pub(super) fn silhouettes(
    script: &Path,
    engine: &str,
    dir: &Path,
    bake: &str,
    source: &str,
    more: Option<&str>,
) -> Vec<(String, f64, f64)> {
    let query = format!("mode=silhouette&bake=/data/{bake}&source=/data/{source}{}", more.unwrap_or_default());
    let result = page(script, engine, dir, &query, &[]);
    let results = result["page"]["results"].as_array().unwrap();
    assert!(!results.is_empty(), "{bake}: nothing compared");
    results
        .iter()
        .map(|r| {
            assert!(r["pixels"].as_u64().unwrap() > 1000, "{bake}: the character covers too little: {r}");
            (r["clip"].as_str().unwrap().to_string(), r["time"].as_f64().unwrap(), r["mismatch"].as_f64().unwrap())
        })
        .collect()
}

#[test]
fn a_crowd_instance_matches_three_js_s_own_player_for_every_texture_format() {
    let (Some(script), Some(data)) = (browser(), data_dir()) else { return };
    let script = script.with_file_name("engines.mjs");
    let dir = tempfile::tempdir().unwrap();
    let (man, fox, robot) = (data.join("CesiumMan.glb"), data.join("Fox.glb"), data.join("RobotExpressive.glb"));
    let skin = ["--texture", "skin-trs"];
    // Every bake on the default curve, the source's own (three.js plays glTF's LINEAR as slerp
    // and lerp); Fox's first as the package's README bakes it, for the three player.
    let vertex = ["--texture", "vertex"];
    let bakes: [(&str, &Path, Vec<&str>); 10] = [
        ("fox-readme", &fox, vec!["--player", "three", "--max-error-deg", "0.5"]),
        ("man-exr", &man, [&skin[..], &["--format", "exr", "--max-error-deg", "0.5"]].concat()),
        ("man-half", &man, [&skin[..], &["--format", "exr", "--precision", "f16", "--max-error-deg", "0.5"]].concat()),
        ("man-png16", &man, [&skin[..], &["--format", "png16", "--max-error-deg", "0.5"]].concat()),
        ("fox-atlas", &fox, [&skin[..], &["--format", "exr", "--atlas", "--rate", "60"]].concat()),
        ("fox-png16", &fox, [&skin[..], &["--format", "png16", "--rate", "60"]].concat()),
        // Vertex textures: CesiumMan's with normals, Fox's without (lit by its faces).
        ("man-vertex", &man, [&vertex[..], &["--format", "exr", "--rate", "30"]].concat()),
        ("fox-vertex", &fox, [&vertex[..], &["--format", "png16", "--atlas", "--rate", "60"]].concat()),
        // RobotExpressive's rigid parts (12 of its 14 meshes hang from bones without a skin),
        // as the README bakes it and in a vertex texture.
        ("robot-readme", &robot, [&skin[..], &["--format", "exr", "--max-error-deg", "0.5", "--atlas"]].concat()),
        ("robot-vertex", &robot, [&vertex[..], &["--format", "exr", "--rate", "48"]].concat()),
    ];
    for (name, source, args) in &bakes {
        bake_into(dir.path(), name, source, args);
    }
    let mut worst = 0.0f64;
    for (name, source, _) in &bakes {
        let stem = source.file_stem().unwrap().to_str().unwrap();
        let file = source.file_name().unwrap().to_str().unwrap();
        for (clip, time, mismatch) in
            silhouettes(&script, "three", dir.path(), &format!("{name}/{stem}.json"), file, None)
        {
            eprintln!("{name} '{clip}' at {time:.3} s: {:.2}% of the silhouette differs", 100.0 * mismatch);
            assert!(mismatch <= SILHOUETTE_TOLERANCE, "{name} '{clip}' at {time} s: {mismatch} of the silhouette");
            worst = worst.max(mismatch);
        }
    }
    eprintln!("worst {:.2}% of a silhouette", 100.0 * worst);
    // The same comparison fails for a player that reads the rows bottom-up, or ignores time.
    for broken in ["rows", "time"] {
        let mismatches = silhouettes(
            &script,
            "three",
            dir.path(),
            "man-exr/CesiumMan.json",
            "CesiumMan.glb",
            Some(&format!("&break={broken}")),
        );
        let most = mismatches.iter().map(|m| m.2).fold(0.0, f64::max);
        eprintln!("with the {broken} broken: up to {:.1}% of the silhouette differs", 100.0 * most);
        assert!(most > 5.0 * SILHOUETTE_TOLERANCE, "with the {broken} broken the test still passes: {mismatches:?}");
    }
    // Crowds of 100, every clip, lit and textured by the glTF's own materials.
    for (name, stem) in [("man-exr", "CesiumMan"), ("fox-atlas", "Fox"), ("fox-vertex", "Fox")] {
        let query = format!("mode=crowd&bake=/data/{name}/{stem}.json&instances=100&frames=3");
        let result = page(&script, "three", dir.path(), &query, &[]);
        assert_eq!(result["page"]["instances"], 100, "{name}: {result}");
        // Every drawn part has the glTF's base-colour texture (a vertex bake's through the
        // baked glTF's material and UVs).
        assert!(result["page"]["textured"].as_u64() >= Some(1), "{name}: untextured: {result}");
    }
    // A bake the package cannot play is refused naming the file and what to bake.
    bake_into(dir.path(), "man-npy", &man, &skin);
    let result = page(&script, "three", dir.path(), "mode=refuse&bake=/data/man-npy/CesiumMan.json", &[]);
    let refused = result["page"]["refused"].as_str().unwrap_or_default();
    assert!(refused.contains("CesiumMan.json: a skin-trs bake of npy files"), "{result}");
    assert!(refused.contains("--format exr"), "{refused}");
    // The package as a user installs it, from `npm pack`'s tarball into a project of their own
    // (three.js, its peer, is the page's), plays a bake as the repository's copy does.
    let installed = installed_package(dir.path());
    let extra = ["--package", installed.to_str().unwrap()];
    let query = "mode=silhouette&bake=/data/man-exr/CesiumMan.json&source=/data/CesiumMan.glb";
    let result = page(&script, "three", dir.path(), query, &extra);
    let most = result["page"]["results"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["mismatch"].as_f64().unwrap())
        .fold(0.0, f64::max);
    assert!(most <= SILHOUETTE_TOLERANCE, "the installed package: {most} of a silhouette");
    // examples/three/ as shipped (its three.js from the CDN it names, answered locally).
    let result = page(&script, "three", dir.path(), "bake=/data/fox-atlas/Fox.json", &["--example"]);
    assert_eq!(result["title"], "100 instances playing Survey, Walk, Run", "{result}");
}

/// `packages/quatcurve-three` packed (`npm pack`) and installed from the tarball into a new
/// project under `dir`, as its README says (offline: the package has no dependency of its
/// own); the installed package's directory.
fn installed_package(dir: &Path) -> std::path::PathBuf {
    let project = dir.join("user-project");
    std::fs::create_dir_all(&project).unwrap();
    std::fs::write(project.join("package.json"), r#"{"name": "user-project", "private": true, "type": "module"}"#)
        .unwrap();
    let package = Path::new(env!("CARGO_MANIFEST_DIR")).join("packages/quatcurve-three");
    let npm = |args: &[&str]| {
        let out = std::process::Command::new("npm").args(args).current_dir(&project).output().unwrap();
        assert!(out.status.success(), "npm {args:?}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).trim().to_string()
    };
    let tarball = npm(&["pack", package.to_str().unwrap(), "--pack-destination", ".", "--silent"]);
    npm(&[
        "install",
        &format!("./{tarball}"),
        "--offline",
        "--legacy-peer-deps",
        "--no-audit",
        "--no-fund",
        "--silent",
    ]);
    let installed = project.join("node_modules/quatcurve-three");
    assert!(installed.join("src/bones.glsl").exists(), "the tarball lacks the shader library");
    installed
}

#[test]
fn the_package_s_shader_libraries_are_the_ones_quatcurve_shaders_generates() {
    for program in ["bones", "vertex"] {
        let package =
            Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("packages/quatcurve-three/src/{program}.glsl"));
        let out = assert_cmd::Command::cargo_bin("quatcurve")
            .unwrap()
            .args(["shaders", "--program", program, "--lang", "glsl-es", "--library"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        let shipped = std::fs::read_to_string(&package).unwrap();
        assert!(
            shipped == String::from_utf8_lossy(&out.stdout),
            "{} is stale: regenerate it with `quatcurve shaders --program {program} --lang glsl-es --library --output {}`",
            package.display(),
            package.display()
        );
    }
}
