//! The (cyclic) block tridiagonal solve of each Newton step: 3x3 blocks, block Thomas, a
//! cyclic system bordered by its last unknown. Written once over [`Matrix`], for one track's
//! `DMat3` blocks and for four tracks' lanes ([`M4`]).

use super::f64x4::{Lanes64, M4, SINGULAR, V4};
use glam::{DMat3, DVec3 as V3};
use std::ops::{Add, AddAssign, Mul, Sub};

/// A 3x3 block: `DMat3`, or four lanes of them.
pub(super) trait Matrix:
    Copy
    + Add<Output = Self>
    + AddAssign
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Mul<Self::Vector, Output = Self::Vector>
{
    /// The vector a block multiplies.
    type Vector: Copy + Sub<Output = Self::Vector> + Block<Self>;
    /// Which lanes met a singular pivot: `bool`, or a [`Mask`].
    type Singular: Copy;
    fn zero() -> Self;
    fn nonsingular() -> Self::Singular;
    /// The inverse, and whether (which lanes) it does not exist ([`SINGULAR`]).
    fn checked_inverse(self) -> (Self, Self::Singular);
    fn either(a: Self::Singular, b: Self::Singular) -> Self::Singular;
}

impl Matrix for DMat3 {
    type Vector = V3;
    type Singular = bool;
    fn zero() -> Self {
        DMat3::ZERO
    }
    fn nonsingular() -> bool {
        false
    }
    #[inline(always)]
    fn checked_inverse(self) -> (Self, bool) {
        let det = self.determinant();
        (self.inverse(), !det.is_finite() || det.abs() < SINGULAR)
    }
    #[inline(always)]
    fn either(a: bool, b: bool) -> bool {
        a | b
    }
}

impl<L: Lanes64> AddAssign for M4<L> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<L: Lanes64> Matrix for M4<L> {
    type Vector = V4<L>;
    type Singular = L;
    #[inline(always)]
    fn zero() -> Self {
        M4::zero()
    }
    #[inline(always)]
    fn nonsingular() -> L {
        L::none()
    }
    #[inline(always)]
    fn checked_inverse(self) -> (Self, L) {
        self.inverse()
    }
    #[inline(always)]
    fn either(a: L, b: L) -> L {
        a | b
    }
}

/// What a linear solve carries per block: a vector, or a vector and a block column (the
/// border of a cyclic system).
pub(super) trait Block<M>: Copy {
    fn lmul(m: &M, x: Self) -> Self;
    fn minus(self, o: Self) -> Self;
}

impl Block<DMat3> for V3 {
    #[inline(always)]
    fn lmul(m: &DMat3, x: Self) -> Self {
        *m * x
    }
    #[inline(always)]
    fn minus(self, o: Self) -> Self {
        self - o
    }
}

impl<L: Lanes64> Block<M4<L>> for V4<L> {
    #[inline(always)]
    fn lmul(m: &M4<L>, x: Self) -> Self {
        *m * x
    }
    #[inline(always)]
    fn minus(self, o: Self) -> Self {
        self - o
    }
}

impl<M: Matrix> Block<M> for (M::Vector, M) {
    #[inline(always)]
    fn lmul(m: &M, x: Self) -> Self {
        (*m * x.0, *m * x.1)
    }
    #[inline(always)]
    fn minus(self, o: Self) -> Self {
        (self.0 - o.0, self.1 - o.1)
    }
}

