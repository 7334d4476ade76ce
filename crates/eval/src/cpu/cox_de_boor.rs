//! The cumulative B-spline basis on unequal knots, eight samples at a time: the SIMD twin of
//! [`quatcurve_core::basis::bspline_cumulative_into`]. Each lane has its own span: fitted curves have a
//! knot every frame or two, so a group of eight samples straddles several spans, and one
//! triangle with each lane's knot constants costs what one span's did. [`CoxDeBoor`] computes
//! the constants for all lanes at once (reciprocals, zero for repeated knots as in the
//! reference) and keeps them while the lanes stay on their spans.

use super::lanes::LANES;
use super::lanes::MAX_FACTORS;
use super::simd::Lanes;
use quatcurve_core::curve::MAX_ORDER;

/// Per lane, `1 / (b - a)`, or 0 for a zero-length interval (the reference's convention).
#[inline(always)]
fn inverses(a: &[f64; LANES], b: &[f64; LANES]) -> [f64; LANES] {
    let mut out = [0.0; LANES];
    for lane in 0..LANES {
        let d = b[lane] - a[lane];
        // Branch-free, so that the loop vectorizes: a zero interval divides by one, then
        // the mask drops it.
        let inv = 1.0 / if d == 0.0 { 1.0 } else { d };
        out[lane] = if d == 0.0 { 0.0 } else { inv };
    }
    out
}

/// The triangle of basis values, `tri[m][r]` per lane.
type Triangle = [[[f64; LANES]; MAX_FACTORS + 1]; MAX_FACTORS + 2];

/// The Cox-de Boor state a piece keeps from group to group: each lane's span and its knot
/// constants, filled in place, and the triangle's storage (every entry a call reads it wrote
/// in the same call).
pub struct CoxDeBoor {
    k: usize,
    /// The lanes' spans the constants are for; `None` before the first group.
    spans: Option<[usize; LANES]>,
    /// Per lane, its span's start: the origin of its time.
    origin: [f64; LANES],
    /// `rel[i]`: knot `span - k + 1 + i` relative to the origin, `i < 2k`.
    rel: [[f64; LANES]; 2 * MAX_ORDER],
    /// `inv[m][r]`: `1 / (t_j+m - t_j)` for `j = span - m + r`, `r <= m + 1`, levels
    /// `1 <= m < k` (building order `m + 1` from order `m` reads `r` and `r + 1`).
    inv: [[[f64; LANES]; MAX_ORDER + 1]; MAX_ORDER],
    tri: Triangle,
}

impl CoxDeBoor {
    /// No span yet, for order `k`.
    pub fn new(k: usize) -> Self {
        Self {
            k,
            spans: None,
            origin: [0.0; LANES],
            rel: [[0.0; LANES]; 2 * MAX_ORDER],
            inv: [[[0.0; LANES]; MAX_ORDER + 1]; MAX_ORDER],
            tri: [[[0.0; LANES]; MAX_FACTORS + 1]; MAX_FACTORS + 2],
        }
    }

