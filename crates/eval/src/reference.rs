//! The f64 reference evaluator: simple, obviously right, and the oracle every fast path is
//! checked against.
//!
//! KKS families (slerp, Bezier, Hermite, B-spline) are all `q(t) = q_s prod_j exp(v_j b_j(t))`
//! and share [`cumulative_product`], whose derivatives are the closed-form recursion of
//! DESIGN section 2. Squad and Nam-Kim are compositions of shortest-path slerps; their
//! derivatives come from evaluating the same closed form on [`Jet`]s (exact differentiation by
//! the chain rule, see [`quatcurve_core::real`]).
//!
//! The normalized B-spline is no product: a sum of control points, normalized, also on jets.
//!
//! Squad's three slerps and Nam-Kim's blend use the *unfolded* geodesic
//! ([`Quaternion::geodesic`]), as Shoemake and NK eq. 3 write them (`log` with `th = arccos w in
//! [0, pi]`), on keys already made sign-continuous and squad points `s_i` in `q_i`'s
//! hemisphere. A shortest-path fold inside a blend flips wherever its two moving endpoints
//! drift more than a quarter turn apart (near-antipodal keys, large velocities), tearing the
//! curve mid-segment; unfolded, each segment is continuous and ends exactly on `+q_{i+1}`.
//! Both rules give the same curve whenever those endpoints stay within a quarter turn, which
//! covers ordinary animation data.

use crate::batch::TrackView;
use quatcurve_core::basis::{bernstein_cumulative, bspline_cumulative_into, BasisJet};
use quatcurve_core::curve::{Curve, MAX_ORDER};
use quatcurve_core::quat::{QuatF64, Quaternion, Vec3F64, Vector3};
use quatcurve_core::real::{Jet, Real};
use quatcurve_core::segment::{key_segment, locate, wrap};

/// One evaluated sample: rotation and physical body-frame derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// The unit rotation `q(t)`.
    pub rotation: QuatF64,
    /// Body angular velocity `2 vec(q^-1 q')`, rad per unit time.
    pub angular_velocity: Vec3F64,
    /// Body angular acceleration, the time derivative of `angular_velocity`.
    pub angular_acceleration: Vec3F64,
}

/// One factor `exp(v b(t))` of a cumulative product, with `b`, `b'`, `b''` in time units.
#[derive(Clone, Copy, Debug)]
pub struct Factor {
    /// The coefficient (half-angle rotation vector).
    pub v: Vec3F64,
    /// `[b(t), b'(t), b''(t)]`.
    pub b: BasisJet,
}

/// Evaluates `q_s prod exp(v_j b_j)` and its body derivatives by the recursion
/// `W_j = A_j^-1 W_{j-1} A_j + v_j b_j'`,
/// `W_j' = A_j^-1 W_{j-1}' A_j + 2 (A_j^-1 W_{j-1} A_j) x (v_j b_j') + v_j b_j''`,
/// with `W = q^-1 q'`, so `omega = 2 W` and `alpha = 2 W'` (DESIGN section 2).
#[must_use]
pub fn cumulative_product(start: QuatF64, factors: impl IntoIterator<Item = Factor>) -> Sample {
    product::<true>(start, factors)
}

/// [`cumulative_product`]; without `DERIVATIVES` the rotation alone (the same bits), its
/// velocity and acceleration left zero.
fn product<const DERIVATIVES: bool>(start: QuatF64, factors: impl IntoIterator<Item = Factor>) -> Sample {
    let mut q = start;
    let mut w = Vec3F64::zero();
    let mut w_dot = Vec3F64::zero();
    for Factor { v, b } in factors {
        let a = QuatF64::exp(v.scale(b[0]));
        if DERIVATIVES {
            let a_inv = a.conjugate();
            let carried = a_inv.rotate(w);
            let spin = v.scale(b[1]);
            w_dot = a_inv.rotate(w_dot) + carried.cross(spin).scale(2.0) + v.scale(b[2]);
            w = carried + spin;
        }
        q = q * a;
    }
    Sample { rotation: q, angular_velocity: w.scale(2.0), angular_acceleration: w_dot.scale(2.0) }
}

