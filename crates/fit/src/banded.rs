//! Symmetric positive definite systems with a narrow band (a B-spline fit's normal equations:
//! control points `i` and `j` interact only when `|i - j| < order`), solved by a banded
//! Cholesky factorization in `O(n * band^2)`.

/// The lower band of a symmetric matrix: entry `(i, i - d)` at `band[i * width + d]`, one
/// allocation for the whole band.
#[derive(Clone)]
pub struct Banded {
    band: Vec<f64>,
    width: usize,
}

impl Banded {
    /// An `n` by `n` zero matrix with `width - 1` sub-diagonals.
    #[must_use]
    pub fn zeros(n: usize, width: usize) -> Self {
        Self { band: vec![0.0; n * width], width }
    }

    /// Adds `value` to entry `(i, j)`, `|i - j| < width`, and its mirror.
    pub fn add(&mut self, i: usize, j: usize, value: f64) {
        let (row, col) = if i >= j { (i, j) } else { (j, i) };
        debug_assert!(row - col < self.width, "({i}, {j}) outside the band");
        self.band[row * self.width + row - col] += value;
    }

    /// `A = L L^T`, or `None` when the matrix is not positive definite.
    #[must_use]
    pub fn factor(mut self) -> Option<Cholesky> {
        let width = self.width;
        let n = self.band.len() / width;
        for i in 0..n {
            for d in (0..width.min(i + 1)).rev() {
                let j = i - d;
                let mut sum = self.band[i * width + d];
                for k in 1..(width - d).min(j + 1) {
                    sum -= self.band[i * width + d + k] * self.band[j * width + k];
                }
                if d == 0 {
                    if sum <= 0.0 || !sum.is_finite() {
                        return None;
                    }
                    self.band[i * width] = sum.sqrt();
                } else {
                    self.band[i * width + d] = sum / self.band[j * width];
                }
            }
        }
        Some(Cholesky { lower: self })
    }
}

/// A factored [`Banded`] matrix: `L` over its band.
pub struct Cholesky {
    lower: Banded,
}

impl Cholesky {
    /// Solves `A x = b` in place.
    pub fn solve(&self, b: &mut [f64]) {
        let (band, width, n) = (&self.lower.band, self.lower.width, b.len());
        for i in 0..n {
            let sum: f64 = (1..width.min(i + 1)).map(|d| band[i * width + d] * b[i - d]).sum();
            b[i] = (b[i] - sum) / band[i * width];
        }
        for i in (0..n).rev() {
            let sum: f64 = (1..width.min(n - i)).map(|d| band[(i + d) * width + d] * b[i + d]).sum();
            b[i] = (b[i] - sum) / band[i * width];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_banded_system_as_a_dense_product_checks() {
        let n = 9;
        let width = 4;
        // A diagonally dominant band: positive definite.
        let entry = |i: usize, j: usize| if i == j { 10.0 + i as f64 } else { 1.0 / (1.0 + (i + 2 * j) as f64) };
        let mut a = Banded::zeros(n, width);
        for i in 0..n {
            for j in i.saturating_sub(width - 1)..=i {
                a.add(i, j, entry(i.max(j), i.min(j)));
            }
        }
        let x: Vec<f64> = (0..n).map(|i| i as f64 - 3.0 + (i * i) as f64 * 0.1).collect();
        let mut b: Vec<f64> = (0..n)
            .map(|i| {
                x.iter()
                    .enumerate()
                    .filter(|(j, _)| i.abs_diff(*j) < width)
                    .map(|(j, v)| entry(i.max(j), i.min(j)) * v)
                    .sum()
            })
            .collect();
        a.factor().unwrap().solve(&mut b);
        for (got, want) in b.iter().zip(&x) {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
    }

    #[test]
    fn a_singular_matrix_is_refused() {
        assert!(Banded::zeros(3, 2).factor().is_none());
    }
}
