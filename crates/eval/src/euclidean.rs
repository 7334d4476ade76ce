//! The Euclidean analogue of every curve, for translation and scale channels (KKS section 1):
//! the same basis functions and knots as the rotation curve, with the group `(R^3, +)` in
//! place of unit quaternions, so `exp` and `log` are the identity and the cumulative product
//! `q_0 prod exp(w_i B~_i)` becomes the sum `p_0 + sum (p_i - p_{i-1}) B~_i`.
//!
//! A baked clip therefore moves its translations with exactly the smoothness, locality and
//! key interpolation of its rotations. The test that ties the two together: keys on one axis
//! (where rotations commute) give the rotation curve's angle equal to this curve's value.
//! Evaluated in f64 on the CPU: translation channels are few next to rotation channels.
//!
//! Looping (DESIGN section 3, "Loops"): the per-cycle offset `D = p_n - p_0` is kept (root
//! motion that advances every cycle): the curve is `p~(t) + D (t - tau_0) / T` with `p~` the
//! periodic curve through `p_i - D (tau_i - tau_0) / T`, so velocity is periodic and
//! `p(t + T) = p(t) + D`.

use crate::batch::{bspline_knots, catmull_rom_velocities, key_times, squad_points};
use crate::error::{Error, Result, TrackId};
use quatcurve_core::basis::{bernstein_cumulative, bspline_cumulative_values_into};
use quatcurve_core::curve::{Blend, Curve, CurveSpec, KnotMode, Tangents, MAX_ORDER};
use quatcurve_core::quat::Vec3F64;
use quatcurve_core::segment::{arithmetic_span_step, locate, locate_uniform, wrap};

/// A vector curve ready to evaluate: points, per-family coefficients and knots, laid out as
/// the rotation batch lays them out (see [`crate::batch`]).
#[derive(Clone, Debug, PartialEq)]
pub struct VectorCurve {
    curve: Curve,
    order: usize,
    blend: Blend,
    points: Vec<Vec3F64>,
    coefs: Vec<Vec3F64>,
    knots: Vec<f64>,
    domain: [f64; 2],
    /// Looping: the per-cycle offset per unit time, `D / T`.
    drift: Option<Vec3F64>,
    /// The knots' inverse mean spacing where spans are found by arithmetic first
    /// ([`arithmetic_span_step`] of the spans [`Self::periodic`] looks among), else 0.
    inv_step: f64,
}

impl VectorCurve {
    /// Builds the analogue of `spec` through `values` at `times` (`None`: `0, 1, ..., n`).
    ///
    /// # Errors
    /// The rotation builder's rules for times, key counts, orders and knots, naming `id`;
    /// [`Error::NonFiniteValue`] for a NaN or infinite value; [`Error::VectorTangents`] for
    /// `tangents = given` (vector channels carry no per-key velocities).
    pub fn new(
        id: &TrackId,
        times: Option<&[f64]>,
        values: &[[f64; 3]],
        explicit_knots: Option<&[f64]>,
        spec: &CurveSpec,
    ) -> Result<Self> {
        let (keys, times, drift) = detrended_keys(id, times, values, spec)?;
        let steps = |points: &[Vec3F64]| -> Vec<Vec3F64> { points.windows(2).map(|w| w[1] - w[0]).collect() };
        let n = keys.len() - 1;
        let mut curve = VectorCurve {
            curve: spec.curve,
            order: 0,
            blend: spec.blend,
            coefs: steps(&keys),
            points: keys,
            knots: times.clone(),
            domain: [times[0], times[n]],
            drift,
            inv_step: 0.0,
        };
        curve.fit(id, spec, explicit_knots, &times)?;
        let [first, last] = curve.spans();
        curve.inv_step = arithmetic_span_step(&curve.knots[first..=last + 1]);
        Ok(curve)
    }

