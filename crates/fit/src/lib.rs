//! Curve fitting, the core of curve compression: a sampled channel as the fewest control points
//! of a clamped cubic B-spline whose every sample lies within its tolerance (each sample its
//! own: a clip holds its frames tighter than points between them). Rotations take the
//! normalized form (`normalized-bspline` with explicit knots, which every evaluator decodes),
//! vectors its Euclidean analogue `sum B_i(t) p_i`. Knots are placed per channel: a span whose
//! samples are off by more than the tolerance is split at its middle sample, and the control
//! points are fitted again, until every span is within it or has no sample left to split at.
//!
//! Fitting a vector channel is linear least squares on the B-spline basis. Fitting rotations
//! starts from the same least squares on the quaternions' components, then takes
//! Levenberg-Marquardt steps in each control point's tangent space (`Steps`); a step is kept
//! only when the weighted sum of squares falls, and the error is always measured with the
//! reference evaluator.

pub mod banded;
pub mod clip;
pub mod job;

use banded::Banded;
use quatcurve_core::basis::{bspline_cumulative_into, bspline_cumulative_values_into};
use quatcurve_core::quat::{QuatF64, Vec3F64};
use quatcurve_core::segment::locate_ascending;
use quatcurve_qcf::fitted::{clamped, Fit, SpanBasis, ORDER};

/// Levenberg-Marquardt steps at most per knot vector.
const STEPS: usize = 60;

/// The least relative fall in the weighted sum of squares that counts as progress.
const KEPT_GAIN: f64 = 1e-9;

/// Damping values tried (each ten times the last) before a step is given up.
const DAMPING_TRIES: usize = 8;

/// A sample's span `l` and the cumulative basis there ([`spans`]).
type Span = SpanBasis;

/// A sample's first control point and the [`ORDER`] basis values from there ([`collocation`]).
type Row = (usize, [f64; ORDER]);

/// Per sample time (ascending), its span `l` (`locate`) and the cumulative basis there
/// (`B~_{l-k+2..=l}`, [`SpanBasis`]) of a clamped B-spline of order `k` (at most [`ORDER`]): what the
/// reference evaluator computes for each time, computed once per knot vector.
fn spans_of_order(knots: &[f64], k: usize, times: &[f64]) -> Vec<Span> {
    let last = knots.len() - k - 1;
    locate_ascending(knots, k - 1, last, times)
        .map(|(l, t)| {
            let mut basis = [[0.0; 3]; ORDER - 1];
            bspline_cumulative_into(knots, k, l, t, &mut basis[..k - 1]);
            (l, basis)
        })
        .collect()
}

/// [`spans_of_order`] of a cubic.
fn spans(knots: &[f64], times: &[f64]) -> Vec<Span> {
    spans_of_order(knots, ORDER, times)
}

/// Per sample time, the first control point it depends on and the [`ORDER`] basis values
/// `B_i(t)` from there, derived from the cumulative basis of its span (`B_i = B~_i - B~_{i+1}`).
fn collocation(spans: &[Span]) -> Vec<Row> {
    spans
        .iter()
        .map(|(l, cumulative)| {
            // cumulative[m] is B~_{l-k+2+m}; B~ is 1 below that window and 0 above it.
            let at = |m: usize| {
                if m == 0 {
                    1.0
                } else if m < ORDER {
                    cumulative[m - 1][0]
                } else {
                    0.0
                }
            };
            (l + 1 - ORDER, std::array::from_fn(|m| at(m) - at(m + 1)))
        })
        .collect()
}

/// [`collocation`] computed from the knots directly, with the cumulative basis's values
/// alone (no derivatives, nothing allocated per sample): what a linear fit needs.
fn rows(knots: &[f64], times: &[f64]) -> Vec<Row> {
    rows_after(knots, times, None)
}

/// [`rows`], taking a sample's basis from `before` (the rows of the same times on other knots)
/// where the knots it depends on (`2 ORDER` around its span) are the same: a split changes the
/// basis of the few samples near it.
fn rows_after(knots: &[f64], times: &[f64], before: Option<(&[f64], &[Row])>) -> Vec<Row> {
    let last = knots.len() - ORDER - 1;
    let window = |knots: &[f64], l: usize| -> [f64; 2 * ORDER] { std::array::from_fn(|i| knots[l + 1 - ORDER + i]) };
    locate_ascending(knots, ORDER - 1, last, times)
        .enumerate()
        .map(|(s, (l, t))| {
            if let Some((old_knots, old_rows)) = before {
                let (first, b) = old_rows[s];
                if window(old_knots, first + ORDER - 1) == window(knots, l) {
                    return (l + 1 - ORDER, b);
                }
            }
            let mut cumulative = [0.0; ORDER - 1];
            bspline_cumulative_values_into(knots, ORDER, l, t, &mut cumulative);
            let at = |m: usize| match m {
                0 => 1.0,
                m if m < ORDER => cumulative[m - 1],
                _ => 0.0,
            };
            (l + 1 - ORDER, std::array::from_fn(|m| at(m) - at(m + 1)))
        })
        .collect()
}

