//! Why an animation cannot be played, or a frame could not be ([`PlayError`]).

use quatcurve_anim::error::InputError;
use quatcurve_device::DeviceError;

/// Why an animation cannot be played as asked, or a frame could not be computed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlayError {
    /// The animation, its clips or the instances break a rule of playback (a clip, joint or
    /// skin named), or its keys cannot make curves.
    #[error(transparent)]
    Animation(#[from] InputError),
    /// The device refused the work or failed.
    #[error(transparent)]
    Device(#[from] DeviceError),
}

impl PlayError {
    /// Whether the device failed, rather than the animation or the instances being at fault.
    #[must_use]
    pub fn is_device_failure(&self) -> bool {
        matches!(self, Self::Device(e) if e.is_device_failure())
    }
}

impl From<quatcurve_eval::error::Error> for PlayError {
    /// Keys the curve builder rejects are the animation's ([`InputError::Keys`]).
    fn from(e: quatcurve_eval::error::Error) -> Self {
        Self::Animation(e.into())
    }
}
