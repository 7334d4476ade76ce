//! Scalars the quaternion math is generic over: `f64`, and [`Jet`], a second-order
//! forward-mode dual number.
//!
//! Why generic: the KKS families have closed-form derivatives (DESIGN section 2), but squad
//! and Nam-Kim are compositions of slerps whose derivatives are exact only through the chain
//! rule. Writing the quaternion math once over [`Real`] and evaluating it on [`Jet`]s *is* that
//! chain rule, applied mechanically, with no finite differences and no second copy of the math.

use std::fmt::Debug;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// A real scalar: `f64` or a [`Jet`] carrying first and second derivatives.
///
/// Branch decisions (small-angle series, hemisphere folds) are taken on [`Real::value`], so a
/// jet follows exactly the same formula as the plain value it carries.
pub trait Real:
    Copy + Debug + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
{
    /// A constant (zero derivatives).
    fn cst(x: f64) -> Self;
    /// The plain value, without derivatives.
    fn value(self) -> f64;
    /// Square root.
    #[must_use]
    fn sqrt(self) -> Self;
    /// Sine.
    #[must_use]
    fn sin(self) -> Self;
    /// Cosine.
    #[must_use]
    fn cos(self) -> Self;
    /// Four-quadrant arctangent of `self / x`.
    #[must_use]
    fn atan2(self, x: Self) -> Self;
    /// Multiplication by a plain constant.
    #[must_use]
    fn scale(self, k: f64) -> Self {
        self * Self::cst(k)
    }
    /// Applies a scalar function given `[f, f', f'']` at `self.value()` (the chain rule).
    #[must_use]
    fn apply(self, f: [f64; 3]) -> Self;
    /// `(cos sqrt x, sin sqrt x / sqrt x)` at `x = self`: the two factors of `exp`.
    #[must_use]
    fn cos_sinc_sqrt(self) -> (Self, Self) {
        (self.apply(cos_sqrt(self.value())), self.apply(sinc_sqrt(self.value())))
    }
    /// `atan sqrt x / sqrt x` at `x = self`: the factor of `log` below a quarter turn.
    #[must_use]
    fn atanc_sqrt(self) -> Self {
        self.apply(atanc_sqrt(self.value()))
    }
}

/// Below this argument the functions of `x` below use their Taylor series. Their closed forms
/// divide differences like `cos - sinc` by `x`, which lose digits for small `x` (3 digits at
/// x = 1e-4 in f32); the series are exact to rounding up to here.
pub const SERIES_LIMIT: f64 = 0.25;

/// `p(x)`, `p'(x)`, `p''(x)` of the polynomial with coefficients `c` (lowest first), by Horner.
fn polynomial(c: impl DoubleEndedIterator<Item = f64>, x: f64) -> [f64; 3] {
    let (mut p, mut d1, mut d2) = (0.0, 0.0, 0.0);
    for ck in c.rev() {
        d2 = d2 * x + d1;
        d1 = d1 * x + p;
        p = p * x + ck;
    }
    [p, d1, 2.0 * d2]
}

/// Taylor coefficients (lowest first) `(-1)^k / (2k + o)!`: `o = 0` is `cos sqrt x`, `o = 1`
/// is `sin sqrt x / sqrt x`; 10 terms reach rounding below [`SERIES_LIMIT`]. Constant tables:
/// these run in every f64 exp and log (the builder's Newton solve, the reference), where
/// building them per call was a measured cost.
const fn factorial_series(o: usize) -> [f64; 10] {
    let mut c = [0.0; 10];
    let (mut k, mut term) = (0, 1.0);
    while k < 10 {
        c[k] = term;
        term *= -1.0 / ((2 * k + 1 + o) * (2 * k + 2 + o)) as f64;
        k += 1;
    }
    c
}

/// `cos sqrt x = sum (-1)^k x^k / (2k)!` (the WGSL twin's series are these, rounded to `f32`).
pub const COS_SERIES: [f64; 10] = factorial_series(0);

/// `sin sqrt x / sqrt x = sum (-1)^k x^k / (2k+1)!`.
pub const SINC_SERIES: [f64; 10] = factorial_series(1);

/// Taylor coefficients of `atan sqrt x / sqrt x = sum (-1)^k x^k / (2k+1)`; 30 terms reach
/// 1e-20 at x = 1/4.
pub const ATANC_SERIES: [f64; 30] = {
    let mut c = [0.0; 30];
    let mut k = 0;
    while k < 30 {
        c[k] = if k % 2 == 0 { 1.0 } else { -1.0 } / (2 * k + 1) as f64;
        k += 1;
    }
    c
};

/// `p(x)` alone, by Horner.
fn polynomial_value(c: &[f64], x: f64) -> f64 {
    c.iter().rev().fold(0.0, |p, &ck| p * x + ck)
}

