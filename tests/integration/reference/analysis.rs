//! `analyze` (DESIGN section 14) against integrals computed here a different way: Gauss-Legendre
//! quadrature over every key interval, closed forms (a constant-speed slerp, the natural
//! cubic spline of angles about one axis), and the continuity each family promises.

use crate::common::{keys, times, Gen, Kind};
use quatcurve::analysis::{analyze, nodes, AnalysisError, AnalysisOptions, Metrics};
use quatcurve::{evaluate, Batch, Curve, CurveSpec, Device, DeviceChoice, KnotMode, QuatF64, Track, Vec3F64};

const INERTIA: [f64; 3] = [1.0, 2.5, 0.7];

fn spec(curve: Curve) -> CurveSpec {
    CurveSpec::new(curve)
}

/// Random keys; times uniform for the phantom B-spline (which needs them) and for squad (C1 in
/// time only with uniform times, DESIGN section 3), random otherwise.
fn random_track(seed: u64, curve: Curve, count: usize) -> Track {
    let mut g = Gen::new(seed);
    let uniform = matches!(curve, Curve::BSpline | Curve::Squad);
    let times = times(&mut g, count, uniform);
    Track {
        name: Some(format!("seed{seed}")),
        times: Some(times),
        ..Track::from_rotations(keys(&mut g, count, Kind::Random))
    }
}

fn one(track: &Track, spec: &CurveSpec, options: &AnalysisOptions) -> Metrics {
    let batch = Batch::from_tracks(std::slice::from_ref(track), spec).unwrap();
    analyze(&batch, &Device::Reference, options).unwrap()[0]
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-12)
}

/// Energy, torque energy and arc length by 5-point Gauss-Legendre on 64 pieces of every key
/// interval (nodes never on a key, so the side of a jump never matters).
fn gauss_legendre(track: &Track, spec: &CurveSpec, inertia: [f64; 3]) -> [f64; 3] {
    const X: [f64; 5] =
        [0.0, -0.538_469_310_105_683, 0.538_469_310_105_683, -0.906_179_845_938_664, 0.906_179_845_938_664];
    const W: [f64; 5] = [
        0.568_888_888_888_889,
        0.478_628_670_499_366,
        0.478_628_670_499_366,
        0.236_926_885_056_189,
        0.236_926_885_056_189,
    ];
    let batch = Batch::from_tracks(std::slice::from_ref(track), spec).unwrap();
    let view = batch.view(0);
    let key_times = track.times.clone().unwrap();
    let i = Vec3F64::new(inertia[0], inertia[1], inertia[2]);
    let mul = |a: Vec3F64, b: Vec3F64| Vec3F64::new(a.x * b.x, a.y * b.y, a.z * b.z);
    let mut sums = [0.0; 3];
    for w in key_times.windows(2) {
        let pieces = 64;
        let h = (w[1] - w[0]) / pieces as f64;
        for p in 0..pieces {
            let mid = w[0] + (p as f64 + 0.5) * h;
            for (x, weight) in X.iter().zip(W) {
                let s = evaluate(view, mid + 0.5 * h * x);
                let (omega, alpha) = (s.angular_velocity, s.angular_acceleration);
                let tau = mul(i, alpha) + omega.cross(mul(i, omega));
                let f = [alpha.dot(alpha), tau.dot(tau), omega.length()];
                for (sum, f) in sums.iter_mut().zip(f) {
                    *sum += 0.5 * h * weight * f;
                }
            }
        }
    }
    sums
}

#[test]
fn integrals_match_gauss_legendre_for_every_family() {
    let options = AnalysisOptions { inertia: INERTIA, step: None };
    for (seed, curve) in
        [Curve::BSplineInterp, Curve::Hermite, Curve::Squad, Curve::NamKim, Curve::BSpline, Curve::Bezier, Curve::Slerp]
            .into_iter()
            .enumerate()
    {
        let count = if curve == Curve::Bezier { 5 } else { 7 };
        let track = random_track(seed as u64 + 10, curve, count);
        let m = one(&track, &spec(curve), &options);
        let [energy, torque, arc] = gauss_legendre(&track, &spec(curve), INERTIA);
        for (what, got, want) in [
            ("energy", m.energy, energy),
            ("torque_energy", m.torque_energy, torque),
            ("arc_length", m.arc_length, arc),
        ] {
            if curve == Curve::Slerp && what != "arc_length" {
                // No acceleration inside a slerp segment; the torque is the gyroscopic term alone.
                assert!(m.energy < 1e-18, "{curve}: energy {}", m.energy);
                assert!(relative(got, want) <= 1e-3 || want < 1e-12, "{curve} {what}: {got} vs {want}");
                continue;
            }
            assert!(relative(got, want) <= 1e-3, "{curve} {what}: Simpson {got} vs Gauss-Legendre {want}");
        }
    }
}

