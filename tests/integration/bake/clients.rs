//! Baked glTF files as the tools users open them with see them: the Khronos glTF-Validator
//! reports nothing for a baked `.glb` that it does not report for the original, each clip's
//! first and last frames are its first and last keys, and nothing the replaced keys alone
//! used is left in the file.
//!
//! The validator is the npm package `gltf-validator`, installed by
//! `npm ci --prefix tests/gltf-validator` (`.ci/run` does, and sets
//! `QUATCURVE_REQUIRE_VALIDATOR=1` so that CI cannot skip it).

use super::{angle, data_dir, stderr};
use quatcurve::anim::Property;
use quatcurve::formats::gltf::{self as source, UriPolicy};
use quatcurve::QuatF64;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The real glTF files.
const GLTF_FILES: [&str; 4] = ["Fox.glb", "CesiumMan.glb", "BrainStem.glb", "SimpleSkin.gltf"];

/// Rates and curves every real glTF is baked at.
const RATES: [&str; 3] = ["30", "60", "120"];
const CURVES: [&str; 2] = ["bspline-interp", "slerp"];

/// One bake of every real glTF file: its directory, rate and curve.
struct Bake {
    dir: PathBuf,
    rate: &'static str,
    curve: &'static str,
}

/// Every real glTF baked at every rate and curve, once for the tests of this file (into
/// cargo's scratch directory for integration tests, made anew each run); `None` without data.
fn bakes() -> Option<&'static [Bake]> {
    static BAKES: OnceLock<Option<Vec<Bake>>> = OnceLock::new();
    BAKES
        .get_or_init(|| {
            let data = data_dir()?;
            let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bake-clients");
            let _ = std::fs::remove_dir_all(&root);
            let inputs: Vec<String> = GLTF_FILES.iter().map(|f| data.join(f).display().to_string()).collect();
            let mut bakes = Vec::new();
            for rate in RATES {
                for curve in CURVES {
                    let dir = root.join(format!("{curve}-{rate}"));
                    let mut args: Vec<&str> = vec!["--input"];
                    args.extend(inputs.iter().map(String::as_str));
                    args.extend(["--rate", rate, "--curve", curve, "--output", dir.to_str().unwrap()]);
                    let result = super::bake(&args);
                    assert!(result.status.success(), "{curve} at {rate} Hz: {}", stderr(&result));
                    bakes.push(Bake { dir, rate, curve });
                }
            }
            Some(bakes)
        })
        .as_deref()
}

/// The GLB a bake wrote for `file`.
fn baked(bake: &Bake, file: &str) -> PathBuf {
    bake.dir.join(format!("{}.glb", Path::new(file).file_stem().unwrap().to_str().unwrap()))
}

/// A glTF file's JSON (`.gltf`, or a GLB's JSON chunk).
fn document(path: &Path) -> serde_json::Value {
    let bytes = std::fs::read(path).unwrap();
    if bytes.starts_with(b"glTF") {
        let glb = gltf::binary::Glb::from_slice(&bytes).unwrap();
        serde_json::from_slice(&glb.json).unwrap()
    } else {
        serde_json::from_slice(&bytes).unwrap()
    }
}

/// One file's validator messages: per `(severity, code)`, each message with its pointer.
pub(super) type Messages = BTreeMap<(u64, String), Vec<String>>;

