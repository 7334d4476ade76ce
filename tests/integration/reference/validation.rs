//! One test per input rule: each error names the track (index and name) and the key.

use quatcurve::{Batch, Curve, CurveSpec, Error, EvalJob, KnotMode, Layout, SampleTimes, Sampling, Tangents, Track};

fn keys(n: usize) -> Vec<[f64; 4]> {
    (0..n).map(|i| quatcurve::QuatF64::exp(quatcurve::Vec3F64::new(0.1 * i as f64, 0.0, 0.0)).to_array()).collect()
}

fn named(rotations: Vec<[f64; 4]>) -> Track {
    Track { name: Some("hips".into()), ..Track::from_rotations(rotations) }
}

/// Builds a batch of a fine track followed by `bad` (so the bad one is track 1) and returns
/// the error's message after checking it names the track.
fn message(bad: Track, spec: CurveSpec) -> (Error, String) {
    let mut builder = quatcurve::BatchBuilder::new();
    builder.add(&Track::from_rotations(keys(8)), &CurveSpec::new(Curve::Slerp)).unwrap();
    let err = builder.add(&bad, &spec).expect_err("must be rejected");
    let msg = err.to_string();
    assert!(msg.contains("track 1 \"hips\""), "message does not name the track: {msg}");
    (err, msg)
}

#[test]
fn nan_key() {
    let mut r = keys(5);
    r[3][1] = f64::NAN;
    let (err, msg) = message(named(r), CurveSpec::new(Curve::Slerp));
    assert!(matches!(err, Error::NonFiniteKey { key: 3, .. }) && msg.contains("key 3"), "{msg}");
}

#[test]
fn zero_key() {
    let mut r = keys(5);
    r[2] = [0.0, 1e-9, 0.0, 0.0];
    let (err, msg) = message(named(r), CurveSpec::new(Curve::Slerp));
    assert!(matches!(err, Error::ZeroKey { key: 2, .. }) && msg.contains("key 2"), "{msg}");
}

#[test]
fn decreasing_times() {
    let track = Track { times: Some(vec![0.0, 1.0, 0.5, 2.0]), ..named(keys(4)) };
    let (err, msg) = message(track, CurveSpec::new(Curve::Hermite));
    assert!(matches!(err, Error::TimesNotIncreasing { key: 2, .. }) && msg.contains("key 2"), "{msg}");
}

#[test]
fn repeated_time() {
    let track = Track { times: Some(vec![0.0, 1.0, 1.0, 2.0]), ..named(keys(4)) };
    let (_, msg) = message(track, CurveSpec::new(Curve::Slerp));
    assert!(msg.contains("key 2") && msg.contains("strictly increase"), "{msg}");
}

#[test]
fn wrong_time_count() {
    let track = Track { times: Some(vec![0.0, 1.0]), ..named(keys(4)) };
    let (err, _) = message(track, CurveSpec::new(Curve::Slerp));
    assert!(matches!(err, Error::TimesCount { expected: 4, found: 2, .. }));
}

#[test]
fn too_few_keys_for_the_curve() {
    let (err, msg) = message(named(keys(1)), CurveSpec::new(Curve::Squad));
    assert!(matches!(err, Error::TooFewKeys { min: 2, found: 1, .. }), "{msg}");
    let spec = CurveSpec { order: 6, knots: KnotMode::Uniform, ..CurveSpec::new(Curve::BSpline) };
    let (_, msg) = message(named(keys(5)), spec);
    assert!(msg.contains("at least 6 keys, got 5"), "{msg}");
}

#[test]
fn wrong_knot_count() {
    let spec = CurveSpec { knots: KnotMode::Explicit, ..CurveSpec::new(Curve::BSpline) };
    let track = Track { knots: Some(vec![0.0; 5]), ..named(keys(6)) };
    let (err, msg) = message(track, spec);
    assert!(matches!(err, Error::KnotCount { expected: 10, found: 5, .. }), "{msg}");
    let (_, msg) = message(named(keys(6)), spec);
    assert!(msg.contains("need 10 knots"), "missing knots: {msg}");
}

#[test]
fn decreasing_knots() {
    let spec = CurveSpec { knots: KnotMode::Explicit, ..CurveSpec::new(Curve::BSpline) };
    let knots = vec![0.0, 1.0, 2.0, 3.0, 4.0, 3.5, 6.0, 7.0, 8.0, 9.0];
    let (err, msg) = message(Track { knots: Some(knots), ..named(keys(6)) }, spec);
    assert!(matches!(err, Error::KnotsDecreasing { knot: 5, .. }) && msg.contains("knot 5"), "{msg}");
}

