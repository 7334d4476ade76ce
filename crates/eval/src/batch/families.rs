//! Per-family preparation (DESIGN section 3): from checked keys and times to what the
//! evaluators read, once, in f64: the log-coefficients `w_i`, squad's auxiliary points,
//! tangents, Hermite's three coefficients per segment, B-spline control points with their
//! phantom points and knots, and the solved `bspline-interp` curve. Squad's points and
//! Catmull-Rom velocities are written once over [`Space`], for rotations and for the
//! Euclidean analogue.

use super::keys::{aligned_keys, check_loop, key_times};
use super::knots::bspline_knots;
use crate::error::{Error, Result, TrackId};
use crate::track::Track;
use quatcurve_core::curve::{Curve, CurveSpec, KnotMode, Tangents};
use quatcurve_core::interp;
use quatcurve_core::quat::{relative_log, QuatF64, Vec3F64};
use std::f64::consts::PI;

/// Below this length Hermite's middle coefficient has no axis for extra turns.
pub const MIN_TURN_AXIS: f64 = 1e-12;

/// One track's packed data before it is appended.
pub(super) struct PackedData {
    /// The family evaluators run (`bspline` for `bspline-interp`).
    pub(super) curve: Curve,
    /// B-spline order (0 for other families).
    pub(super) order: usize,
    /// Bezier degree (0 for other families).
    pub(super) bezier_degree: usize,
    pub(super) points: Vec<QuatF64>,
    pub(super) coefs: Vec<[f64; 4]>,
    pub(super) knots: Vec<f64>,
    pub(super) domain: [f64; 2],
}

/// Validates each `(id, track, spec)` and computes its packed data (DESIGN section 3), in
/// f64, in order: the `bspline-interp` tracks' solves go to [`interp::solve_rotations_batch`]
/// together, so that tracks of one shape share SIMD lanes.
pub(super) fn prepare_all(items: &[(TrackId, &Track, CurveSpec)]) -> Vec<Result<PackedData>> {
    let checked: Vec<Result<(Vec<QuatF64>, Vec<f64>)>> =
        items.iter().map(|(id, track, spec)| check(id, track, spec)).collect();
    let solving = |(item, checked): (&(TrackId, &Track, CurveSpec), &Result<_>)| {
        item.2.curve == Curve::BSplineInterp && checked.is_ok()
    };
    let problems: Vec<interp::Problem> = items
        .iter()
        .zip(&checked)
        .filter(|&pair| solving(pair))
        .map(|(item, checked)| {
            let (keys, times) = checked.as_ref().expect("only checked tracks are solved");
            interp::Problem { keys, times, periodic: item.2.looping }
        })
        .collect();
    let mut solved = interp::solve_rotations_batch(&problems).into_iter();
    items
        .iter()
        .zip(checked)
        .map(|(item, checked)| {
            let solving = solving((item, &checked));
            let (keys, times) = checked?;
            let (id, track, spec) = item;
            pack(id, track, spec, keys, times, if solving { solved.next() } else { None })
        })
        .collect()
}

/// The keys of `track` aligned into one hemisphere and its key times, checked for `spec`.
fn check(id: &TrackId, track: &Track, spec: &CurveSpec) -> Result<(Vec<QuatF64>, Vec<f64>)> {
    let keys = aligned_keys(id, &track.rotations, spec)?;
    let times = key_times(id, track.times.as_deref(), keys.len())?;
    if spec.looping {
        check_loop(id, spec, &keys)?;
    }
    Ok((keys, times))
}