/// The least-squares control point offsets for `residuals` on the basis `rows`, `n` controls.
fn least_squares<const N: usize>(
    rows: &[Row],
    weights: &[f64],
    residuals: &[[f64; N]],
    n: usize,
) -> Option<Vec<[f64; N]>> {
    let mut normal = Banded::zeros(n, ORDER);
    let mut rhs = vec![[0.0; N]; n];
    for (((first, b), r), &w) in rows.iter().zip(residuals).zip(weights) {
        for (a, &ba) in b.iter().enumerate() {
            for (c, &bc) in b.iter().enumerate().take(a + 1) {
                normal.add(first + a, first + c, w * ba * bc);
            }
            for (x, &rv) in rhs[first + a].iter_mut().zip(r) {
                *x += w * ba * rv;
            }
        }
    }
    // A control point no sample depends on (a span without samples) keeps its value.
    for i in 0..n {
        normal.add(i, i, 1e-12);
    }
    let factored = normal.factor()?;
    for c in 0..N {
        let mut column: Vec<f64> = rhs.iter().map(|r| r[c]).collect();
        factored.solve(&mut column);
        for (r, v) in rhs.iter_mut().zip(column) {
            r[c] = v;
        }
    }
    Some(rhs)
}

/// Times of the knots to insert: the middle sample of every span where a sample's error
/// exceeds its tolerance, where that sample lies strictly inside the span; a span between two samples
/// that is still off (a flip in one frame, which a smooth cubic cannot follow: it rings, and
/// its control points would need to be more than half a turn apart) gets its inner ends
/// repeated up to `ORDER - 1` times, so the curve passes through a control point there and
/// the span stands alone.
fn splits(knots: &[f64], times: &[f64], errors: &[f64], tolerances: &[f64]) -> Vec<f64> {
    let off = |s: usize| errors[s] > tolerances[s];
    let (start, end) = (knots[0], *knots.last().unwrap());
    let multiplicity = |v: f64| knots.iter().filter(|&&k| k == v).count();
    let mut out = Vec::new();
    let mut j = 0;
    for span in knots.windows(2).filter(|w| w[1] > w[0]) {
        let begin = j;
        while j < times.len() && (times[j] < span[1] || (span[1] == end && times[j] <= span[1])) {
            j += 1;
        }
        let end_sample_off = j < times.len() && off(j);
        if !end_sample_off && !(begin..j).any(off) {
            continue;
        }
        let inside: Vec<usize> = (begin..j).filter(|&s| times[s] > span[0] && times[s] < span[1]).collect();
        if inside.is_empty() {
            for v in [span[0], span[1]] {
                if v > start && v < end && multiplicity(v) < ORDER - 1 && !out.contains(&v) {
                    out.push(v);
                }
            }
        } else {
            out.push(times[inside[inside.len() / 2]]);
        }
    }
    out
}

/// Least-squares weights: the inverse square of each tolerance, the tightest weighing 1 (a
/// zero tolerance counts as the smallest positive one).
fn weights(tolerances: &[f64]) -> Vec<f64> {
    let positive = |t: f64| t.max(f64::MIN_POSITIVE);
    let tightest = tolerances.iter().copied().map(positive).fold(f64::INFINITY, f64::min);
    tolerances.iter().map(|&t| (tightest / positive(t)).powi(2)).collect()
}

/// Merges sorted `a` and `b`.
fn merged(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out: Vec<f64> = a.iter().chain(b).copied().collect();
    out.sort_by(f64::total_cmp);
    out
}

/// Index and value of the largest of `errors`.
fn worst(errors: &[f64]) -> (usize, f64) {
    errors.iter().copied().enumerate().fold((0, 0.0), |w, (i, e)| if e > w.1 { (i, e) } else { w })
}

/// `values` at `times` (at least two, strictly increasing) as a clamped cubic B-spline
/// `sum B_i(t) p_i` whose every sample is within its tolerance (Euclidean distance), or as
/// close as knots at the samples allow. Least squares weighs each sample by the inverse square
/// of its tolerance.
///
/// # Panics
/// With fewer than two samples or a length mismatch.
#[must_use]
pub fn fit_vectors(times: &[f64], values: &[[f64; 3]], tolerances: &[f64]) -> Fit<[f64; 3]> {
    assert!(
        times.len() >= 2 && times.len() == values.len() && times.len() == tolerances.len(),
        "at least two samples, one value and one tolerance each"
    );
    let weights = weights(tolerances);
    let (start, end) = (times[0], *times.last().unwrap());
    let mut interior = Vec::new();
    loop {
        let knots = clamped(ORDER, start, end, &interior);
        let n = knots.len() - ORDER;
        let rows = rows(&knots, times);
        let controls =
            least_squares(&rows, &weights, values, n).expect("a ridge-regularized normal matrix is definite");
        let mut fit = Fit { knots, controls, worst: 0.0, worst_at: 0 };
        let curve = fit.evaluate(times).expect("a fitted curve evaluates");
        let errors: Vec<f64> = curve.iter().zip(values).map(|(p, v)| (*p - Vec3F64::from_array(*v)).length()).collect();
        let new = splits(&fit.knots, times, &errors, tolerances);
        if new.is_empty() {
            (fit.worst_at, fit.worst) = worst(&errors);
            return fit;
        }
        interior = merged(&interior, &new);
    }
}

