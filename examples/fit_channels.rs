//! How many control points `quatcurve::fit` keeps per real clip when every channel alone must
//! stay within an angle (rotations) or a length (translations and scales) at every key: the
//! first measurement of curve compression, before the error budget is shared down the
//! hierarchy and control points are quantized. Bytes as ACL counts raw clips (40 per bone per
//! frame) against f32 control points (16 bytes a rotation, 12 a vector) plus f32 knots (each
//! channel's own).
//!
//! Run: `cargo run --release --example fit_channels -- ../shared/data DEGREES LENGTH`.

use quatcurve::bake::{bvh, gltf, Animation, Property};
use quatcurve::fit::{fit_rotations, fit_vectors, ORDER};
use quatcurve::QuatF64;
use std::time::Instant;

const FILES: [&str; 5] = ["cmu_131_01.bvh", "cmu_131_03.bvh", "CesiumMan.glb", "Fox.glb", "BrainStem.glb"];

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = args.next().unwrap_or_else(|| "../shared/data".into());
    let degrees: f64 = args.next().map_or(0.01, |a| a.parse().expect("an angle in degrees"));
    let length: f64 = args.next().map_or(1e-4, |a| a.parse().expect("a length in file units"));
    println!("per channel within {degrees} degrees and {length} units at every key");
    println!(
        "clip                        frames joints  keys   controls  raw KB  fitted KB  ratio  worst deg  seconds"
    );
    for file in FILES {
        let path = std::path::Path::new(&dir).join(file);
        let animation: Animation = if file.ends_with(".bvh") {
            bvh::read(&path).expect("a BVH file").animation(file)
        } else {
            gltf::read(&path, gltf::UriPolicy::default()).expect("a glTF file").animation
        };
        for clip in &animation.clips {
            let started = Instant::now();
            let (mut keys, mut controls, mut bytes, mut worst) = (0, 0, 0usize, 0.0f64);
            let frames = clip.channels.iter().map(|c| c.times.len()).max().unwrap_or(0);
            for channel in clip.channels.iter().filter(|c| c.times.len() >= 2) {
                keys += channel.times.len();
                let (count, knots) = if channel.property == Property::Rotation {
                    let rotations: Vec<QuatF64> = channel.values.iter().map(|v| QuatF64::from_array(*v)).collect();
                    let fit = fit_rotations(&channel.times, &rotations, degrees.to_radians());
                    worst = worst.max(fit.worst.to_degrees());
                    bytes += 16 * fit.controls.len();
                    (fit.controls.len(), fit.knots.len())
                } else {
                    let values: Vec<[f64; 3]> = channel.values.iter().map(|v| [v[0], v[1], v[2]]).collect();
                    let fit = fit_vectors(&channel.times, &values, length);
                    bytes += 12 * fit.controls.len();
                    (fit.controls.len(), fit.knots.len())
                };
                controls += count;
                // The clamped ends are the clip's: only the interior knots are stored.
                bytes += 4 * (knots - 2 * ORDER);
            }
            let raw = 40 * frames * animation.joints.len();
            println!(
                "{:<27} {frames:>6} {:>6} {keys:>6} {controls:>9} {:>7.1} {:>10.1} {:>6.1} {worst:>10.5} {:>8.2}",
                format!("{file} {}", clip.name),
                animation.joints.len(),
                raw as f64 / 1024.0,
                bytes as f64 / 1024.0,
                raw as f64 / bytes as f64,
                started.elapsed().as_secs_f64()
            );
        }
    }
}
