//! `bspline-interp` (C2 through every key) and loops, against the mathematics: scalar cubic
//! splines written here (natural and periodic, by a dense solve), key error, C2 across keys,
//! natural ends, seam continuity and wrapped sampling.

use crate::common::*;
use quatcurve::euclidean::VectorCurve;
use quatcurve::{Batch, Blend, Curve, CurveSpec, Error, KnotMode, QuatF64, Tangents, Track, TrackId, Vec3F64};

fn interp(looping: bool) -> CurveSpec {
    CurveSpec { looping, ..CurveSpec::new(Curve::BSplineInterp) }
}

/// Dense Gaussian elimination with partial pivoting (test-sized systems).
#[allow(clippy::needless_range_loop)]
fn solve_dense(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs())).unwrap();
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            for k in c..n {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    x
}

/// The scalar cubic spline through `(t_i, y_i)` in second-derivative (moment) form: natural
/// (`M_0 = M_n = 0`), or periodic in its second derivative with `y(t + T) = y(t) + (y_n -
/// y_0)` (the periodic spline when the values close). Returns `[y, y', y'']` at a time.
struct ScalarSpline {
    t: Vec<f64>,
    y: Vec<f64>,
    m: Vec<f64>,
}

impl ScalarSpline {
    fn new(t: &[f64], y: &[f64], periodic: bool) -> Self {
        let n = t.len() - 1;
        let h = |i: usize| t[i + 1] - t[i];
        let slope = |i: usize| (y[i + 1] - y[i]) / h(i);
        let m = if periodic {
            // Unknowns M_0..M_{n-1}; row i uses the neighbours across the seam.
            let mut a = vec![vec![0.0; n]; n];
            let mut b = vec![0.0; n];
            for i in 0..n {
                let prev = (i + n - 1) % n;
                let (h0, h1) = (h(prev), h(i));
                a[i][prev] += h0;
                a[i][i] += 2.0 * (h0 + h1);
                a[i][(i + 1) % n] += h1;
                b[i] = 6.0 * (slope(i) - slope(prev));
            }
            let mut m = solve_dense(a, b);
            m.push(m[0]);
            m
        } else {
            let mut a = vec![vec![0.0; n + 1]; n + 1];
            let mut b = vec![0.0; n + 1];
            a[0][0] = 1.0;
            a[n][n] = 1.0;
            for i in 1..n {
                a[i][i - 1] = h(i - 1);
                a[i][i] = 2.0 * (h(i - 1) + h(i));
                a[i][i + 1] = h(i);
                b[i] = 6.0 * (slope(i) - slope(i - 1));
            }
            solve_dense(a, b)
        };
        Self { t: t.to_vec(), y: y.to_vec(), m }
    }

    fn eval(&self, x: f64) -> [f64; 3] {
        let n = self.t.len() - 1;
        let i = (0..n).rev().find(|&i| self.t[i] <= x).unwrap_or(0);
        let (t0, t1, y0, y1, m0, m1) = (self.t[i], self.t[i + 1], self.y[i], self.y[i + 1], self.m[i], self.m[i + 1]);
        let h = t1 - t0;
        let (a, b) = ((t1 - x) / h, (x - t0) / h);
        let y = a * y0 + b * y1 + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6.0;
        let d = (y1 - y0) / h + ((1.0 - 3.0 * a * a) * m0 + (3.0 * b * b - 1.0) * m1) * h / 6.0;
        [y, d, a * m0 + b * m1]
    }
}

/// Key times with steps from `1` to `ratio` times a random base step.
fn spread_times(g: &mut Gen, count: usize, ratio: f64) -> Vec<f64> {
    let base = g.range(0.05, 0.5);
    let mut t = g.range(-2.0, 2.0);
    (0..count)
        .map(|i| {
            if i > 0 {
                t += base * g.range(1.0, ratio);
            }
            t
        })
        .collect()
}

/// 3D keys: steps of up to `max_deg` degrees about random axes.
fn steps(g: &mut Gen, count: usize, max_deg: f64) -> Vec<QuatF64> {
    let mut q = g.rotation();
    let mut out = vec![q];
    for _ in 1..count {
        q = q * QuatF64::exp(g.direction().scale(g.range(0.0, max_deg.to_radians()) / 2.0));
        out.push(q);
    }
    out
}

fn track_of(keys: &[QuatF64], times: &[f64]) -> Track {
    Track { times: Some(times.to_vec()), ..Track::from_rotations(keys.iter().map(|q| q.to_array()).collect()) }
}