/// `rotations` at `times` (at least two, strictly increasing) as a normalized cubic B-spline
/// ([`quatcurve_qcf::fitted::CUBIC_ROTATIONS`]) whose every sample is within its
/// tolerance (radians), or as close as knots at the samples allow; weighted as
/// [`fit_vectors`]. `None` where no such curve keeps its rule ([`RotationStart::fit_below`]).
///
/// # Panics
/// With fewer than two samples or a length mismatch.
#[must_use]
pub fn fit_rotations(times: &[f64], rotations: &[QuatF64], tolerances: &[f64]) -> Option<Fit<QuatF64>> {
    RotationStart::new(times, rotations, tolerances).fit_below(usize::MAX)
}

/// The linear first stage of [`fit_rotations`]: the quaternions' components fitted as a plain
/// cubic B-spline, whose knots and control points the normalized form starts from. Knots are
/// only added after it, so its control point count is a lower bound on the fit's: a caller
/// with a cheaper form of fewer points need not go on.
pub struct RotationStart<'a> {
    times: &'a [f64],
    tolerances: &'a [f64],
    /// Unit, each on the side of the one before.
    samples: Vec<QuatF64>,
    weights: Vec<f64>,
    interior: Vec<f64>,
    controls: Vec<[f64; 4]>,
}

impl<'a> RotationStart<'a> {
    /// The components' fit of `rotations` at `times` within `tolerances` ([`fit_rotations`]).
    ///
    /// # Panics
    /// With fewer than two samples or a length mismatch.
    #[must_use]
    pub fn new(times: &'a [f64], rotations: &[QuatF64], tolerances: &'a [f64]) -> Self {
        Self::below(times, rotations, tolerances, usize::MAX).expect("no bound on the control points")
    }

    /// [`RotationStart::new`], or `None` once its knots make `most` control points or more:
    /// knots are only added, so the normalized form would have as many ([`Self::fit_below`]),
    /// and the splitting stops there.
    ///
    /// # Panics
    /// With fewer than two samples or a length mismatch.
    #[must_use]
    pub fn below(times: &'a [f64], rotations: &[QuatF64], tolerances: &'a [f64], most: usize) -> Option<Self> {
        assert!(
            times.len() >= 2 && times.len() == rotations.len() && times.len() == tolerances.len(),
            "at least two samples, one rotation and one tolerance each"
        );
        let weights = weights(tolerances);
        let mut samples = rotations.to_vec();
        for j in 1..samples.len() {
            samples[j] = samples[j].normalize().aligned_with(samples[j - 1]);
        }
        let (interior, controls) = component_knots(times, &samples, &weights, tolerances, most)?;
        Some(Self { times, tolerances, samples, weights, interior, controls })
    }

    /// How many control points the components' fit has: at least, the normalized form's.
    #[must_use]
    pub fn controls(&self) -> usize {
        self.controls.len()
    }

    /// The normalized form from here: Levenberg-Marquardt steps on the knots, then spans
    /// still off split and the steps run again, until none is; `None` once its knots make
    /// `most` control points or more (a caller with a cheaper form of that many stops there:
    /// frames that flip by more than a quarter turn split a cubic down to C0 at every sample),
    /// or where its control points break the form's rule (two of one span half a turn apart:
    /// a joint that turns that far within a few frames).
    #[must_use]
    pub fn fit_below(self, most: usize) -> Option<Fit<QuatF64>> {
        let Self { times, tolerances, samples, weights, mut interior, controls } = self;
        let (start, end) = (times[0], *times.last().unwrap());
        let mut fit: Option<Fit<QuatF64>> = None;
        loop {
            if interior.len() + ORDER >= most {
                return None;
            }
            let knots = clamped(ORDER, start, end, &interior);
            let spans = spans(&knots, times);
            let rows = collocation(&spans);
            // First guess: the components' control points, normalized; after a split, each
            // control point at its Greville abscissa on the last fit.
            let greville: Vec<f64> =
                (0..knots.len() - ORDER).map(|i| knots[i + 1..i + ORDER].iter().sum::<f64>() / 3.0).collect();
            let guess = match &fit {
                Some(previous) => previous.evaluate(&greville).ok()?,
                None => controls.iter().map(|c| QuatF64::from_array(*c).normalize()).collect(),
            };
            let start_fit = Fit { knots, controls: guess, worst: f64::INFINITY, worst_at: 0 };
            let (current, errors) = refine(start_fit, &samples, &spans, &rows, &weights)?;
            let new = splits(&current.knots, times, &errors, tolerances);
            let done = new.is_empty();
            interior = merged(&interior, &new);
            fit = Some(current);
            if done {
                return fit;
            }
        }
    }
}

