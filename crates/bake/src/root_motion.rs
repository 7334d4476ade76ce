//! Root motion (`bake --root-motion extract`, DESIGN section 7): the root's horizontal
//! translation and heading (yaw about +Y, glTF's and BVH's up) taken out of a clip's textures
//! into a per-frame root track in the sidecar, so the clip plays in place and the game moves
//! the character. The track composed with the in-place textures gives the kept clip back:
//! `model = Root(t) * model_in_place`, `Root(t) = translate(x, 0, z) * rotate_y(heading)`.

use super::texture::{self, LOCAL_CHANNELS};
use super::Baked;
use crate::error::{BakeError, Refusal};
use quatcurve_anim::{Animation, Property};
use quatcurve_eval::skeleton::{self, Affine};
use serde::{Deserialize, Serialize};

/// What `--root-motion` does with the root's horizontal motion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RootMotion {
    /// It stays in the textures.
    #[default]
    Keep,
    /// It moves to the sidecar's root track; the textures play in place.
    Extract,
}

quatcurve_core::curve::names!(RootMotion, "root motion", Keep => "keep", Extract => "extract");

/// A clip's root track and the scene roots' local rows with the track taken out (every joint's
/// model transform is then `Root(t)^-1 * model`).
#[derive(Clone, Debug, PartialEq)]
pub struct InPlace {
    /// The joints without a parent ([`Animation::joints`]).
    pub roots: Vec<usize>,
    /// Their local rows in place (rotation, translation, scale), frame-major: `roots.len()`
    /// rows a frame.
    pub rows: Vec<[f32; LOCAL_CHANNELS]>,
    /// What was taken out.
    pub track: RootTrack,
}

/// One clip's root track, frame by frame (the sidecar's `root_motion`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RootTrack {
    /// The joint whose motion it is: the first joint, parents first, with a translation
    /// channel in the clip.
    pub joint: String,
    /// The up axis the heading turns about and the plane the position moves in.
    pub up: String,
    /// Per frame: `[x, z]` in model units.
    pub position: Vec<[f64; 2]>,
    /// Per frame: radians about +Y, continuous (unwrapped) from frame to frame.
    pub heading: Vec<f64>,
    /// Per frame: `[dx/dt, dz/dt]` in units per second (central differences of the frames;
    /// one-sided at an open clip's ends, across the seam of a loop).
    pub velocity: Vec<[f64; 2]>,
    /// Per frame: radians per second, as `velocity`.
    pub turn_rate: Vec<f64>,
    /// A loop's displacement over one cycle: `[dx, dz]` and the heading's turn; what the game
    /// adds each time the clip wraps.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub per_cycle: Option<Cycle>,
}

/// What one cycle of a loop moves the root by.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Cycle {
    /// `[dx, dz]`, model units.
    pub displacement: [f64; 2],
    /// Radians about +Y.
    pub turn: f64,
}

/// `translate(x, 0, z) * rotate_y(heading)`.
#[must_use]
pub fn root_matrix(position: [f64; 2], heading: f64) -> Affine {
    let (s, c) = heading.sin_cos();
    [c, 0.0, s, position[0], 0.0, 1.0, 0.0, 0.0, -s, 0.0, c, position[1]]
}

/// The heading of a model-space transform: its rotation's twist about +Y (`2 atan2(q_y, q_w)`).
fn heading(m: &Affine) -> f64 {
    let (trs, _) = skeleton::rigid(m);
    2.0 * trs[1].atan2(trs[3])
}