/// The validator's messages for each file; `None` when the validator is not installed and CI
/// does not require it.
pub(super) fn validate(files: &[PathBuf]) -> Option<Vec<Messages>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/gltf-validator");
    let installed = root.join("node_modules/gltf-validator").is_dir()
        && std::process::Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success());
    if !installed {
        assert!(
            std::env::var("QUATCURVE_REQUIRE_VALIDATOR").as_deref() != Ok("1"),
            "QUATCURVE_REQUIRE_VALIDATOR=1 but the glTF validator is not installed: npm ci --prefix \
                tests/gltf-validator (needs node)"
        );
        eprintln!("skipped: the glTF validator is not installed (npm ci --prefix tests/gltf-validator)");
        return None;
    }
    let out = std::process::Command::new("node").arg(root.join("validate.mjs")).args(files).output().unwrap();
    assert!(out.status.success(), "the validator failed: {}", String::from_utf8_lossy(&out.stderr));
    let reports: Vec<serde_json::Value> =
        String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(reports.len(), files.len());
    Some(
        reports
            .iter()
            .map(|report| {
                let mut messages = Messages::new();
                for m in report["messages"].as_array().unwrap() {
                    let key = (m["severity"].as_u64().unwrap(), m["code"].as_str().unwrap().to_string());
                    messages.entry(key).or_default().push(format!("{} {}", m["pointer"], m["message"]));
                }
                messages
            })
            .collect(),
    )
}

/// `file` passes the Khronos validator without an error (skipped where the validator is not
/// installed, as [`validate`] says).
pub(super) fn assert_no_validator_error(file: &Path) {
    let Some(reports) = validate(&[file.to_path_buf()]) else { return };
    let errors: Vec<String> = reports[0]
        .iter()
        .filter(|((severity, _), _)| *severity == 0)
        .map(|(key, m)| format!("{key:?}: {}", m[0]))
        .collect();
    assert!(errors.is_empty(), "{}: {errors:?}", file.display());
}

#[test]
fn baked_glbs_pass_the_khronos_validator_as_their_originals_do() {
    let Some(bakes) = bakes() else { return };
    let data = data_dir().unwrap();
    let mut files: Vec<PathBuf> = GLTF_FILES.iter().map(|f| data.join(f)).collect();
    for bake in bakes {
        files.extend(GLTF_FILES.iter().map(|f| baked(bake, f)));
    }
    let Some(reports) = validate(&files) else { return };
    let (originals, baked_reports) = reports.split_at(GLTF_FILES.len());
    let mut new = Vec::new();
    for (k, report) in baked_reports.iter().enumerate() {
        let (bake, file) = (&bakes[k / GLTF_FILES.len()], GLTF_FILES[k % GLTF_FILES.len()]);
        let original = &originals[k % GLTF_FILES.len()];
        // Every severity, hints included: a message the original does not have (or has fewer
        // times) is the bake's.
        for (key, messages) in report {
            let before = original.get(key).map_or(0, Vec::len);
            if messages.len() > before {
                new.push(format!(
                    "{file} ({} at {} Hz): {} x {key:?} where the original has {before}, e.g. {}",
                    bake.curve,
                    bake.rate,
                    messages.len(),
                    messages[0]
                ));
            }
        }
    }
    assert!(
        new.is_empty(),
        "the validator reports for baked files what it does not for the originals:\n{}",
        new.join("\n")
    );
}

/// Per (clip, node, property): the channel's key times and values as the library reads them.
type Channels = HashMap<(String, usize, Property), (Vec<f64>, Vec<[f64; 4]>)>;

fn channels(path: &Path) -> (Channels, HashMap<String, [f64; 2]>) {
    let file = source::read(path, UriPolicy::default()).unwrap();
    let mut channels = HashMap::new();
    let mut spans = HashMap::new();
    for clip in &file.animation.clips {
        spans.insert(clip.name.clone(), clip.span());
        for c in &clip.channels {
            let (times, values) = c.keyed().expect("a source's keys");
            channels.insert((clip.name.clone(), c.joint, c.property), (times.to_vec(), values.to_vec()));
        }
    }
    (channels, spans)
}