fn build(track: &Track, spec: &CurveSpec) -> Batch {
    Batch::from_tracks(std::slice::from_ref(track), spec).unwrap_or_else(|e| panic!("{}: {e}", describe(spec)))
}

/// Keys about one axis: bspline-interp is the natural cubic spline of the angles, and
/// looping the periodic one (with whole turns carried as a per-cycle offset: a wheel).
#[test]
fn one_axis_equals_the_scalar_natural_and_periodic_splines() {
    for seed in 0..120u64 {
        let mut g = Gen::new(seed);
        let looping = seed % 2 == 1;
        let count = 2 + (g.next_u64() % 10) as usize + usize::from(looping);
        let axis = g.direction();
        let times = spread_times(&mut g, count, 10.0);
        let mut angles = vec![g.range(-3.0, 3.0)];
        for _ in 1..count {
            let last = *angles.last().unwrap();
            angles.push(last + g.range(-170f64, 170.0).to_radians());
        }
        if looping {
            // Close the loop, some with a whole turn (a spinning wheel), the closing step
            // kept below a half turn so keys stay the shortest way round.
            let turn = if seed % 4 == 1 { std::f64::consts::TAU } else { 0.0 };
            let n = count - 1;
            angles[n] = angles[0] + turn;
            if (angles[n] - angles[n - 1]).abs() > 170f64.to_radians() {
                angles[n - 1] = angles[n] - 0.5 * (angles[n] - angles[n - 2]).signum();
            }
        }
        let keys: Vec<QuatF64> = angles.iter().map(|&a| QuatF64::exp(axis.scale(a / 2.0))).collect();
        if angles.windows(2).any(|w| (w[1] - w[0]).abs() > 175f64.to_radians()) {
            continue;
        }
        let batch = build(&track_of(&keys, &times), &interp(looping));
        let scalar = ScalarSpline::new(&times, &angles, looping);
        let (lo, hi) = (times[0], times[count - 1]);
        for i in 0..=200 {
            let t = lo + (hi - lo) * i as f64 / 200.0;
            let s = eval(&batch, 0, t);
            let [y, dy, ddy] = scalar.eval(t);
            let err = s.rotation.angle_to(QuatF64::exp(axis.scale(y / 2.0)));
            assert!(err < 1e-9, "seed {seed} loop {looping}: rotation off the scalar spline by {err:e} at t={t}");
            assert!(
                rel_err(s.angular_velocity, axis.scale(dy)) < 1e-8,
                "seed {seed}: omega {:?} vs {dy}",
                s.angular_velocity
            );
            assert!(
                rel_err(s.angular_acceleration, axis.scale(ddy)) < 1e-7,
                "seed {seed}: alpha {:?} vs {ddy}",
                s.angular_acceleration
            );
        }
    }
}

/// Body acceleration just left of `t` (the span before) and at `t` (the span after).
fn alpha_sides(batch: &Batch, t: f64, scale: f64) -> (Vec3F64, Vec3F64) {
    (eval(batch, 0, t - 1e-9 * scale).angular_acceleration, eval(batch, 0, t).angular_acceleration)
}

