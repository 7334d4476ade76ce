//! The built-in synthetic crowd that `quatcurve bake` uses without `--input`: characters on a
//! grid walking forward, each joint swinging in a looping gait with per-character variety.
//! Deterministic (a hash of the indices, no random numbers), so runs are comparable.

use quatcurve_anim::{Animation, Channel, Clip, Joint, Property};

use quatcurve_core::quat::{QuatF64, Vec3F64};
use rayon::prelude::*;
use std::f64::consts::TAU;

/// Characters in the default crowd.
pub const CHARACTERS: usize = 1000;
/// Clip length in seconds.
pub const SECONDS: f64 = 10.0;
/// Keys per second of the source animation (resampled by `bake --rate`).
pub const KEY_RATE: f64 = 10.0;

/// The skeleton, parents first: joint name, parent (index in this table; the hips are the
/// root), rest offset from the parent (m, y up, z forward), swing amplitude (rad), phase
/// offset within the gait cycle.
const SKELETON: [(&str, usize, [f64; 3], f64, f64); 24] = [
    ("hips", usize::MAX, [0.0, 0.0, 0.0], 0.10, 0.0),
    ("spine", 0, [0.0, 0.12, 0.0], 0.06, 0.5),
    ("chest", 1, [0.0, 0.18, 0.0], 0.05, 0.5),
    ("neck", 2, [0.0, 0.22, 0.0], 0.04, 1.0),
    ("head", 3, [0.0, 0.10, 0.0], 0.05, 1.2),
    ("l_clavicle", 2, [0.05, 0.18, 0.0], 0.05, 3.1),
    ("l_shoulder", 5, [0.14, 0.0, 0.0], 0.45, 3.1),
    ("l_elbow", 6, [0.0, -0.28, 0.0], 0.35, 3.6),
    ("l_wrist", 7, [0.0, -0.25, 0.0], 0.15, 4.0),
    ("r_clavicle", 2, [-0.05, 0.18, 0.0], 0.05, 0.0),
    ("r_shoulder", 9, [-0.14, 0.0, 0.0], 0.45, 0.0),
    ("r_elbow", 10, [0.0, -0.28, 0.0], 0.35, 0.5),
    ("r_wrist", 11, [0.0, -0.25, 0.0], 0.15, 0.9),
    ("l_hip", 0, [0.1, -0.05, 0.0], 0.50, 0.0),
    ("l_knee", 13, [0.0, -0.42, 0.0], 0.65, 0.8),
    ("l_ankle", 14, [0.0, -0.40, 0.0], 0.25, 1.6),
    ("l_toe", 15, [0.0, -0.06, 0.12], 0.20, 2.2),
    ("r_hip", 0, [-0.1, -0.05, 0.0], 0.50, 3.1),
    ("r_knee", 17, [0.0, -0.42, 0.0], 0.65, 3.9),
    ("r_ankle", 18, [0.0, -0.40, 0.0], 0.25, 4.7),
    ("r_toe", 19, [0.0, -0.06, 0.12], 0.20, 5.3),
    ("tail", 0, [0.0, 0.0, -0.12], 0.30, 2.0),
    ("l_ear", 4, [0.06, 0.12, 0.0], 0.20, 1.5),
    ("r_ear", 4, [-0.06, 0.12, 0.0], 0.20, 4.6),
];

/// Joints per character.
pub const JOINTS: usize = SKELETON.len();

/// `characters` walkers: one clip "walk" of [`SECONDS`] keyed at [`KEY_RATE`], a rotation
/// channel per joint and a translation channel on each hips (the root of its character's
/// hierarchy). Every gait has a whole number of cycles in the clip, so the rotations loop.
#[must_use]
pub fn crowd(characters: usize) -> Animation {
    let keys = (SECONDS * KEY_RATE).round() as usize + 1;
    let times: Vec<f64> = (0..keys).map(|i| i as f64 / KEY_RATE).collect();
    let side = (characters as f64).sqrt().ceil() as usize;
    // Characters on every core, then laid end to end in character order.
    let people: Vec<(Vec<Joint>, Vec<Channel>)> =
        (0..characters).into_par_iter().map(|c| character(c, side, &times)).collect();
    let (mut joints, mut channels) =
        (Vec::with_capacity(characters * JOINTS), Vec::with_capacity(characters * (JOINTS + 1)));
    for (js, chs) in people {
        joints.extend(js);
        channels.extend(chs);
    }
    Animation { joints, clips: vec![Clip { name: "walk".into(), channels }], skins: Vec::new() }
}

/// Character `c` of a crowd `side` characters wide: its joints (indices [`JOINTS`] `* c`
/// onwards) and channels keyed at `times`.
fn character(c: usize, side: usize, times: &[f64]) -> (Vec<Joint>, Vec<Channel>) {
    let (mut joints, mut channels) = (Vec::with_capacity(JOINTS), Vec::with_capacity(JOINTS + 1));
    let h = |k: u64| ((c as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15 ^ k) >> 40) as f64 / (1u64 << 24) as f64;
    let cycles = 9.0 + (4.0 * h(1)).floor(); // 0.9 to 1.2 steps per second
    let (vigour, lean) = (0.8 + 0.4 * h(2), 0.1 * h(3) - 0.05);
    let phase = TAU * h(4);
    let origin = [1.5 * (c % side) as f64, 0.0, 1.5 * (c / side) as f64];
    let first = c * JOINTS;
    for (j, &(name, parent, rest, amplitude, offset)) in SKELETON.iter().enumerate() {
        let joint = first + j;
        let (parent, rest) = if j == 0 { (None, [origin[0], 0.95, origin[2]]) } else { (Some(first + parent), rest) };
        joints.push(Joint::at(format!("c{c}/{name}"), parent, rest));
        let values = times
            .iter()
            .map(|&t| {
                let a = (TAU * cycles * t / SECONDS + phase + offset).sin();
                let swing = 0.5 * vigour * amplitude * a;
                QuatF64::exp(Vec3F64::new(swing, 0.3 * swing * (2.0 * a).cos(), 0.5 * lean)).to_array()
            })
            .collect();
        channels.push(Channel::keys(joint, Property::Rotation, times.to_vec(), values));
        if j == 0 {
            let speed = 1.2 * vigour;
            let values = times
                .iter()
                .map(|&t| {
                    let bob = 0.03 * (2.0 * (TAU * cycles * t / SECONDS + phase)).cos();
                    [origin[0], 0.95 + bob, origin[2] + speed * t, 0.0]
                })
                .collect();
            channels.push(Channel::keys(joint, Property::Translation, times.to_vec(), values));
        }
    }
    (joints, channels)
}
