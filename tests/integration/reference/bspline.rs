//! B-spline structure: C^(k-2) continuity across knots, local control, phantom end points.

use crate::common::*;
use quatcurve::{Batch, Curve, CurveSpec, KnotMode, QuatF64, Track, Vec3F64};

fn spec(order: usize, knots: KnotMode) -> CurveSpec {
    CurveSpec { order, knots, ..CurveSpec::new(Curve::BSpline) }
}

/// Jumps of rotation, omega, alpha and (by one-sided differences of alpha) the third
/// derivative across an interior knot `t`, measured from both sides.
fn jumps(batch: &Batch, t: f64, h: f64) -> [f64; 4] {
    let left = |dt: f64| eval(batch, 0, t - dt);
    let right = |dt: f64| eval(batch, 0, t + dt);
    // Left limit: evaluate a hair before the knot and extrapolate linearly (error O(eps^2)).
    let eps = 1e-7 * h;
    let (l0, l1) = (left(eps), left(2.0 * eps));
    let r0 = eval(batch, 0, t);
    // Continuous: the angle across the knot equals the angle over the previous step of eps.
    let rot = (l0.rotation.angle_to(r0.rotation) - l1.rotation.angle_to(l0.rotation)).abs();
    let extrapolate = |a: Vec3F64, b: Vec3F64| a.scale(2.0) - b;
    let omega = (extrapolate(l0.angular_velocity, l1.angular_velocity) - r0.angular_velocity).max_abs();
    let alpha = (extrapolate(l0.angular_acceleration, l1.angular_acceleration) - r0.angular_acceleration).max_abs();
    // Third derivative from each side: second-order one-sided differences of alpha.
    let one_sided = |f: &dyn Fn(f64) -> quatcurve::Sample, sign: f64| {
        let (a0, a1, a2) =
            (f(1e-9 * h).angular_acceleration, f(h).angular_acceleration, f(2.0 * h).angular_acceleration);
        (a1.scale(4.0) - a0.scale(3.0) - a2).scale(sign / (2.0 * h))
    };
    let third = (one_sided(&left, -1.0) - one_sided(&right, 1.0)).max_abs();
    [rot, omega, alpha, third]
}

#[test]
fn continuity_is_c_k_minus_2_across_every_knot() {
    // Derivatives up to order k-2 must match (measured up to the third); the first derivative
    // that may jump (order k-1) must actually jump somewhere, or the test could not fail.
    let mut worst = [0.0f64; 4];
    for seed in 0..12 {
        for order in 2..=8 {
            for knots in [KnotMode::Uniform, KnotMode::Clamped, KnotMode::Explicit] {
                let s = spec(order, knots);
                let mut g = Gen::new(seed);
                let count = order + 4;
                let mut track = track(&mut g, &s, count, Kind::Random);
                if knots == KnotMode::Explicit {
                    // Simple interior knots here: repeated knots lower continuity by design.
                    let mut t = 0.0;
                    track.knots = Some(
                        (0..count + order)
                            .map(|_| {
                                t += g.range(0.3, 1.0);
                                t
                            })
                            .collect(),
                    );
                }
                let batch = Batch::from_tracks(&[track], &s).unwrap();
                let view = batch.view(0);
                let [lo, hi] = view.track.domain();
                let interior: Vec<f64> = view.knots.iter().copied().filter(|&t| t > lo && t < hi).collect();
                let mut saw_jump = false;
                for &t in &interior {
                    let j = jumps(&batch, t, 1e-3);
                    let scale = 1.0 + eval(&batch, 0, t).angular_acceleration.max_abs();
                    let limits = [1e-9, 1e-6 * scale, 1e-5 * scale, 1e-3 * scale * 10.0];
                    for d in 0..4 {
                        if d + 2 <= order {
                            assert!(
                                j[d] < limits[d],
                                "order {order} {knots:?} seed {seed}: derivative {d} jumps by {} at knot {t}",
                                j[d]
                            );
                            worst[d] = worst[d].max(j[d] / limits[d]);
                        }
                    }
                    if order - 1 <= 3 && j[order - 1] > 10.0 * limits[order - 1] {
                        saw_jump = true;
                    }
                }
                if order <= 4 && !interior.is_empty() {
                    assert!(
                        saw_jump,
                        "order {order} {knots:?}: derivative {} never jumps; the measurement is blind",
                        order - 1
                    );
                }
            }
        }
    }
    eprintln!("continuity: worst jump / limit per derivative order 0..3 = {worst:?}");
}