    /// `[B~, B~', B~'']` (time units) of the `F = k - 1` factors at the lanes' times `t`, lane
    /// `l` in span `spans[l]` (`k - 1 <= span`, `span + k <= knots.len()`); the derivatives
    /// only with `DERIVATIVES`. The constants are computed only when a lane's span changed.
    /// The triangle runs in f64 (plain loops over the lanes, which the compiler vectorizes):
    /// in f32 its rounding, summed over seven factors of near half-turns, reached 1.1e-5 rad
    /// at order 8, over DESIGN's bar.
    #[inline(always)]
    pub fn jets<S: Lanes, const F: usize, const DERIVATIVES: bool>(
        &mut self,
        knots: &[f64],
        spans: &[usize; LANES],
        t: &[f64; LANES],
        out: &mut [[S; 3]; F],
    ) {
        debug_assert_eq!(self.k, F + 1);
        if self.spans != Some(*spans) {
            self.fill::<F>(knots, spans);
        }
        let k = F + 1;
        let mut x = [0.0; LANES];
        for lane in 0..LANES {
            x[lane] = t[lane] - self.origin[lane];
        }
        let (rel, inv, tri) = (&self.rel, &self.inv, &mut self.tri);
        // tri[m][r] = B_{span-m+1+r, m}(t), orders m = 1..=k; basis j = span - m + r of order
        // m + 1 blends (t - t_j) / (t_j+m - t_j) of basis j and (t_j+m+1 - t) / (t_j+m+1 -
        // t_j+1) of basis j + 1, both of order m. Knot j is rel[j - span + k - 1].
        tri[1][0] = [1.0; LANES];
        for m in 1..k {
            for r in 0..=m {
                let mut b = [0.0; LANES];
                if r >= 1 {
                    let (a, inv, prev) = (&rel[k - 1 - m + r], &inv[m][r], &tri[m][r - 1]);
                    for lane in 0..LANES {
                        b[lane] = (x[lane] - a[lane]) * inv[lane] * prev[lane];
                    }
                }
                if r < m {
                    let (c, inv, prev) = (&rel[k + r], &inv[m][r + 1], &tri[m][r]);
                    for lane in 0..LANES {
                        b[lane] += (c[lane] - x[lane]) * inv[lane] * prev[lane];
                    }
                }
                tri[m + 1][r] = b;
            }
        }
        let kf = k as f64;
        let mut tail = [0.0; LANES];
        for f in (0..F).rev() {
            // Factor f is basis i = span - k + 2 + f: entry f + 1 of order k, f of order k - 1,
            // f - 1 and f of order k - 2; its derivative divides by t_i+k-1 - t_i (level
            // k - 1, entry f + 1), t_i+k-2 - t_i and t_i+k-1 - t_i+1 (level k - 2, entries f
            // and f + 1).
            for lane in 0..LANES {
                tail[lane] += tri[k][f + 1][lane];
            }
            let mut jet = [lanes(tail), S::ZERO, S::ZERO];
            if DERIVATIVES {
                let d1 = &inv[k - 1][f + 1];
                let mut first = [0.0; LANES];
                for lane in 0..LANES {
                    first[lane] = tri[k - 1][f][lane] * (kf - 1.0) * d1[lane];
                }
                jet[1] = lanes(first);
                if k >= 3 {
                    let (d2a, d2b) = (&inv[k - 2][f], &inv[k - 2][f + 1]);
                    let mut inner = [0.0; LANES];
                    for lane in 0..LANES {
                        let below = if f >= 1 { tri[k - 2][f - 1][lane] } else { 0.0 };
                        let above = if f < k - 2 { tri[k - 2][f][lane] } else { 0.0 };
                        inner[lane] = (below * d2a[lane] - above * d2b[lane]) * (kf - 1.0) * (kf - 2.0) * d1[lane];
                    }
                    jet[2] = lanes(inner);
                }
            }
            out[f] = jet;
        }
    }

    /// The constants of the lanes' spans, written over the entries order `k` reads (the
    /// others are never read).
    #[inline(always)]
    fn fill<const F: usize>(&mut self, knots: &[f64], spans: &[usize; LANES]) {
        let k = F + 1;
        // Knots span - k + 1 ..= span + k of each lane, as they are and relative to the span.
        let mut raw = [[0.0; LANES]; 2 * MAX_ORDER];
        for (lane, &span) in spans.iter().enumerate() {
            let window = &knots[span + 1 - k..=span + k];
            for (i, &knot) in window.iter().enumerate() {
                raw[i][lane] = knot;
            }
            self.origin[lane] = knots[span];
        }
        for (rel, raw) in self.rel.iter_mut().zip(&raw).take(2 * k) {
            for ((rel, &knot), &origin) in rel.iter_mut().zip(raw).zip(&self.origin) {
                *rel = knot - origin;
            }
        }
        // Level m, entry r: knots j = span - m + r and j + m, rel entries k - 1 - m + r and
        // k - 1 + r; from the knots themselves, so that equal knots give exactly zero.
        for m in 1..k {
            for r in 0..=m + 1 {
                self.inv[m][r] = inverses(&raw[k - 1 - m + r], &raw[k - 1 + r]);
            }
        }
        self.spans = Some(*spans);
    }
}

/// f64 lanes rounded into a lane register.
#[inline(always)]
fn lanes<S: Lanes>(v: [f64; LANES]) -> S {
    S::new(v.map(|v| v as f32))
}
