//! Cumulative basis functions `B~_i(t)` of KKS section 4.2, with their first two derivatives.
//!
//! A Euclidean spline `p(t) = sum p_i B_i(t)` rewritten as `p_0 B~_0 + sum (p_i - p_{i-1}) B~_i`
//! with `B~_i = sum_{j >= i} B_j` becomes the quaternion curve `q_0 prod exp(w_i B~_i(t))`.
//! Every family's basis lives here once; evaluators only multiply exponentials.

/// A basis value with its first and second derivatives in the basis' own parameter.
pub type BasisJet = [f64; 3];

/// Cumulative Bernstein basis of degree `n` at `u in [0, 1]` (KKS eq. 9): entries
/// `i = 1..=n` as `out[i - 1] = [B~_{i,n}(u), d/du, d2/du2]`.
///
/// Uses `d/du B~_{i,n} = n B_{i-1,n-1}` and `d2/du2 B~_{i,n} = n (n-1) (B_{i-2,n-2} - B_{i-1,n-2})`;
/// the Bernstein rows come from the de Casteljau triangle, which is stable for any degree.
/// Sums run from the top (`B~_n` first) so that values near `u = 0` keep full precision.
#[must_use]
pub fn bernstein_cumulative(n: usize, u: f64) -> Vec<BasisJet> {
    let mut rows: Vec<Vec<f64>> = vec![vec![1.0]];
    for m in 1..=n {
        let prev = &rows[m - 1];
        let row: Vec<f64> = (0..=m)
            .map(|j| {
                let keep = if j < m { (1.0 - u) * prev[j] } else { 0.0 };
                let up = if j > 0 { u * prev[j - 1] } else { 0.0 };
                keep + up
            })
            .collect();
        rows.push(row);
    }
    let at = |m: isize, j: isize| -> f64 {
        if m < 0 || j < 0 || j > m {
            0.0
        } else {
            rows[m as usize][j as usize]
        }
    };
    let (n_i, nf) = (n as isize, n as f64);
    let mut out = vec![[0.0; 3]; n];
    let mut tail = 0.0;
    for i in (1..=n_i).rev() {
        tail += at(n_i, i);
        out[(i - 1) as usize] =
            [tail, nf * at(n_i - 1, i - 1), nf * (nf - 1.0) * (at(n_i - 2, i - 2) - at(n_i - 2, i - 1))];
    }
    out
}

/// Cumulative B-spline basis of order `k` (degree `k - 1`) at time `t` in knot span `l`
/// (`knots[l] <= t < knots[l + 1]`, or the closed last span): entries for
/// `i = l-k+2 ..= l` as `out[i - (l-k+2)] = [B~_{i,k}(t), d/dt, d2/dt2]` (KKS section 5.3).
/// Outside that window `B~_i` is 1 (`i <= l-k+1`) or 0 (`i > l`), constant.
///
/// Values: `B~_i = sum_{j=i}^{l} B_{j,k}` from the Cox-de Boor triangle. Derivatives: KKS's
/// `B~'_{i,k} = (k-1) B_{i,k-1} / (t_{i+k-1} - t_i)`, differentiated once more with the same
/// rule. Quotients with a zero-length denominator (repeated knots) are 0 by convention.
#[must_use]
pub fn bspline_cumulative(knots: &[f64], k: usize, l: usize, t: f64) -> Vec<BasisJet> {
    let mut out = vec![[0.0; 3]; k - 1];
    bspline_cumulative_into(knots, k, l, t, &mut out);
    out
}

/// [`bspline_cumulative`] into `out[..k - 1]`, without allocating (the fast CPU path calls
/// it per sample).
pub fn bspline_cumulative_into(knots: &[f64], k: usize, l: usize, t: f64, out: &mut [BasisJet]) {
    // Rows k - 2, k - 1 and k of the triangle: the derivatives read the two below the last.
    let mut rows = [[0.0f64; MAX_TRIANGLE]; 3];
    let last = cox_de_boor(knots, k, l, t, |m, row| {
        if m + 2 >= k {
            rows[m + 2 - k] = *row;
        }
    });
    rows[2] = last;
    let div = |a: f64, b: f64| if b == 0.0 { 0.0 } else { a / b };
    // B_{j,m}(t), zero outside the triangle.
    let basis = |m: usize, j: isize| -> f64 {
        if m == 0 {
            return 0.0;
        }
        let r = j - (l as isize - m as isize + 1);
        if r < 0 || r >= m as isize {
            0.0
        } else {
            rows[m + 2 - k][r as usize]
        }
    };
    let kn = |j: isize| knots[j as usize];
    let kf = k as f64;
    let first = l as isize - k as isize + 2;
    let mut tail = 0.0;
    for i in (first..=l as isize).rev() {
        tail += basis(k, i);
        let d1 = (kf - 1.0) * div(basis(k - 1, i), kn(i + k as isize - 1) - kn(i));
        let d2 = if k >= 3 {
            let inner = div(basis(k - 2, i), kn(i + k as isize - 2) - kn(i))
                - div(basis(k - 2, i + 1), kn(i + k as isize - 1) - kn(i + 1));
            (kf - 1.0) * (kf - 2.0) * div(inner, kn(i + k as isize - 1) - kn(i))
        } else {
            0.0
        };
        out[(i - first) as usize] = [tail, d1, d2];
    }
}