#[test]
fn maxima_bound_dense_samples() {
    let options = AnalysisOptions::default();
    for curve in [Curve::BSplineInterp, Curve::Hermite, Curve::NamKim] {
        let track = random_track(3, curve, 6);
        let m = one(&track, &spec(curve), &options);
        let batch = Batch::from_tracks(std::slice::from_ref(&track), &spec(curve)).unwrap();
        let [lo, hi] = batch.tracks()[0].domain();
        let (mut w, mut a) = (0.0f64, 0.0f64);
        for j in 0..=7919 {
            let s = evaluate(batch.view(0), lo + (hi - lo) * j as f64 / 7919.0);
            w = w.max(s.angular_velocity.length());
            a = a.max(s.angular_acceleration.length());
        }
        assert!(
            m.max_omega >= w * (1.0 - 1e-3) && m.max_omega <= w * (1.0 + 1e-2),
            "{curve}: max_omega {} vs sampled {w}",
            m.max_omega
        );
        assert!(
            m.max_alpha >= a * (1.0 - 1e-3) && m.max_alpha <= a * (1.0 + 1e-2),
            "{curve}: max_alpha {} vs sampled {a}",
            m.max_alpha
        );
    }
}

#[test]
fn a_constant_speed_slerp_has_no_acceleration_and_a_gyroscopic_torque_only() {
    // Keys 0.4 rad apart about one tilted axis, 0.5 s apart: omega = 0.8 rad/s about the axis.
    let axis = Vec3F64::new(1.0, 2.0, 2.0).scale(1.0 / 3.0);
    let rotations = (0..6).map(|i| QuatF64::exp(axis.scale(0.2 * i as f64)).to_array()).collect();
    let track = Track { times: Some((0..6).map(|i| 0.5 * i as f64).collect()), ..Track::from_rotations(rotations) };
    let m = one(&track, &spec(Curve::Slerp), &AnalysisOptions { inertia: INERTIA, step: None });
    let omega = axis.scale(0.8);
    let gyro = omega.cross(Vec3F64::new(INERTIA[0] * omega.x, INERTIA[1] * omega.y, INERTIA[2] * omega.z));
    assert!(m.energy < 1e-20 && m.max_alpha < 1e-9, "{m:?}");
    assert!(relative(m.torque_energy, gyro.dot(gyro) * 2.5) < 1e-9, "{} vs {}", m.torque_energy, gyro.dot(gyro) * 2.5);
    assert!(relative(m.arc_length, 2.0) < 1e-9 && relative(m.max_omega, 0.8) < 1e-9, "{m:?}");
    assert!(m.omega_jump < 1e-9 && m.alpha_jump < 1e-9, "{m:?}");
}

/// Second derivatives `M_i` of the natural cubic spline through `(t_i, y_i)` (Thomas algorithm).
fn natural_spline_moments(t: &[f64], y: &[f64]) -> Vec<f64> {
    let n = t.len() - 1;
    let h: Vec<f64> = (0..n).map(|i| t[i + 1] - t[i]).collect();
    let mut m = vec![0.0; n + 1];
    if n < 2 {
        return m;
    }
    // Rows 1..n-1: h[i-1] M[i-1] + 2 (h[i-1] + h[i]) M[i] + h[i] M[i+1] = 6 (slope[i] - slope[i-1]).
    let (mut diag, mut rhs) = (vec![0.0; n], vec![0.0; n]);
    for i in 1..n {
        diag[i] = 2.0 * (h[i - 1] + h[i]);
        rhs[i] = 6.0 * ((y[i + 1] - y[i]) / h[i] - (y[i] - y[i - 1]) / h[i - 1]);
        if i > 1 {
            let f = h[i - 1] / diag[i - 1];
            diag[i] -= f * h[i - 1];
            rhs[i] -= f * rhs[i - 1];
        }
    }
    for i in (1..n).rev() {
        let next = if i + 1 < n { h[i] * m[i + 1] } else { 0.0 };
        m[i] = (rhs[i] - next) / diag[i];
    }
    m
}