/// 3D keys with steps up to 170 degrees and key intervals 10x apart, open and looping: every
/// key hit within 1e-12 rad, alpha continuous at every key, natural ends (open) or q, omega
/// and alpha continuous across the seam (loop), and wrapped sampling.
#[test]
fn through_every_key_c2_natural_or_periodic_on_hard_inputs() {
    let (mut worst_key, mut failures) = (0.0f64, 0);
    let probe: u64 = std::env::var("QC_PROBE").ok().and_then(|v| v.parse().ok()).unwrap_or(200);
    for seed in 0..probe {
        let mut g = Gen::new(1000 + seed);
        let looping = seed % 2 == 1;
        let count = 2 + (g.next_u64() % 14) as usize + 2 * usize::from(looping);
        let max_deg = [30.0, 90.0, 170.0][seed as usize % 3];
        let mut keys = steps(&mut g, count, max_deg);
        if looping {
            let n = count - 1;
            keys[n] = if g.coin() { keys[0] } else { -keys[0] };
            if keys[n - 1].angle_to(keys[n]) > 170f64.to_radians() {
                continue;
            }
        }
        let times = spread_times(&mut g, count, 10.0);
        let batch = match Batch::from_tracks(&[track_of(&keys, &times)], &interp(looping)) {
            // Newton fails on about 1 in 1,500 of these (measured over 3,000 seeds), all of
            // them loops of 170-degree steps: allowed, as a named error, at that rate.
            Err(e @ Error::NoConvergence { .. }) if max_deg > 150.0 && failures < 1 => {
                eprintln!("seed {seed}: {e}");
                failures += 1;
                continue;
            }
            built => built.unwrap_or_else(|e| panic!("seed {seed}: {e}")),
        };
        let n = count - 1;
        let scale = times[n] - times[0];
        let alpha_max = (0..=400)
            .map(|i| eval(&batch, 0, times[0] + scale * i as f64 / 400.0).angular_acceleration.length())
            .fold(1.0, f64::max);
        for (i, &key) in keys.iter().enumerate() {
            let err = eval(&batch, 0, times[i]).rotation.angle_to(key);
            worst_key = worst_key.max(err);
            assert!(err <= 1e-12, "seed {seed}: key {i} missed by {err:e}");
        }
        for &t in &times[1..n] {
            let (left, right) = alpha_sides(&batch, t, scale);
            assert!(
                (left - right).length() <= 1e-4 * alpha_max,
                "seed {seed}: alpha jumps by {:e} at key time {t} (max |alpha| {alpha_max:e})",
                (left - right).length()
            );
        }
        let (first, last) = (eval(&batch, 0, times[0]), eval(&batch, 0, times[n]));
        if looping {
            assert!(first.rotation.angle_to(last.rotation) < 1e-12, "seed {seed}: seam rotation");
            assert!(
                (first.angular_velocity - last.angular_velocity).length() <= 1e-9 * alpha_max.max(1.0) * scale,
                "seed {seed}: seam omega"
            );
            assert!(
                (first.angular_acceleration - last.angular_acceleration).length() <= 1e-8 * alpha_max,
                "seed {seed}: seam alpha"
            );
            let t = times[0] + 0.37 * scale;
            let (a, b) = (eval(&batch, 0, t), eval(&batch, 0, t + 3.0 * scale));
            assert!(
                a.rotation.angle_to(b.rotation) < 1e-12
                    && (a.angular_velocity - b.angular_velocity).length() < 1e-9 * alpha_max,
                "seed {seed}: wrap"
            );
            let c = eval(&batch, 0, t - 2.0 * scale);
            assert!(a.rotation.angle_to(c.rotation) < 1e-12, "seed {seed}: wrap backwards");
        } else {
            for end in [first, last] {
                assert!(
                    end.angular_acceleration.length() <= 1e-9 * alpha_max,
                    "seed {seed}: natural end alpha {:?}",
                    end.angular_acceleration
                );
            }
        }
    }
    eprintln!("bspline-interp: worst key error {worst_key:e} rad over 200 hard tracks");
}

/// Every family that loops keeps its continuity class across the seam: q and omega (C1
/// families) and alpha (C2) agree at the two ends, and samples wrap.
#[test]
fn looping_families_are_continuous_across_the_seam() {
    let specs = [
        CurveSpec::new(Curve::Slerp),
        CurveSpec::new(Curve::Squad),
        CurveSpec::new(Curve::Hermite),
        CurveSpec { blend: Blend::Quadratic, ..CurveSpec::new(Curve::NamKim) },
        CurveSpec::new(Curve::NamKim),
        CurveSpec { knots: KnotMode::Phantom, ..CurveSpec::new(Curve::BSpline) },
        interp(false),
    ];
    for seed in 0..40u64 {
        for spec in specs {
            let spec = CurveSpec { looping: true, ..spec };
            let mut g = Gen::new(seed);
            let count = 3 + (g.next_u64() % 8) as usize;
            let mut keys = steps(&mut g, count, 120.0);
            keys[count - 1] = keys[0].mul_scalar(if g.coin() { 1.0 } else { -1.0 });
            // Squad is C1 in time only on uniform times, phantom needs them.
            let uniform = matches!(spec.curve, Curve::Squad | Curve::BSpline);
            let times = if uniform {
                (0..count).map(|i| 0.5 + 0.3 * i as f64).collect()
            } else {
                spread_times(&mut g, count, 4.0)
            };
            let batch = build(&track_of(&keys, &times), &spec);
            let (first, last) = (eval(&batch, 0, times[0]), eval(&batch, 0, times[count - 1]));
            let label = describe(&spec);
            assert!(first.rotation.angle_to(last.rotation) < 1e-12, "{label} seed {seed}: seam rotation");
            let scale = first.angular_velocity.length().max(last.angular_velocity.length()).max(1.0);
            if spec.curve != Curve::Slerp {
                assert!(
                    (first.angular_velocity - last.angular_velocity).length() < 1e-9 * scale,
                    "{label} seed {seed}: seam omega {:?} vs {:?}",
                    first.angular_velocity,
                    last.angular_velocity
                );
            }
            if matches!(spec.curve, Curve::BSpline | Curve::BSplineInterp) {
                let a = first.angular_acceleration.length().max(1.0);
                assert!(
                    (first.angular_acceleration - last.angular_acceleration).length() < 1e-8 * a,
                    "{label} seed {seed}: seam alpha"
                );
            }
            let period = times[count - 1] - times[0];
            let t = times[0] + 0.61 * period;
            assert!(
                eval(&batch, 0, t).rotation.angle_to(eval(&batch, 0, t + 2.0 * period).rotation) < 1e-12,
                "{label}: wrap"
            );
        }
    }
}

