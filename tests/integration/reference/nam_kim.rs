//! Nam-Kim: Hermite end conditions, and the forward-difference generator's drift against
//! direct evaluation (NK section 3).

use crate::common::*;
use quatcurve::reference::nam_kim_forward_difference;
use quatcurve::{Batch, Blend, Curve, CurveSpec, QuatF64, Tangents, Vec3F64};

#[test]
fn reproduces_key_rotations_and_angular_velocities() {
    for blend in [Blend::Cubic, Blend::Quadratic] {
        let spec = CurveSpec { tangents: Tangents::Given, blend, ..CurveSpec::new(Curve::NamKim) };
        for seed in 0..100 {
            let mut g = Gen::new(seed);
            let track = track(&mut g, &spec, 2 + seed as usize % 5, KINDS[seed as usize % 4]);
            let batch = Batch::from_tracks(std::slice::from_ref(&track), &spec).unwrap();
            let times = track.times.as_ref().unwrap();
            for (i, &t) in times.iter().enumerate() {
                let s = eval(&batch, 0, t);
                let omega = Vec3F64::from_array(track.angular_velocities.as_ref().unwrap()[i]);
                assert!(s.rotation.angle_to(QuatF64::from_array(track.rotations[i])) < 1e-12);
                assert!(rel_err(s.angular_velocity, omega) < 1e-11, "{blend:?} seed {seed} key {i}");
            }
        }
    }
}

/// Worst angle between forward-difference and direct samples over `segments` random segments.
fn drift(steps: usize, blend: Blend, max_speed: f64) -> f64 {
    let spec = CurveSpec { tangents: Tangents::Given, blend, ..CurveSpec::new(Curve::NamKim) };
    let mut worst = 0.0f64;
    for seed in 0..20 {
        let mut g = Gen::new(seed);
        let mut track = track(&mut g, &spec, 4, Kind::Random);
        track.angular_velocities = Some(velocities(&mut g, 4, max_speed));
        let batch = Batch::from_tracks(std::slice::from_ref(&track), &spec).unwrap();
        let times = track.times.as_ref().unwrap();
        for seg in 0..3 {
            let fast = nam_kim_forward_difference(batch.view(0), seg, steps);
            for (j, q) in fast.iter().enumerate() {
                let t = times[seg] + (times[seg + 1] - times[seg]) * j as f64 / steps as f64;
                worst = worst.max(q.angle_to(eval(&batch, 0, t).rotation));
            }
        }
    }
    worst
}

#[test]
fn forward_differences_stay_close_to_direct_evaluation() {
    // Measured drift (f64): grows roughly linearly with the step count. Bounds are ~10x the
    // measured worst so a real regression (e.g. an accumulating bias) fails.
    let mut report = Vec::new();
    for (steps, bound) in [(10usize, 5e-14), (100, 3e-13), (1_000, 3e-12), (10_000, 3e-11)] {
        for blend in [Blend::Cubic, Blend::Quadratic] {
            let d = drift(steps, blend, 20.0);
            report.push(format!("{steps} steps {blend:?}: {d:.2e} rad"));
            assert!(d < bound, "{steps} steps {blend:?}: drift {d:e} > {bound:e}");
        }
    }
    eprintln!("nam-kim forward-difference drift: {}", report.join("; "));
}