/// The packed data of checked keys and times; `solved` is a `bspline-interp` track's solve.
fn pack(
    id: &TrackId,
    track: &Track,
    spec: &CurveSpec,
    keys: Vec<QuatF64>,
    times: Vec<f64>,
    solved: Option<std::result::Result<interp::Solved, interp::NoConvergence>>,
) -> Result<PackedData> {
    let n = keys.len() - 1;
    let (t0, tn) = (times[0], times[n]);
    let vec_coef = |v: Vec3F64| [v.x, v.y, v.z, 0.0];
    let steps = || (1..=n).map(|i| vec_coef(relative_log(keys[i - 1], keys[i])));
    let piecewise = |coefs: Vec<[f64; 4]>, points: Vec<QuatF64>| PackedData {
        curve: spec.curve,
        order: 0,
        bezier_degree: 0,
        coefs,
        points,
        knots: times.clone(),
        domain: [t0, tn],
    };
    Ok(match spec.curve {
        Curve::Slerp => piecewise(steps().collect(), keys),
        Curve::Bezier => PackedData {
            curve: spec.curve,
            order: 0,
            bezier_degree: n,
            coefs: steps().collect(),
            points: keys,
            knots: vec![t0, tn],
            domain: [t0, tn],
        },
        Curve::Squad => piecewise(squad_points(&keys, spec.looping).into_iter().map(QuatF64::to_array).collect(), keys),
        Curve::Hermite => {
            let omega = key_velocities(id, track, spec, &keys, &times)?;
            let coefs = hermite_coefs(id, track, &keys, &times, &omega)?;
            piecewise(coefs, keys)
        }
        Curve::NamKim => {
            let omega = key_velocities(id, track, spec, &keys, &times)?;
            let coefs = (0..n)
                .flat_map(|i| {
                    let half_t = 0.5 * (times[i + 1] - times[i]);
                    [vec_coef(omega[i].scale(half_t)), vec_coef(omega[i + 1].scale(half_t))]
                })
                .collect();
            piecewise(coefs, keys)
        }
        Curve::BSpline | Curve::NormalizedBSpline => bspline(id, track, spec, keys, &times)?,
        Curve::BSplineInterp => {
            let solved = solved.expect("prepare_all solves every bspline-interp track");
            let solved = solved.map_err(|e| Error::NoConvergence {
                track: id.clone(),
                key: e.worst_key,
                error: e.error,
                iterations: e.iterations,
                tolerance: interp::KEY_TOLERANCE,
            })?;
            let coefs = solved.coefs.into_iter().map(vec_coef).collect();
            PackedData {
                curve: Curve::BSpline,
                order: 4,
                bezier_degree: 0,
                points: solved.points,
                coefs,
                knots: solved.knots,
                domain: [t0, tn],
            }
        }
    })
}

/// What the per-family preparation needs of the space keys live in: unit quaternions for
/// rotations, `R^3` for translations and scales (the Euclidean analogue, KKS section 1), so
/// that squad's points and Catmull-Rom velocities are written once for both.
pub(crate) trait Space: Copy {
    /// Velocity per unit of [`Space::step`] per unit time: 2 for rotations, whose logs are
    /// half angles (DESIGN section 1), 1 for vectors.
    const RATE: f64;
    /// The step from `a` to `b`: `log(a^-1 b)` the short way, or `b - a`.
    fn step(a: Self, b: Self) -> Vec3F64;
    /// `a` moved by `v`: `a exp(v)`, or `a + v`.
    fn moved(a: Self, v: Vec3F64) -> Self;
}

impl Space for QuatF64 {
    const RATE: f64 = 2.0;
    fn step(a: Self, b: Self) -> Vec3F64 {
        relative_log(a, b)
    }
    fn moved(a: Self, v: Vec3F64) -> Self {
        a * QuatF64::exp(v)
    }
}

impl Space for Vec3F64 {
    const RATE: f64 = 1.0;
    fn step(a: Self, b: Self) -> Vec3F64 {
        b - a
    }
    fn moved(a: Self, v: Vec3F64) -> Self {
        a + v
    }
}

/// Squad's auxiliary points `s_i = q_i exp(-(log(q_i^-1 q_{i+1}) + log(q_i^-1 q_{i-1})) / 4)`
/// (P eq. 19; for vectors `p_i - ((p_{i+1} - p_i) + (p_{i-1} - p_i)) / 4`), with `s_0 = q_0`
/// and `s_n = q_n`; looping, `s_0` uses `q_{n-1}` before it and `s_n` is `q_n` moved by the
/// same offset, so both sides of the seam agree.
pub(crate) fn squad_points<S: Space>(keys: &[S], looping: bool) -> Vec<S> {
    let n = keys.len() - 1;
    let offset = |i: usize, prev: S, next: S| (S::step(keys[i], next) + S::step(keys[i], prev)).scale(-0.25);
    let seam = looping.then(|| offset(0, keys[n - 1], keys[1]));
    (0..=n)
        .map(|i| {
            if i == 0 || i == n {
                return seam.map_or(keys[i], |v| S::moved(keys[i], v));
            }
            S::moved(keys[i], offset(i, keys[i - 1], keys[i + 1]))
        })
        .collect()
}

/// The non-uniform Catmull-Rom velocity at `key` from its neighbours `prev` (`d0` before) and
/// `next` (`d1` after), DESIGN section 3 (for rotations the body angular velocity).
fn catmull_rom<S: Space>(key: S, prev: S, next: S, d0: f64, d1: f64) -> Vec3F64 {
    let back = -S::step(key, prev).scale(1.0 / d0);
    let ahead = S::step(key, next).scale(1.0 / d1);
    (back.scale(d1 / (d0 + d1)) + ahead.scale(d0 / (d0 + d1))).scale(S::RATE)
}