/// `cos(sqrt x)` with its first two derivatives in `x` (`x >= 0`): the scalar part of `exp`.
#[must_use]
pub fn cos_sqrt(x: f64) -> [f64; 3] {
    if x < SERIES_LIMIT {
        return polynomial(COS_SERIES.into_iter(), x);
    }
    let s = sinc_sqrt(x);
    let r = x.sqrt();
    [r.cos(), -0.5 * s[0], -0.5 * s[1]]
}

/// `sin(sqrt x) / sqrt x` with its first two derivatives in `x`: the vector factor of `exp`.
/// Closed form: `S' = (C - S) / 2x`, `S'' = (C' - 3 S') / 2x` with `C = cos sqrt x`.
#[must_use]
pub fn sinc_sqrt(x: f64) -> [f64; 3] {
    if x < SERIES_LIMIT {
        return polynomial(SINC_SERIES.into_iter(), x);
    }
    let r = x.sqrt();
    let (sin, cos) = r.sin_cos();
    let s = sin / r;
    let d1 = (cos - s) / (2.0 * x);
    let d2 = (-0.5 * s - 3.0 * d1) / (2.0 * x);
    [s, d1, d2]
}

/// `atan(sqrt x) / sqrt x` with its first two derivatives in `x`: the factor of `log` for
/// `x = tan^2 th`. Closed form: `A' = (B - A) / 2x`, `A'' = (-B^2 - 3 A') / 2x`, `B = 1 / (1 + x)`.
#[must_use]
pub fn atanc_sqrt(x: f64) -> [f64; 3] {
    if x < SERIES_LIMIT {
        return polynomial(ATANC_SERIES.into_iter(), x);
    }
    let r = x.sqrt();
    let a = r.atan() / r;
    let b = 1.0 / (1.0 + x);
    let d1 = (b - a) / (2.0 * x);
    let d2 = (-b * b - 3.0 * d1) / (2.0 * x);
    [a, d1, d2]
}

impl Real for f64 {
    #[inline]
    fn cst(x: f64) -> Self {
        x
    }
    #[inline]
    fn value(self) -> f64 {
        self
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn sin(self) -> Self {
        f64::sin(self)
    }
    #[inline]
    fn cos(self) -> Self {
        f64::cos(self)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        f64::atan2(self, x)
    }
    #[inline]
    fn scale(self, k: f64) -> Self {
        self * k
    }
    #[inline]
    fn apply(self, f: [f64; 3]) -> Self {
        f[0]
    }
    /// Values only, from the libm functions down to `x = 1e-4` and a short series below: no
    /// derivatives nobody reads and no 30-term series (the builder's solve runs millions of
    /// these). Without derivatives nothing cancels, so the closed forms are exact to a few ulp.
    #[inline]
    fn cos_sinc_sqrt(self) -> (Self, Self) {
        if self < VALUE_SERIES_LIMIT {
            return (polynomial_value(&COS_SERIES[..5], self), polynomial_value(&SINC_SERIES[..5], self));
        }
        let r = self.sqrt();
        let (sin, cos) = r.sin_cos();
        (cos, sin / r)
    }
    #[inline]
    fn atanc_sqrt(self) -> Self {
        if self < VALUE_SERIES_LIMIT {
            return polynomial_value(&ATANC_SERIES[..5], self);
        }
        let r = self.sqrt();
        r.atan() / r
    }
}

/// Below this `x` the value-only f64 forms use five series terms (the next is below 1e-20).
const VALUE_SERIES_LIMIT: f64 = 1e-4;

/// A value with its first and second derivatives with respect to one parameter (time).
///
/// Arithmetic applies the product and chain rules, so any formula evaluated on jets yields
/// its exact first and second derivatives (up to rounding).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Jet {
    /// The value f(t).
    pub v: f64,
    /// The first derivative f'(t).
    pub d: f64,
    /// The second derivative f''(t).
    pub dd: f64,
}

impl Jet {
    /// The independent variable `t` itself (f' = 1, f'' = 0).
    #[must_use]
    pub fn variable(t: f64) -> Self {
        Self { v: t, d: 1.0, dd: 0.0 }
    }

    /// Applies a scalar function given its value and first two derivatives at `self.v`.
    #[inline]
    fn chain(self, f: f64, f1: f64, f2: f64) -> Self {
        Self { v: f, d: f1 * self.d, dd: f2 * self.d * self.d + f1 * self.dd }
    }
}

impl Add for Jet {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self { v: self.v + o.v, d: self.d + o.d, dd: self.dd + o.dd }
    }
}

impl Sub for Jet {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self { v: self.v - o.v, d: self.d - o.d, dd: self.dd - o.dd }
    }
}

impl Neg for Jet {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self { v: -self.v, d: -self.d, dd: -self.dd }
    }
}