    /// Fills the family's coefficients (and points, knots and domain where the family changes
    /// them) from the keys in `points` at `times`.
    fn fit(&mut self, id: &TrackId, spec: &CurveSpec, explicit_knots: Option<&[f64]>, times: &[f64]) -> Result<()> {
        let curve = self;
        let steps = |points: &[Vec3F64]| -> Vec<Vec3F64> { points.windows(2).map(|w| w[1] - w[0]).collect() };
        let (n, looping) = (curve.points.len() - 1, spec.looping);
        let [t0, tn] = curve.domain;
        match spec.curve {
            Curve::Slerp => {}
            Curve::Bezier => {
                curve.order = n;
                curve.knots = vec![t0, tn];
            }
            Curve::Squad => curve.coefs = squad_points(&curve.points, looping),
            Curve::Hermite => {
                let v = velocities(id, spec.tangents, &curve.points, times, looping)?;
                curve.coefs = (0..n)
                    .flat_map(|i| {
                        let third = (times[i + 1] - times[i]) / 3.0;
                        let (w1, w3) = (v[i].scale(third), v[i + 1].scale(third));
                        [w1, curve.points[i + 1] - curve.points[i] - w1 - w3, w3]
                    })
                    .collect();
            }
            Curve::NamKim => {
                let v = velocities(id, spec.tangents, &curve.points, times, looping)?;
                curve.coefs = (0..n).flat_map(|i| [v[i], v[i + 1]].map(|v| v.scale(times[i + 1] - times[i]))).collect();
            }
            // A normalized B-spline's analogue is the plain one: vectors need no normalizing.
            Curve::BSpline | Curve::NormalizedBSpline => {
                let k = spec.order;
                curve.curve = Curve::BSpline;
                curve.order = k;
                curve.knots = bspline_knots(id, explicit_knots, spec, times)?;
                if spec.knots == KnotMode::Phantom {
                    let p = &curve.points;
                    // Mirrored key steps, or looping the neighbours across the seam.
                    let (first, last) =
                        if looping { (p[n - 1], p[1]) } else { (p[0].scale(2.0) - p[1], p[n].scale(2.0) - p[n - 1]) };
                    curve.points.insert(0, first);
                    curve.points.push(last);
                }
                curve.coefs = steps(&curve.points);
                let m = curve.points.len() - 1;
                curve.domain = [curve.knots[k - 1], curve.knots[m + 1]];
            }
            Curve::BSplineInterp => {
                // The natural (or periodic) cubic spline, as a cubic B-spline on the same
                // knots as the rotation curve.
                let (points, knots) =
                    quatcurve_core::interp::solve_vectors(&curve.points, times, looping).ok_or_else(|| {
                        Error::NoConvergence {
                            track: id.clone(),
                            key: 0,
                            error: f64::NAN,
                            iterations: 1,
                            tolerance: quatcurve_core::interp::KEY_TOLERANCE,
                        }
                    })?;
                curve.curve = Curve::BSpline;
                curve.order = 4;
                curve.coefs = steps(&points);
                curve.points = points;
                curve.knots = knots;
            }
        }
        Ok(())
    }

    /// The family evaluated (a natural spline is a cubic B-spline).
    #[must_use]
    pub fn curve(&self) -> Curve {
        self.curve
    }

    /// A B-spline's order or a Bezier curve's degree (0 for the other families): the rotation
    /// batch's one field for both.
    #[must_use]
    pub fn order(&self) -> usize {
        self.order
    }

    /// The Nam-Kim blend function.
    #[must_use]
    pub fn blend(&self) -> Blend {
        self.blend
    }

    /// Keys or control points (looping: with the per-cycle offset removed).
    #[must_use]
    pub fn points(&self) -> &[Vec3F64] {
        &self.points
    }

    /// The family's coefficients, laid out as the rotation batch's.
    #[must_use]
    pub fn coefs(&self) -> &[Vec3F64] {
        &self.coefs
    }

    /// Segment boundaries or the knot vector.
    #[must_use]
    pub fn knots(&self) -> &[f64] {
        &self.knots
    }

    /// A loop's per-cycle offset per second (`D / T`); `None` for an open curve.
    #[must_use]
    pub fn drift(&self) -> Option<Vec3F64> {
        self.drift
    }

    /// The curve's domain; evaluation clamps to it.
    #[must_use]
    pub fn domain(&self) -> [f64; 2] {
        self.domain
    }

    /// The value at time `t` (clamped to the domain; looping, wrapped and advanced by the
    /// per-cycle offset).
    #[must_use]
    pub fn evaluate(&self, t: f64) -> Vec3F64 {
        match self.drift {
            Some(rate) => self.periodic(wrap(t, self.domain)) + rate.scale(t - self.domain[0]),
            None => self.periodic(t),
        }
    }

    /// [`locate`] on the knots, by arithmetic first where they are about equally spaced (the
    /// same span: the guess is walked to it).
    fn locate(&self, first: usize, last: usize, t: f64) -> (usize, f64) {
        let knots = &self.knots;
        if self.inv_step > 0.0 {
            locate_uniform(knots, first, last, [knots[first], knots[last + 1]], t, self.inv_step)
        } else {
            locate(knots, first, last, t)
        }
    }

    /// [`quatcurve_core::segment::key_segment`] through [`Self::locate`]: `(segment, clamped
    /// t, segment length)`.
    fn key_segment(&self, t: f64) -> (usize, f64, f64) {
        let [first, last] = self.spans();
        let (i, t) = self.locate(first, last, t);
        (i, t, self.knots[i + 1] - self.knots[i])
    }

    /// The first and last spans [`Self::periodic`] looks `t` up among: a B-spline's from its
    /// order less one to its last control point, else every key segment.
    fn spans(&self) -> [usize; 2] {
        match self.curve {
            Curve::BSpline | Curve::NormalizedBSpline | Curve::BSplineInterp => [self.order - 1, self.points.len() - 1],
            _ => [0, self.knots.len() - 2],
        }
    }

