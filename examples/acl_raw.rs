//! A BVH clip's local poses at every frame, as the raw input of the ACL harness
//! (`examples/acl/`): rotations as they are, translations in centimetres (ACL's error
//! threshold is in the clip's units).
//!
//! Run: `cargo run --release --example acl_raw -- CLIP.bvh OUT.raw UNIT_CM` (CMU: 5.644).
//! Layout, little-endian: `u32` joints, `u32` frames, `f32` rate (Hz), an `i32` parent per
//! joint (-1 for a root), then per frame per joint seven `f32`: rotation `x, y, z, w`,
//! translation `x, y, z`.

use quatcurve::formats::bvh;

use quatcurve::anim::Property;
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [input, output, unit_cm] = args.as_slice() else {
        panic!("usage: acl_raw CLIP.bvh OUT.raw UNIT_CM");
    };
    let unit_cm: f64 = unit_cm.parse().expect("UNIT_CM is a number");
    let animation = bvh::read(Path::new(input)).unwrap_or_else(|e| panic!("{input}: {e}")).animation("clip");
    let (joints, clip) = (&animation.joints, &animation.clips[0]);
    // A BVH clip keys every animated channel at every frame.
    let keys: Vec<(&[f64], &[[f64; 4]])> = clip.channels.iter().map(|c| c.keyed().expect("BVH keys")).collect();
    let frames = keys.iter().map(|(times, _)| times.len()).max().expect("an animated channel");
    let times = keys.iter().find(|(times, _)| times.len() == frames).expect("a full channel").0;
    let rate = (frames - 1) as f64 / (times[frames - 1] - times[0]);
    // Rest pose first, then the animated channels over it.
    let mut poses: Vec<[f64; 7]> = (0..frames)
        .flat_map(|_| {
            joints.iter().map(|j| {
                let [x, y, z, w] = j.rotation;
                let [tx, ty, tz] = j.translation;
                [x, y, z, w, tx, ty, tz]
            })
        })
        .collect();
    for (channel, (times, values)) in clip.channels.iter().zip(keys) {
        assert_eq!(times.len(), frames, "{input}: a channel keyed at some frames only");
        let columns = match channel.property {
            Property::Rotation => 0..4,
            Property::Translation => 4..7,
            Property::Scale => continue,
        };
        for (f, value) in values.iter().enumerate() {
            poses[f * joints.len() + channel.joint][columns.clone()].copy_from_slice(&value[..columns.len()]);
        }
    }
    let mut out = Vec::new();
    out.extend((joints.len() as u32).to_le_bytes());
    out.extend((frames as u32).to_le_bytes());
    out.extend((rate as f32).to_le_bytes());
    for joint in joints {
        out.extend(joint.parent.map_or(-1, |p| p as i32).to_le_bytes());
    }
    for pose in &poses {
        for (i, &v) in pose.iter().enumerate() {
            let v = if i >= 4 { v * unit_cm } else { v };
            out.extend((v as f32).to_le_bytes());
        }
    }
    std::fs::write(output, out).unwrap_or_else(|e| panic!("{output}: {e}"));
    println!("{input}: {} joints, {frames} frames at {} Hz", joints.len(), rate as f32);
}
