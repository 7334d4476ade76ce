//! `quatcurve play`'s instance schedule (DESIGN section 17): which clip each instance plays,
//! from which phase, and what it blends with, the same on every run so that a palette file
//! is reproducible and comparable across devices.

use crate::{ClipTime, Instance, Playback};
use quatcurve_anim::error::{AnimationError, InputError};
use quatcurve_anim::Animation;

/// The phase step between consecutive instances, as a fraction of a clip's span: the golden
/// ratio's fractional part, so that any number of instances spreads evenly over a clip and
/// no two share a phase.
pub const PHASE_STEP: f64 = 0.618_033_988_749_894_9;

/// `quatcurve play`'s instances at each frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Schedule {
    /// Instances per frame.
    pub instances: usize,
    /// Frames per second.
    pub rate: f64,
    /// Every instance's blend weight towards its second pose; `None`: no blend.
    pub blend: Option<f32>,
    /// The clip every instance blends towards; `None`: the clip after its own (itself in a
    /// file of one).
    pub blend_clip: Option<usize>,
}

/// The time in a clip `to` seconds long at the phase that `time` is of a clip `from` seconds
/// long: how far into the clip blended towards its pose is taken. The viewer's WebGPU path
/// takes it so too (`webgpu.js`, `draw`; a browser test holds the page to this).
#[must_use]
pub fn same_phase(time: f64, from: f64, to: f64) -> f64 {
    if from > 0.0 {
        time / from * to
    } else {
        0.0
    }
}

/// The clip `given` names: its index, or else its name.
///
/// # Errors
/// [`AnimationError::NoSuchClip`], listing the clips.
pub fn clip_named(animation: &Animation, given: &str) -> Result<usize, InputError> {
    let clips = &animation.clips;
    let index = given.parse::<usize>().ok().filter(|&i| i < clips.len());
    index.or_else(|| clips.iter().position(|c| c.name == given)).ok_or_else(|| {
        let listed = quatcurve_eval::error::one_of(clips.iter().enumerate().map(|(i, c)| format!("{i} '{}'", c.name)));
        AnimationError::NoSuchClip { given: given.to_string(), clips: listed }.into()
    })
}

impl Schedule {
    /// The instances of frame `frame` (at `frame / rate` seconds). Instance `i` plays clip
    /// `i mod clips` from phase `frac(i * PHASE_STEP)` of its span, so instance 0 plays clip
    /// 0 from its start. With a blend, its second pose is [`Self::blend_clip`] (by default the
    /// next clip, `(c + 1) mod clips`) at the same phase ([`same_phase`]). A loop plays on (its
    /// root advancing each period); an open clip starts again after its end.
    #[must_use]
    pub fn frame(&self, playback: &Playback, frame: usize) -> Vec<Instance> {
        let clips = playback.animation().clips.len();
        let now = frame as f64 / self.rate;
        let at = |clip: usize, t: f64| {
            let duration = playback.duration(clip);
            let time = if playback.looping(clip) || t <= duration || duration <= 0.0 { t } else { t % duration };
            ClipTime { clip, time }
        };
        (0..self.instances)
            .map(|i| {
                let clip = i % clips;
                let first = at(clip, (i as f64 * PHASE_STEP).fract() * playback.duration(clip) + now);
                let second = self.blend.map(|weight| {
                    let towards = self.blend_clip.unwrap_or((clip + 1) % clips);
                    let time = same_phase(first.time, playback.duration(clip), playback.duration(towards));
                    (at(towards, time), weight)
                });
                Instance { first, second }
            })
            .collect()
    }
}