#[test]
fn knot_multiplicity_too_high() {
    let spec = CurveSpec { knots: KnotMode::Explicit, ..CurveSpec::new(Curve::BSpline) };
    // Domain [t_3, t_10] = [3, 10]: the knot 5 repeated 4 times inside it breaks continuity.
    let knots = vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 5.0, 5.0, 5.0, 9.0, 10.0, 11.0, 12.0, 13.0];
    let (err, msg) = message(Track { knots: Some(knots.clone()), ..named(keys(10)) }, spec);
    assert!(matches!(err, Error::KnotMultiplicity { knot: 5, multiplicity: 4, max: 3, .. }), "{msg}");
    assert!(msg.contains("knot 5"), "{msg}");
    // At the domain ends multiplicity k is allowed (clamped ends).
    let clamped = vec![3.0, 3.0, 3.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 10.0, 10.0, 10.0];
    assert!(Batch::from_tracks(&[Track { knots: Some(clamped), ..named(keys(10)) }], &spec).is_ok());
}

#[test]
fn velocity_count_mismatch() {
    let spec = CurveSpec { tangents: Tangents::Given, ..CurveSpec::new(Curve::Hermite) };
    let track = Track { angular_velocities: Some(vec![[0.0; 3]; 3]), ..named(keys(4)) };
    let (err, msg) = message(track, spec);
    assert!(matches!(err, Error::VelocityCount { expected: 4, found: 3, .. }), "{msg}");
}

#[test]
fn nan_velocity() {
    let spec = CurveSpec { tangents: Tangents::Given, ..CurveSpec::new(Curve::NamKim) };
    let mut v = vec![[0.0; 3]; 4];
    v[1][2] = f64::INFINITY;
    let (err, msg) = message(Track { angular_velocities: Some(v), ..named(keys(4)) }, spec);
    assert!(matches!(err, Error::NonFiniteVelocity { key: 1, .. }) && msg.contains("key 1"), "{msg}");
}

#[test]
fn extra_turn_on_a_zero_arc() {
    let spec = CurveSpec { tangents: Tangents::Zero, ..CurveSpec::new(Curve::Hermite) };
    let same = vec![[0.0, 0.0, 0.0, 1.0]; 3];
    let (err, msg) = message(Track { extra_turns: Some(vec![0, 1]), ..named(same) }, spec);
    assert!(matches!(err, Error::ExtraTurnOnZeroArc { segment: 1, .. }) && msg.contains("segment 1"), "{msg}");
}

#[test]
fn extra_turns_count() {
    let (err, _) = message(Track { extra_turns: Some(vec![0]), ..named(keys(4)) }, CurveSpec::new(Curve::Hermite));
    assert!(matches!(err, Error::ExtraTurnsCount { expected: 3, found: 1, .. }));
}

#[test]
fn non_uniform_times_for_uniform_knots() {
    let track = Track { times: Some(vec![0.0, 1.0, 2.5, 3.0, 4.0]), ..named(keys(5)) };
    let (err, msg) = message(track, CurveSpec::new(Curve::BSpline));
    assert!(matches!(err, Error::NonUniformTimes { key: 2, .. }) && msg.contains("key 2"), "{msg}");
}

#[test]
fn phantom_needs_order_four() {
    let spec = CurveSpec { order: 5, ..CurveSpec::new(Curve::BSpline) };
    let (_, msg) = message(named(keys(6)), spec);
    assert!(msg.contains("phantom") && msg.contains("order 4"), "{msg}");
}

#[test]
fn order_out_of_range() {
    let spec = CurveSpec { order: 9, knots: KnotMode::Uniform, ..CurveSpec::new(Curve::BSpline) };
    let (_, msg) = message(named(keys(12)), spec);
    assert!(msg.contains("order 9"), "{msg}");
}

#[test]
fn empty_batch() {
    let err = Batch::from_tracks(&[], &CurveSpec::new(Curve::BSpline)).unwrap_err();
    assert_eq!(err, Error::EmptyBatch);
}

#[test]
fn non_finite_sample_time() {
    let batch =
        Batch::from_tracks(&[Track::from_rotations(keys(3)), named(keys(3))], &CurveSpec::new(Curve::Slerp)).unwrap();
    let own = [0.0, f64::NAN];
    let err = SampleTimes::new(&batch, &[None, Some(&own)], Sampling::Count(3)).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("track 1 \"hips\"") && msg.contains("sample time 1"), "{msg}");
}

#[test]
fn frame_layout_needs_equal_counts() {
    let batch =
        Batch::from_tracks(&[Track::from_rotations(keys(3)), named(keys(3))], &CurveSpec::new(Curve::Slerp)).unwrap();
    let own = [0.5];
    let times = SampleTimes::new(&batch, &[None, Some(&own)], Sampling::Count(3)).unwrap();
    let job = EvalJob::new(&batch, &times).layout(Layout::Frame).derivatives(false);
    let msg = job.validate().unwrap_err().to_string();
    assert!(msg.contains("track 1 \"hips\" has 1"), "{msg}");
    assert!(job.layout(Layout::Track).run().is_ok());
}