/// Keys about one axis that close (no offset): each looping family equals its Euclidean
/// twin on the angles (where rotations commute), which follows the same seam rules.
#[test]
fn one_axis_loops_equal_their_euclidean_twins() {
    let specs = [
        CurveSpec::new(Curve::Squad),
        CurveSpec::new(Curve::Hermite),
        CurveSpec { tangents: Tangents::Zero, ..CurveSpec::new(Curve::Hermite) },
        CurveSpec::new(Curve::NamKim),
        CurveSpec { knots: KnotMode::Phantom, ..CurveSpec::new(Curve::BSpline) },
        interp(false),
    ];
    for seed in 0..30u64 {
        for spec in specs {
            let spec = CurveSpec { looping: true, ..spec };
            let mut g = Gen::new(seed);
            let count = 3 + (g.next_u64() % 8) as usize;
            let axis = g.direction();
            let mut angles: Vec<f64> = (0..count).map(|_| g.range(-1.4, 1.4)).collect();
            angles[count - 1] = angles[0];
            let uniform = matches!(spec.curve, Curve::BSpline);
            // Key spacing within 2x: Nam-Kim's arcs stay within a turn of each other, where
            // the rotation blend is the scalar one.
            let times =
                if uniform { (0..count).map(|i| 0.25 * i as f64).collect() } else { spread_times(&mut g, count, 2.0) };
            let keys: Vec<QuatF64> = angles.iter().map(|&a| QuatF64::exp(axis.scale(a / 2.0))).collect();
            let batch = build(&track_of(&keys, &times), &spec);
            let values: Vec<[f64; 3]> = angles.iter().map(|&a| [a, 0.0, 0.0]).collect();
            let twin = VectorCurve::new(&TrackId { index: 0, name: None }, Some(&times), &values, None, &spec).unwrap();
            for i in 0..=100 {
                let t = times[0] + (times[count - 1] - times[0]) * (i as f64 / 100.0 * 1.3 - 0.15);
                let angle = twin.evaluate(t).x;
                let err = eval(&batch, 0, t).rotation.angle_to(QuatF64::exp(axis.scale(angle / 2.0)));
                assert!(
                    err < 1e-9,
                    "{} seed {seed}: {err:e} from the Euclidean twin at t={t} times {times:?} angles {angles:?}",
                    describe(&spec)
                );
            }
        }
    }
}

/// The Euclidean analogue: natural cubic spline through the keys, and looping with the
/// per-cycle offset kept (root motion): `p(t + T) = p(t) + D`, velocity periodic.
#[test]
fn vector_interp_is_the_natural_spline_and_loops_keep_their_offset() {
    let id = TrackId { index: 0, name: Some("root".into()) };
    for seed in 0..40u64 {
        let mut g = Gen::new(seed);
        let count = 2 + (g.next_u64() % 9) as usize;
        let times = spread_times(&mut g, count, 10.0);
        let values: Vec<[f64; 3]> =
            (0..count).map(|_| [g.range(-2.0, 2.0), g.range(-2.0, 2.0), g.range(-2.0, 2.0)]).collect();
        let open = VectorCurve::new(&id, Some(&times), &values, None, &interp(false)).unwrap();
        let looped = VectorCurve::new(&id, Some(&times), &values, None, &interp(true)).unwrap();
        let n = count - 1;
        let offset = Vec3F64::from_array(values[n]) - Vec3F64::from_array(values[0]);
        let period = times[n] - times[0];
        for axis in 0..3 {
            let ys: Vec<f64> = values.iter().map(|v| v[axis]).collect();
            let natural = ScalarSpline::new(&times, &ys, false);
            let periodic = ScalarSpline::new(&times, &ys, true);
            for i in 0..=50 {
                let t = times[0] + period * i as f64 / 50.0;
                let get = |v: Vec3F64| v.to_array()[axis];
                assert!(
                    (get(open.evaluate(t)) - natural.eval(t)[0]).abs() < 1e-9,
                    "seed {seed}: natural spline at {t}"
                );
                assert!(
                    (get(looped.evaluate(t)) - periodic.eval(t)[0]).abs() < 1e-9,
                    "seed {seed}: periodic spline with offset at {t}"
                );
            }
        }
        let t = times[0] + 0.3 * period;
        let shifted = looped.evaluate(t + period) - looped.evaluate(t) - offset;
        assert!(shifted.length() < 1e-9, "seed {seed}: p(t + T) - p(t) - D = {shifted:?}");
        // Velocity near both ends of the period equals the periodic spline's (continuous
        // across the seam by construction), to finite-difference accuracy.
        let velocity = |t: f64| derivative(|x| looped.evaluate(x), t, 1e-4 * period);
        for t in [times[0] + 1e-3 * period, times[n] - 1e-3 * period] {
            let v = velocity(t);
            for axis in 0..3 {
                let ys: Vec<f64> = values.iter().map(|v| v[axis]).collect();
                let dy = ScalarSpline::new(&times, &ys, true).eval(t)[1];
                assert!(
                    (v.to_array()[axis] - dy).abs() < 1e-6 * dy.abs().max(1.0),
                    "seed {seed}: velocity {v:?} vs periodic spline {dy} at {t}"
                );
            }
        }
    }
}

