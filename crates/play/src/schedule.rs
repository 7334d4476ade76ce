//! `quatcurve play`'s instance schedule (DESIGN section 17): which clip each instance plays,
//! from which phase, and what it blends with, the same on every run so that a palette file
//! is reproducible and comparable across devices.

use crate::{ClipTime, Instance, Playback};

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
}

impl Schedule {
    /// The instances of frame `frame` (at `frame / rate` seconds). Instance `i` plays clip
    /// `i mod clips` from phase `frac(i * PHASE_STEP)` of its span, so instance 0 plays clip
    /// 0 from its start. With a blend, its second pose is the next clip (`(c + 1) mod
    /// clips`, the same clip for a file of one) half that clip's span further on. A loop plays
    /// on (its root advancing each period); an open clip starts again after its end.
    #[must_use]
    pub fn frame(&self, playback: &Playback, frame: usize) -> Vec<Instance> {
        let clips = playback.animation().clips.len();
        let now = frame as f64 / self.rate;
        let at = |clip: usize, offset: f64| {
            let duration = playback.duration(clip);
            let t = offset + now;
            let time = if playback.looping(clip) || t <= duration || duration <= 0.0 { t } else { t % duration };
            ClipTime { clip, time }
        };
        (0..self.instances)
            .map(|i| {
                let clip = i % clips;
                let phase = (i as f64 * PHASE_STEP).fract() * playback.duration(clip);
                let second = self.blend.map(|weight| {
                    let next = (clip + 1) % clips;
                    (at(next, phase + playback.duration(next) / 2.0), weight)
                });
                Instance { first: at(clip, phase), second }
            })
            .collect()
    }
}
