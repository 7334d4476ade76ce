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
    type Vector: Copy + Sub<Output = Self::Vector>;
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

impl<M: Matrix> Block<M> for (M::Vector,) {
    #[inline(always)]
    fn lmul(m: &M, x: Self) -> Self {
        (*m * x.0,)
    }
    #[inline(always)]
    fn minus(self, o: Self) -> Self {
        (self.0 - o.0,)
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

/// Block tridiagonal solve (block Thomas) of `lower_r x_{r-1} + diag_r x_r + upper_r x_{r+1}
/// = rhs_r` in place; returns where a pivot block was singular (the solution is garbage
/// there). `carry` is scratch space.
#[inline(always)]
fn solve_tridiagonal<M: Matrix, T: Block<M>>(
    lower: &[M],
    diag: &[M],
    upper: &[M],
    rhs: &mut [T],
    carry: &mut Vec<M>,
) -> M::Singular {
    let n = rhs.len();
    carry.clear();
    let mut singular = M::nonsingular();
    for r in 0..n {
        let mut d = diag[r];
        if r > 0 {
            d = d - lower[r] * carry[r - 1];
            rhs[r] = rhs[r].minus(T::lmul(&lower[r], rhs[r - 1]));
        }
        let (inv, s) = d.checked_inverse();
        singular = M::either(singular, s);
        carry.push(inv * upper[r]);
        rhs[r] = T::lmul(&inv, rhs[r]);
    }
    for r in (0..n.saturating_sub(1)).rev() {
        rhs[r] = rhs[r].minus(T::lmul(&carry[r], rhs[r + 1]));
    }
    singular
}

/// The arrays a linear solve fills, kept across Newton iterations (allocating and zeroing
/// them per solve was a measured cost).
pub(super) struct Scratch<M: Matrix> {
    lower: Vec<M>,
    diag: Vec<M>,
    upper: Vec<M>,
    /// Row 0: column n-1; row n-1: column 0 (cyclic systems, n >= 3).
    corner: Vec<M>,
    carry: Vec<M>,
    plain: Vec<(M::Vector,)>,
    aug: Vec<(M::Vector, M)>,
}

impl<M: Matrix> Default for Scratch<M> {
    fn default() -> Self {
        let v = Vec::new;
        Self { lower: v(), diag: v(), upper: v(), corner: v(), carry: v(), plain: Vec::new(), aug: Vec::new() }
    }
}

/// Solves the (possibly cyclic) block tridiagonal system whose row `r` has blocks `blocks[r]`
/// on the unknowns `cols[r]` (the same unknown may appear twice: the blocks add) into `x`;
/// returns where it is singular.
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
    // Sort each row's blocks into lower / diagonal / upper / corner (cyclic wrap).
    let Scratch { lower, diag, upper, corner, carry, plain, aug } = scratch;
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
        plain.clear();
        for &v in rhs {
            plain.push((v,));
        }
        let singular = solve_tridiagonal(lower, diag, upper, plain, carry);
        for v in plain.iter() {
            x.push(v.0);
        }
        return singular;
    }
    // Border the last unknown: rows 0..n-2 solve T [y | Z] = [rhs | border], then the last
    // row gives x_{n-1}, and x' = y - Z x_{n-1}.
    let m = n - 1;
    aug.clear();
    for &v in &rhs[..m] {
        aug.push((v, zero));
    }
    aug[0].1 = corner[0];
    aug[m - 1].1 += upper[m - 1];
    // Row m - 1's upper block went into the border: the tridiagonal part ends there.
    upper[m - 1] = zero;
    let singular = solve_tridiagonal(&lower[..m], &diag[..m], &upper[..m], aug, carry);
    let (first, last) = (corner[m], lower[m]);
    let s = diag[m] - last * aug[m - 1].1 - first * aug[0].1;
    let (s_inv, s_singular) = s.checked_inverse();
    let xm = s_inv * (rhs[m] - last * aug[m - 1].0 - first * aug[0].0);
    for &(y, z) in aug.iter() {
        x.push(y - z * xm);
    }
    x.push(xm);
    M::either(singular, s_singular)
}
