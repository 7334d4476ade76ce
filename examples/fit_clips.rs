//! Curve compression measured per real clip: `quatcurve::fit::clip` keeps every channel as
//! the fewest B-spline control points (or kept keys) that hold ACL's object-space error
//! (virtual vertices at `--vertex-distance-cm` from each joint) within a budget at every source
//! frame, and reports the error between frames too. Bytes as ACL counts a raw clip (40 per
//! joint per frame) against the clip's bytes in the `.qcf` container. CMU's BVH unit is
//! 5.644 cm, glTF's the metre.
//!
//! Run: `cargo run --release --example fit_clips -- ../shared/data MAX_ERROR_CM [BETWEEN_CM]
//! [VERTEX_CM]` (defaults 0.01, 0.3, 3).

use quatcurve::formats::{bvh, gltf};

use quatcurve::anim::Animation;
use quatcurve::fit::clip::{fit_clip, Budget};
use std::time::Instant;

const FILES: [(&str, f64); 5] = [
    ("cmu_131_01.bvh", 5.644),
    ("cmu_131_03.bvh", 5.644),
    ("CesiumMan.glb", 100.0),
    ("Fox.glb", 100.0),
    ("BrainStem.glb", 100.0),
];

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = args.next().unwrap_or_else(|| "../shared/data".into());
    let max_error_cm: f64 = args.next().map_or(0.01, |a| a.parse().expect("a length in cm"));
    let between_cm: f64 = args.next().map_or(0.3, |a| a.parse().expect("a length in cm"));
    let vertex_cm: f64 = args.next().map_or(3.0, |a| a.parse().expect("a length in cm"));
    println!(
        "every source frame within {max_error_cm} cm and between frames within {between_cm} cm, at virtual vertices \
         {vertex_cm} cm from each joint (bytes as the container stores the clip)"
    );
    println!(
        "| clip | frames | joints | raw KB | fitted KB | ratio | worst at frames cm | between frames cm | seconds |"
    );
    println!("|---|---:|---:|---:|---:|---:|---|---|---:|");
    for (file, unit_cm) in FILES {
        let path = std::path::Path::new(&dir).join(file);
        let animation: Animation = if file.ends_with(".bvh") {
            bvh::read(&path).expect("a BVH file").animation(file)
        } else {
            gltf::read(&path, gltf::UriPolicy::default()).expect("a glTF file").animation
        };
        let budget = Budget {
            max_error: max_error_cm / unit_cm,
            between_error: between_cm / unit_cm,
            vertex_distance: vertex_cm / unit_cm,
        };
        for (c, clip) in animation.clips.iter().enumerate() {
            let started = Instant::now();
            let fit = fit_clip(&animation, c, &budget).expect("a fit within the budget");
            let name = |j: usize| animation.joints[j].name.as_str();
            println!(
                "| {file} {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.5} ({}, {:.3} s) | {:.4} ({}, {:.3} s) | {:.1} |",
                clip.name,
                fit.frames,
                animation.joints.len(),
                fit.raw_bytes as f64 / 1024.0,
                fit.fitted_bytes as f64 / 1024.0,
                fit.raw_bytes as f64 / fit.fitted_bytes as f64,
                fit.at_frames.error * unit_cm,
                name(fit.at_frames.joint),
                fit.at_frames.time,
                fit.between_frames.error * unit_cm,
                name(fit.between_frames.joint),
                fit.between_frames.time,
                started.elapsed().as_secs_f64()
            );
        }
    }
}