/// Takes each clip's root motion out of `baked`: the textures then play in place, and
/// [`Baked::in_place`] holds each clip's root track (none for a clip without a translation
/// channel). The track is the root-motion joint's (the first joint, parents first, with a
/// translation channel); it is taken out of every scene root, so the whole scene plays in
/// place.
///
/// # Errors
/// [`Refusal::SeveralRoots`] for a clip that moves joints under more than one scene root
/// (several characters); [`quatcurve_anim::error::AnimationError`] for a hierarchy that has a cycle.
pub fn extract(animation: &Animation, baked: &mut Baked) -> Result<(), BakeError> {
    let order = animation.parents_first()?;
    let roots: Vec<usize> = (0..animation.joints.len()).filter(|&j| animation.joints[j].parent.is_none()).collect();
    let mut in_place = Vec::with_capacity(animation.clips.len());
    for (c, clip) in animation.clips.iter().enumerate() {
        let translated: Vec<usize> =
            clip.channels.iter().filter(|ch| ch.property == Property::Translation).map(|ch| ch.joint).collect();
        let Some(&joint) = order.iter().find(|j| translated.contains(j)) else {
            in_place.push(None);
            continue;
        };
        // One track moves one character: translations under two scene roots are two.
        let root_of = |mut j: usize| {
            while let Some(parent) = animation.joints[j].parent {
                j = parent;
            }
            j
        };
        let mut moving: Vec<usize> = translated.iter().map(|&j| root_of(j)).collect();
        moving.sort_unstable();
        moving.dedup();
        if moving.len() > 1 {
            let roots = moving.iter().map(|&r| animation.joints[r].name.clone()).collect();
            return Err(Refusal::SeveralRoots { clip: clip.name.clone(), roots }.into());
        }
        let joints = animation.joints.len();
        let local = texture::local(animation, baked, c);
        let model = skeleton::forward_kinematics(&animation.parents(), &order, &local);
        let frames = baked.clips[c].times.len();
        let mut position = Vec::with_capacity(frames);
        let mut headings: Vec<f64> = Vec::with_capacity(frames);
        let mut rows = Vec::with_capacity(frames * roots.len());
        for frame in 0..frames {
            let at = (frame * joints + joint) * texture::MATRIX_CHANNELS;
            let m: Affine = std::array::from_fn(|i| f64::from(model[at + i]));
            let p = [m[3], m[11]];
            let mut h = heading(&m);
            // Unwrapped: within half a turn of the frame before.
            if let Some(&before) = headings.last() {
                h -= std::f64::consts::TAU * ((h - before) / std::f64::consts::TAU).round();
            }
            let undo = skeleton::inverse(&root_matrix(p, h)).expect("a rigid transform inverts");
            for &r in &roots {
                let at = (frame * joints + r) * LOCAL_CHANNELS;
                // A rigid transform times T * R * S is T' * R' * S: rotation, translation and scale.
                let (row, _) =
                    skeleton::rigid(&skeleton::compose(&undo, &skeleton::trs_row(&local[at..at + LOCAL_CHANNELS])));
                rows.push(row.map(|v| v as f32));
            }
            position.push(p);
            headings.push(h);
        }
        let looping = baked.clips[c].closes() && frames > 1;
        let per_cycle = looping.then(|| Cycle {
            displacement: [position[frames - 1][0] - position[0][0], position[frames - 1][1] - position[0][1]],
            turn: headings[frames - 1] - headings[0],
        });
        let (velocity, turn_rate) = rates(&position, &headings, baked.clips[c].rate, per_cycle.as_ref());
        let track = RootTrack {
            joint: animation.joints[joint].name.clone(),
            up: "+y".into(),
            position,
            heading: headings,
            velocity,
            turn_rate,
            per_cycle,
        };
        in_place.push(Some(InPlace { roots: roots.clone(), rows, track }));
    }
    baked.in_place = in_place;
    Ok(())
}

/// Velocities and turn rates per frame: central differences, one-sided at an open clip's
/// ends; a loop's ends look across the seam (its frame before the first is the last but one,
/// less a cycle).
fn rates(position: &[[f64; 2]], heading: &[f64], rate: f64, cycle: Option<&Cycle>) -> (Vec<[f64; 2]>, Vec<f64>) {
    let n = position.len();
    if n < 2 {
        return (vec![[0.0; 2]; n], vec![0.0; n]);
    }
    let at = |i: isize| -> ([f64; 2], f64) {
        match cycle {
            Some(cy) if i < 0 => {
                let (p, h) = (position[n - 2], heading[n - 2]);
                ([p[0] - cy.displacement[0], p[1] - cy.displacement[1]], h - cy.turn)
            }
            Some(cy) if i >= n as isize => {
                let (p, h) = (position[1], heading[1]);
                ([p[0] + cy.displacement[0], p[1] + cy.displacement[1]], h + cy.turn)
            }
            _ => {
                let i = i.clamp(0, n as isize - 1) as usize;
                (position[i], heading[i])
            }
        }
    };
    let (mut velocity, mut turn) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n as isize {
        let (lo, hi) = if cycle.is_some() { (i - 1, i + 1) } else { ((i - 1).max(0), (i + 1).min(n as isize - 1)) };
        let ((p0, h0), (p1, h1)) = (at(lo), at(hi));
        let dt = (hi - lo) as f64 / rate;
        velocity.push([(p1[0] - p0[0]) / dt, (p1[1] - p0[1]) / dt]);
        turn.push((h1 - h0) / dt);
    }
    (velocity, turn)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_root_matrix_turns_about_y_and_moves_in_the_ground_plane() {
        let m = root_matrix([1.0, 2.0], std::f64::consts::FRAC_PI_2);
        // +Z turns to +X under a quarter turn about +Y.
        assert!((m[2] - 1.0).abs() < 1e-12 && m[10].abs() < 1e-12);
        assert_eq!([m[3], m[7], m[11]], [1.0, 0.0, 2.0]);
        assert!((heading(&m) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn rates_are_central_differences_and_look_across_a_loop_s_seam() {
        // Moving +1 in x per frame at 10 Hz, turning 0.1 rad per frame.
        let position: Vec<[f64; 2]> = (0..5).map(|i| [f64::from(i), 0.0]).collect();
        let heading: Vec<f64> = (0..5).map(|i| 0.1 * f64::from(i)).collect();
        let (v, w) = rates(&position, &heading, 10.0, None);
        assert!(v.iter().all(|v| (v[0] - 10.0).abs() < 1e-9 && v[1] == 0.0), "{v:?}");
        assert!(w.iter().all(|w| (w - 1.0).abs() < 1e-9), "{w:?}");
        let cycle = Cycle { displacement: [4.0, 0.0], turn: 0.4 };
        let (v, w) = rates(&position, &heading, 10.0, Some(&cycle));
        assert!(v.iter().all(|v| (v[0] - 10.0).abs() < 1e-9), "{v:?}");
        assert!(w.iter().all(|w| (w - 1.0).abs() < 1e-9), "{w:?}");
    }
}