#[test]
fn loop_errors_name_the_track() {
    let keys =
        [QuatF64::identity(), QuatF64::exp(Vec3F64::new(0.3, 0.0, 0.0)), QuatF64::exp(Vec3F64::new(0.3, 0.2, 0.0))];
    let track = Track { name: Some("spine".into()), ..track_of(&keys, &[0.0, 1.0, 2.0]) };
    let err = Batch::from_tracks(std::slice::from_ref(&track), &interp(true)).unwrap_err();
    assert!(matches!(err, Error::LoopNotClosed { last: 2, .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("\"spine\"") && msg.contains("key 2") && msg.contains("first rotation"), "{msg}");

    let closed = track_of(&[keys[0], keys[1], keys[2], keys[1], keys[0]], &[0.0, 1.0, 2.0, 3.0, 4.0]);
    for spec in [
        CurveSpec::new(Curve::Bezier),
        CurveSpec { knots: KnotMode::Uniform, ..CurveSpec::new(Curve::BSpline) },
        CurveSpec { knots: KnotMode::Clamped, ..CurveSpec::new(Curve::BSpline) },
    ] {
        let spec = CurveSpec { looping: true, ..spec };
        let err = Batch::from_tracks(std::slice::from_ref(&closed), &spec).unwrap_err();
        assert!(matches!(err, Error::LoopUnsupported { .. }), "{}: {err:?}", describe(&spec));
        assert!(err.to_string().contains("track 0") && err.to_string().contains("cannot loop"), "{err}");
    }
    // A whole turn closes: q_n = -q_0 is the same rotation.
    let wheel: Vec<QuatF64> =
        (0..=4).map(|i| QuatF64::exp(Vec3F64::new(0.0, 0.0, std::f64::consts::FRAC_PI_4 * i as f64))).collect();
    assert!(wheel[4].dot(wheel[0]) < -0.99);
    Batch::from_tracks(&[track_of(&wheel, &[0.0, 1.0, 2.0, 3.0, 4.0])], &interp(true)).unwrap();
}

/// Keys a near half turn apart at every step, with a 1000x jump in key spacing: the C2
/// interpolant would need control steps past a half turn, which shortest-path logs cannot
/// express, so Newton cannot converge. The error names the track, the worst key and the rule.
#[test]
fn non_convergence_is_an_error_naming_the_track_and_key() {
    let mut keys = vec![QuatF64::identity()];
    for i in 1..8 {
        let axis = if i % 2 == 0 { Vec3F64::new(1.0, 0.0, 0.0) } else { Vec3F64::new(0.0, 1.0, 0.0) };
        keys.push(*keys.last().unwrap() * QuatF64::exp(axis.scale(179f64.to_radians() / 2.0)));
    }
    let times = [0.0, 1.0, 1.001, 2.0, 2.001, 3.0, 3.001, 4.0];
    let track = Track { name: Some("jitter".into()), ..track_of(&keys, &times) };
    let err = Batch::from_tracks(std::slice::from_ref(&track), &interp(false)).unwrap_err();
    let Error::NoConvergence { key, error, .. } = &err else { panic!("expected NoConvergence, got {err:?}") };
    assert!(*key < 8 && *error > 1e-12, "{err:?}");
    let msg = err.to_string();
    assert!(
        msg.contains("\"jitter\"") && msg.contains(&format!("key {key}")) && msg.contains("did not converge"),
        "{msg}"
    );
}