/// Catmull-Rom velocities at every key, one-sided at the ends; across a loop's seam key 0
/// sees key n-1 before it (`d_{-1} = d_{n-1}`) and key n takes the same velocity, so both
/// sides of the seam agree.
pub(crate) fn catmull_rom_velocities<S: Space>(keys: &[S], times: &[f64], looping: bool) -> Vec<Vec3F64> {
    let n = keys.len() - 1;
    let seam =
        looping.then(|| catmull_rom(keys[0], keys[n - 1], keys[1], times[n] - times[n - 1], times[1] - times[0]));
    (0..=n)
        .map(|i| match seam {
            Some(v) if i == 0 || i == n => v,
            _ if i == 0 => S::step(keys[0], keys[1]).scale(S::RATE / (times[1] - times[0])),
            _ if i == n => S::step(keys[n - 1], keys[n]).scale(S::RATE / (times[n] - times[n - 1])),
            _ => catmull_rom(keys[i], keys[i - 1], keys[i + 1], times[i] - times[i - 1], times[i + 1] - times[i]),
        })
        .collect()
}

/// Body angular velocity (rad/s) at each key, from the chosen source (DESIGN section 3).
fn key_velocities(
    id: &TrackId,
    track: &Track,
    spec: &CurveSpec,
    keys: &[QuatF64],
    times: &[f64],
) -> Result<Vec<Vec3F64>> {
    let n = keys.len() - 1;
    match spec.tangents {
        Tangents::Zero => Ok(vec![Vec3F64::zero(); n + 1]),
        Tangents::Given => {
            let given = track.angular_velocities.as_deref().unwrap_or(&[]);
            if given.len() != n + 1 {
                return Err(Error::VelocityCount { track: id.clone(), expected: n + 1, found: given.len() });
            }
            given
                .iter()
                .enumerate()
                .map(|(key, &value)| {
                    if value.iter().all(|c| c.is_finite()) {
                        Ok(Vec3F64::from_array(value))
                    } else {
                        Err(Error::NonFiniteVelocity { track: id.clone(), key, value })
                    }
                })
                .collect()
        }
        Tangents::CatmullRom => Ok(catmull_rom_velocities(keys, times, spec.looping)),
    }
}

/// KKS section 5.2 per segment: `w1 = w_a/3`, `w3 = w_b/3` used as given (never folded), and
/// `w2 = log(q_1^-1 q_2)` with `q_1 = q_a exp(w1)`, `q_2 = q_b exp(-w3)` folded to the short
/// way, plus `pi * m` along its axis for `m` extra turns.
///
/// When the fold negates `q_2`, the segment's product runs from `q_a` to `-q_b`. To keep the
/// output sign-continuous, segment `i` starts from `sigma_i q_i` where `sigma_i` is the product
/// of the fold signs of segments `0..i`, stored in `w2`'s fourth slot. Rotations are unchanged.
fn hermite_coefs(
    id: &TrackId,
    track: &Track,
    keys: &[QuatF64],
    times: &[f64],
    omega: &[Vec3F64],
) -> Result<Vec<[f64; 4]>> {
    let n = keys.len() - 1;
    let turns = match &track.extra_turns {
        Some(turns) if turns.len() != n => {
            return Err(Error::ExtraTurnsCount { track: id.clone(), expected: n, found: turns.len() })
        }
        Some(turns) => turns.clone(),
        None => vec![0; n],
    };
    let mut coefs = Vec::with_capacity(3 * n);
    let mut start_sign = 1.0;
    for i in 0..n {
        let half_t = 0.5 * (times[i + 1] - times[i]);
        let w1 = omega[i].scale(half_t / 3.0);
        let w3 = omega[i + 1].scale(half_t / 3.0);
        let q1 = keys[i] * QuatF64::exp(w1);
        let q2 = keys[i + 1] * QuatF64::exp(-w3);
        let sign = if q1.dot(q2) < 0.0 { -1.0 } else { 1.0 };
        let mut w2 = (q1.conjugate() * q2.mul_scalar(sign)).log();
        if turns[i] != 0 {
            let len = w2.length();
            if len < MIN_TURN_AXIS {
                return Err(Error::ExtraTurnOnZeroArc { track: id.clone(), segment: i, turns: turns[i] });
            }
            w2 = w2 + w2.scale(PI * turns[i] as f64 / len);
        }
        coefs.push([w1.x, w1.y, w1.z, 0.0]);
        coefs.push([w2.x, w2.y, w2.z, start_sign]);
        coefs.push([w3.x, w3.y, w3.z, 0.0]);
        start_sign *= sign;
    }
    Ok(coefs)
}