#[test]
fn bad_sampling_requests() {
    let batch = Batch::from_tracks(&[Track::from_rotations(keys(3))], &CurveSpec::new(Curve::Slerp)).unwrap();
    for bad in
        [Sampling::Count(0), Sampling::Rate(0.0), Sampling::Rate(-1.0), Sampling::Rate(f64::NAN), Sampling::Rate(1e12)]
    {
        assert!(matches!(SampleTimes::uniform(&batch, bad), Err(Error::BadSampling(_))), "{bad:?}");
    }
}

#[test]
fn a_batch_extended_in_slices_is_the_batch_built_at_once_and_a_bad_slice_changes_nothing() {
    // More tracks than one prepared chunk, mixed curves, so slices cross chunk boundaries.
    let spec = |i: usize| CurveSpec {
        looping: false,
        ..CurveSpec::new(if i % 3 == 0 { Curve::Hermite } else { Curve::BSplineInterp })
    };
    let tracks: Vec<Track> =
        (0..20_000).map(|i| Track { name: Some(format!("t{i}")), ..Track::from_rotations(keys(4 + i % 5)) }).collect();
    let whole = Batch::from_tracks_each(&tracks, spec).unwrap();
    let mut builder = quatcurve::BatchBuilder::new();
    assert_eq!(builder.extend(&tracks[..7], spec).unwrap(), 0..7);
    assert_eq!(builder.extend(&tracks[7..], |i| spec(i + 7)).unwrap(), 7..20_000);
    // A slice whose 17,001st track is bad: an error naming its index in the batch, and the
    // builder as it was (its chunk and every chunk before it dropped again).
    let mut bad: Vec<Track> = tracks[..17_001].to_vec();
    bad[17_000].rotations[2] = [0.0; 4];
    let err = builder.extend(&bad, spec).expect_err("a zero key").to_string();
    assert!(err.contains("track 37000 \"t17000\": key 2 has norm 0"), "{err}");
    assert_eq!(builder.build().unwrap(), whole);
}

/// Tracks keyed at the same times share one knot vector in the batch; each still sees its own
/// (equal to the batch of that track alone), and other times get their own.
#[test]
fn tracks_keyed_at_the_same_times_share_one_knot_vector() {
    let at = |times: &[f64], turn: f64| Track {
        times: Some(times.to_vec()),
        ..Track::from_rotations(
            (0..times.len())
                .map(|i| quatcurve::QuatF64::exp(quatcurve::Vec3F64::new(turn * i as f64, 0.2, 0.0)).to_array())
                .collect(),
        )
    };
    let (same, other) = ([0.0, 0.4, 1.0, 1.7, 2.0], [0.0, 0.5, 1.0, 1.5, 2.5]);
    let tracks = [at(&same, 0.1), at(&same, 0.3), at(&same, -0.2), at(&other, 0.1)];
    for curve in [Curve::BSplineInterp, Curve::Hermite, Curve::Slerp] {
        let spec = CurveSpec::new(curve);
        let batch = Batch::from_tracks(&tracks, &spec).unwrap();
        let offsets: Vec<usize> = batch.tracks().iter().map(|t| t.knot_offset()).collect();
        assert!(
            offsets[0] == offsets[1] && offsets[1] == offsets[2] && offsets[3] != offsets[0],
            "{curve}: {offsets:?}"
        );
        assert_eq!(batch.knots().len(), batch.tracks()[0].knot_count() + batch.tracks()[3].knot_count(), "{curve}");
        for (i, track) in tracks.iter().enumerate() {
            let alone = Batch::from_tracks(std::slice::from_ref(track), &spec).unwrap();
            let (a, b) = (batch.view(i), alone.view(0));
            assert!(
                a.knots == b.knots
                    && a.points == b.points
                    && a.coefs == b.coefs
                    && a.track.uniform_knots() == b.track.uniform_knots(),
                "{curve} track {i}"
            );
        }
    }
}

/// Keys turning a quarter turn each (half angles pi / 4 apart): the first and third control
/// points of a span are a half turn apart, where the normalized sum can vanish; a span of two
/// (order 2) holds neighbours only, which alignment keeps within a half turn.
#[test]
fn normalized_bspline_control_points_a_half_turn_apart() {
    let turning: Vec<[f64; 4]> =
        (0..6).map(|i| quatcurve::QuatF64::exp(quatcurve::Vec3F64::new(0.0, 0.0, 0.8 * i as f64)).to_array()).collect();
    let spec = CurveSpec { knots: KnotMode::Clamped, ..CurveSpec::new(Curve::NormalizedBSpline) };
    let (err, msg) = message(named(turning.clone()), spec);
    assert!(
        matches!(err, Error::ControlPointsApart { first: 0, second: 2, order: 4, angle, .. } if (angle - 3.2).abs() < 1e-9)
            && msg.contains("control points 0 and 2")
            && msg.contains("half turn"),
        "{msg}"
    );
    let pairs = CurveSpec { order: 2, knots: KnotMode::Clamped, ..CurveSpec::new(Curve::NormalizedBSpline) };
    assert!(Batch::from_tracks(&[named(turning)], &pairs).is_ok());
}