/// `integral theta''^2` of the natural spline: theta'' is linear on each interval.
fn natural_spline_energy(t: &[f64], y: &[f64]) -> f64 {
    let m = natural_spline_moments(t, y);
    t.windows(2)
        .enumerate()
        .map(|(i, w)| (w[1] - w[0]) / 3.0 * (m[i] * m[i] + m[i] * m[i + 1] + m[i + 1] * m[i + 1]))
        .sum()
}

fn about(axis: Vec3F64, angles: &[f64], key_times: &[f64]) -> Track {
    let rotations = angles.iter().map(|&a| QuatF64::exp(axis.scale(0.5 * a)).to_array()).collect();
    Track { times: Some(key_times.to_vec()), ..Track::from_rotations(rotations) }
}

#[test]
fn one_axis_bspline_interp_energy_is_the_natural_spline_integral() {
    // By hand: angles 0, a, 0 at 0, 1, 2 s give M_1 = -3a, so the energy is 2 * (9 a^2 / 3) = 6 a^2.
    let a = 0.8;
    let m = one(
        &about(Vec3F64::new(0.0, 0.0, 1.0), &[0.0, a, 0.0], &[0.0, 1.0, 2.0]),
        &spec(Curve::BSplineInterp),
        &AnalysisOptions::default(),
    );
    assert!(relative(m.energy, 6.0 * a * a) < 1e-7, "{} vs {}", m.energy, 6.0 * a * a);
    assert!(relative(natural_spline_energy(&[0.0, 1.0, 2.0], &[0.0, a, 0.0]), 6.0 * a * a) < 1e-12);
    for seed in 0..8 {
        let mut g = Gen::new(100 + seed);
        let count = 3 + (seed as usize % 6);
        let key_times = times(&mut g, count, false);
        let mut angles = vec![g.range(-1.0, 1.0)];
        for _ in 1..count {
            angles.push(angles.last().unwrap() + g.range(-2.0, 2.0));
        }
        let want = natural_spline_energy(&key_times, &angles);
        let axis = g.direction();
        let m = one(&about(axis, &angles, &key_times), &spec(Curve::BSplineInterp), &AnalysisOptions::default());
        assert!(relative(m.energy, want) < 1e-7, "seed {seed}: {} vs {want}", m.energy);
        // About a principal axis omega x (I omega) = 0, so tau = Izz theta''.
        let inertia = AnalysisOptions { inertia: [2.0, 3.0, 5.0], step: None };
        let z = one(&about(Vec3F64::new(0.0, 0.0, 1.0), &angles, &key_times), &spec(Curve::BSplineInterp), &inertia);
        assert!(relative(z.torque_energy, 25.0 * want) < 1e-7, "seed {seed}: {} vs {}", z.torque_energy, 25.0 * want);
    }
}