/// The values alone of [`bspline_cumulative_into`] (the same sums, so the same bits), into
/// `out[..k - 1]`: what a curve's value needs (a vector channel per sample), without the
/// derivatives' quotients.
pub fn bspline_cumulative_values_into(knots: &[f64], k: usize, l: usize, t: f64, out: &mut [f64]) {
    let row = cox_de_boor(knots, k, l, t, |_, _| {});
    let first = l as isize - k as isize + 2;
    let mut tail = 0.0;
    for i in (first..=l as isize).rev() {
        let r = i - (l as isize - k as isize + 1);
        tail += if r < 0 || r >= k as isize { 0.0 } else { row[r as usize] };
        out[(i - first) as usize] = tail;
    }
}

/// Entries of a Cox-de Boor triangle's row: the highest order, [`crate::curve::MAX_ORDER`].
const MAX_TRIANGLE: usize = crate::curve::MAX_ORDER;

/// The last row of the Cox-de Boor triangle at `t` on span `l`, `row[r] = B_{l-k+1+r, k}(t)`
/// for `r = 0..k`, each row `m = 1..k` shown to `seen(m, row)` before the next replaces it in
/// place: de Boor's triangular scheme (Piegl and Tiller's `BasisFuns`), one quotient per pair
/// of neighbours (6 for a cubic, where the recursion as written takes 18). Its denominators
/// are knot differences that span `[t_l, t_{l+1}]`, so they vanish only on an empty span, whose
/// quotients are 0.
#[inline]
fn cox_de_boor(
    knots: &[f64],
    k: usize,
    l: usize,
    t: f64,
    mut seen: impl FnMut(usize, &[f64; MAX_TRIANGLE]),
) -> [f64; MAX_TRIANGLE] {
    let mut row = [0.0f64; MAX_TRIANGLE];
    row[0] = 1.0;
    // left[j] = t - t_{l+1-j}, right[j] = t_{l+j} - t.
    let (mut left, mut right) = ([0.0f64; MAX_TRIANGLE], [0.0f64; MAX_TRIANGLE]);
    for m in 1..k {
        seen(m, &row);
        left[m] = t - knots[l + 1 - m];
        right[m] = knots[l + m] - t;
        let mut saved = 0.0;
        for r in 0..m {
            let width = right[r + 1] + left[m - r];
            let quotient = if width == 0.0 { 0.0 } else { row[r] / width };
            row[r] = saved + right[r + 1] * quotient;
            saved = left[m - r] * quotient;
        }
        row[m] = saved;
    }
    row
}

/// The cumulative basis functions of one span as polynomials in the span parameter
/// `u in [0, 1]`, coefficients lowest first (8 slots, unused ones zero): interpolated at
/// `degree + 1` equispaced nodes of `basis`, so exact for polynomials of that degree up to f64
/// rounding. The fast paths evaluate these instead of the triangles above wherever the basis
/// is the same on every span (slerp, Hermite, B-splines on equally spaced knots).
#[must_use]
pub fn fit_polynomials(degree: usize, basis: impl Fn(f64) -> Vec<BasisJet>) -> Vec<[f64; 8]> {
    let n = degree + 1;
    let nodes: Vec<f64> = (0..n).map(|i| i as f64 / degree.max(1) as f64).collect();
    let values: Vec<Vec<BasisJet>> = nodes.iter().map(|&u| basis(u)).collect();
    (0..values[0].len())
        .map(|f| {
            let mut a: Vec<Vec<f64>> = nodes.iter().map(|&u| (0..n).map(|p| u.powi(p as i32)).collect()).collect();
            let mut b: Vec<f64> = values.iter().map(|v| v[f][0]).collect();
            solve(&mut a, &mut b);
            let mut c = [0.0; 8];
            c[..n].copy_from_slice(&b);
            c
        })
        .collect()
}

