//! When every key rotates about one fixed axis, each KKS family is `exp(phi(t) u)` where
//! `phi` is the scalar spline of the key half-angles with the same basis (KKS section 4); the
//! normalized B-spline is `exp(phi(t) u)` with `phi` the angle of the plain splines of the
//! half angles' cosines and sines.
//! The scalar splines here are independent textbook algorithms (de Casteljau, de Boor,
//! cubic Hermite), not the crate's cumulative bases.

use crate::common::Gen;
use proptest::prelude::*;
use quatcurve::{Batch, Curve, CurveSpec, KnotMode, QuatF64, Tangents, Track};

fn de_casteljau(points: &[f64], u: f64) -> f64 {
    let mut p = points.to_vec();
    for r in 1..p.len() {
        for j in 0..p.len() - r {
            p[j] = (1.0 - u) * p[j] + u * p[j + 1];
        }
    }
    p[0]
}

/// de Boor's algorithm for a scalar B-spline of order `k` on `knots` (domain
/// `[knots[k-1], knots[n+1]]`, last span closed).
fn de_boor(points: &[f64], knots: &[f64], k: usize, t: f64) -> f64 {
    let n = points.len() - 1;
    let p = k - 1;
    let mut l = k - 1;
    for j in (k - 1)..=n {
        if knots[j] <= t && knots[j] < knots[j + 1] {
            l = j;
        }
    }
    let mut d: Vec<f64> = (0..=p).map(|j| points[j + l - p]).collect();
    for r in 1..=p {
        for j in (r..=p).rev() {
            let a = (t - knots[j + l - p]) / (knots[j + 1 + l - r] - knots[j + l - p]);
            d[j] = (1.0 - a) * d[j - 1] + a * d[j];
        }
    }
    d[p]
}

fn hermite(p0: f64, p1: f64, m0: f64, m1: f64, len: f64, u: f64) -> f64 {
    let (u2, u3) = (u * u, u * u * u);
    (2.0 * u3 - 3.0 * u2 + 1.0) * p0
        + (u3 - 2.0 * u2 + u) * len * m0
        + (-2.0 * u3 + 3.0 * u2) * p1
        + (u3 - u2) * len * m1
}

/// The scalar spline of `phi` for `spec`, as DESIGN section 3 defines the time parameterization.
fn scalar_curve(spec: &CurveSpec, phi: &[f64], times: &[f64], rates: &[f64], knots: Option<&[f64]>, t: f64) -> f64 {
    let n = phi.len() - 1;
    let (t0, tn) = (times[0], times[n]);
    let seg = |t: f64| (0..n).rev().find(|&i| times[i] <= t).unwrap_or(0);
    match spec.curve {
        Curve::Slerp => {
            let i = seg(t);
            let u = (t - times[i]) / (times[i + 1] - times[i]);
            phi[i] + u * (phi[i + 1] - phi[i])
        }
        Curve::Bezier => de_casteljau(phi, (t - t0) / (tn - t0)),
        Curve::Hermite => {
            let i = seg(t);
            let len = times[i + 1] - times[i];
            hermite(phi[i], phi[i + 1], rates[i], rates[i + 1], len, (t - times[i]) / len)
        }
        Curve::BSpline | Curve::NormalizedBSpline => {
            let k = spec.order;
            let dt = (tn - t0) / n as f64;
            // The control points' half angles and the knot vector.
            let (controls, kv): (Vec<f64>, Vec<f64>) = match spec.knots {
                KnotMode::Phantom => {
                    let mut c = vec![2.0 * phi[0] - phi[1]];
                    c.extend_from_slice(phi);
                    c.push(2.0 * phi[n] - phi[n - 1]);
                    (c, (0..n + 7).map(|j| t0 + (j as f64 - 3.0) * dt).collect())
                }
                KnotMode::Uniform => {
                    (phi.to_vec(), (0..=n + k).map(|j| t0 + (j as f64 - (k as f64 - 1.0)) * dt).collect())
                }
                KnotMode::Clamped => {
                    let inner = n + 2 - k;
                    let mut kv = vec![t0; k];
                    kv.extend((1..inner).map(|j| t0 + j as f64 * (tn - t0) / inner as f64));
                    kv.extend(vec![tn; k]);
                    (phi.to_vec(), kv)
                }
                KnotMode::Explicit => (phi.to_vec(), knots.unwrap().to_vec()),
            };
            if spec.curve == Curve::BSpline {
                de_boor(&controls, &kv, k, t)
            } else {
                // The components (cos, sin u) summed, then normalized: the angle of the sums.
                let sines: Vec<f64> = controls.iter().map(|a| a.sin()).collect();
                let cosines: Vec<f64> = controls.iter().map(|a| a.cos()).collect();
                de_boor(&sines, &kv, k, t).atan2(de_boor(&cosines, &kv, k, t))
            }
        }
        Curve::Squad | Curve::NamKim => unreachable!("not KKS families"),
        Curve::BSplineInterp => unreachable!("checked against its own scalar twin in interp.rs"),
    }
}

