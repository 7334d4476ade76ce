//! KKS cubic Hermite (KKS section 5.2): end orientations and angular velocities, extra turns,
//! and end coefficients used as given however large.

use crate::common::*;
use quatcurve::{Batch, Curve, CurveSpec, QuatF64, Tangents, Track, Vec3F64};

fn given() -> CurveSpec {
    CurveSpec { tangents: Tangents::Given, ..CurveSpec::new(Curve::Hermite) }
}

#[test]
fn reproduces_key_rotations_and_angular_velocities_from_both_sides() {
    let mut worst = 0.0f64;
    for seed in 0..200 {
        let mut g = Gen::new(seed);
        let kind = KINDS[seed as usize % 4];
        let count = 2 + (seed as usize % 6);
        let track = track(&mut g, &given(), count, kind);
        let batch = Batch::from_tracks(std::slice::from_ref(&track), &given()).unwrap();
        let times = track.times.as_ref().unwrap();
        let omegas = track.angular_velocities.as_ref().unwrap();
        for i in 0..count {
            let key = QuatF64::from_array(track.rotations[i]).normalize();
            let omega = Vec3F64::from_array(omegas[i]);
            let at = eval(&batch, 0, times[i]);
            assert!(at.rotation.angle_to(key) < 1e-12, "seed {seed} key {i}");
            assert!(
                rel_err(at.angular_velocity, omega) < 1e-12,
                "seed {seed} key {i}: {:?} vs {omega:?}",
                at.angular_velocity
            );
            worst = worst.max(rel_err(at.angular_velocity, omega));
            if i > 0 {
                // The segment ending at key i, evaluated at its end (left limit).
                let left = eval(&batch, 0, times[i] - 1e-10);
                assert!(rel_err(left.angular_velocity, omega) < 1e-6, "seed {seed} key {i} from the left");
            }
        }
    }
    eprintln!("hermite: worst end-velocity relative error {worst:e}");
}

#[test]
fn end_coefficients_are_used_as_given_even_beyond_a_quarter_turn() {
    // |w_a / 3| = T |omega| / 6 = 3 rad > pi/2: a fold would change the end velocity.
    let q0 = QuatF64::identity();
    let q1 = QuatF64::exp(Vec3F64::new(0.0, 0.0, 0.4));
    let omega_a = Vec3F64::new(18.0, 0.0, 0.0);
    let omega_b = Vec3F64::new(0.0, -18.0, 0.0);
    let track = Track {
        times: Some(vec![0.0, 1.0]),
        rotations: vec![q0.to_array(), q1.to_array()],
        angular_velocities: Some(vec![omega_a.to_array(), omega_b.to_array()]),
        ..Track::default()
    };
    let batch = Batch::from_tracks(&[track], &given()).unwrap();
    let w1 = batch.coefs()[0];
    assert_eq!(w1, [3.0, 0.0, 0.0, 0.0], "w1 = T omega_a / 6 exactly");
    assert_eq!(batch.coefs()[2], [0.0, -3.0, 0.0, 0.0]);
    assert!(rel_err(eval(&batch, 0, 0.0).angular_velocity, omega_a) < 1e-12);
    assert!(rel_err(eval(&batch, 0, 1.0).angular_velocity, omega_b) < 1e-12);
    assert!(eval(&batch, 0, 1.0).rotation.angle_to(q1) < 1e-12);
}

#[test]
fn extra_turns_change_the_path_but_not_the_ends() {
    let mut g = Gen::new(11);
    for turns in [-2i64, -1, 1, 3] {
        let mut track = track(&mut g, &given(), 4, Kind::Random);
        let base = Batch::from_tracks(std::slice::from_ref(&track), &given()).unwrap();
        track.extra_turns = Some(vec![0, turns, 0]);
        let turned = Batch::from_tracks(std::slice::from_ref(&track), &given()).unwrap();
        let times = track.times.as_ref().unwrap();
        for &t in times {
            let (a, b) = (eval(&base, 0, t), eval(&turned, 0, t));
            assert!(a.rotation.angle_to(b.rotation) < 1e-11, "turns {turns}: key at {t} moved");
            assert!(rel_err(a.angular_velocity, b.angular_velocity) < 1e-9);
        }
        // Inside the turned segment the path differs; elsewhere it is identical.
        // Not the middle: there an even number of turns multiplies by exp(pi u) = -1 only.
        let mid = 0.7 * times[1] + 0.3 * times[2];
        assert!(eval(&base, 0, mid).rotation.angle_to(eval(&turned, 0, mid).rotation) > 1e-3);
        let other = 0.5 * (times[0] + times[1]);
        assert_eq!(eval(&base, 0, other), eval(&turned, 0, other));
        // Each turn adds pi along w2's own axis (a full physical turn).
        let w = |c: [f64; 4]| Vec3F64::new(c[0], c[1], c[2]);
        let (w_base, w_turn) = (w(base.coefs()[4]), w(turned.coefs()[4]));
        let expected = w_base + w_base.scale(std::f64::consts::PI * turns as f64 / w_base.length());
        assert!((w_turn - expected).length() < 1e-12);
    }
}