#[test]
fn alpha_jumps_only_where_the_family_is_c1() {
    let options = AnalysisOptions::default();
    for seed in 0..6 {
        for (curve, looping) in [
            (Curve::BSplineInterp, false),
            (Curve::BSpline, false),
            (Curve::Hermite, false),
            (Curve::Squad, false),
            (Curve::BSplineInterp, true),
            (Curve::Hermite, true),
        ] {
            let mut track = random_track(200 + seed, curve, 6);
            if looping {
                let first = track.rotations[0];
                track.rotations.push(first);
                let times = track.times.as_mut().unwrap();
                times.push(times.last().unwrap() + 0.7);
            }
            let spec = CurveSpec { looping, knots: KnotMode::Phantom, ..spec(curve) };
            let m = one(&track, &spec, &options);
            let c2 = matches!(curve, Curve::BSplineInterp | Curve::BSpline);
            if c2 {
                assert!(
                    m.alpha_jump <= 1e-6 * m.max_alpha,
                    "{curve} loop {looping} seed {seed}: jump {} of {}",
                    m.alpha_jump,
                    m.max_alpha
                );
            } else {
                assert!(
                    m.alpha_jump >= 1e-2 * m.max_alpha,
                    "{curve} loop {looping} seed {seed}: jump {} of {}",
                    m.alpha_jump,
                    m.max_alpha
                );
            }
            assert!(
                m.omega_jump <= 1e-6 * m.max_omega,
                "{curve} loop {looping} seed {seed}: omega jump {}",
                m.omega_jump
            );
        }
        let slerp = one(&random_track(200 + seed, Curve::Slerp, 6), &spec(Curve::Slerp), &options);
        assert!(slerp.omega_jump >= 1e-2 * slerp.max_omega, "slerp seed {seed}: {slerp:?}");
        // Squad on non-uniform times is C1 in its segment parameter, not in time.
        let squad = one(&random_track(200 + seed, Curve::Hermite, 6), &spec(Curve::Squad), &options);
        assert!(squad.omega_jump >= 1e-3 * squad.max_omega, "squad, non-uniform times, seed {seed}: {squad:?}");
    }
}

#[test]
fn the_fast_cpu_path_gives_the_same_figures() {
    let options = AnalysisOptions { inertia: INERTIA, step: None };
    let cpu = Device::open(DeviceChoice::Cpu).unwrap();
    for curve in [Curve::BSplineInterp, Curve::Hermite, Curve::Squad, Curve::NamKim] {
        let tracks: Vec<Track> = (0..3).map(|s| random_track(300 + s, curve, 6)).collect();
        let batch = Batch::from_tracks(&tracks, &spec(curve)).unwrap();
        let (want, got) =
            (analyze(&batch, &Device::Reference, &options).unwrap(), analyze(&batch, &cpu, &options).unwrap());
        for (w, g) in want.iter().zip(&got) {
            for (what, a, b) in [
                ("energy", g.energy, w.energy),
                ("torque", g.torque_energy, w.torque_energy),
                ("arc", g.arc_length, w.arc_length),
                ("max_alpha", g.max_alpha, w.max_alpha),
            ] {
                assert!(relative(a, b) <= 1e-3, "{curve} {what}: cpu {a} vs reference {b}");
            }
            assert!(
                g.alpha_jump <= w.alpha_jump + 1e-3 * w.max_alpha && g.alpha_jump >= w.alpha_jump - 1e-3 * w.max_alpha,
                "{curve}: jump {} vs {}",
                g.alpha_jump,
                w.alpha_jump
            );
        }
    }
}

#[test]
fn bad_options_are_errors() {
    let track = random_track(1, Curve::Hermite, 4);
    let batch = Batch::from_tracks(std::slice::from_ref(&track), &spec(Curve::Hermite)).unwrap();
    let run = |options: AnalysisOptions| analyze(&batch, &Device::Reference, &options).unwrap_err();
    assert!(matches!(run(AnalysisOptions { inertia: [1.0, 0.0, 1.0], step: None }), AnalysisError::BadInertia(_)));
    assert!(matches!(run(AnalysisOptions { inertia: [1.0; 3], step: Some(f64::NAN) }), AnalysisError::BadStep(_)));
    let e = run(AnalysisOptions { inertia: [1.0; 3], step: Some(1e-12) });
    assert!(matches!(e, AnalysisError::TooManyNodes { .. }) && e.to_string().contains("seed1"), "{e}");
    // A step so small that the node count overflows any integer is the same error.
    assert!(matches!(
        run(AnalysisOptions { inertia: [1.0; 3], step: Some(1e-300) }),
        AnalysisError::TooManyNodes { .. }
    ));
    // Every span gets an even number of steps, at least 2, and nodes stay inside the domain.
    let n = nodes(batch.view(0), "t", Some(10.0)).unwrap();
    assert!(n.spans.iter().all(|s| s.steps == 2), "{:?}", n.spans);
    let [lo, hi] = batch.tracks()[0].domain();
    assert!(n.times.iter().all(|&t| t >= lo && t < hi), "{:?}", n.times);
}
