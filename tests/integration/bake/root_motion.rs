//! `bake --root-motion extract` (DESIGN section 7): the root track in the sidecar composed
//! with the in-place textures gives back, for every joint, the textures baked with the motion
//! kept; in place, the root-motion joint stays over the origin and loops stay seamless.

use super::textures::bake_into;
use super::{data_dir, read_npy};

/// `translate(x, 0, z) * rotate_y(heading) * m` for a 3x4 row-major `m`.
fn root_times(position: [f64; 2], heading: f64, m: &[f32]) -> [f64; 12] {
    let r = quatcurve::bake::root_motion::root_matrix(position, heading);
    let m: Vec<f64> = m.iter().map(|&v| f64::from(v)).collect();
    quatcurve::skeleton::compose(&r, &m.try_into().unwrap())
}

#[test]
fn the_root_track_and_the_in_place_textures_give_the_clip_back() {
    let Some(data) = data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    for name in ["Fox.glb", "CesiumMan.glb", "cmu_131_03.bvh"] {
        let input = data.join(name);
        let stem = input.file_stem().unwrap().to_string_lossy().into_owned();
        let [keep_dir, place_dir] = ["keep", "extract"].map(|k| dir.path().join(format!("{stem}-{k}")));
        let keep = bake_into(&keep_dir, &input, &["--texture", "model"]);
        let place = bake_into(&place_dir, &input, &["--texture", "model", "--root-motion", "extract"]);
        for (kept, clip) in keep["clips"].as_array().unwrap().iter().zip(place["clips"].as_array().unwrap()) {
            let what = format!("{name} '{}'", clip["name"].as_str().unwrap());
            let track = &clip["root_motion"];
            assert!(track.is_object(), "{what}: no root track");
            let joint = place["joints"].as_array().unwrap().iter().position(|j| *j == track["joint"]).unwrap();
            let (shape, before) = read_npy(&keep_dir.join(kept["file"].as_str().unwrap()));
            let (_, after) = read_npy(&place_dir.join(clip["file"].as_str().unwrap()));
            let (frames, joints) = (shape[0] as usize, shape[1] as usize);
            let scale = before.iter().fold(1.0f32, |a, v| a.max(v.abs()));
            let mut worst = 0.0f64;
            let mut travelled = 0.0f64;
            for f in 0..frames {
                let p = &track["position"][f];
                let position = [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()];
                let heading = track["heading"][f].as_f64().unwrap();
                travelled = travelled.max(position[0].hypot(position[1]));
                for j in 0..joints {
                    let at = (f * joints + j) * 12;
                    let back = root_times(position, heading, &after[at..at + 12]);
                    for i in 0..12 {
                        worst = worst.max((back[i] - f64::from(before[at + i])).abs() / f64::from(scale));
                    }
                }
                // In place, the root joint stays over the origin.
                let at = (f * joints + joint) * 12;
                let (x, z) = (after[at + 3], after[at + 11]);
                assert!(x.hypot(z) <= 1e-4 * scale, "{what} frame {f}: the root is at ({x}, {z}) in place");
            }
            eprintln!(
                "{what}: root joint {}, travels up to {travelled:.3}, reassembled within {worst:.1e}",
                track["joint"]
            );
            assert!(
                worst <= 2e-6,
                "{what}: the root track and in-place texture give back the kept one within {worst:e}"
            );
            if clip["loop"].as_bool().unwrap() {
                let cycle = &track["per_cycle"];
                assert!(cycle.is_object(), "{what}: a loop without its per-cycle displacement");
                // In place, a loop's last frame is still its first.
                let row = joints * 12;
                let seam = (0..row).map(|i| (after[i] - after[(frames - 1) * row + i]).abs()).fold(0.0f32, f32::max);
                assert!(seam <= 1e-5 * scale, "{what}: the in-place loop opens by {seam} at its seam");
            }
        }
    }
}

#[test]
fn root_motion_of_several_characters_in_one_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("crowd");
    let result = super::bake(&[
        "--characters",
        "2",
        "--root-motion",
        "extract",
        "--device",
        "cpu",
        "--output",
        out.to_str().unwrap(),
    ]);
    assert_eq!(result.status.code(), Some(2), "{}", super::stderr(&result));
    let message = super::stderr(&result);
    assert!(
        message.contains("2 scene roots move") && message.contains("keep the root motion in the textures"),
        "{message}"
    );
    assert!(!out.join("crowd.json").exists(), "nothing written for that input");
}