fn check(seed: u64, spec: CurveSpec) -> Result<(), TestCaseError> {
    let mut g = Gen::new(seed);
    let count = spec.min_keys().max(2) + (g.next_u64() % 6) as usize;
    let count = if spec.curve == Curve::Bezier { count.min(9) } else { count };
    let axis = g.direction();
    // A normalized B-spline's span (k control points) must turn by less than a half turn:
    // half angles within a quarter turn.
    let step = if spec.curve == Curve::NormalizedBSpline { 1.5 / (spec.order - 1) as f64 } else { 1.4 };
    let mut phi = vec![g.range(-3.0, 3.0)];
    for _ in 1..count {
        let last = *phi.last().unwrap();
        phi.push(last + g.range(-step, step));
    }
    let uniform = matches!(spec.curve, Curve::BSpline | Curve::NormalizedBSpline)
        && matches!(spec.knots, KnotMode::Phantom | KnotMode::Uniform);
    let times = crate::common::times(&mut g, count, uniform);
    // Hermite reaches the scalar middle step with extra turns about w2's axis; that axis is
    // only defined to ~eps / |w2|, so draw rates that keep the folded step above 0.01 rad.
    let folded_step = |rates: &[f64], i: usize| {
        let delta = phi[i + 1] - phi[i] - (times[i + 1] - times[i]) * (rates[i] + rates[i + 1]) / 3.0;
        delta - (delta / std::f64::consts::PI).round() * std::f64::consts::PI
    };
    let mut rates: Vec<f64> = (0..count).map(|_| g.range(-10.0, 10.0)).collect();
    while (0..count - 1).any(|i| folded_step(&rates, i).abs() < 0.01) {
        rates = (0..count).map(|_| g.range(-10.0, 10.0)).collect();
    }
    let knots = (spec.knots == KnotMode::Explicit).then(|| crate::common::explicit_knots(&mut g, spec.order, count));
    let track = Track {
        name: Some("axis".into()),
        times: Some(times.clone()),
        // Some keys given with the opposite sign: alignment must undo it.
        rotations: phi
            .iter()
            .map(|&p| QuatF64::exp(axis.scale(p)).mul_scalar(if g.coin() { -1.0 } else { 1.0 }).to_array())
            .collect(),
        angular_velocities: Some(rates.iter().map(|&r| axis.scale(2.0 * r).to_array()).collect()),
        knots: knots.clone(),
        ..Track::default()
    };
    // KKS Hermite folds w2 into (-pi/2, pi/2]; the scalar Hermite's middle step
    // Delta = phi_1 - phi_0 - T (m_0 + m_1) / 3 is reached with the matching extra turns.
    let track = if spec.curve == Curve::Hermite {
        let turns = (0..count - 1)
            .map(|i| {
                let len = times[i + 1] - times[i];
                let delta = phi[i + 1] - phi[i] - len * (rates[i] + rates[i + 1]) / 3.0;
                let m = (delta / std::f64::consts::PI).round();
                (m * folded_step(&rates, i).signum()) as i64
            })
            .collect();
        Track { extra_turns: Some(turns), ..track }
    } else {
        track
    };
    let batch = Batch::from_tracks(&[track], &spec).unwrap();
    let [lo, hi] = batch.tracks()[0].domain();
    for i in 0..=200 {
        let t = lo + (hi - lo) * i as f64 / 200.0;
        let q = quatcurve::evaluate(batch.view(0), t).rotation;
        let scalar = scalar_curve(&spec, &phi, &times, &rates, knots.as_deref(), t);
        let expected = QuatF64::exp(axis.scale(scalar));
        let err = q.angle_to(expected);
        prop_assert!(err < 1e-12, "{spec:?}: t={t} off the scalar spline by {err:e} rad");
    }
    Ok(())
}

fn axis_specs() -> Vec<CurveSpec> {
    let mut specs = vec![
        CurveSpec::new(Curve::Slerp),
        CurveSpec::new(Curve::Bezier),
        CurveSpec { tangents: Tangents::Given, ..CurveSpec::new(Curve::Hermite) },
        CurveSpec::new(Curve::BSpline),
    ];
    for order in 2..=8 {
        for knots in [KnotMode::Uniform, KnotMode::Clamped, KnotMode::Explicit] {
            specs.push(CurveSpec { order, knots, ..CurveSpec::new(Curve::BSpline) });
        }
    }
    specs.extend(crate::common::all_specs().into_iter().filter(|s| s.curve == Curve::NormalizedBSpline));
    specs
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn families_about_one_axis_equal_their_scalar_splines(seed in any::<u64>()) {
        for spec in axis_specs() {
            check(seed, spec)?;
        }
    }
}