/// Rotation and body derivatives from a quaternion carried on jets:
/// `W = q^-1 q'`, `W' = q^-1 q'' - W^2`.
#[must_use]
pub fn sample_from_jets(q: Quaternion<Jet>) -> Sample {
    let value = q.value();
    let d1 = QuatF64::from_xyzw(q.x.d, q.y.d, q.z.d, q.w.d);
    let d2 = QuatF64::from_xyzw(q.x.dd, q.y.dd, q.z.dd, q.w.dd);
    let inv = value.conjugate();
    let w = inv * d1;
    let w_dot = inv * d2 - w * w;
    Sample { rotation: value, angular_velocity: w.vec().scale(2.0), angular_acceleration: w_dot.vec().scale(2.0) }
}

fn coef_vec(c: [f64; 4]) -> Vec3F64 {
    Vec3F64::new(c[0], c[1], c[2])
}

fn coef_quat(c: [f64; 4]) -> QuatF64 {
    QuatF64::from_array(c)
}

/// Scales a basis jet in the segment parameter `u` to time units for a segment of length `len`.
pub(crate) fn per_time(b: BasisJet, len: f64) -> BasisJet {
    [b[0], b[1] / len, b[2] / (len * len)]
}

/// Evaluates one packed track at time `t` (clamped to its domain, or wrapped when looping).
#[must_use]
pub fn evaluate(view: TrackView<'_>, t: f64) -> Sample {
    evaluate_kks::<true>(view, t)
}

/// [`evaluate`]; without `DERIVATIVES` the KKS families' rotation alone (the same bits, a
/// third of the work), squad and Nam-Kim as with them.
fn evaluate_kks<const DERIVATIVES: bool>(view: TrackView<'_>, t: f64) -> Sample {
    let TrackView { track, points, coefs, knots } = view;
    let t = if track.looping() { wrap(t, track.domain()) } else { t };
    match track.curve() {
        Curve::Slerp => {
            let (i, t, len) = key_segment(knots, t);
            let u = (t - knots[i]) / len;
            product::<DERIVATIVES>(points[i], [Factor { v: coef_vec(coefs[i]), b: [u, 1.0 / len, 0.0] }])
        }
        Curve::Bezier => {
            let (_, t, len) = key_segment(knots, t);
            let u = (t - knots[0]) / len;
            let basis = bernstein_cumulative(track.bezier_degree(), u);
            let factors = coefs.iter().zip(basis).map(|(&c, b)| Factor { v: coef_vec(c), b: per_time(b, len) });
            product::<DERIVATIVES>(points[0], factors)
        }
        Curve::Hermite => {
            let (i, t, len) = key_segment(knots, t);
            let u = (t - knots[i]) / len;
            let basis = bernstein_cumulative(3, u);
            let seg = &coefs[3 * i..3 * i + 3];
            let start_sign = seg[1][3];
            let factors = seg.iter().zip(basis).map(|(&c, b)| Factor { v: coef_vec(c), b: per_time(b, len) });
            product::<DERIVATIVES>(points[i].mul_scalar(start_sign), factors)
        }
        // bspline-interp is packed as a cubic B-spline on explicit knots.
        Curve::BSpline | Curve::BSplineInterp => {
            let (l, basis) = span_basis(view, t);
            bspline_product::<DERIVATIVES>(view, l, &basis[..track.order() - 1])
        }
        Curve::NormalizedBSpline => {
            let (l, basis) = span_basis(view, t);
            let k = track.order();
            if DERIVATIVES {
                let jets: [Jet; MAX_ORDER - 1] = basis.map(|[v, d, dd]| Jet { v, d, dd });
                sample_from_jets(normalized_bspline(points, k, l, &jets[..k - 1]))
            } else {
                let rotation = bspline_rotation_at(view, l, &basis[..k - 1]);
                Sample { rotation, angular_velocity: Vec3F64::zero(), angular_acceleration: Vec3F64::zero() }
            }
        }
        Curve::Squad => {
            let (i, t, len) = key_segment(knots, t);
            sample_from_jets(squad(view, i, (Jet::variable(t) - Jet::cst(knots[i])).scale(1.0 / len)))
        }
        Curve::NamKim => {
            let (i, t, len) = key_segment(knots, t);
            sample_from_jets(nam_kim(view, i, (Jet::variable(t) - Jet::cst(knots[i])).scale(1.0 / len)))
        }
    }
}