/// Interior knots and control points of `samples` (unit, each on the side of the one before)
/// fitted as four components of a clamped cubic B-spline by linear least squares, split as
/// [`fit_vectors`] until every sample's chord is within half its tolerance (a rotation by a
/// small angle `a` moves the unit quaternion by a chord of about `a / 2`); `None` once the
/// knots make `most` control points or more.
fn component_knots(
    times: &[f64],
    samples: &[QuatF64],
    weights: &[f64],
    tolerances: &[f64],
    most: usize,
) -> Option<(Vec<f64>, Vec<[f64; 4]>)> {
    let values: Vec<[f64; 4]> = samples.iter().map(|q| q.to_array()).collect();
    let chords: Vec<f64> = tolerances.iter().map(|t| t / 2.0).collect();
    let (start, end) = (times[0], *times.last().unwrap());
    let mut interior = Vec::new();
    let mut before: Option<(Vec<f64>, Vec<Row>)> = None;
    loop {
        if interior.len() + ORDER >= most {
            return None;
        }
        let knots = clamped(ORDER, start, end, &interior);
        let rows = rows_after(&knots, times, before.as_ref().map(|(k, r)| (k.as_slice(), r.as_slice())));
        let controls = least_squares(&rows, weights, &values, knots.len() - ORDER)
            .expect("a ridge-regularized normal matrix is definite");
        let errors: Vec<f64> = rows
            .iter()
            .zip(&values)
            .map(|((first, b), v)| {
                let mut p = [0.0; 4];
                for (m, &bm) in b.iter().enumerate() {
                    for (x, c) in p.iter_mut().zip(controls[first + m]) {
                        *x += bm * c;
                    }
                }
                p.iter().zip(v).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt()
            })
            .collect();
        let new = splits(&knots, times, &errors, &chords);
        if new.is_empty() {
            return Some((interior, controls));
        }
        interior = merged(&interior, &new);
        before = Some((knots, rows));
    }
}

/// The samples around `t` among `times` (at least two): the first's index and how far `t` is
/// from it to the next, held to `0..=1` outside.
pub(crate) fn bracket(times: &[f64], t: f64) -> (usize, f64) {
    let j = times.partition_point(|&s| s <= t).clamp(1, times.len() - 1);
    (j - 1, ((t - times[j - 1]) / (times[j] - times[j - 1])).clamp(0.0, 1.0))
}

/// Per control point `i`, the scalar band `sum of w B_i B_(i - d)` over the samples (`d <
/// ORDER`): it depends on the knots and the weights alone, so a knot vector gathers it once
/// for all of its steps.
fn gram(rows: &[Row], weights: &[f64], n: usize) -> Vec<[f64; ORDER]> {
    let mut gram = vec![[0.0; ORDER]; n];
    for ((first, b), &w) in rows.iter().zip(weights) {
        for a in 0..ORDER {
            let wb = w * b[a];
            for c in 0..=a {
                gram[first + a][a - c] += wb * b[c];
            }
        }
    }
    gram
}

/// The Gauss-Newton normal equations of every control point's step (its body frame) for
/// `residuals` (each sample's, in the curve's body frame there), undamped. On the normalized
/// form `q = p / |p|`, `p = sum B_i c_i`, turning control point `i` by `exp(d)` moves `p` by
/// `B_i c_i (d, 0)`, and the curve turns by `e = vec(q^-1 dp) / |p|` (the projection off `q`
/// drops nothing from the vector part): `J_i = B_i M(q^-1 c_i) / |p|` with `M(m) d = vec(m (d,
/// 0))`. The normal equations couple a point's three components (a band of `3 * ORDER`). Each
/// damping tried solves them again without gathering them again.
///
/// Assembled per control point, not per sample, with `|p|` taken as 1 (a span's control points
/// lie a few degrees apart, so `|p|` is 1 to a few parts in 1e4): `J^T r` is exact then,
/// block `a` being `vec(c_a^-1 sum of w B_a q (r, 0))`, and `J^T J` is taken with the
/// quaternions' full 4-d products, `M(m_a)^T M(m_c)` plus the outer product of the two
/// points' `vec(m)`s: `c_a^-1 c_c` whatever the sample. Block `(a, c)` is then `(sum of w B_a
/// B_c) M(c_a^-1 c_c)` ([`gram`]). That adds a positive term of second order in the points'
/// distance from the curve, a little damping of its own; over the samples only a quaternion
/// per control point is gathered.
struct Steps {
    normal: Banded,
    rhs: Vec<f64>,
    /// The mean diagonal (`sum B^2` over the samples per control point), damping's unit.
    mean: f64,
}

