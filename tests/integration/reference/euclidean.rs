//! The Euclidean analogue (translation and scale channels) is the rotation curve's own scalar
//! spline: with keys on one axis, rotations commute and `log q(t)` along that axis equals the
//! vector curve's component, for every family, tangent source and knot mode (a normalized
//! B-spline's analogue is the plain B-spline's).

use crate::common::{all_specs, describe, explicit_knots, times, Gen};
use proptest::prelude::*;
use quatcurve::euclidean::VectorCurve;
use quatcurve::{Batch, Curve, Error, KnotMode, QuatF64, Tangents, Track, TrackId, Vec3F64};

fn check(seed: u64) -> Result<(), TestCaseError> {
    let mut g = Gen::new(seed);
    for spec in all_specs().into_iter().filter(|s| s.tangents != Tangents::Given) {
        let count = spec.min_keys().max(2) + (g.next_u64() % 6) as usize;
        let count = if spec.curve == Curve::Bezier { count.min(9) } else { count };
        // Half-angles within +-1 rad and steps below 0.4 rad: no fold anywhere on one axis.
        let mut values = vec![[g.range(-0.5, 0.5), g.range(-0.5, 0.5), g.range(-0.5, 0.5)]];
        for _ in 1..count {
            let last = *values.last().unwrap();
            values.push(last.map(|v| (v + g.range(-0.4, 0.4)).clamp(-1.0, 1.0)));
        }
        let bspline = matches!(spec.curve, Curve::BSpline | Curve::NormalizedBSpline);
        let uniform = bspline && matches!(spec.knots, KnotMode::Phantom | KnotMode::Uniform);
        // A normalized B-spline's analogue is the plain B-spline's: vectors need no normalizing.
        let rotation_spec = if spec.curve == Curve::NormalizedBSpline {
            quatcurve::CurveSpec { curve: Curve::BSpline, ..spec }
        } else {
            spec
        };
        let times = times(&mut g, count, uniform);
        let knots = (spec.knots == KnotMode::Explicit).then(|| explicit_knots(&mut g, spec.order, count));
        let id = TrackId { index: 0, name: None };
        let curve = VectorCurve::new(&id, Some(&times), &values, knots.as_deref(), &spec).unwrap();
        for axis in 0..3 {
            let unit = Vec3F64::from_array(std::array::from_fn(|c| if c == axis { 1.0 } else { 0.0 }));
            let track = Track {
                times: Some(times.clone()),
                rotations: values.iter().map(|v| QuatF64::exp(unit.scale(v[axis])).to_array()).collect(),
                knots: knots.clone(),
                ..Track::default()
            };
            let batch = Batch::from_tracks(&[track], &rotation_spec).unwrap();
            let [lo, hi] = batch.tracks()[0].domain();
            prop_assert_eq!(curve.domain(), [lo, hi]);
            for i in 0..=100 {
                let t = lo + (hi - lo) * (i as f64 / 100.0) + if i == 0 { -0.5 } else { 0.0 };
                let angle = quatcurve::evaluate(batch.view(0), t).rotation.log().to_array()[axis];
                let value = curve.evaluate(t).to_array()[axis];
                let err = (angle - value).abs();
                prop_assert!(
                    err < 1e-12,
                    "{}: axis {axis}, t={t}: vector {value} vs rotation angle {angle} ({err:e})",
                    describe(&spec)
                );
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    #[test]
    fn vector_curves_are_the_rotation_curves_on_one_axis(seed in any::<u64>()) {
        check(seed)?;
    }
}

#[test]
fn vector_channels_reject_bad_values_and_given_tangents_by_name() {
    let id = TrackId { index: 3, name: Some("hips/translation".into()) };
    let values = [[0.0, 1.0, 2.0], [0.0, f64::NAN, 2.0], [1.0, 1.0, 1.0]];
    let err = VectorCurve::new(&id, None, &values, None, &quatcurve::CurveSpec::new(Curve::Hermite)).unwrap_err();
    assert!(matches!(err, Error::NonFiniteValue { key: 1, .. }), "{err}");
    assert!(err.to_string().contains("hips/translation") && err.to_string().contains("key 1"), "{err}");
    let spec = quatcurve::CurveSpec { tangents: Tangents::Given, ..quatcurve::CurveSpec::new(Curve::NamKim) };
    let err = VectorCurve::new(&id, None, &[[0.0; 3], [1.0; 3]], None, &spec).unwrap_err();
    assert!(matches!(err, Error::VectorTangents { .. }), "{err}");
    let err =
        VectorCurve::new(&id, Some(&[0.0, 0.0]), &[[0.0; 3], [1.0; 3]], None, &quatcurve::CurveSpec::new(Curve::Slerp))
            .unwrap_err();
    assert!(matches!(err, Error::TimesNotIncreasing { key: 1, .. }), "{err}");
}
