//! The (cyclic) block tridiagonal solve of each Newton step: 3x3 blocks, block Thomas, a
//! cyclic system bordered by its last unknown.

use glam::{DMat3, DVec3 as V3};

/// What a linear solve carries per block: a vector, or a vector and a 3x3 block column (the
/// border of a cyclic system).
pub(super) trait Block: Copy {
    fn lmul(m: &DMat3, x: Self) -> Self;
    fn minus(self, o: Self) -> Self;
}

impl Block for V3 {
    fn lmul(m: &DMat3, x: Self) -> Self {
        *m * x
    }
    fn minus(self, o: Self) -> Self {
        self - o
    }
}

impl Block for (V3, DMat3) {
    fn lmul(m: &DMat3, x: Self) -> Self {
        (*m * x.0, *m * x.1)
    }
    fn minus(self, o: Self) -> Self {
        (self.0 - o.0, self.1 - o.1)
    }
}

/// Block tridiagonal solve (block Thomas) of `lower_r x_{r-1} + diag_r x_r + upper_r x_{r+1}
/// = rhs_r` in place; `None` when a pivot block is singular.
/// `carry` is scratch space.
pub(super) fn solve_tridiagonal<T: Block>(
    lower: &[DMat3],
    diag: &[DMat3],
    upper: &[DMat3],
    rhs: &mut [T],
    carry: &mut Vec<DMat3>,
) -> Option<()> {
    let n = rhs.len();
    carry.clear();
    for r in 0..n {
        let mut d = diag[r];
        if r > 0 {
            d -= lower[r] * carry[r - 1];
            rhs[r] = rhs[r].minus(T::lmul(&lower[r], rhs[r - 1]));
        }
        let det = d.determinant();
        if !det.is_finite() || det.abs() < 1e-300 {
            return None;
        }
        let inv = d.inverse();
        carry.push(inv * upper[r]);
        rhs[r] = T::lmul(&inv, rhs[r]);
    }
    for r in (0..n.saturating_sub(1)).rev() {
        rhs[r] = rhs[r].minus(T::lmul(&carry[r], rhs[r + 1]));
    }
    Some(())
}

/// The arrays a linear solve fills, kept across Newton iterations (allocating and zeroing
/// them per solve was a measured cost).
#[derive(Default)]
pub(super) struct Scratch {
    lower: Vec<DMat3>,
    diag: Vec<DMat3>,
    upper: Vec<DMat3>,
    /// Row 0: column n-1; row n-1: column 0 (cyclic systems, n >= 3).
    corner: Vec<DMat3>,
    carry: Vec<DMat3>,
    aug: Vec<(V3, DMat3)>,
}

/// Solves the (possibly cyclic) block tridiagonal system whose row `r` has blocks `blocks[r]`
/// on the unknowns `cols[r]` (the same unknown may appear twice: the blocks add) into `x`.
pub(super) fn solve(
    columns: &[[Option<usize>; 3]],
    blocks: &[[DMat3; 3]],
    rhs: &[V3],
    periodic: bool,
    scratch: &mut Scratch,
    x: &mut Vec<V3>,
) -> Option<()> {
    let n = rhs.len();
    let zero = DMat3::ZERO;
    // Sort each row's blocks into lower / diagonal / upper / corner (cyclic wrap).
    let Scratch { lower, diag, upper, corner, carry, aug } = scratch;
    for v in [&mut *lower, &mut *diag, &mut *upper, &mut *corner] {
        v.clear();
        v.resize(n, zero);
    }
    for r in 0..n {
        for (col, block) in columns[r].iter().zip(&blocks[r]) {
            let Some(c) = *col else { continue };
            let slot = if c == r {
                &mut diag[r]
            } else if c + 1 == r {
                &mut lower[r]
            } else if c == r + 1 {
                &mut upper[r]
            } else {
                &mut corner[r]
            };
            *slot += *block;
        }
    }
    x.clear();
    if !periodic || n < 3 {
        x.extend_from_slice(rhs);
        return solve_tridiagonal(lower, diag, upper, x, carry);
    }
    // Border the last unknown: rows 0..n-2 solve T [y | Z] = [rhs | border], then the last
    // row gives x_{n-1}, and x' = y - Z x_{n-1}.
    let m = n - 1;
    aug.clear();
    aug.extend((0..m).map(|r| (rhs[r], zero)));
    aug[0].1 = corner[0];
    aug[m - 1].1 += upper[m - 1];
    // Row m - 1's upper block went into the border: the tridiagonal part ends there.
    upper[m - 1] = zero;
    solve_tridiagonal(&lower[..m], &diag[..m], &upper[..m], aug, carry)?;
    let (first, last) = (corner[m], lower[m]);
    let s = diag[m] - last * aug[m - 1].1 - first * aug[0].1;
    let det = s.determinant();
    if !det.is_finite() || det.abs() < 1e-300 {
        return None;
    }
    let xm = s.inverse() * (rhs[m] - last * aug[m - 1].0 - first * aug[0].0);
    x.extend(aug.iter().map(|(y, z)| *y - *z * xm));
    x.push(xm);
    Some(())
}
