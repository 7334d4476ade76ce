//! The Jacobians of the half-angle exp and log about one rotation vector, as polynomials in its
//! cross-product matrix ([`AxisPoly`]): the algebra of the Newton blocks.

use crate::quat::{QuatF64, Vec3F64};
use glam::{DMat3, DVec3 as V3};

/// The crate's vector as glam's (the solve's 3x3 algebra is glam's).
pub(super) fn g(v: Vec3F64) -> V3 {
    V3::new(v.x, v.y, v.z)
}

/// Glam's vector as the crate's.
pub(super) fn d(v: V3) -> Vec3F64 {
    Vec3F64::new(v.x, v.y, v.z)
}

/// `[v]x`: `skew(v) u = v x u`.
pub(super) fn skew(v: V3) -> DMat3 {
    DMat3::from_cols(V3::new(0.0, v.z, -v.y), V3::new(-v.z, 0.0, v.x), V3::new(v.y, -v.x, 0.0))
}

/// `c[0] I + c[1] [v]x + c[2] [v]x^2`. Every Jacobian of the half-angle exp and log about one
/// rotation vector `v` has this form, and two of them about the same `v` multiply as
/// polynomials in `[v]x` (`[v]x^3 = -|v|^2 [v]x`): a few scalars instead of a 3x3 product,
/// and a vector is moved by two cross products.
#[derive(Clone, Copy, Debug)]
pub(super) struct AxisPoly {
    v: V3,
    pub(super) c: [f64; 3],
}

impl AxisPoly {
    /// Right Jacobian of the half-angle exp at `s v`, times `s`: `exp(s (v + d)) = exp(s v)
    /// exp(s jr(s v) d)` to first order. `jr(u)` is SO(3)'s `J_r(2 u)`, `I - (sin^2 h / h^2)
    /// [u]x + ((2h - sin 2h) / 2h^3) [u]x^2` with `h = |u|`; `c` holds those two coefficients
    /// for `u = s v` ([`exp_jr`]).
    pub(super) fn exp_jacobian(v: V3, s: f64, c: [f64; 2]) -> Self {
        Self { v, c: [s, -s * s * c[0], s * s * s * c[1]] }
    }

    /// Inverse right and left Jacobians of the half-angle log at `v`, `I +- [v]x + c [v]x^2`:
    /// `log(exp(v) exp(d)) = v + jr_inv d` and `log(exp(d) exp(v)) = v + jl_inv d` to first
    /// order, with `c = (1 - h cot h) / h^2`, `h = |v| < pi` ([`log_coef`], [`step_log_coef`]).
    pub(super) fn log_jacobians(v: V3, c: f64) -> (Self, Self) {
        (Self { v, c: [1.0, 1.0, c] }, Self { v, c: [1.0, -1.0, c] })
    }

    /// The product `self * o` of two polynomials about the same vector.
    pub(super) fn times(self, o: Self) -> Self {
        let ([a0, a1, a2], [b0, b1, b2]) = (self.c, o.c);
        let h2 = self.v.length_squared();
        let c = [a0 * b0, a0 * b1 + a1 * b0 - h2 * (a1 * b2 + a2 * b1), a0 * b2 + a1 * b1 + a2 * b0 - h2 * a2 * b2];
        Self { v: self.v, c }
    }

    /// `self x`.
    pub(super) fn apply(self, x: V3) -> V3 {
        let vx = self.v.cross(x);
        x * self.c[0] + vx * self.c[1] + self.v.cross(vx) * self.c[2]
    }

    /// The matrix, with `[v]x^2 = v v^T - |v|^2 I`.
    pub(super) fn matrix(self) -> DMat3 {
        let ([c0, c1, c2], v) = (self.c, self.v);
        let diagonal = c0 - c2 * v.length_squared();
        let column = |j: usize, e: V3| v * (c2 * v[j]) + v.cross(e) * c1 + e * diagonal;
        DMat3::from_cols(column(0, V3::X), column(1, V3::Y), column(2, V3::Z))
    }
}

/// `exp(v)` and the coefficients of its Jacobian ([`AxisPoly::exp_jacobian`]), from one
/// `sin_cos` (the row evaluation needs the one, its Jacobian the other, and they share the
/// angle).
pub(super) fn exp_jr(v: V3) -> (QuatF64, [f64; 2]) {
    let h2 = v.length_squared();
    let h = h2.sqrt();
    if h < 1e-4 {
        return (QuatF64::exp(d(v)), [1.0 - h2 / 3.0, 2.0 / 3.0 - 2.0 * h2 / 15.0]);
    }
    // One sin_cos: sin 2h = 2 sin h cos h.
    let (s, c) = h.sin_cos();
    let jr = [s * s / h2, (2.0 * h - 2.0 * s * c) / (2.0 * h2 * h)];
    // Below h = 1e-2 `QuatF64::exp` takes its value-only series; kept, so that the rotation is
    // exactly `QuatF64::exp`'s.
    let e = if h2 >= 1e-4 {
        QuatF64::from_xyzw(v.x * (s / h), v.y * (s / h), v.z * (s / h), c)
    } else {
        QuatF64::exp(d(v))
    };
    (e, jr)
}

/// The coefficient of [`AxisPoly::log_jacobians`] at `v`.
pub(super) fn log_coef(v: V3) -> f64 {
    let h = v.length();
    if h < 1e-4 {
        1.0 / 3.0 + h * h / 45.0
    } else {
        let (s, c) = h.sin_cos();
        (1.0 - h * c / s) / (h * h)
    }
}

/// The coefficient of [`AxisPoly::log_jacobians`] for a step `v` whose rotation `rel` is at
/// hand (`exp v = +-rel`, so `rel = +-(cos h, sin h v / h)`): `cot h` read off `rel` instead
/// of a `sin_cos`. Components of `rel` carry rounding of order 1e-16, so `c h^2` does of order
/// 1e-16 / h: the series covers `h < 1e-3`.
pub(super) fn step_log_coef(v: V3, rel: QuatF64) -> f64 {
    let h2 = v.length_squared();
    if h2 < 1e-6 {
        1.0 / 3.0 + h2 / 45.0
    } else {
        // h cot h = h^2 cos h / (sin h h) = h^2 rel.w / (rel.vec . v).
        let along = rel.x * v.x + rel.y * v.y + rel.z * v.z;
        (1.0 - h2 * rel.w / along) / h2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Polynomials in `[v]x`: matrix, product and action against plain 3x3 arithmetic.
    #[test]
    fn axis_polynomials_multiply_as_their_matrices() {
        let v = V3::new(0.7, -1.3, 0.4);
        let (a, b) = (AxisPoly { v, c: [0.9, -0.35, 0.6] }, AxisPoly { v, c: [1.1, 0.8, -0.25] });
        let k = skew(v);
        let plain = |p: AxisPoly| DMat3::IDENTITY * p.c[0] + k * p.c[1] + k * k * p.c[2];
        let close = |x: DMat3, y: DMat3| (0..3).all(|j| (x.col(j) - y.col(j)).length() < 1e-14);
        assert!(close(a.matrix(), plain(a)), "{:?} against {:?}", a.matrix(), plain(a));
        assert!(close(a.times(b).matrix(), plain(a) * plain(b)));
        assert!(close(b.times(a).matrix(), plain(a) * plain(b)), "they commute");
        let x = V3::new(-0.2, 0.5, 2.0);
        assert!((a.apply(x) - plain(a) * x).length() < 1e-14);
    }
}
