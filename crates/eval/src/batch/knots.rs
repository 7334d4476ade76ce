//! Knot vectors: the full knot vector of a B-spline for each knot mode (shared with the
//! Euclidean analogue, so both use one basis), the uniform-times rule, explicit knots checked.

use crate::error::{Error, Result, TrackId};
use quatcurve_core::curve::{CurveSpec, KnotMode, MAX_ORDER, MIN_ORDER};

/// Relative tolerance on key spacing for knot modes that need uniform times.
pub const UNIFORM_TIME_TOLERANCE: f64 = 1e-3;

/// Relative spacing tolerance of [`knots_are_uniform`].
pub const UNIFORM_KNOT_TOLERANCE: f64 = 1e-9;

/// Whether a knot vector is equally spaced (to [`UNIFORM_KNOT_TOLERANCE`]).
#[must_use]
pub fn knots_are_uniform(knots: &[f64]) -> bool {
    let n = knots.len();
    if n < 2 || knots[n - 1] <= knots[0] {
        return false;
    }
    let dt = (knots[n - 1] - knots[0]) / (n - 1) as f64;
    knots.windows(2).all(|w| ((w[1] - w[0]) - dt).abs() <= UNIFORM_KNOT_TOLERANCE * dt)
}

/// Checks `|tau_i - tau_0 - i dt| <= UNIFORM_TIME_TOLERANCE dt` (DESIGN section 3).
fn check_uniform(id: &TrackId, times: &[f64], mode: KnotMode) -> Result<()> {
    let n = times.len() - 1;
    let dt = (times[n] - times[0]) / n as f64;
    for (key, &value) in times.iter().enumerate() {
        let expected = times[0] + key as f64 * dt;
        if (value - expected).abs() > UNIFORM_TIME_TOLERANCE * dt {
            return Err(Error::NonUniformTimes {
                track: id.clone(),
                key,
                value,
                expected,
                mode: mode.to_string(),
                tolerance: UNIFORM_TIME_TOLERANCE,
            });
        }
    }
    Ok(())
}

/// `a + (b - a) s` written so that `s = 0` gives `a` and `s = 1` gives `b` exactly.
fn lerp(a: f64, b: f64, s: f64) -> f64 {
    a * (1.0 - s) + b * s
}

/// The full knot vector of a B-spline through `times.len()` keys (DESIGN section 3): phantom
/// knots cover the two phantom control points too (`n + 7` knots), the other modes `n + k + 1`.
/// Shared with the Euclidean analogue ([`crate::euclidean`]), so both use the same basis.
pub(crate) fn bspline_knots(
    id: &TrackId,
    explicit: Option<&[f64]>,
    spec: &CurveSpec,
    times: &[f64],
) -> Result<Vec<f64>> {
    let k = spec.order;
    check_order(id, k)?;
    let n = times.len() - 1;
    let (t0, tn) = (times[0], times[n]);
    Ok(match spec.knots {
        KnotMode::Phantom => {
            if k != 4 {
                return Err(Error::BadOrder {
                    track: id.clone(),
                    reason: format!(
                        "phantom knots are defined for order 4 only, not {k}; use uniform, clamped or explicit"
                    ),
                });
            }
            check_uniform(id, times, spec.knots)?;
            // Control points c_0..c_{n+2}; knots t_j = tau_0 + (j - 3) dt, j = 0..=n+6.
            (0..n + 7).map(|j| lerp(t0, tn, (j as f64 - 3.0) / n as f64)).collect()
        }
        KnotMode::Uniform => {
            check_uniform(id, times, spec.knots)?;
            (0..=n + k).map(|j| lerp(t0, tn, (j as f64 - (k as f64 - 1.0)) / n as f64)).collect()
        }
        KnotMode::Clamped => {
            let inner = n + 2 - k;
            let mut knots = vec![t0; k];
            knots.extend((1..inner).map(|j| lerp(t0, tn, j as f64 / inner as f64)));
            knots.extend(std::iter::repeat(tn).take(k));
            knots
        }
        KnotMode::Explicit => {
            let knots = explicit.unwrap_or(&[]);
            check_explicit_knots(id, knots, k, n)?;
            knots.to_vec()
        }
    })
}

/// A B-spline order within [`MIN_ORDER`]`..=`[`MAX_ORDER`].
pub(super) fn check_order(id: &TrackId, k: usize) -> Result<()> {
    if !(MIN_ORDER..=MAX_ORDER).contains(&k) {
        return Err(Error::BadOrder {
            track: id.clone(),
            reason: format!("bspline order {k} is outside {MIN_ORDER}..={MAX_ORDER}"),
        });
    }
    Ok(())
}

/// Validates a user knot vector for `n + 1` control points of order `k`: length n + k + 1,
/// finite, non-decreasing, multiplicity at most k - 1 strictly inside the domain and at most k
/// elsewhere, non-empty domain.
pub(super) fn check_explicit_knots(id: &TrackId, knots: &[f64], k: usize, n: usize) -> Result<()> {
    let expected = n + k + 1;
    if knots.len() != expected {
        return Err(Error::KnotCount { track: id.clone(), order: k, keys: n + 1, expected, found: knots.len() });
    }
    for (knot, &value) in knots.iter().enumerate() {
        if !value.is_finite() {
            return Err(Error::NonFiniteKnot { track: id.clone(), knot, value });
        }
        if knot > 0 && value < knots[knot - 1] {
            return Err(Error::KnotsDecreasing { track: id.clone(), knot, value, previous: knots[knot - 1] });
        }
    }
    let (start, end) = (knots[k - 1], knots[n + 1]);
    if start >= end {
        return Err(Error::EmptyDomain { track: id.clone(), first: k - 1, last: n + 1, start, end });
    }
    let mut run_start = 0;
    for knot in 1..=knots.len() {
        if knot < knots.len() && knots[knot] == knots[run_start] {
            continue;
        }
        let multiplicity = knot - run_start;
        // A knot on its own is within every bound (k - 1 >= 1): only runs are looked at.
        if multiplicity > 1 {
            let value = knots[run_start];
            let inside = value > start && value < end;
            let (max, place) = if inside { (k - 1, "inside the domain") } else { (k, "at or outside the domain ends") };
            if multiplicity > max {
                return Err(Error::KnotMultiplicity {
                    track: id.clone(),
                    knot: run_start,
                    value,
                    multiplicity,
                    max,
                    order: k,
                    place,
                });
            }
        }
        run_start = knot;
    }
    Ok(())
}