/// [`fit_polynomials`] of the B-spline of order `k` (2..=8) on equally spaced knots: the same
/// `k - 1` polynomials on every span, in the span parameter.
#[must_use]
pub fn uniform_bspline_polynomials(k: usize) -> Vec<[f64; 8]> {
    // Unit-spaced knots 0..2k-1: span k-1 is [k-1, k], where t = k-1+u.
    let knots: Vec<f64> = (0..2 * k).map(|j| j as f64).collect();
    fit_polynomials(k - 1, |u| bspline_cumulative(&knots, k, k - 1, k as f64 - 1.0 + u))
}

/// [`fit_polynomials`] of the cumulative Bernstein basis of degree `n` (`n <= 7`).
#[must_use]
pub fn bernstein_polynomials(n: usize) -> Vec<[f64; 8]> {
    fit_polynomials(n, |u| bernstein_cumulative(n, u))
}

/// Gaussian elimination with partial pivoting (tiny systems, f64).
fn solve(a: &mut [Vec<f64>], b: &mut [f64]) {
    let n = b.len();
    for col in 0..n {
        let pivot = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs())).unwrap_or(col);
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..n {
            let f = a[row][col] / a[col][col];
            let (top, bottom) = a.split_at_mut(row);
            for (x, p) in bottom[0][col..n].iter_mut().zip(&top[col][col..n]) {
                *x -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|c| a[row][c] * b[c]).sum();
        b[row] = (b[row] - s) / a[row][row];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Plain (non-cumulative) B-spline basis by the textbook recursion, independent of the
    /// triangle above; used to check values.
    fn cox_de_boor(knots: &[f64], j: usize, k: usize, t: f64) -> f64 {
        if k == 1 {
            return if knots[j] <= t && t < knots[j + 1] { 1.0 } else { 0.0 };
        }
        let a = knots[j + k - 1] - knots[j];
        let b = knots[j + k] - knots[j + 1];
        let left = if a > 0.0 { (t - knots[j]) / a * cox_de_boor(knots, j, k - 1, t) } else { 0.0 };
        let right = if b > 0.0 { (knots[j + k] - t) / b * cox_de_boor(knots, j + 1, k - 1, t) } else { 0.0 };
        left + right
    }

    #[test]
    fn bernstein_cumulative_cubic_is_kks_hermite_basis() {
        for &u in &[0.0, 0.2, 0.5, 0.9, 1.0] {
            let b = bernstein_cumulative(3, u);
            let expect = [1.0 - (1.0 - u).powi(3), 3.0 * u * u - 2.0 * u.powi(3), u.powi(3)];
            let d1 = [3.0 * (1.0 - u).powi(2), 6.0 * u * (1.0 - u), 3.0 * u * u];
            let d2 = [-6.0 * (1.0 - u), 6.0 - 12.0 * u, 6.0 * u];
            for i in 0..3 {
                assert!((b[i][0] - expect[i]).abs() < 1e-15);
                assert!((b[i][1] - d1[i]).abs() < 1e-14);
                assert!((b[i][2] - d2[i]).abs() < 1e-13);
            }
        }
    }

    #[test]
    fn bspline_cumulative_matches_textbook_recursion_and_differences() {
        let knots = [0.0, 0.0, 0.5, 1.0, 1.0, 2.0, 3.5, 4.0, 5.0, 5.0, 5.5, 6.0];
        for k in 2..=5 {
            let m = knots.len() - k - 1; // control points 0..=m-1... (n+1 = len - k)
            let n = m;
            for l in (k - 1)..=n {
                if knots[l] == knots[l + 1] {
                    continue;
                }
                for s in 1..8 {
                    let t = knots[l] + (knots[l + 1] - knots[l]) * s as f64 / 8.0;
                    let cum = bspline_cumulative(&knots, k, l, t);
                    let first = l + 2 - k;
                    for (off, jet) in cum.iter().enumerate() {
                        let i = first + off;
                        let plain: f64 = (i..=n).map(|j| cox_de_boor(&knots, j, k, t)).sum();
                        assert!((jet[0] - plain).abs() < 1e-14, "k {k} l {l} i {i}");
                        let h = 1e-5;
                        let f = |t: f64| bspline_cumulative(&knots, k, l, t)[off][0];
                        let d1 = (f(t + h) - f(t - h)) / (2.0 * h);
                        let d2 = (f(t + h) - 2.0 * f(t) + f(t - h)) / (h * h);
                        assert!((jet[1] - d1).abs() < 1e-7, "k {k} d1 {} vs {d1}", jet[1]);
                        if k >= 3 {
                            assert!((jet[2] - d2).abs() < 1e-4, "k {k} d2 {} vs {d2}", jet[2]);
                        }
                    }
                }
            }
        }
    }
}