/// A B-spline track on span `l` with the cumulative basis `basis` there
/// (`B~_{l-k+2..=l}` and their derivatives, as `bspline_cumulative_into` gives them): KKS's
/// product from the span's first control point.
fn bspline_product<const DERIVATIVES: bool>(view: TrackView<'_>, l: usize, basis: &[BasisJet]) -> Sample {
    let k = view.track.order();
    let first = l + 2 - k;
    let factors = basis.iter().enumerate().map(|(j, &b)| Factor { v: coef_vec(view.coefs[first + j - 1]), b });
    product::<DERIVATIVES>(view.points[l + 1 - k], factors)
}

/// A B-spline track's span `l` at `t` and its cumulative basis there (`B~_{l-k+2..=l}` with
/// derivatives, the first `k - 1` entries): on the stack, as every sample of every B-spline
/// track comes here.
fn span_basis(view: TrackView<'_>, t: f64) -> (usize, [BasisJet; MAX_ORDER - 1]) {
    let k = view.track.order();
    let (l, t) = locate(view.knots, k - 1, view.points.len() - 1, t);
    let mut basis = [[0.0; 3]; MAX_ORDER - 1];
    bspline_cumulative_into(view.knots, k, l, t, &mut basis[..k - 1]);
    (l, basis)
}

/// `normalize(sum B_i c_i)` on span `l` of a normalized B-spline of order `k` from the span's
/// cumulative basis (`B~_{l-k+2..=l}`; on jets, with time derivatives): `B_i = B~_i -
/// B~_{i+1}`, `B~` being 1 below the window and 0 above it.
fn normalized_bspline<R: Real>(points: &[QuatF64], k: usize, l: usize, cumulative: &[R]) -> Quaternion<R> {
    let at = |r: usize| match r {
        0 => R::cst(1.0),
        r if r < k => cumulative[r - 1],
        _ => R::cst(0.0),
    };
    let sum = (0..k)
        .map(|r| Quaternion::from_f64(points[l + 1 - k + r]).mul_scalar(at(r) - at(r + 1)))
        .fold(Quaternion::from_f64(QuatF64::from_xyzw(0.0, 0.0, 0.0, 0.0)), |a, b| a + b);
    sum.mul_scalar(R::cst(1.0) / sum.dot(sum).sqrt())
}

/// The rotation of a B-spline track (either form) at a time whose span `l` (as `locate` finds
/// it) and cumulative basis there (`B~_{l-k+2..=l}`, derivatives not read) the caller already
/// has: a fit evaluating one knot vector at the same times step after step computes them once.
#[must_use]
pub fn bspline_rotation_at(view: TrackView<'_>, l: usize, basis: &[BasisJet]) -> QuatF64 {
    if view.track.curve() == Curve::NormalizedBSpline {
        let k = view.track.order();
        let values: [f64; MAX_ORDER - 1] = std::array::from_fn(|i| basis.get(i).map_or(0.0, |b| b[0]));
        return normalized_bspline(view.points, k, l, &values[..k - 1]).value();
    }
    bspline_product::<false>(view, l, basis).rotation
}

/// The rotation alone at time `t`: as [`evaluate`], but no derivatives: the KKS families skip
/// their recursion, squad and Nam-Kim the jets (each about a third of the work).
#[must_use]
pub fn evaluate_rotation(view: TrackView<'_>, t: f64) -> QuatF64 {
    match view.track.curve() {
        Curve::Squad | Curve::NamKim => {
            let t = if view.track.looping() { wrap(t, view.track.domain()) } else { t };
            let (i, t, len) = key_segment(view.knots, t);
            let h = (t - view.knots[i]) * (1.0 / len);
            if view.track.curve() == Curve::Squad {
                squad(view, i, h)
            } else {
                nam_kim(view, i, h)
            }
        }
        _ => evaluate_kks::<false>(view, t).rotation,
    }
}