#[test]
fn moving_one_control_point_changes_only_its_support() {
    for seed in 0..10 {
        for order in 2..=8 {
            for knots in [KnotMode::Phantom, KnotMode::Uniform, KnotMode::Clamped, KnotMode::Explicit] {
                if knots == KnotMode::Phantom && order != 4 {
                    continue;
                }
                let s = spec(order, knots);
                let mut g = Gen::new(seed + 100);
                let count = order + 5;
                let track = track(&mut g, &s, count, Kind::Random);
                let base = Batch::from_tracks(std::slice::from_ref(&track), &s).unwrap();
                let key = 1 + (g.next_u64() as usize) % (count - 2);
                let mut moved = track.clone();
                let nudge = QuatF64::exp(g.direction().scale(0.05));
                moved.rotations[key] = (QuatF64::from_array(track.rotations[key]) * nudge).to_array();
                let other = Batch::from_tracks(&[moved], &s).unwrap();
                // Control point index of the key: phantom mode prepends one point.
                let l = if knots == KnotMode::Phantom { key + 1 } else { key };
                let kv = base.view(0).knots;
                let (support_lo, support_hi) = (kv[l], kv[l + order]);
                let [lo, hi] = base.tracks()[0].domain();
                let mut changed_inside = false;
                for i in 0..=400 {
                    let t = lo + (hi - lo) * i as f64 / 400.0;
                    let diff = eval(&base, 0, t).rotation.angle_to(eval(&other, 0, t).rotation);
                    if t < support_lo - 1e-9 || t > support_hi + 1e-9 {
                        assert_eq!(
                            diff, 0.0,
                            "order {order} {knots:?}: key {key} moved the curve at t={t}, outside \
                            [{support_lo}, {support_hi}]"
                        );
                    } else if diff > 1e-6 {
                        changed_inside = true;
                    }
                }
                // Repeated knots can leave no part of the support inside the domain.
                if support_lo.max(lo) < support_hi.min(hi) {
                    assert!(changed_inside, "order {order} {knots:?}: moving key {key} changed nothing");
                }
            }
        }
    }
}

#[test]
fn phantom_mode_passes_through_the_end_keys_and_approximates_the_rest() {
    for seed in 0..50 {
        for kind in KINDS {
            let s = CurveSpec::new(Curve::BSpline);
            let mut g = Gen::new(seed);
            let count = 2 + (seed as usize % 7);
            let track = track(&mut g, &s, count, kind);
            let batch = Batch::from_tracks(std::slice::from_ref(&track), &s).unwrap();
            let times = track.times.as_ref().unwrap();
            let keys: Vec<QuatF64> = track.rotations.iter().map(|&k| QuatF64::from_array(k).normalize()).collect();
            let n = count - 1;
            assert!(eval(&batch, 0, times[0]).rotation.angle_to(keys[0]) < 1e-14);
            assert!(eval(&batch, 0, times[n]).rotation.angle_to(keys[n]) < 1e-14);
            if kind == Kind::Random && n >= 2 {
                // Approximating: an interior key is generally missed.
                let miss = (1..n).map(|i| eval(&batch, 0, times[i]).rotation.angle_to(keys[i])).fold(0.0, f64::max);
                assert!(miss > 1e-6, "phantom B-spline interpolated every key (seed {seed})");
            }
        }
    }
}

#[test]
fn repeated_knots_lower_continuity_but_keep_the_curve_whole() {
    // Order 4 with a double interior knot: C1 there (omega continuous), alpha may jump.
    let s = spec(4, KnotMode::Explicit);
    let mut g = Gen::new(3);
    let mut track = track(&mut g, &s, 7, Kind::Random);
    track.knots = Some(vec![0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 3.0, 3.5, 4.0, 4.5, 5.0]);
    let batch = Batch::from_tracks(&[track], &s).unwrap();
    let j = jumps(&batch, 3.0, 1e-3);
    let scale = 1.0 + eval(&batch, 0, 3.0).angular_acceleration.max_abs();
    assert!(j[0] < 1e-9 && j[1] < 1e-6 * scale, "double knot broke C1: {j:?}");
    assert!(j[2] > 1e-3, "double knot should let alpha jump: {j:?}");
    let _ = Track::default();
}
