//! Squad against a by-hand evaluation of its definition (through glam's own slerp and
//! axis-angle functions, not the crate's exp/log), and slerp through near-antipodal keys.

use crate::common::*;
use glam::DQuat as G;
use quatcurve::{Batch, Curve, CurveSpec, QuatF64, Track, Vec3F64};

/// Half-angle log with glam's full-angle axis-angle: log q = axis * angle / 2.
fn glam_log(q: G) -> glam::DVec3 {
    let (axis, angle) = q.to_axis_angle();
    axis * (angle / 2.0)
}

/// Half-angle exp: exp v = rotation by 2|v| about v.
fn glam_exp(v: glam::DVec3) -> G {
    G::from_scaled_axis(v * 2.0)
}

/// Relative log with the second key folded to the first key's hemisphere.
fn rel(a: G, b: G) -> glam::DVec3 {
    let b = if a.dot(b) < 0.0 { -b } else { b };
    glam_log(a.conjugate() * b)
}

/// The unfolded geodesic `a exp(h log(a^-1 b))` (glam's own slerp folds, so not that).
fn geodesic(a: G, b: G, h: f64) -> G {
    a * glam_exp(glam_log(a.conjugate() * b) * h)
}

#[test]
fn squad_matches_its_definition_by_hand() {
    let spec = CurveSpec::new(Curve::Squad);
    let mut worst = 0.0f64;
    for seed in 0..100 {
        let mut gen = Gen::new(seed);
        let kind = if seed % 2 == 0 { Kind::Random } else { Kind::SignFlipped };
        let count = 2 + (seed as usize % 7);
        let track = track(&mut gen, &spec, count, kind);
        let batch = Batch::from_tracks(std::slice::from_ref(&track), &spec).unwrap();
        // By hand: aligned keys, auxiliary points (P eq. 19), then the three geodesics.
        let mut keys: Vec<G> = Vec::new();
        for k in &track.rotations {
            let q = G::from_array(*k).normalize();
            let q = match keys.last() {
                Some(p) if p.dot(q) < 0.0 => -q,
                _ => q,
            };
            keys.push(q);
        }
        let n = count - 1;
        let aux: Vec<G> = (0..=n)
            .map(|i| {
                if i == 0 || i == n {
                    keys[i]
                } else {
                    keys[i] * glam_exp(-(rel(keys[i], keys[i + 1]) + rel(keys[i], keys[i - 1])) / 4.0)
                }
            })
            .collect();
        let times = track.times.as_ref().unwrap();
        for i in 0..n {
            for f in [0.0, 0.1, 0.35, 0.5, 0.8, 0.99] {
                let t = times[i] + f * (times[i + 1] - times[i]);
                let h = f;
                let by_hand =
                    geodesic(geodesic(keys[i], keys[i + 1], h), geodesic(aux[i], aux[i + 1], h), 2.0 * h * (1.0 - h));
                // Where the blend's endpoints stay in one hemisphere this is also the folded
                // (shortest-path) slerp of DESIGN; glam's slerp must agree there.
                let (path, aux_h) = (keys[i].slerp(keys[i + 1], h), aux[i].slerp(aux[i + 1], h));
                if aux[i].dot(aux[i + 1]) > 0.0 && path.dot(aux_h) > 0.0 {
                    let folded = path.slerp(aux_h, 2.0 * h * (1.0 - h));
                    assert!(
                        QuatF64::from_array(folded.to_array()).angle_to(QuatF64::from_array(by_hand.to_array())) < 1e-9
                    );
                }
                let ours = eval(&batch, 0, t).rotation;
                let err = ours.angle_to(QuatF64::from_xyzw(by_hand.x, by_hand.y, by_hand.z, by_hand.w));
                worst = worst.max(err);
                assert!(err < 1e-9, "seed {seed} segment {i} h {h}: {err:e} rad");
            }
        }
    }
    eprintln!("squad vs by-hand (glam): worst {worst:e} rad");
}

#[test]
fn squad_with_two_keys_is_slerp() {
    let mut gen = Gen::new(5);
    let track = track(&mut gen, &CurveSpec::new(Curve::Squad), 2, Kind::Random);
    let squad = Batch::from_tracks(std::slice::from_ref(&track), &CurveSpec::new(Curve::Squad)).unwrap();
    let slerp = Batch::from_tracks(&[track], &CurveSpec::new(Curve::Slerp)).unwrap();
    let [lo, hi] = squad.tracks()[0].domain();
    for i in 0..=50 {
        let t = lo + (hi - lo) * i as f64 / 50.0;
        assert!(eval(&squad, 0, t).rotation.angle_to(eval(&slerp, 0, t).rotation) < 1e-14);
    }
}

#[test]
fn slerp_goes_the_short_way_between_near_antipodal_keys() {
    let spec = CurveSpec::new(Curve::Slerp);
    for degrees in [170.0f64, 179.0, 179.9, 179.999] {
        let a = QuatF64::exp(Vec3F64::new(0.1, 0.2, 0.3));
        let step = QuatF64::exp(Vec3F64::new(0.0, 0.0, degrees.to_radians() / 2.0));
        // The second key given in the far hemisphere.
        let b = -(a * step);
        let track = Track { rotations: vec![a.to_array(), b.to_array()], ..Track::default() };
        let batch = Batch::from_tracks(&[track], &spec).unwrap();
        let mid = eval(&batch, 0, 0.5).rotation;
        let half = (degrees / 2.0).to_radians();
        assert!((mid.angle_to(a) - half).abs() < 1e-12, "{degrees}: {}", mid.angle_to(a));
        assert!((mid.angle_to(b) - half).abs() < 1e-12);
        let s = eval(&batch, 0, 0.25);
        assert!(rel_err(s.angular_velocity, Vec3F64::new(0.0, 0.0, degrees.to_radians())) < 1e-12);
    }
}

#[test]
fn the_rotation_alone_equals_the_full_evaluation() {
    // evaluate_rotation skips the jets for squad and Nam-Kim, and the KKS families' derivative
    // recursion; it must be the same curve, to the bit where only the recursion is skipped.
    let mut g = crate::common::Gen::new(12);
    for spec in crate::common::all_specs() {
        for kind in crate::common::KINDS {
            let track = crate::common::track(&mut g, &spec, spec.min_keys().max(2) + 3, kind);
            let batch = quatcurve::Batch::from_tracks(&[track], &spec).unwrap();
            let [lo, hi] = batch.tracks()[0].domain();
            for i in 0..=50 {
                let t = lo + (hi - lo) * i as f64 / 50.0;
                let full = quatcurve::evaluate(batch.view(0), t).rotation;
                let alone = quatcurve::reference::evaluate_rotation(batch.view(0), t);
                assert!(full.angle_to(alone) < 1e-14, "{}: t={t}", crate::common::describe(&spec));
                if !matches!(spec.curve, quatcurve::Curve::Squad | quatcurve::Curve::NamKim) {
                    assert_eq!(full.to_array(), alone.to_array(), "{}: t={t}", crate::common::describe(&spec));
                }
            }
        }
    }
}