/// Control points, knot vector and coefficients of a B-spline track (DESIGN section 3).
fn bspline(id: &TrackId, track: &Track, spec: &CurveSpec, keys: Vec<QuatF64>, times: &[f64]) -> Result<PackedData> {
    let k = spec.order;
    let knots = bspline_knots(id, track.knots.as_deref(), spec, times)?;
    let points = if spec.knots == KnotMode::Phantom {
        // q_-1 = q_0 q_1^-1 q_0 and q_{n+1} = q_n q_{n-1}^-1 q_n: the key steps mirrored; or,
        // looping, the neighbours across the seam carried over it: q_-1 = q_0 q_n^-1 q_{n-1}
        // and q_{n+1} = q_n q_0^-1 q_1 (key n-1 and key 1 when the keys close exactly).
        let n = keys.len() - 1;
        let (first, last) = if spec.looping {
            (keys[0] * keys[n].conjugate() * keys[n - 1], keys[n] * keys[0].conjugate() * keys[1])
        } else {
            (keys[0] * keys[1].conjugate() * keys[0], keys[n] * keys[n - 1].conjugate() * keys[n])
        };
        let mut points = Vec::with_capacity(n + 3);
        points.push(first);
        points.extend_from_slice(&keys);
        points.push(last);
        points
    } else {
        keys
    };
    let m = points.len() - 1;
    let domain = [knots[k - 1], knots[m + 1]];
    if spec.curve == Curve::NormalizedBSpline {
        check_half_turns(id, spec, &points)?;
        return Ok(PackedData {
            curve: spec.curve,
            order: k,
            bezier_degree: 0,
            points,
            coefs: Vec::new(),
            knots,
            domain,
        });
    }
    let mut coefs: Vec<[f64; 4]> = (1..=m)
        .map(|i| {
            let w = relative_log(points[i - 1], points[i]);
            [w.x, w.y, w.z, 0.0]
        })
        .collect();
    if spec.knots == KnotMode::Phantom && !spec.looping {
        // q_-1^-1 q_0 = q_0^-1 q_1 exactly (and likewise at the end): reuse the key's
        // coefficient so the curve passes through q_0 and q_n to rounding.
        coefs[0] = coefs[1];
        coefs[m - 1] = coefs[m - 2];
    }
    Ok(PackedData { curve: Curve::BSpline, order: k, bezier_degree: 0, points, coefs, knots, domain })
}

/// A normalized B-spline's rule (DESIGN section 3): every two control points of a span (`k` in
/// a row) less than a half turn apart (a positive dot product). Then every term of `|sum B_i
/// c_i|^2 = sum B_i B_j (c_i . c_j)` is at least 0 and the diagonal's sum at least `1 / k`, so
/// the sum never comes nearer zero than `1 / sqrt k`; beyond it the sum can vanish, and the
/// direction it normalizes to means nothing.
fn check_half_turns(id: &TrackId, spec: &CurveSpec, points: &[QuatF64]) -> Result<()> {
    for (j, &b) in points.iter().enumerate() {
        let from = j.saturating_sub(spec.order - 1);
        for (i, &a) in points[from..j].iter().enumerate() {
            check_half_turn(id, spec, (from + i, a), (j, b))?;
        }
    }
    Ok(())
}

/// [`check_half_turns`] for control points `i` and `j` of one span; the packers of tracks and of
/// splines (`BatchBuilder::extend_splines`) take the pairs in the same order (each point against
/// those before it), so that both name the same pair.
pub(super) fn check_half_turn(
    id: &TrackId,
    spec: &CurveSpec,
    (i, a): (usize, QuatF64),
    (j, b): (usize, QuatF64),
) -> Result<()> {
    if a.dot(b) > 0.0 {
        return Ok(());
    }
    Err(Error::ControlPointsApart {
        track: id.clone(),
        first: i,
        second: j,
        // The turn from one to the other along the aligned control points, at least a half
        // turn here (`angle_to` measures the shorter way round).
        angle: 2.0 * a.dot(b).clamp(-1.0, 1.0).acos(),
        phantom: spec.knots == KnotMode::Phantom,
        order: spec.order,
    })
}
