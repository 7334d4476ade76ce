//! `--format babylon` bakes in Babylon.js, in Debian's headless Chromium (WebGL2 on
//! SwiftShader, driven by `tests/browser/engines.mjs`): Babylon's own
//! `BakedVertexAnimationManager`, playing the bake's JSON as Babylon's own loader reads it,
//! draws the silhouettes Babylon draws playing the source .glb, at four frames of every clip;
//! Babylon's own `VertexAnimationBaker`, baking the same clips, gives the same matrices at the
//! same frames; a player that ignores the time, or the space Babylon draws a skinned mesh in,
//! fails; `examples/babylon/` plays a crowd of 100 with no page error. And what the format
//! cannot hold is refused by name.

use super::three::{bake_into, page, silhouettes, SILHOUETTE_TOLERANCE};
use super::viewer::browser;
use super::{bake, data_dir, stderr};
use std::path::Path;

/// Matrix entries agree with Babylon's baker within this (the rotation part as it is, the
/// translation relative to the mesh's size): both are f32 slerps of the same keys composed down
/// the same hierarchy (measured: 1.3e-6 on CesiumMan, 3.2e-7 on Fox; one frame later differs
/// by 0.03 to 0.4).
const MATRIX_TOLERANCE: f64 = 1e-5;

/// Baked for the babylon player: CesiumMan one clip at a file, Fox's three clips in one atlas;
/// at 60 Hz on the default curve,
/// the source's own slerp that Babylon plays glTF's LINEAR keys with, so that its own baker is
/// comparable frame by frame.
fn babylon_bakes(dir: &Path, data: &Path) -> [(&'static str, &'static str); 2] {
    // CesiumMan's open clip at exactly 60 Hz, as Babylon's baker samples it; Fox's loops at 60
    // Hz fitted to whole frames of their periods, so that each ends on its seam.
    let args = ["--player", "babylon", "--rate", "60"];
    bake_into(dir, "man", &data.join("CesiumMan.glb"), &[&args[..], &["--exact-rate"]].concat());
    bake_into(dir, "fox", &data.join("Fox.glb"), &[&args[..], &["--atlas"]].concat());
    [("man/CesiumMan.json", "CesiumMan.glb"), ("fox/Fox.json", "Fox.glb")]
}

#[test]
fn babylon_s_own_manager_plays_the_bake_as_babylon_plays_the_source_and_its_own_baker_agrees() {
    let (Some(script), Some(data)) = (browser(), data_dir()) else { return };
    let script = script.with_file_name("engines.mjs");
    let dir = tempfile::tempdir().unwrap();
    for (bake, source) in babylon_bakes(dir.path(), &data) {
        // A loop one period on and ten (an open clip in its first cycle): the manager's period
        // is the clip's.
        for cycles in [1, 10] {
            for (clip, time, mismatch) in
                silhouettes(&script, "babylon", dir.path(), bake, source, Some(&format!("&cycles={cycles}")))
            {
                eprintln!(
                    "{bake} '{clip}' at {time:.3} s, {cycles} periods on: {:.2}% of the silhouette differs",
                    100.0 * mismatch
                );
                assert!(
                    mismatch <= SILHOUETTE_TOLERANCE,
                    "{bake} '{clip}' at {time} s, {cycles} periods on: {mismatch} of the silhouette"
                );
            }
        }
        let result =
            page(&script, "babylon", dir.path(), &format!("mode=baker&bake=/data/{bake}&source=/data/{source}"), &[]);
        let size = result["page"]["size"].as_f64().unwrap();
        let clips = result["page"]["results"].as_array().unwrap();
        assert!(!clips.is_empty(), "{bake}: Babylon's baker compared nothing: {result}");
        for clip in clips {
            let differs = |which: &str| {
                let d = &clip[which];
                d["rotation"].as_f64().unwrap().max(d["translation"].as_f64().unwrap() / size)
            };
            eprintln!(
                "{bake} '{}': {} frames, Babylon's baker differs by {:.1e} (one frame later {:.1e})",
                clip["clip"].as_str().unwrap_or_default(),
                clip["frames"],
                differs("same"),
                differs("next")
            );
            assert!(differs("same") <= MATRIX_TOLERANCE, "{bake}: Babylon's baker disagrees: {clip}");
            assert!(
                differs("next") > 100.0 * MATRIX_TOLERANCE,
                "{bake}: the comparison cannot tell frames apart: {clip}"
            );
        }
    }
    // A player that ignores time, or draws the skin matrices in the glTF's world rather than in
    // the space of the node Babylon hangs the mesh from, fails the same comparison; so do Fox's
    // loops ten periods on, played a row a frame (Babylon's cycle a row longer than the clip's).
    for (broken, bake, source) in [
        ("&break=time", "man/CesiumMan.json", "CesiumMan.glb"),
        ("&break=space", "man/CesiumMan.json", "CesiumMan.glb"),
        ("&break=period&cycles=10", "fox/Fox.json", "Fox.glb"),
    ] {
        let mismatches = silhouettes(&script, "babylon", dir.path(), bake, source, Some(broken));
        let most = mismatches.iter().map(|m| m.2).fold(0.0, f64::max);
        eprintln!("with {broken}: up to {:.1}% of the silhouette differs", 100.0 * most);
        assert!(most > 5.0 * SILHOUETTE_TOLERANCE, "with {broken} the test still passes: {mismatches:?}");
    }
    // examples/babylon/ as shipped (Babylon.js from the CDN it names, answered locally).
    let result = page(&script, "babylon", dir.path(), "bake=/data/fox/Fox.json", &["--example"]);
    assert_eq!(result["title"], "100 instances playing Survey, Walk, Run", "{result}");
}

#[test]
fn what_babylon_s_format_cannot_hold_is_refused_by_name() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("out");
    let run = |input: &str, extra: &[&str]| {
        let input = data.join(input);
        let args =
            [&["--input", input.to_str().unwrap(), "--output", output.to_str().unwrap(), "--format", "babylon"], extra];
        let out = bake(&args.concat());
        assert_eq!(out.status.code(), Some(2), "{extra:?} was not refused");
        stderr(&out)
    };
    assert!(run("CesiumMan.glb", &["--texture", "skin-trs"]).contains("bake a skin texture, not a skin-trs one"));
    assert!(run("CesiumMan.glb", &["--texture", "skin", "--precision", "f16"]).contains("32-bit floats"));
    let bvh = run("cmu_131_01.bvh", &["--texture", "skin"]);
    assert!(bvh.contains("babylon plays a glTF skin's bones"), "{bvh}");
    // Babylon never wraps rows: a texture wider or taller than a side is refused, naming it.
    let wide = run("CesiumMan.glb", &["--texture", "skin", "--max-texture-size", "64"]);
    assert!(wide.contains("80 texels wide ((bones + 1) * 4), over a side of 64"), "{wide}");
    let tall = run("CesiumMan.glb", &["--texture", "skin", "--max-texture-size", "100", "--rate", "60"]);
    assert!(tall.contains("rows tall (one per frame, never wrapped), over a side of 100"), "{tall}");
    assert!(!output.exists() || std::fs::read_dir(&output).unwrap().next().is_none(), "a refused bake wrote files");
}