#[test]
fn every_baked_clip_starts_and_ends_on_its_first_and_last_keys() {
    let Some(bakes) = bakes() else { return };
    let data = data_dir().unwrap();
    let mut worst = (0.0f64, String::new());
    for file in GLTF_FILES {
        let (keys, spans) = channels(&data.join(file));
        for bake in bakes {
            let path = baked(bake, file);
            let sidecar = super::json(&path.with_extension("json"));
            let looping: HashMap<&str, bool> = sidecar["clips"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| (c["name"].as_str().unwrap(), c["loop"].as_bool().unwrap()))
                .collect();
            let (baked_channels, _) = channels(&path);
            assert_eq!(baked_channels.len(), keys.len(), "{file}: every channel baked");
            for ((clip, joint, property), (times, values)) in &baked_channels {
                let what =
                    format!("{file} ({} at {} Hz) clip '{clip}' node {joint} {property:?}", bake.curve, bake.rate);
                let (key_times, key_values) = &keys[&(clip.clone(), *joint, *property)];
                let span = spans[clip];
                // Frames cover the clip from its first key to its last (f32 times in the file).
                assert!(
                    (times[0] - span[0]).abs() <= 1e-6 * span[1].abs().max(1.0),
                    "{what}: first frame at {} s, clip starts at {} s",
                    times[0],
                    span[0]
                );
                assert!(
                    (times[times.len() - 1] - span[1]).abs() <= 1e-6 * span[1].abs().max(1.0),
                    "{what}: last frame at {} s, clip ends at {} s",
                    times[times.len() - 1],
                    span[1]
                );
                // A looping channel keyed over less than its clip wraps instead of holding.
                let covers = key_times[0] <= span[0] && span[1] <= key_times[key_times.len() - 1];
                if looping[clip.as_str()] && !covers {
                    continue;
                }
                for (baked_value, key) in
                    [(values[0], key_values[0]), (values[values.len() - 1], key_values[key_values.len() - 1])]
                {
                    let error = match property {
                        Property::Rotation => {
                            angle(QuatF64::from_array(baked_value).normalize(), QuatF64::from_array(key).normalize())
                        }
                        _ => {
                            (0..3).map(|i| (baked_value[i] - key[i]).abs() / key[i].abs().max(1.0)).fold(0.0, f64::max)
                        }
                    };
                    if error > worst.0 {
                        worst = (error, what.clone());
                    }
                }
            }
        }
    }
    eprintln!("worst clip-end error against the first and last keys: {:.2e} ({})", worst.0, worst.1);
    assert!(worst.0 <= 1e-6, "a baked clip's end is {} from its key ({})", worst.0, worst.1);
}

/// Bytes of the buffer views that the accessors `used` (and nothing else in `doc`) refer to.
fn view_bytes(doc: &serde_json::Value, used: &[u64]) -> u64 {
    let accessors = doc["accessors"].as_array().unwrap();
    let views: std::collections::BTreeSet<u64> =
        used.iter().filter_map(|&a| accessors[a as usize]["bufferView"].as_u64()).collect();
    let others: std::collections::BTreeSet<u64> = (0..accessors.len() as u64)
        .filter(|a| !used.contains(a))
        .filter_map(|a| accessors[a as usize]["bufferView"].as_u64())
        .collect();
    views
        .iter()
        .filter(|v| !others.contains(v))
        .map(|&v| doc["bufferViews"][v as usize]["byteLength"].as_u64().unwrap())
        .sum()
}

/// The accessors of every sampler that bake replaces (rotation, translation, scale).
fn sampler_accessors(doc: &serde_json::Value) -> Vec<u64> {
    let mut used = Vec::new();
    for anim in doc["animations"].as_array().unwrap() {
        for channel in anim["channels"].as_array().unwrap() {
            if channel["target"]["path"] != "weights" {
                let sampler = &anim["samplers"][channel["sampler"].as_u64().unwrap() as usize];
                used.extend([sampler["input"].as_u64().unwrap(), sampler["output"].as_u64().unwrap()]);
            }
        }
    }
    used.sort_unstable();
    used.dedup();
    used
}