impl Steps {
    fn new(
        rows: &[Row],
        gram: &[[f64; ORDER]],
        curve: &[QuatF64],
        controls: &[QuatF64],
        weights: &[f64],
        residuals: &[[f64; 3]],
    ) -> Self {
        let n = controls.len();
        // world[i]: sum of w B_i q (r, 0).
        let mut world = vec![[0.0; 4]; n];
        for ((((first, b), q), r), &w) in rows.iter().zip(curve).zip(residuals).zip(weights) {
            let v = (*q * QuatF64::from_xyzw(r[0], r[1], r[2], 0.0)).to_array();
            for a in 0..ORDER {
                let wb = w * b[a];
                for (sum, v) in world[first + a].iter_mut().zip(v) {
                    *sum += wb * v;
                }
            }
        }
        let controls: Vec<QuatF64> = controls.iter().map(|c| c.normalize()).collect();
        let mut normal = Banded::zeros(3 * n, 3 * ORDER);
        let mut rhs = vec![0.0; 3 * n];
        for i in 0..n {
            let [x, y, z, _] = (controls[i].conjugate() * QuatF64::from_array(world[i])).to_array();
            rhs[3 * i..3 * i + 3].copy_from_slice(&[x, y, z]);
            for (d, &sum) in gram[i].iter().enumerate().take(i + 1) {
                let j = i - d;
                let block = vec_product(controls[i].conjugate() * controls[j]);
                for (x, row) in block.iter().enumerate() {
                    for (y, &value) in row.iter().enumerate().filter(|&(y, _)| d > 0 || y <= x) {
                        normal.add(3 * i + x, 3 * j + y, sum * value);
                    }
                }
            }
        }
        let mean = gram.iter().map(|g| g[0]).sum::<f64>() / n as f64;
        Self { normal, rhs, mean }
    }

    /// The steps with `damping` (relative to the mean diagonal) added to the diagonal, and the
    /// fall in the weighted sum of squares the linear model predicts for them (`d . g + l |d|^2`
    /// for `(J^T W J + l I) d = g`); `None` when the system is not positive definite.
    fn damped(&self, damping: f64) -> Option<(Vec<[f64; 3]>, f64)> {
        let diagonal = 1e-12 + damping * self.mean;
        let mut normal = self.normal.clone();
        for i in 0..self.rhs.len() {
            normal.add(i, i, diagonal);
        }
        let mut steps = self.rhs.clone();
        normal.factor()?.solve(&mut steps);
        let predicted = steps.iter().zip(&self.rhs).map(|(d, g)| d * g + diagonal * d * d).sum();
        Some((steps.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(), predicted))
    }
}

/// `M(m)`: the matrix of `d -> vec(m (d, 0))`, `m_w I + [m_v]x`.
fn vec_product(m: QuatF64) -> [[f64; 3]; 3] {
    let [x, y, z, w] = m.to_array();
    [[w, -z, y], [z, w, -x], [-y, x, w]]
}

