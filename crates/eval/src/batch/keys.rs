//! The rules every rotation key and key time meets (DESIGN sections 1 and 3): finite,
//! non-zero keys made unit and sign-continuous, strictly increasing times, closing loops.

use crate::error::{Error, Result, TrackId};
use quatcurve_core::curve::{Curve, CurveSpec};
use quatcurve_core::quat::QuatF64;

/// Keys with a norm below this are errors (they carry no direction).
pub const MIN_KEY_NORM: f64 = 1e-6;

/// Largest angle (rad) between a looping track's last key and its first (DESIGN section 3).
pub const LOOP_TOLERANCE: f64 = 1e-3;

/// A looping spec must be a family that loops, and the keys must close.
pub(super) fn check_loop(id: &TrackId, spec: &CurveSpec, keys: &[QuatF64]) -> Result<()> {
    if !spec.can_loop() {
        return Err(Error::LoopUnsupported {
            track: id.clone(),
            curve: curve_label(spec),
            looping: CurveSpec::looping_curves(),
        });
    }
    if let Some(angle) = loop_gap(keys[0], keys[keys.len() - 1]) {
        return Err(Error::LoopNotClosed { track: id.clone(), last: keys.len() - 1, angle, tolerance: LOOP_TOLERANCE });
    }
    Ok(())
}

/// The angle (rad) from unit rotation `first` to `last` when it is more than
/// [`LOOP_TOLERANCE`] (or not a number): the gap of a loop that does not close.
#[must_use]
pub fn loop_gap(first: QuatF64, last: QuatF64) -> Option<f64> {
    let angle = first.angle_to(last);
    (angle.is_nan() || angle > LOOP_TOLERANCE).then_some(angle)
}

/// The curve as messages name it: B-splines with their order and knot mode.
pub(super) fn curve_label(spec: &CurveSpec) -> String {
    match spec.curve {
        Curve::BSpline | Curve::NormalizedBSpline => {
            format!("{} order {} with {} knots", spec.curve, spec.order, spec.knots)
        }
        other => other.to_string(),
    }
}

/// Normalizes keys and makes them sign-continuous (DESIGN section 1).
pub(super) fn aligned_keys(id: &TrackId, rotations: &[[f64; 4]], spec: &CurveSpec) -> Result<Vec<QuatF64>> {
    check_key_count(id, spec, rotations.len())?;
    aligned(id, rotations).collect()
}

/// At least the keys `spec` needs.
pub(super) fn check_key_count(id: &TrackId, spec: &CurveSpec, found: usize) -> Result<()> {
    let min = spec.min_keys();
    if found < min {
        return Err(Error::TooFewKeys { track: id.clone(), curve: curve_label(spec), min, found });
    }
    Ok(())
}

/// `rotations` normalized, each in the hemisphere of the one before it (the first as it is);
/// a bad key is its error in its place.
pub(super) fn aligned<'a>(id: &'a TrackId, rotations: &'a [[f64; 4]]) -> impl Iterator<Item = Result<QuatF64>> + 'a {
    let mut prev: Option<QuatF64> = None;
    rotations.iter().enumerate().map(move |(key, &value)| {
        let q = normalized_key(id, key, value)?;
        let q = prev.map_or(q, |prev| q.aligned_with(prev));
        prev = Some(q);
        Ok(q)
    })
}

/// Key `key` of track `id` as a unit quaternion: finite and not (near) zero. The one check of
/// a rotation key, also for the keys bake holds constant.
pub fn normalized_key(id: &TrackId, key: usize, value: [f64; 4]) -> Result<QuatF64> {
    let q = QuatF64::from_array(value);
    if !q.is_finite() {
        return Err(Error::NonFiniteKey { track: id.clone(), key, value });
    }
    let norm = q.length();
    if norm < MIN_KEY_NORM {
        return Err(Error::ZeroKey { track: id.clone(), key, norm, min: MIN_KEY_NORM });
    }
    Ok(q.mul_scalar(1.0 / norm))
}

/// The key times, defaulting to `0, 1, ..., n`; finite and strictly increasing.
pub fn key_times(id: &TrackId, times: Option<&[f64]>, count: usize) -> Result<Vec<f64>> {
    let Some(times) = times else {
        return Ok((0..count).map(|i| i as f64).collect());
    };
    if times.len() != count {
        return Err(Error::TimesCount { track: id.clone(), expected: count, found: times.len() });
    }
    for (key, &value) in times.iter().enumerate() {
        if !value.is_finite() {
            return Err(Error::NonFiniteTime { track: id.clone(), key, value });
        }
        if key > 0 && value <= times[key - 1] {
            return Err(Error::TimesNotIncreasing { track: id.clone(), key, value, previous: times[key - 1] });
        }
    }
    Ok(times.to_vec())
}
