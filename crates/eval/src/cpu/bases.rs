//! The CPU's bases in the segment parameter, eight parameters at a time: polynomials fitted
//! once per family and order (slerp, Hermite, B-splines on equally spaced knots) and the de
//! Casteljau triangle of Bezier curves, whose degree varies per track. B-splines on other
//! knots take the Cox-de Boor triangle ([`super::cox_de_boor`]).

use super::lanes::MAX_FACTORS;
use super::simd::Lanes;
use quatcurve_core::basis::{bernstein_polynomials, fit_polynomials, uniform_bspline_polynomials};
use quatcurve_core::curve::{MAX_ORDER, MIN_ORDER};

/// A cumulative basis that is a fixed polynomial of the segment parameter `u in [0, 1]`:
/// `count` functions of degree `len - 1 < 8`, f32 coefficients lowest first.
#[derive(Clone, Debug)]
pub(super) struct PolyBasis {
    count: usize,
    len: usize,
    coefs: Vec<[f32; 8]>,
}

impl PolyBasis {
    /// The f32 twin of `coefs`, polynomials of degree `degree`.
    fn new(degree: usize, coefs: Vec<[f64; 8]>) -> Self {
        Self { count: coefs.len(), len: degree + 1, coefs: coefs.into_iter().map(|c| c.map(|v| v as f32)).collect() }
    }

    /// `[p, p', p'']` of each of the `F` functions (of degree `F`) at `u`, derivatives in
    /// `u`; without `derivatives` only `p`, by Horner's rule.
    #[inline(always)]
    pub(super) fn eval<S: Lanes, const F: usize>(&self, u: S, derivatives: bool, out: &mut [[S; 3]; F]) {
        debug_assert!(self.count == F && self.len == F + 1);
        for (c, out) in self.coefs.iter().zip(out.iter_mut()) {
            let (mut p, mut d1, mut d2) = (S::ZERO, S::ZERO, S::ZERO);
            for k in (0..=F).rev() {
                let ck = S::splat(c[k]);
                if derivatives {
                    d2 = d2.mul_add(u, d1);
                    d1 = d1.mul_add(u, p);
                }
                p = p.mul_add(u, ck);
            }
            *out = [p, d1, d2 * S::splat(2.0)];
        }
    }
}

/// The polynomial bases: they depend on nothing but the order, so the evaluator fits them
/// once.
#[derive(Clone, Debug)]
pub(super) struct Bases {
    pub(super) slerp: PolyBasis,
    pub(super) hermite: PolyBasis,
    /// Uniform-knot B-spline bases, index `k - MIN_ORDER` for orders [`MIN_ORDER`]`..=`[`MAX_ORDER`].
    pub(super) bspline: Vec<PolyBasis>,
}

impl Bases {
    /// Fits every basis from the reference's.
    pub(super) fn new() -> Self {
        Self {
            slerp: PolyBasis::new(1, fit_polynomials(1, |u| vec![[u, 1.0, 0.0]])),
            hermite: PolyBasis::new(3, bernstein_polynomials(3)),
            bspline: (MIN_ORDER..=MAX_ORDER).map(|k| PolyBasis::new(k - 1, uniform_bspline_polynomials(k))).collect(),
        }
    }
}

/// How a track's basis is computed.
pub(super) enum Basis<'a> {
    /// SIMD polynomial in the segment parameter.
    Poly(&'a PolyBasis),
    /// SIMD Cox-de Boor triangle (B-splines on unequal knots).
    CoxDeBoor,
    /// SIMD de Casteljau triangle (Bezier curves, whose degree varies per track).
    Bernstein,
}

/// The cumulative Bernstein basis of degree `F` and its `u` derivatives, eight parameters at
/// a time: the SIMD twin of [`quatcurve_core::basis::bernstein_cumulative`] (de Casteljau rows `F - 2`,
/// `F - 1`, `F`; sums from the top).
#[inline(always)]
pub(super) fn bernstein_cumulative_lanes<S: Lanes, const F: usize>(u: S, out: &mut [[S; 3]; F]) {
    let v = S::ONE - u;
    let zero = [S::ZERO; MAX_FACTORS + 1];
    let (mut row, mut prev, mut prev2) = (zero, zero, zero);
    row[0] = S::ONE;
    for m in 1..=F {
        let mut next = zero;
        next[0] = v * row[0];
        for j in 1..m {
            next[j] = v.mul_add(row[j], u * row[j - 1]);
        }
        next[m] = u * row[m - 1];
        (prev2, prev, row) = (prev, row, next);
    }
    let n = F as f32;
    let mut tail = S::ZERO;
    for i in (1..=F).rev() {
        tail = tail + row[i];
        let below = if i >= 2 { prev2[i - 2] } else { S::ZERO };
        out[i - 1] = [tail, prev[i - 1] * S::splat(n), (below - prev2[i - 1]) * S::splat(n * (n - 1.0))];
    }
}
