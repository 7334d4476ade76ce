//! Textures as images an engine imports (`--format exr|png16`), read back by independent readers
//! (the `exr` crate's and the `image` crate's decoders) through the sidecar's own numbers and
//! address formula, against the `.npy` bake of the same files: f32 EXR exactly, half EXR within
//! 1e-3 relative, PNG16 within one step of each channel's range.

use super::{bake, data_dir, json, read_npy, stderr};
use std::path::Path;

/// The value at texel `t` of joint `j` in row `r` of an image, by the sidecar's formula.
fn at(texels: &[[f32; 4]], grid: &serde_json::Value, r: usize, j: usize, t: usize) -> [f32; 4] {
    let n = |k: &str| grid[k].as_u64().unwrap() as usize;
    let (width, per_joint, frame_width) = (n("width"), n("texels_per_joint"), n("frame_width"));
    let (rows_per_frame, per_column) = (n("rows_per_frame"), n("frames_per_column"));
    let a = j * per_joint + t;
    let (x, y) =
        ((r / per_column) * frame_width + a % frame_width, (r % per_column) * rows_per_frame + a / frame_width);
    texels[y * width + x]
}

/// An EXR's RGBA texels, row after row, by the `exr` crate's reader.
pub(super) fn read_exr(path: &Path) -> (usize, usize, Vec<[f32; 4]>) {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| (size.width(), size.height(), vec![[0.0f32; 4]; size.width() * size.height()]),
        |(w, _, texels), p, (r, g, b, a): (f32, f32, f32, f32)| texels[p.y() * *w + p.x()] = [r, g, b, a],
    )
    .unwrap();
    image.layer_data.channel_data.pixels
}

/// A 16-bit PNG's RGBA samples mapped back through `remap` (per texel slot and channel).
fn read_png16(path: &Path, remap: &serde_json::Value, per_joint: usize) -> (usize, usize, Vec<[f32; 4]>) {
    let image = image::open(path).unwrap();
    let image::DynamicImage::ImageRgba16(buffer) = image else { panic!("{}: not 16-bit RGBA", path.display()) };
    let (width, height) = (buffer.width() as usize, buffer.height() as usize);
    let texels = buffer
        .pixels()
        .enumerate()
        .map(|(i, p)| {
            let slot = &remap[(i % width) % per_joint];
            std::array::from_fn(|c| {
                let (lo, hi) = (slot[c][0].as_f64().unwrap(), slot[c][1].as_f64().unwrap());
                (lo + (hi - lo) * f64::from(p.0[c]) / 65535.0) as f32
            })
        })
        .collect();
    (width, height, texels)
}

