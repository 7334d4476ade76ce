//! Whether a clip plays as a loop ([`clip_loops`]): its rotations close and its curve can
//! loop, or the caller says so ([`LoopMode`]). The bake and playback ask the same question.

use crate::curves::CurveChoice;
use crate::error::{AnimationError, InputError};
use crate::{Animation, Channel, Clip, Property};

pub use quatcurve_eval::options::LoopMode;

/// Whether `clip` bakes as a loop under `mode` with `choice` (DESIGN section 5b).
///
/// # Errors
/// With [`LoopMode::On`]: a curve that cannot loop, or the first rotation channel whose last
/// key is not its first rotation, named.
pub fn clip_loops(
    animation: &Animation,
    clip: &Clip,
    choice: &CurveChoice,
    mode: LoopMode,
) -> Result<bool, InputError> {
    let spec = choice.spec();
    if clip.channels.iter().any(Channel::is_spline) {
        // A fitted clip is the open curve it was fitted as.
        return match mode {
            LoopMode::On => Err(AnimationError::FittedLoop { clip: clip.name.clone() }.into()),
            _ => Ok(false),
        };
    }
    let open = quatcurve_eval::options::opening;
    let rotations = || {
        clip.channels
            .iter()
            .filter(|c| c.property == Property::Rotation)
            .filter_map(|c| c.keyed().map(|(_, values)| (c, values)))
            .filter(|(_, values)| values.len() > 1)
    };
    match mode {
        LoopMode::Off => Ok(false),
        LoopMode::Auto => {
            Ok(mode.loops(&spec, || rotations().count() > 0 && rotations().all(|(_, v)| open(v).is_none())))
        }
        LoopMode::On => {
            if !spec.can_loop() {
                return Err(AnimationError::CurveDoesNotLoop {
                    clip: clip.name.clone(),
                    curve: choice.name().to_string(),
                    looping: quatcurve_core::curve::CurveSpec::looping_curves(),
                }
                .into());
            }
            if let Some((c, angle)) = rotations().find_map(|(c, v)| open(v).map(|a| (c, a))) {
                let (channel, tolerance) = (animation.label(clip, c), quatcurve_eval::batch::LOOP_TOLERANCE);
                return Err(AnimationError::LoopOpen { channel, angle, tolerance }.into());
            }
            Ok(true)
        }
    }
}