impl Mul for Jet {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        Self { v: self.v * o.v, d: self.d * o.v + self.v * o.d, dd: self.dd * o.v + 2.0 * self.d * o.d + self.v * o.dd }
    }
}

impl Div for Jet {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let r = 1.0 / o.v;
        self * o.chain(r, -r * r, 2.0 * r * r * r)
    }
}

impl Real for Jet {
    #[inline]
    fn cst(x: f64) -> Self {
        Self { v: x, d: 0.0, dd: 0.0 }
    }
    #[inline]
    fn value(self) -> f64 {
        self.v
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, 0.5 / s, -0.25 / (s * self.v))
    }
    #[inline]
    fn sin(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(s, c, -s)
    }
    #[inline]
    fn cos(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(c, -s, -c)
    }
    fn atan2(self, x: Self) -> Self {
        // d/dt atan2(y, x) = (x y' - y x') / (x^2 + y^2); differentiate that quotient once more.
        let y = self;
        let r2 = x.v * x.v + y.v * y.v;
        let num = x.v * y.d - y.v * x.d;
        let num_d = x.v * y.dd - y.v * x.dd; // the x'y' terms cancel
        let r2_d = 2.0 * (x.v * x.d + y.v * y.d);
        Self { v: y.v.atan2(x.v), d: num / r2, dd: num_d / r2 - num * r2_d / (r2 * r2) }
    }
    #[inline]
    fn scale(self, k: f64) -> Self {
        Self { v: self.v * k, d: self.d * k, dd: self.dd * k }
    }
    #[inline]
    fn apply(self, f: [f64; 3]) -> Self {
        self.chain(f[0], f[1], f[2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Central differences of a scalar function: (f', f'').
    fn fd(f: impl Fn(f64) -> f64, t: f64) -> (f64, f64) {
        let h = 1e-4;
        ((f(t + h) - f(t - h)) / (2.0 * h), (f(t + h) - 2.0 * f(t) + f(t - h)) / (h * h))
    }

    fn check(jet: Jet, f: impl Fn(f64) -> f64, t: f64) {
        let (d, dd) = fd(&f, t);
        assert!((jet.v - f(t)).abs() < 1e-14, "value {} vs {}", jet.v, f(t));
        assert!((jet.d - d).abs() < 1e-7 * (1.0 + d.abs()), "d {} vs {d}", jet.d);
        assert!((jet.dd - dd).abs() < 1e-5 * (1.0 + dd.abs()), "dd {} vs {dd}", jet.dd);
    }

    #[test]
    fn smooth_functions_of_x_match_their_definitions_and_derivatives() {
        type Jet = fn(f64) -> [f64; 3];
        type Definition = fn(f64) -> f64;
        let defs: [(Jet, Definition); 3] = [
            (cos_sqrt, |x: f64| x.sqrt().cos()),
            (sinc_sqrt, |x: f64| x.sqrt().sin() / x.sqrt()),
            (atanc_sqrt, |x: f64| x.sqrt().atan() / x.sqrt()),
        ];
        for (f, def) in defs {
            for &x in &[1e-3, 0.01, 0.2, 0.249_999, 0.25, 0.3, 1.0, 4.0, 30.0] {
                let [v, d1, d2] = f(x);
                assert!((v - def(x)).abs() < 1e-15, "value at {x}");
                let h = 2e-3 * x.max(0.05);
                let fd1 = (def(x + h) - def(x - h)) / (2.0 * h);
                let fd2 = (def(x + h) - 2.0 * def(x) + def(x - h)) / (h * h);
                assert!((d1 - fd1).abs() < 1e-6 * (1.0 + d1.abs()), "d1 at {x}: {d1} vs {fd1}");
                assert!((d2 - fd2).abs() < 1e-4 * (1.0 + d2.abs()), "d2 at {x}: {d2} vs {fd2}");
            }
            // Continuous across the series limit.
            let below = f(SERIES_LIMIT * (1.0 - 1e-12));
            let above = f(SERIES_LIMIT);
            for i in 0..3 {
                assert!((below[i] - above[i]).abs() < 1e-11, "jump in derivative {i}");
            }
        }
    }

    #[test]
    fn jet_rules_match_finite_differences() {
        for &t in &[0.3, 1.1, 2.5] {
            let x = Jet::variable(t);
            check(x * x.sin() / (x + Jet::cst(1.0)), |t| t * t.sin() / (t + 1.0), t);
            check((x * x + Jet::cst(0.5)).sqrt().cos(), |t| (t * t + 0.5).sqrt().cos(), t);
            check((x * x).sin().atan2(x.cos() - Jet::cst(2.0)), |t| (t * t).sin().atan2(t.cos() - 2.0), t);
            check(-(x - x.scale(3.0)), |t| 2.0 * t, t);
        }
    }
}