#[test]
fn image_textures_hold_the_npy_values_where_the_sidecar_says() {
    let Some(data) = data_dir() else { return };
    let out = tempfile::tempdir().unwrap();
    let inputs: Vec<String> = ["Fox.glb", "CesiumMan.glb", "BrainStem.glb", "cmu_131_01.bvh", "cmu_131_03.bvh"]
        .iter()
        .map(|f| data.join(f).display().to_string())
        .collect();
    let mut worst = std::collections::BTreeMap::new();
    for texture in ["local", "skin"] {
        let dir = |name: &str| out.path().join(format!("{texture}-{name}"));
        for (name, extra) in [
            ("npy", vec![]),
            ("exr", vec!["--format", "exr"]),
            ("half", vec!["--format", "exr", "--precision", "f16"]),
            ("png16", vec!["--format", "png16"]),
            // BrainStem's 1050 frames in columns of at most 512.
            ("columns", vec!["--format", "exr", "--max-texture-size", "512"]),
        ] {
            let mut args: Vec<&str> = vec!["--input"];
            args.extend(inputs.iter().map(String::as_str));
            let path = dir(name);
            args.extend(["--texture", texture, "--device", "cpu", "--output", path.to_str().unwrap()]);
            args.extend(extra);
            let result = bake(&args);
            assert!(result.status.success(), "{texture} {name}: {}", stderr(&result));
        }
        for stem in ["Fox", "CesiumMan", "BrainStem", "cmu_131_01", "cmu_131_03"] {
            for name in ["exr", "half", "png16", "columns"] {
                let sidecar = json(&dir(name).join(format!("{stem}.json")));
                let channels = sidecar["channels"].as_array().unwrap().len();
                let texels = sidecar["texels"].as_array().unwrap();
                for record in sidecar["textures"].as_array().unwrap() {
                    // The same texture as .npy: the same name, another extension.
                    let file = Path::new(record["file"].as_str().unwrap()).with_extension("npy");
                    let (shape, values) = read_npy(&dir("npy").join(file));
                    let path = dir(name).join(record["file"].as_str().unwrap());
                    let per_joint = record["texels_per_joint"].as_u64().unwrap() as usize;
                    let (width, height, image) =
                        if name == "png16" { read_png16(&path, &record["remap"], per_joint) } else { read_exr(&path) };
                    assert_eq!(
                        (width, height),
                        (record["width"].as_u64().unwrap() as usize, record["height"].as_u64().unwrap() as usize)
                    );
                    assert!(width <= 4096 && height <= 4096, "{}: {width} x {height}", path.display());
                    let (frames, joints) = (shape[0] as usize, shape[1] as usize);
                    assert_eq!(record["joints"].as_u64().unwrap() as usize, joints);
                    for r in 0..frames {
                        for j in 0..joints {
                            for (t, slot) in texels.iter().enumerate() {
                                let got = at(&image, record, r, j, t);
                                for (c, channel) in slot.as_array().unwrap().iter().enumerate() {
                                    let Some(ch) =
                                        sidecar["channels"].as_array().unwrap().iter().position(|n| n == channel)
                                    else {
                                        continue;
                                    };
                                    let want = values[(r * joints + j) * channels + ch];
                                    let error = match name {
                                        "png16" => {
                                            let range = &record["remap"][t][c];
                                            let span = range[1].as_f64().unwrap() - range[0].as_f64().unwrap();
                                            // In steps of the range, beyond f32's own rounding of the value.
                                            let rounding = f64::from(f32::EPSILON) * f64::from(want.abs().max(1.0));
                                            (f64::from((got[c] - want).abs()) - rounding).max(0.0)
                                                / (span / 65535.0).max(f64::MIN_POSITIVE)
                                        }
                                        _ => f64::from((got[c] - want).abs()) / f64::from(want.abs().max(1.0)),
                                    };
                                    let w = worst.entry(name).or_insert(0.0f64);
                                    *w = w.max(error);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    eprintln!("worst read-back errors: {worst:?} (exr and half: relative; png16: in steps of the channel's range)");
    assert_eq!(worst["exr"], 0.0, "f32 EXR holds the npy floats exactly");
    assert_eq!(worst["columns"], 0.0, "f32 EXR in columns holds the npy floats exactly");
    let brainstem = json(&out.path().join("local-columns/BrainStem.json"));
    let record = &brainstem["textures"][0];
    assert!(
        record["width"].as_u64().unwrap() > record["frame_width"].as_u64().unwrap()
            && record["width"].as_u64().unwrap() <= 512
            && record["height"].as_u64().unwrap() <= 512,
        "BrainStem's frames wrap into columns within 512: {record}"
    );
    assert!(worst["half"] <= 1e-3, "half EXR within 1e-3 relative: {}", worst["half"]);
    assert!(worst["png16"] <= 0.5 + 1e-3, "PNG16 within half a step of each channel's range: {}", worst["png16"]);
}

#[test]
fn image_textures_are_the_same_bytes_every_time() {
    let Some(data) = data_dir() else { return };
    let out = tempfile::tempdir().unwrap();
    let fox = data.join("Fox.glb").display().to_string();
    for format in ["exr", "png16"] {
        let [a, b] = ["a", "b"].map(|k| out.path().join(format!("{format}-{k}")));
        for dir in [&a, &b] {
            let result = bake(&["--input", &fox, "--format", format, "--atlas", "--output", dir.to_str().unwrap()]);
            assert!(result.status.success(), "{}", stderr(&result));
        }
        let file = if format == "exr" { "Fox.exr" } else { "Fox.png" };
        assert_eq!(
            std::fs::read(a.join(file)).unwrap(),
            std::fs::read(b.join(file)).unwrap(),
            "{format}: deterministic"
        );
    }
}

#[test]
fn an_image_too_small_for_a_frame_and_options_an_image_cannot_take_are_refused() {
    let Some(data) = data_dir() else { return };
    let out = tempfile::tempdir().unwrap();
    let fox = data.join("Fox.glb").display().to_string();
    // Fox's 26 joints take 78 texels: a side of 64 cannot hold one frame's row.
    let small = out.path().join("small");
    let result =
        bake(&["--input", &fox, "--format", "exr", "--max-texture-size", "64", "--output", small.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(
        stderr(&result).contains("clip 'Survey'")
            && stderr(&result).contains("more than a texture side of 64 can hold"),
        "{}",
        stderr(&result)
    );
    assert!(
        !small.join("Fox.Survey.exr").exists() && !small.join("Fox.json").exists(),
        "nothing written for that input"
    );
    let result =
        bake(&["--input", &fox, "--format", "png16", "--precision", "f16", "--output", small.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2));
    assert!(stderr(&result).contains("--precision f16 does not apply to png16"), "{}", stderr(&result));
    let result = bake(&["--input", &fox, "--format", "tga", "--output", small.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(2));
    // The npy texture of the same clip, for the record: 22 frames of 26 joints.
    let npy = out.path().join("npy");
    assert!(bake(&["--input", &fox, "--output", npy.to_str().unwrap()]).status.success());
    assert_eq!(read_npy(&npy.join("Fox.Walk.npy")).0, [22, 26, 10]);
}