/// Block tridiagonal solve (block Thomas) of `rows[r][0] x_{r-1} + rows[r][1] x_r +
/// rows[r][2] x_{r+1} = rhs_r` in place (the first row's `[0]` and the last row's `[2]` are
/// not read); returns where a pivot block was singular (the solution is garbage there).
/// `carry` is scratch space.
#[inline(always)]
fn solve_tridiagonal<M: Matrix, T: Block<M>>(rows: &[[M; 3]], rhs: &mut [T], carry: &mut Vec<M>) -> M::Singular {
    let n = rhs.len();
    carry.clear();
    let mut singular = M::nonsingular();
    for r in 0..n {
        let [lower, diag, upper] = &rows[r];
        let mut d = *diag;
        if r > 0 {
            d = d - *lower * carry[r - 1];
            rhs[r] = rhs[r].minus(T::lmul(lower, rhs[r - 1]));
        }
        let (inv, s) = d.checked_inverse();
        singular = M::either(singular, s);
        if r + 1 < n {
            carry.push(inv * *upper);
        }
        rhs[r] = T::lmul(&inv, rhs[r]);
    }
    for r in (0..n.saturating_sub(1)).rev() {
        rhs[r] = rhs[r].minus(T::lmul(&carry[r], rhs[r + 1]));
    }
    singular
}

/// The arrays a linear solve fills, kept across Newton iterations (allocating them per solve
/// was a measured cost).
pub(super) struct Scratch<M: Matrix> {
    /// Rows sorted into `[lower, diagonal, upper]` where a short cyclic system meets one
    /// unknown twice in a row.
    sorted: Vec<[M; 3]>,
    carry: Vec<M>,
    aug: Vec<(M::Vector, M)>,
}

impl<M: Matrix> Default for Scratch<M> {
    fn default() -> Self {
        Self { sorted: Vec::new(), carry: Vec::new(), aug: Vec::new() }
    }
}

/// Solves the (possibly cyclic) block tridiagonal system whose row `r` has blocks `blocks[r]`
/// on the unknowns `columns[r]` into `x`; returns where it is singular. An open system's row
/// `r` reads unknowns `r - 1, r, r + 1` (none past the ends), a cyclic one's the same modulo
/// the row count, so the blocks are read in place; a cyclic system of fewer than three rows
/// meets an unknown twice in a row, and its blocks are added up first.
#[inline(always)]
pub(super) fn solve<M: Matrix>(
    columns: &[[Option<usize>; 3]],
    blocks: &[[M; 3]],
    rhs: &[M::Vector],
    periodic: bool,
    scratch: &mut Scratch<M>,
    x: &mut Vec<M::Vector>,
) -> M::Singular {
    let n = rhs.len();
    let zero = M::zero();
    let Scratch { sorted, carry, aug } = scratch;
    x.clear();
    x.extend_from_slice(rhs);
    if !periodic {
        return solve_tridiagonal(blocks, x, carry);
    }
    if n < 3 {
        sorted.clear();
        for (r, (cols, row)) in columns.iter().zip(blocks).enumerate() {
            let mut out = [zero; 3];
            for (col, block) in cols.iter().zip(row) {
                let Some(c) = *col else { continue };
                let slot = if c == r {
                    1
                } else if c + 1 == r {
                    0
                } else {
                    2
                };
                out[slot] += *block;
            }
            sorted.push(out);
        }
        return solve_tridiagonal(sorted, x, carry);
    }
    // Border the last unknown: rows 0..n-2 solve T [y | Z] = [rhs | border], then the last
    // row gives x_{n-1}, and x' = y - Z x_{n-1}. Row 0's lower block is the corner on
    // x_{n-1}, row m - 1's upper block is on x_{n-1} too; both go into the border.
    let m = n - 1;
    aug.clear();
    for &v in &rhs[..m] {
        aug.push((v, zero));
    }
    aug[0].1 = blocks[0][0];
    aug[m - 1].1 += blocks[m - 1][2];
    let singular = solve_tridiagonal(&blocks[..m], aug, carry);
    let [last, diag, first] = blocks[m];
    let s = diag - last * aug[m - 1].1 - first * aug[0].1;
    let (s_inv, s_singular) = s.checked_inverse();
    let xm = s_inv * (rhs[m] - last * aug[m - 1].0 - first * aug[0].0);
    x.clear();
    for &(y, z) in aug.iter() {
        x.push(y - z * xm);
    }
    x.push(xm);
    M::either(singular, s_singular)
}