/// Levenberg-Marquardt steps on the control points of `fit` (the sum of squared residual
/// angles falls at every step kept; damping, a multiple of the normal matrix's mean diagonal,
/// grows until a step helps); its worst sample, and every sample's angle to the curve, measured
/// by the reference evaluator at the samples. The steps evaluate the curve at the samples'
/// `spans` (their basis computed once, the reference's own bits), `rows` their collocation.
/// `None` where `fit`'s own control points break the normalized form's rule (steps that would
/// break it are not kept).
fn refine(
    mut fit: Fit<QuatF64>,
    samples: &[QuatF64],
    spans: &[Span],
    rows: &[Row],
    weights: &[f64],
) -> Option<(Fit<QuatF64>, Vec<f64>)> {
    // `None` for control points the normalized form refuses (two of a span half a turn apart).
    let residuals_of = |controls: &Fit<QuatF64>| -> Option<(Vec<QuatF64>, Vec<[f64; 3]>, f64)> {
        let curve = controls.evaluate_spans(spans).ok()?;
        // Body-frame residuals, in the exp/log convention of the controls' update.
        let residuals: Vec<[f64; 3]> =
            curve.iter().zip(samples).map(|(q, s)| (q.conjugate() * *s).log().to_array()).collect();
        let sum = residuals.iter().zip(weights).map(|(r, w)| w * (r[0] * r[0] + r[1] * r[1] + r[2] * r[2])).sum();
        Some((curve, residuals, sum))
    };
    let (mut curve, mut residuals, mut sum) = residuals_of(&fit)?;
    let gram = gram(rows, weights, fit.controls.len());
    let mut damping = 0.0;
    for _ in 0..STEPS {
        let mut kept = false;
        let system = Steps::new(rows, &gram, &curve, &fit.controls, weights, &residuals);
        for _ in 0..DAMPING_TRIES {
            let Some((steps, predicted)) = system.damped(damping) else { break };
            // More damping only shortens the step: once the model promises less than a kept
            // step must gain, none of them is tried (else a converged fit's last step tries all
            // dampings: half of the steps' curve evaluations).
            if predicted <= sum * KEPT_GAIN {
                break;
            }
            let controls = fit
                .controls
                .iter()
                .zip(&steps)
                .map(|(c, d)| (*c * QuatF64::exp(Vec3F64::from_array(*d))).normalize())
                .collect();
            let candidate = Fit { knots: fit.knots.clone(), controls, worst: 0.0, worst_at: 0 };
            let better = residuals_of(&candidate).filter(|&(_, _, s)| s < sum);
            if let Some((c, r, s)) = better {
                kept = s < sum * (1.0 - KEPT_GAIN);
                (fit, curve, residuals, sum) = (candidate, c, r, s);
                damping *= 0.1;
                break;
            }
            damping = if damping == 0.0 { 1e-4 } else { damping * 10.0 };
        }
        if !kept {
            break;
        }
    }
    // `curve` is the kept fit's at the spans: the reference evaluator's at the samples, to the bit.
    let errors: Vec<f64> = curve.iter().zip(samples).map(|(q, s)| q.angle_to(*s)).collect();
    (fit.worst_at, fit.worst) = worst(&errors);
    Some((fit, errors))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rotation(t: f64) -> QuatF64 {
        QuatF64::from_rotation_vector(Vec3F64::new((2.0 * t).sin(), 0.3 * t, (3.0 * t).cos() * 0.5))
    }

    /// [`Steps`] assembled sample by sample, block by block, as the Jacobian reads: the
    /// oracle of its per-control-point assembly. `J^T r` with the curve's turn `J_m = B_m
    /// M(q^-1 c_m)`, `J^T J` with the same move's full 4-d quaternion, `B_m q^-1 c_m (d, 0)`.
    #[allow(clippy::type_complexity)]
    fn rotation_steps_per_sample(
        rows: &[Row],
        curve: &[QuatF64],
        controls: &[QuatF64],
        weights: &[f64],
        residuals: &[[f64; 3]],
        damping: f64,
    ) -> Option<Vec<[f64; 3]>> {
        let n = controls.len();
        let mut normal = Banded::zeros(3 * n, 3 * ORDER);
        let mut rhs = vec![0.0; 3 * n];
        for ((((first, b), q), r), &w) in rows.iter().zip(curve).zip(residuals).zip(weights) {
            // Column k of block m: sqrt(w) B_m (q^-1 c_m) (e_k, 0), as 4 rows; the curve's
            // turn is its first 3, against sqrt(w) r.
            let root = w.sqrt();
            let r = r.map(|v| v * root);
            let column = |m: usize, k: usize| -> [f64; 4] {
                let mut e = [0.0; 4];
                e[k] = 1.0;
                (q.conjugate() * controls[first + m] * QuatF64::from_array(e)).to_array().map(|v| v * b[m] * root)
            };
            for a in 0..ORDER {
                for x in 0..3 {
                    let row = 3 * (first + a) + x;
                    let ja = column(a, x);
                    rhs[row] += (0..3).map(|k| ja[k] * r[k]).sum::<f64>();
                    for c in 0..=a {
                        for y in 0..3 {
                            let col = 3 * (first + c) + y;
                            if col <= row {
                                let jc = column(c, y);
                                normal.add(row, col, (0..4).map(|k| ja[k] * jc[k]).sum());
                            }
                        }
                    }
                }
            }
        }
        // Damping relative to the mean diagonal (`sum B^2` over the samples per control point).
        let mean = rows.iter().zip(weights).map(|((_, b), w)| w * b.iter().map(|v| v * v).sum::<f64>()).sum::<f64>()
            / n as f64;
        for i in 0..3 * n {
            normal.add(i, i, 1e-12 + damping * mean);
        }
        normal.factor()?.solve(&mut rhs);
        Some(rhs.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
    }

    #[test]
    fn the_steps_gathered_per_control_point_are_the_per_sample_normal_equations() {
        let knots = clamped(ORDER, 0.0, 1.0, &[0.2, 0.45, 0.5, 0.8]);
        let times: Vec<f64> = (0..=50).map(|j| j as f64 / 50.0).collect();
        let rows = collocation(&spans(&knots, &times));
        let controls: Vec<QuatF64> = (0..knots.len() - ORDER).map(|i| rotation(0.7 * i as f64)).collect();
        let fit = Fit { knots: knots.clone(), controls: controls.clone(), worst: 0.0, worst_at: 0 };
        let curve = fit.evaluate(&times).unwrap();
        let residuals: Vec<[f64; 3]> =
            times.iter().map(|&t| [0.01 * (7.0 * t).sin(), 0.02 * t, -0.005 * (3.0 * t).cos()]).collect();
        let weights: Vec<f64> = times.iter().map(|&t| 1.0 + t * t).collect();
        for damping in [0.0, 1e-3] {
            let system =
                Steps::new(&rows, &gram(&rows, &weights, controls.len()), &curve, &controls, &weights, &residuals);
            let gathered = system.damped(damping).unwrap().0;
            let oracle = rotation_steps_per_sample(&rows, &curve, &controls, &weights, &residuals, damping).unwrap();
            for (a, b) in gathered.iter().flatten().zip(oracle.iter().flatten()) {
                assert!((a - b).abs() <= 1e-9 * b.abs().max(1e-3), "{damping}: {a} against {b}");
            }
        }
    }

    #[test]
    fn the_fall_a_step_predicts_is_the_fall_it_makes_near_the_fit() {
        // Control points a little off the curve they fit: the linear model is close, so the
        // fall in the weighted sum of squares it predicts is the fall the step makes (the
        // dampings stop on it).
        let knots = clamped(ORDER, 0.0, 1.0, &[0.25, 0.5, 0.75]);
        let times: Vec<f64> = (0..=80).map(|j| j as f64 / 80.0).collect();
        let spans = spans(&knots, &times);
        let rows = collocation(&spans);
        let truth: Vec<QuatF64> = (0..knots.len() - ORDER).map(|i| rotation(0.4 * i as f64)).collect();
        let samples = Fit { knots: knots.clone(), controls: truth.clone(), worst: 0.0, worst_at: 0 }
            .evaluate_spans(&spans)
            .unwrap();
        let off = |i: usize| Vec3F64::new(0.002 * (i as f64).sin(), -0.001, 0.0015 * (i as f64).cos());
        let controls: Vec<QuatF64> = truth.iter().enumerate().map(|(i, c)| *c * QuatF64::exp(off(i))).collect();
        let weights: Vec<f64> = times.iter().map(|&t| 1.0 + t).collect();
        let sum_of = |controls: &[QuatF64]| {
            let fit = Fit { knots: knots.clone(), controls: controls.to_vec(), worst: 0.0, worst_at: 0 };
            let curve = fit.evaluate_spans(&spans).unwrap();
            let residuals: Vec<[f64; 3]> =
                curve.iter().zip(&samples).map(|(q, s)| (q.conjugate() * *s).log().to_array()).collect();
            let sum: f64 = residuals.iter().zip(&weights).map(|(r, w)| w * r.iter().map(|v| v * v).sum::<f64>()).sum();
            (curve, residuals, sum)
        };
        let (curve, residuals, sum) = sum_of(&controls);
        let system = Steps::new(&rows, &gram(&rows, &weights, controls.len()), &curve, &controls, &weights, &residuals);
        for damping in [0.0, 1e-2, 1.0] {
            let (steps, predicted) = system.damped(damping).unwrap();
            let moved: Vec<QuatF64> = controls
                .iter()
                .zip(&steps)
                .map(|(c, d)| (*c * QuatF64::exp(Vec3F64::from_array(*d))).normalize())
                .collect();
            let fall = sum - sum_of(&moved).2;
            assert!(
                predicted > 0.0 && (fall - predicted).abs() <= 0.05 * predicted,
                "{damping}: {fall} against {predicted}"
            );
        }
    }

    #[test]
    fn a_curve_evaluated_at_its_spans_is_the_reference_evaluators_to_the_bit() {
        let knots = clamped(ORDER, 0.0, 1.0, &[0.2, 0.5, 0.5, 0.5, 0.8]);
        let controls: Vec<QuatF64> = (0..knots.len() - ORDER).map(|i| rotation(0.9 * i as f64)).collect();
        let fit = Fit { knots: knots.clone(), controls, worst: 0.0, worst_at: 0 };
        let times: Vec<f64> = (0..=100).map(|j| j as f64 / 100.0).collect();
        assert_eq!(fit.evaluate_spans(&spans(&knots, &times)).unwrap(), fit.evaluate(&times).unwrap());
    }

    #[test]
    fn the_rows_from_the_knots_are_the_collocation_of_the_spans() {
        let knots = clamped(ORDER, 0.0, 1.0, &[0.2, 0.5, 0.5, 0.55, 0.8]);
        let times: Vec<f64> = (0..=90).map(|j| j as f64 / 90.0).collect();
        assert_eq!(rows(&knots, &times), collocation(&spans(&knots, &times)));
        // Taken over from other knots where a sample's own knots are the same: still the same.
        let coarse = clamped(ORDER, 0.0, 1.0, &[0.5, 0.8]);
        let after = rows_after(&knots, &times, Some((&coarse, &rows(&coarse, &times))));
        assert_eq!(after, rows(&knots, &times));
    }

    #[test]
    fn the_collocation_rows_are_a_partition_of_unity_on_their_controls() {
        let knots = clamped(ORDER, 0.0, 1.0, &[0.2, 0.5, 0.55]);
        for (first, b) in collocation(&spans(&knots, &[0.0, 0.1, 0.2, 0.51, 0.99, 1.0])) {
            assert!(first + ORDER <= knots.len() - ORDER);
            assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-12 && b.iter().all(|&v| v >= -1e-15), "{b:?}");
        }
    }

    #[test]
    fn a_vector_spline_is_fitted_back_exactly_on_its_own_knots() {
        let times: Vec<f64> = (0..=60).map(|j| j as f64 / 60.0).collect();
        let values: Vec<[f64; 3]> = times.iter().map(|&t| [t * t * t, (t - 0.5).powi(2), 1.0 - t]).collect();
        // A cubic polynomial is one span: four control points reproduce it.
        let fit = fit_vectors(&times, &values, &vec![1e-9; times.len()]);
        assert_eq!(fit.controls.len(), ORDER);
        assert!(fit.worst < 1e-12, "{}", fit.worst);
    }

    #[test]
    fn every_sample_of_a_fitted_channel_is_within_the_tolerance() {
        let times: Vec<f64> = (0..=240).map(|j| j as f64 / 120.0).collect();
        let rotations: Vec<QuatF64> = times.iter().map(|&t| rotation(t)).collect();
        for tolerance in [1e-3, 1e-5] {
            let fit = fit_rotations(&times, &rotations, &vec![tolerance; times.len()]).unwrap();
            let curve = fit.evaluate(&times).unwrap();
            assert!(
                curve.iter().zip(&rotations).all(|(q, s)| q.angle_to(*s) <= tolerance),
                "{tolerance}: {}",
                fit.worst
            );
            assert!(fit.controls.len() < times.len() / 4, "{tolerance}: {} controls", fit.controls.len());
        }
        let values: Vec<[f64; 3]> = times.iter().map(|&t| [t.sin(), (5.0 * t).cos(), t]).collect();
        let fit = fit_vectors(&times, &values, &vec![1e-4; times.len()]);
        assert!(fit.worst <= 1e-4 && fit.controls.len() < times.len() / 4, "{} {}", fit.worst, fit.controls.len());
    }

    #[test]
    fn the_components_fit_holds_no_more_control_points_than_the_normalized_form_it_starts() {
        let times: Vec<f64> = (0..=240).map(|j| j as f64 / 120.0).collect();
        // Smooth, and with frame-to-frame jitter as mocap has.
        let jitter = |j: usize| 0.002 * ((j * 7919) % 13) as f64 / 13.0;
        let smooth: Vec<QuatF64> = times.iter().map(|&t| rotation(t)).collect();
        let noisy: Vec<QuatF64> = times
            .iter()
            .enumerate()
            .map(|(j, &t)| rotation(t) * QuatF64::from_rotation_vector(Vec3F64::new(jitter(j), 0.0, -jitter(j + 3))))
            .collect();
        for (name, rotations) in [("smooth", smooth), ("noisy", noisy)] {
            for tolerance in [1e-3, 1e-4] {
                let tolerances = vec![tolerance; times.len()];
                let start = || RotationStart::new(&times, &rotations, &tolerances);
                let lower = start().controls();
                let fit = start().fit_below(usize::MAX).unwrap();
                let n = fit.controls.len();
                assert!(lower <= n, "{name} {tolerance}: {lower} > {n}");
                assert!(fit.worst <= tolerance, "{name} {tolerance}: {}", fit.worst);
                // Bounded: no fit at the lower bound, the same fit just above the fit's count.
                assert!(start().fit_below(lower).is_none(), "{name} {tolerance}");
                assert!(RotationStart::below(&times, &rotations, &tolerances, lower).is_none(), "{name} {tolerance}");
                let below = RotationStart::below(&times, &rotations, &tolerances, lower + 1);
                assert_eq!(below.map(|s| s.controls), Some(start().controls), "{name} {tolerance}");
                assert_eq!(start().fit_below(n + 1), Some(fit), "{name} {tolerance}");
            }
        }
    }

    #[test]
    fn flips_near_a_half_turn_give_a_curve_within_the_rule_or_none() {
        // A turn of nearly a half turn in one frame: the control points around it can come
        // half a turn apart, which the normalized form refuses. The fit gives a curve within
        // its tolerance that every evaluator accepts, or none (the keys form then), never a
        // panic.
        let times: Vec<f64> = (0..=40).map(f64::from).collect();
        let (mut fitted, mut refused) = (0, 0);
        for turn in [2.0, 2.8, 3.0, 3.1, 3.135] {
            for ring in [0.0, 0.3] {
                let rotations: Vec<QuatF64> = times
                    .iter()
                    .map(|&t| {
                        let a = if t < 20.0 { 0.0 } else { turn };
                        let wobble = ring * (0.7 * t).sin();
                        QuatF64::from_rotation_vector(Vec3F64::new(wobble, 0.2 * wobble, a))
                    })
                    .collect();
                match fit_rotations(&times, &rotations, &vec![1e-4; times.len()]) {
                    Some(fit) => {
                        let curve = fit.evaluate(&times).expect("a kept fit keeps the rule");
                        let worst = curve.iter().zip(&rotations).map(|(q, s)| q.angle_to(*s)).fold(0.0, f64::max);
                        assert!(worst <= 1e-4, "turn {turn}, ring {ring}: worst {worst}");
                        fitted += 1;
                    }
                    None => refused += 1,
                }
            }
        }
        // Both ways taken: the refusal is reached here, not only the curves within the rule.
        assert!(fitted > 0 && refused > 0, "{fitted} fitted, {refused} refused");
    }

    #[test]
    fn a_flip_in_one_frame_is_still_within_the_tolerance_at_every_sample() {
        // A cubic rings around a step, so the spans near it are split down to the samples
        // (knots of multiplicity 3 at a step would stop the ringing: not yet).
        let times: Vec<f64> = (0..=40).map(f64::from).collect();
        let rotations: Vec<QuatF64> = times
            .iter()
            .map(|&t| QuatF64::from_rotation_vector(Vec3F64::new(0.0, 0.0, if t < 20.0 { 0.1 } else { 2.5 })))
            .collect();
        let fit = fit_rotations(&times, &rotations, &vec![1e-4; times.len()]).unwrap();
        assert!(fit.worst <= 1e-4, "worst {} at sample {}", fit.worst, fit.worst_at);
    }
}
