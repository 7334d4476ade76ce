//! SMPL-family pose arrays resampled in memory by a bake's options and rules (Python's
//! `quatcurve.resample_poses`): the curve, the frame grid and the warnings of a bake of the
//! same arrays as an archive, without files.

use super::options::BakeOptions;
use super::report::unbaked_ends;
use crate::error::BakeError;
use quatcurve_anim::curves::CurveChoice;
use quatcurve_device::Device;
use quatcurve_formats::smpl::{Resampled, SmplFile};

/// `file`'s poses (and root translation) at `options.rate` (exactly, with `exact_rate`), with
/// the warnings a bake of it would give.
///
/// # Errors
/// As a bake of the file: keys the curve refuses, a clip too long for the rate, a device
/// failure.
pub fn resample(file: SmplFile, options: &BakeOptions, device: &Device) -> Result<(Resampled, Vec<String>), BakeError> {
    let animation = file.animation("poses");
    let choice = options.choice_or(None);
    let baked = super::bake(&animation, &choice, options.clip_rate(), options.looping, device)?;
    let mut warnings = super::source_step_warnings(&animation);
    warnings.extend(unbaked_ends(&animation, &baked));
    Ok((file.resampled(&baked.frames()[0], choice == CurveChoice::Source), warnings))
}