/// Squad on segment `i` at segment parameter `h` (any [`Real`]): three unfolded geodesics.
fn squad<R: Real>(view: TrackView<'_>, i: usize, h: R) -> Quaternion<R> {
    let (points, coefs) = (view.points, view.coefs);
    let lift = Quaternion::<R>::from_f64;
    let path = lift(points[i]).geodesic(lift(points[i + 1]), h);
    let aux = lift(coef_quat(coefs[i])).geodesic(lift(coef_quat(coefs[i + 1])), h);
    path.geodesic(aux, (h - h * h).scale(2.0))
}

/// Nam-Kim on segment `i` at segment parameter `s` (any [`Real`]): the blend of two arcs.
fn nam_kim<R: Real>(view: TrackView<'_>, i: usize, s: R) -> Quaternion<R> {
    let (a, b) = (coef_vec(view.coefs[2 * i]), coef_vec(view.coefs[2 * i + 1]));
    let c1 = Quaternion::from_f64(view.points[i]) * Quaternion::exp(Vector3::from_f64(a).mul_scalar(s));
    let c2 =
        Quaternion::from_f64(view.points[i + 1]) * Quaternion::exp(Vector3::from_f64(b).mul_scalar(s - R::cst(1.0)));
    c1.geodesic(c2, view.track.blend().ratio(s))
}

/// NK's forward-difference generator (NK section 3, appendix B) for a Nam-Kim segment sampled
/// at `steps + 1` uniform parameters `s = j / steps`, `j = 0..=steps`.
///
/// Points on each great arc come from the recurrence `x_{j+1} = (2 - sigma) x_j - x_{j-1}`
/// with `sigma = 2 (1 - cos(theta / steps)) = 4 sin^2(theta / (2 steps))`: four multiplications per point instead of a
/// sine and a cosine. `C_1` runs forward from `q_i`, `C_2` backward from `q_{i+1}`, so each is
/// most accurate where it matters most (NK section 4). Only the blend slerp is evaluated
/// directly. The drift against [`evaluate`] is measured by the tests.
///
/// # Panics
/// If the track is not Nam-Kim, `segment` is out of range, or `steps` is 0.
#[must_use]
pub fn nam_kim_forward_difference(view: TrackView<'_>, segment: usize, steps: usize) -> Vec<QuatF64> {
    assert_eq!(view.track.curve(), Curve::NamKim, "forward differences apply to nam-kim tracks");
    assert!(steps > 0, "at least one step");
    let i = segment;
    let (a, b) = (coef_vec(view.coefs[2 * i]), coef_vec(view.coefs[2 * i + 1]));
    let forward = great_arc(view.points[i], a.scale(1.0 / steps as f64), steps);
    let mut backward = great_arc(view.points[i + 1], b.scale(-1.0 / steps as f64), steps);
    backward.reverse();
    (0..=steps)
        .map(|j| {
            let f = view.track.blend().ratio(j as f64 / steps as f64);
            forward[j].geodesic(backward[j], f)
        })
        .collect()
}

/// `steps + 1` points `q exp(j v)`, `j = 0..=steps`, by NK's forward differences.
fn great_arc(q: QuatF64, v: Vec3F64, steps: usize) -> Vec<QuatF64> {
    let mut out = Vec::with_capacity(steps + 1);
    out.push(q);
    let first = q * QuatF64::exp(v);
    // NK's 2 (1 - cos phi), written 4 sin^2(phi / 2) to avoid cancellation at small steps.
    let half = 0.5 * v.length();
    let sigma = 4.0 * half.sin() * half.sin();
    let mut d = first - q;
    out.push(first);
    for j in 1..steps {
        d = d - out[j].mul_scalar(sigma);
        let next = out[j] + d;
        out.push(next);
    }
    out
}