    /// The curve without the looping offset.
    fn periodic(&self, t: f64) -> Vec3F64 {
        let Self { points, coefs, knots, .. } = self;
        let sum = |start: Vec3F64, terms: &mut dyn Iterator<Item = (Vec3F64, f64)>| {
            terms.fold(start, |p, (c, b)| p + c.scale(b))
        };
        match self.curve {
            Curve::Slerp => {
                let (i, t, len) = self.key_segment(t);
                points[i] + coefs[i].scale((t - knots[i]) / len)
            }
            Curve::Bezier => {
                let (_, t, len) = self.key_segment(t);
                let basis = bernstein_cumulative(self.order, (t - knots[0]) / len);
                sum(points[0], &mut coefs.iter().zip(basis).map(|(&c, b)| (c, b[0])))
            }
            Curve::Hermite => {
                let (i, t, len) = self.key_segment(t);
                let basis = bernstein_cumulative(3, (t - knots[i]) / len);
                sum(points[i], &mut coefs[3 * i..3 * i + 3].iter().zip(basis).map(|(&c, b)| (c, b[0])))
            }
            Curve::BSpline | Curve::NormalizedBSpline | Curve::BSplineInterp => {
                let k = self.order;
                let [first, last] = self.spans();
                let (l, t) = self.locate(first, last, t);
                let first = l + 2 - k;
                // On the stack: a bake evaluates a vector channel at every frame.
                let mut basis = [0.0; MAX_ORDER - 1];
                bspline_cumulative_values_into(knots, k, l, t, &mut basis[..k - 1]);
                sum(points[l + 1 - k], &mut basis[..k - 1].iter().enumerate().map(|(j, &b)| (coefs[first + j - 1], b)))
            }
            Curve::Squad => {
                let (i, t, len) = self.key_segment(t);
                let h = (t - knots[i]) / len;
                let lerp = |a: Vec3F64, b: Vec3F64, s: f64| a + (b - a).scale(s);
                lerp(lerp(points[i], points[i + 1], h), lerp(coefs[i], coefs[i + 1], h), 2.0 * h * (1.0 - h))
            }
            Curve::NamKim => {
                let (i, t, len) = self.key_segment(t);
                let s = (t - knots[i]) / len;
                let c1 = points[i] + coefs[2 * i].scale(s);
                let c2 = points[i + 1] + coefs[2 * i + 1].scale(s - 1.0);
                c1 + (c2 - c1).scale(self.blend.ratio(s))
            }
        }
    }
}

/// Per-key velocities: Catmull-Rom ([`catmull_rom_velocities`], as for rotations) or zero;
/// vector channels carry no given velocities.
fn velocities(
    id: &TrackId,
    tangents: Tangents,
    keys: &[Vec3F64],
    times: &[f64],
    looping: bool,
) -> Result<Vec<Vec3F64>> {
    match tangents {
        Tangents::Zero => Ok(vec![Vec3F64::zero(); keys.len()]),
        Tangents::Given => Err(Error::VectorTangents { track: id.clone() }),
        Tangents::CatmullRom => Ok(catmull_rom_velocities(keys, times, looping)),
    }
}

/// The checked keys of a vector channel and their times; looping, with the per-cycle offset
/// removed (the last key equals the first exactly) and returned as a rate per unit time.
fn detrended_keys(
    id: &TrackId,
    times: Option<&[f64]>,
    values: &[[f64; 3]],
    spec: &CurveSpec,
) -> Result<(Vec<Vec3F64>, Vec<f64>, Option<Vec3F64>)> {
    let min = spec.min_keys();
    if values.len() < min {
        return Err(Error::TooFewKeys { track: id.clone(), curve: spec.curve.to_string(), min, found: values.len() });
    }
    if let Some(key) = values.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
        return Err(Error::NonFiniteValue { track: id.clone(), key, value: values[key] });
    }
    let times = key_times(id, times, values.len())?;
    let mut keys: Vec<Vec3F64> = values.iter().map(|&v| Vec3F64::from_array(v)).collect();
    let n = keys.len() - 1;
    let (t0, tn) = (times[0], times[n]);
    let mut drift = None;
    if spec.looping {
        if !spec.can_loop() {
            return Err(Error::LoopUnsupported {
                track: id.clone(),
                curve: spec.curve.to_string(),
                looping: CurveSpec::looping_curves(),
            });
        }
        // Remove the per-cycle offset; p~_n = p~_0 exactly.
        let rate = (keys[n] - keys[0]).scale(1.0 / (tn - t0));
        for (i, key) in keys.iter_mut().enumerate().skip(1) {
            *key = *key - rate.scale(times[i] - t0);
        }
        keys[n] = keys[0];
        drift = Some(rate);
    }
    Ok((keys, times, drift))
}