#[test]
fn a_baked_glb_keeps_nothing_that_only_the_replaced_keys_used() {
    let Some(bakes) = bakes() else { return };
    let data = data_dir().unwrap();
    for bake in bakes {
        for file in ["BrainStem.glb", "CesiumMan.glb", "Fox.glb"] {
            let (original, path) = (data.join(file), baked(bake, file));
            let (before, after) = (document(&original), document(&path));
            // A sampler's bytes: its keys, and its accessors' JSON.
            let sampler_bytes = |doc: &serde_json::Value| {
                let used = sampler_accessors(doc);
                let text: usize = used.iter().map(|&a| doc["accessors"][a as usize].to_string().len() + 1).sum();
                view_bytes(doc, &used) + text as u64
            };
            let (replaced, new) = (sampler_bytes(&before), sampler_bytes(&after));
            let (size_before, size_after) =
                (std::fs::metadata(&original).unwrap().len(), std::fs::metadata(&path).unwrap().len());
            // Up to 3 bytes of padding for each of the two chunks, and up to 15 before the keys.
            let bound = size_before - replaced + new + 21;
            assert!(
                size_after <= bound,
                "{file} ({} at {} Hz): {size_after} bytes, more than the original's \
                {size_before} - {replaced} replaced + {new} new + 21 padding = {bound}",
                bake.curve,
                bake.rate
            );
            // Everything else is kept: as many accessors and views as the original has, less
            // the replaced ones, plus the new ones.
            let count = |doc: &serde_json::Value, key: &str| doc[key].as_array().map_or(0, Vec::len);
            let (old_samplers, new_samplers) = (sampler_accessors(&before).len(), sampler_accessors(&after).len());
            assert_eq!(
                count(&after, "accessors"),
                count(&before, "accessors") - old_samplers + new_samplers,
                "{file}: accessors"
            );
            assert_eq!(count(&after, "meshes"), count(&before, "meshes"));
            assert_eq!(count(&after, "images"), count(&before, "images"));
        }
    }
}

/// The mesh files of vertex bakes (`<stem>.mesh.glb`: skinned primitives as plain meshes, each
/// vertex's texel address in `TEXCOORD_0`) for every skinned file (BrainStem's decoded from
/// Draco), addressed for a small side so addresses span rows: the validator finds no error,
/// warning or hint in them, only the information that it sees no material reading
/// `TEXCOORD_0` (a vertex texture's shader does).
#[test]
fn vertex_texture_meshes_pass_the_khronos_validator() {
    let Some(data) = data_dir() else { return };
    let out = tempfile::tempdir().unwrap();
    let names = ["Fox.glb", "CesiumMan.glb", "SimpleSkin.gltf", "BrainStem.glb"];
    let mut args = vec!["--texture", "vertex", "--max-texture-size", "1024", "--input"];
    let inputs: Vec<String> = names.iter().map(|f| data.join(f).display().to_string()).collect();
    args.extend(inputs.iter().map(String::as_str));
    args.extend(["--output", out.path().to_str().unwrap()]);
    let result = super::bake(&args);
    assert!(result.status.success(), "{}", stderr(&result));
    let files: Vec<PathBuf> = names
        .iter()
        .map(|n| out.path().join(format!("{}.mesh.glb", Path::new(n).file_stem().unwrap().to_str().unwrap())))
        .collect();
    let Some(reports) = validate(&files) else { return };
    for (name, report) in names.iter().zip(&reports) {
        for ((severity, code), messages) in report {
            let texcoord_unused = code == "UNUSED_OBJECT" && messages.iter().all(|m| m.contains("/TEXCOORD_0"));
            assert!(*severity == 2 && texcoord_unused, "{name}: {code} (severity {severity}): {messages:?}");
        }
    }
    let document = document(&files[1]);
    assert_eq!(document["meshes"].as_array().unwrap().len(), 1);
    assert!(document.get("skins").is_none() && document.get("animations").is_none());
    let attributes = document["meshes"][0]["primitives"][0]["attributes"].as_object().unwrap();
    let mut keys: Vec<&str> = attributes.keys().map(String::as_str).collect();
    keys.sort_unstable();
    assert_eq!(keys, ["NORMAL", "POSITION", "TEXCOORD_0"]);
}
