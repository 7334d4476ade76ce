//! The cumulative B-spline basis on unequal knots, eight samples at a time: the SIMD twin of
//! [`crate::basis::bspline_cumulative_into`]. The knot quotients of a span are the same for
//! every lane, so [`SpanKnots`] computes them once per span (reciprocals, zero for
//! repeated knots as in the reference) and the triangle itself is all lane arithmetic;
//! [`CoxDeBoor`] keeps both from group to group.

use super::lanes::LANES;
use super::lanes::MAX_FACTORS;
use super::simd::Lanes;

/// `1 / (b - a)`, or 0 for a zero-length interval (the reference's convention).
fn inverse(a: f64, b: f64) -> f64 {
    if b == a {
        0.0
    } else {
        1.0 / (b - a)
    }
}

/// What span `span`'s triangle needs from the knots, for order `k`.
#[derive(Clone, Debug)]
pub struct SpanKnots {
    pub span: usize,
    k: usize,
    /// Start of the span, the origin of lane times.
    origin: f64,
    /// Building order `m + 1` from order `m`, entry `r` (basis `j = span - m + r`):
    /// `(t_j, 1 / (t_j+m - t_j))` and `(t_j+m+1, 1 / (t_j+m+1 - t_j+1))`, knots relative to
    /// the origin.
    left: [[(f64, f64); MAX_FACTORS + 1]; MAX_FACTORS + 1],
    right: [[(f64, f64); MAX_FACTORS + 1]; MAX_FACTORS + 1],
    /// Per factor `i` (`i = span - k + 2 + f`): `1 / (t_i+k-1 - t_i)`, `1 / (t_i+k-2 - t_i)`,
    /// `1 / (t_i+k-1 - t_i+1)`.
    derivative: [[f64; 3]; MAX_FACTORS],
}

/// The triangle of basis values, `tri[m][r]` per lane: storage a piece reuses, since every
/// entry [`SpanKnots::jets`] reads it wrote in the same call.
pub type Triangle = [[[f64; LANES]; MAX_FACTORS + 1]; MAX_FACTORS + 2];

/// The Cox-de Boor state a piece keeps from group to group: the last span's constants and the
/// triangle, both filled in place (a triangle zeroed per group and constants built and moved
/// per span were a third of the time of a track with a knot every few samples).
pub struct CoxDeBoor {
    constants: SpanKnots,
    /// Whether `constants` hold a span yet.
    filled: bool,
    tri: Triangle,
}

impl CoxDeBoor {
    /// No span yet, for order `k`.
    pub fn new(k: usize) -> Self {
        let constants = SpanKnots {
            span: 0,
            k,
            origin: 0.0,
            left: [[(0.0, 0.0); MAX_FACTORS + 1]; MAX_FACTORS + 1],
            right: [[(0.0, 0.0); MAX_FACTORS + 1]; MAX_FACTORS + 1],
            derivative: [[0.0; 3]; MAX_FACTORS],
        };
        Self { constants, filled: false, tri: [[[0.0; LANES]; MAX_FACTORS + 1]; MAX_FACTORS + 2] }
    }

    /// [`SpanKnots::jets`] of span `span`, its constants computed only when the span changed.
    #[inline(always)]
    pub fn jets<S: Lanes, const F: usize, const DERIVATIVES: bool>(
        &mut self,
        knots: &[f64],
        span: usize,
        t: &[f64; LANES],
        out: &mut [[S; 3]; F],
    ) {
        if !self.filled || self.constants.span != span {
            self.constants.fill(knots, span);
            self.filled = true;
        }
        self.constants.jets::<S, F, DERIVATIVES>(t, out, &mut self.tri);
    }
}

impl SpanKnots {
    /// The constants of span `span` (`k - 1 <= span`, `span + k <= knots.len()`), written over
    /// the entries order `k` reads (the others are never read).
    fn fill(&mut self, knots: &[f64], span: usize) {
        let k = self.k;
        let origin = knots[span];
        let rel = |j: usize| knots[j] - origin;
        for m in 1..k {
            for r in 0..=m {
                let j = span + r - m;
                self.left[m][r] = (rel(j), inverse(knots[j], knots[j + m]));
                self.right[m][r] = (rel(j + m + 1), inverse(knots[j + 1], knots[j + m + 1]));
            }
        }
        for (f, d) in self.derivative.iter_mut().enumerate().take(k - 1) {
            let i = span + 2 + f - k;
            *d = [
                inverse(knots[i], knots[i + k - 1]),
                inverse(knots[i], knots[i + k - 2]),
                inverse(knots[i + 1], knots[i + k - 1]),
            ];
        }
        (self.span, self.origin) = (span, origin);
    }

    /// `[B~, B~', B~'']` (time units) of the `F = k - 1` factors at the lanes' times `t`; the
    /// derivatives only with `DERIVATIVES`. The triangle runs in f64 (plain loops over the
    /// lanes, which the compiler vectorizes): in f32 its rounding, summed over seven factors
    /// of near half-turns, reached 1.1e-5 rad at order 8, over DESIGN's bar.
    #[inline(always)]
    pub fn jets<S: Lanes, const F: usize, const DERIVATIVES: bool>(
        &self,
        t: &[f64; LANES],
        out: &mut [[S; 3]; F],
        tri: &mut Triangle,
    ) {
        debug_assert_eq!(self.k, F + 1);
        let k = F + 1;
        let x = t.map(|t| t - self.origin);
        // tri[m][r] = B_{span-m+1+r, m}(t), orders m = 1..=k; each read below is of an entry
        // written above it in this call.
        tri[1][0] = [1.0; LANES];
        for m in 1..k {
            for r in 0..=m {
                let mut b = [0.0; LANES];
                if r >= 1 {
                    let ((a, inv), prev) = (self.left[m][r], &tri[m][r - 1]);
                    for lane in 0..LANES {
                        b[lane] = (x[lane] - a) * inv * prev[lane];
                    }
                }
                if r < m {
                    let ((c, inv), prev) = (self.right[m][r], &tri[m][r]);
                    for lane in 0..LANES {
                        b[lane] += (c - x[lane]) * inv * prev[lane];
                    }
                }
                tri[m + 1][r] = b;
            }
        }
        let kf = k as f64;
        let mut tail = [0.0; LANES];
        for f in (0..F).rev() {
            // Factor f is basis i = span - k + 2 + f: entry f + 1 of order k, f of order k - 1,
            // f - 1 and f of order k - 2.
            for lane in 0..LANES {
                tail[lane] += tri[k][f + 1][lane];
            }
            let mut jet = [lanes(tail), S::ZERO, S::ZERO];
            if DERIVATIVES {
                let [d1, d2a, d2b] = self.derivative[f];
                jet[1] = lanes(tri[k - 1][f].map(|b| b * (kf - 1.0) * d1));
                if k >= 3 {
                    let mut inner = [0.0; LANES];
                    for lane in 0..LANES {
                        let below = if f >= 1 { tri[k - 2][f - 1][lane] } else { 0.0 };
                        let above = if f < k - 2 { tri[k - 2][f][lane] } else { 0.0 };
                        inner[lane] = (below * d2a - above * d2b) * (kf - 1.0) * (kf - 2.0) * d1;
                    }
                    jet[2] = lanes(inner);
                }
            }
            out[f] = jet;
        }
    }
}

/// f64 lanes rounded into a lane register.
#[inline(always)]
fn lanes<S: Lanes>(v: [f64; LANES]) -> S {
    S::new(v.map(|v| v as f32))
}
