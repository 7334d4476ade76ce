//! Quaternion and 3-vector algebra in the papers' half-angle convention (DESIGN section 1).
//!
//! Storage order is `x, y, z, w` (as glam and glTF). The papers write `(w, x, y, z)`.
//! `exp v = (cos|v|, sin|v|/|v| v)` and `log (cos th, sin th u) = th u` with `th in [0, pi]`:
//! the physical rotation angle is `2 th`. Everything is generic over [`Real`] so the same
//! formulas run on `f64` and on derivative-carrying [`Jet`](crate::real::Jet)s.
//!
//! Small angles: exp and log are written through smooth functions of squared norms
//! ([`cos_sqrt`](crate::real::cos_sqrt), [`sinc_sqrt`](crate::real::sinc_sqrt),
//! [`atanc_sqrt`](crate::real::atanc_sqrt)) with exact series branches, so they are exact
//! to rounding and differentiable through zero (no `sqrt(0)`), and their derivatives do not
//! cancel digits (which matters in f32 on the GPU twin).

use crate::real::Real;
use std::ops::{Add, Mul, Neg, Sub};

/// A 3-vector: angular velocities, log-coefficients `w_i`, pure quaternion parts.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Vector3<R> {
    /// x component.
    pub x: R,
    /// y component.
    pub y: R,
    /// z component.
    pub z: R,
}

/// A quaternion `w + x i + y j + z k`, stored `x, y, z, w`.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Quaternion<R> {
    /// i component.
    pub x: R,
    /// j component.
    pub y: R,
    /// k component.
    pub z: R,
    /// Real (scalar) component.
    pub w: R,
}

/// An `f64` vector.
pub type Vec3F64 = Vector3<f64>;
/// An `f64` quaternion.
pub type QuatF64 = Quaternion<f64>;

impl<R: Real> Vector3<R> {
    /// Builds a vector from components.
    #[must_use]
    pub fn new(x: R, y: R, z: R) -> Self {
        Self { x, y, z }
    }

    /// The zero vector.
    #[must_use]
    pub fn zero() -> Self {
        Self::new(R::cst(0.0), R::cst(0.0), R::cst(0.0))
    }

    /// Dot product.
    #[must_use]
    pub fn dot(self, o: Self) -> R {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Cross product.
    #[must_use]
    pub fn cross(self, o: Self) -> Self {
        Self::new(self.y * o.z - self.z * o.y, self.z * o.x - self.x * o.z, self.x * o.y - self.y * o.x)
    }

    /// Squared length.
    #[must_use]
    pub fn length_squared(self) -> R {
        self.dot(self)
    }

    /// Multiplication by a scalar of the same kind.
    #[must_use]
    pub fn mul_scalar(self, k: R) -> Self {
        Self::new(self.x * k, self.y * k, self.z * k)
    }

    /// Multiplication by a plain constant.
    #[must_use]
    pub fn scale(self, k: f64) -> Self {
        Self::new(self.x.scale(k), self.y.scale(k), self.z.scale(k))
    }

    /// Lifts a plain vector (zero derivatives).
    #[must_use]
    pub fn from_f64(v: Vec3F64) -> Self {
        Self::new(R::cst(v.x), R::cst(v.y), R::cst(v.z))
    }

    /// Drops derivatives.
    #[must_use]
    pub fn value(self) -> Vec3F64 {
        Vector3::new(self.x.value(), self.y.value(), self.z.value())
    }
}

impl Vec3F64 {
    /// Builds from an array `[x, y, z]`.
    #[must_use]
    pub fn from_array(a: [f64; 3]) -> Self {
        Self::new(a[0], a[1], a[2])
    }

    /// `[x, y, z]`.
    #[must_use]
    pub fn to_array(self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }

    /// Euclidean length.
    #[must_use]
    pub fn length(self) -> f64 {
        self.length_squared().sqrt()
    }

    /// Largest absolute component.
    #[must_use]
    pub fn max_abs(self) -> f64 {
        self.x.abs().max(self.y.abs()).max(self.z.abs())
    }
}

impl<R: Real> Add for Vector3<R> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl<R: Real> Sub for Vector3<R> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl<R: Real> Neg for Vector3<R> {
    type Output = Self;
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}

impl<R: Real> Quaternion<R> {
    /// Builds a quaternion from `x, y, z, w`.
    #[must_use]
    pub fn from_xyzw(x: R, y: R, z: R, w: R) -> Self {
        Self { x, y, z, w }
    }

    /// The identity rotation.
    #[must_use]
    pub fn identity() -> Self {
        Self::from_xyzw(R::cst(0.0), R::cst(0.0), R::cst(0.0), R::cst(1.0))
    }

    /// The pure quaternion `(0, v)`.
    #[must_use]
    pub fn pure(v: Vector3<R>) -> Self {
        Self::from_xyzw(v.x, v.y, v.z, R::cst(0.0))
    }

    /// The vector part `(x, y, z)`.
    #[must_use]
    pub fn vec(self) -> Vector3<R> {
        Vector3::new(self.x, self.y, self.z)
    }

    /// 4D dot product.
    #[must_use]
    pub fn dot(self, o: Self) -> R {
        self.x * o.x + self.y * o.y + self.z * o.z + self.w * o.w
    }

    /// Conjugate; the inverse of a unit quaternion.
    #[must_use]
    pub fn conjugate(self) -> Self {
        Self::from_xyzw(-self.x, -self.y, -self.z, self.w)
    }

    /// Multiplication by a scalar of the same kind.
    #[must_use]
    pub fn mul_scalar(self, k: R) -> Self {
        Self::from_xyzw(self.x * k, self.y * k, self.z * k, self.w * k)
    }

    /// Lifts a plain quaternion (zero derivatives).
    #[must_use]
    pub fn from_f64(q: QuatF64) -> Self {
        Self::from_xyzw(R::cst(q.x), R::cst(q.y), R::cst(q.z), R::cst(q.w))
    }

    /// Drops derivatives.
    #[must_use]
    pub fn value(self) -> QuatF64 {
        Quaternion::from_xyzw(self.x.value(), self.y.value(), self.z.value(), self.w.value())
    }

    /// The representative of the same rotation in the hemisphere of `reference`
    /// (`self` negated when the 4D dot product is negative; a tie keeps the sign).
    #[must_use]
    pub fn aligned_with(self, reference: Self) -> Self {
        if self.dot(reference).value() < 0.0 {
            -self
        } else {
            self
        }
    }

    /// Half-angle exponential: `exp v = (cos|v|, sin|v| / |v| * v)`.
    #[must_use]
    pub fn exp(v: Vector3<R>) -> Self {
        let th2 = v.length_squared();
        let (c, sinc) = th2.cos_sinc_sqrt();
        Self::from_xyzw(v.x * sinc, v.y * sinc, v.z * sinc, c)
    }

    /// Half-angle logarithm: `log (cos th, sin th u) = th u`, `th in [0, pi]`.
    ///
    /// Only the direction of `self` matters (the norm is ignored). Below a quarter turn
    /// (`|vec| < w`) the factor is `atan(t)/t / w` with `t^2 = |vec|^2 / w^2`, smooth through 0;
    /// above, `atan2(|vec|, w) / |vec|`. At `th = pi` with a zero vector part
    /// (`q = (-1, 0, 0, 0)`) the axis is undefined; the result is `(pi, 0, 0)`.
    #[must_use]
    pub fn log(self) -> Vector3<R> {
        let v = self.vec();
        let s2 = v.length_squared();
        let w = self.w;
        let (s2v, wv) = (s2.value(), w.value());
        let factor = if wv > 0.0 && s2v < wv * wv {
            let x = s2 / (w * w);
            x.atanc_sqrt() / w
        } else if s2v == 0.0 {
            return Vector3::new(R::cst(std::f64::consts::PI), R::cst(0.0), R::cst(0.0));
        } else {
            let s = s2.sqrt();
            s.atan2(w) / s
        };
        v.mul_scalar(factor)
    }

    /// `self^a = exp(a log self)`.
    #[must_use]
    pub fn powf(self, a: R) -> Self {
        Self::exp(self.log().mul_scalar(a))
    }

    /// Shortest-path slerp `self * exp(h log(self^-1 end))`, with `end` folded into the
    /// hemisphere of `self` first (DESIGN section 1).
    #[must_use]
    pub fn slerp(self, end: Self, h: R) -> Self {
        let rel = (self.conjugate() * end.aligned_with(self)).log();
        self * Self::exp(rel.mul_scalar(h))
    }

    /// The geodesic `self * exp(h log(self^-1 end))` with no hemisphere fold: it ends exactly
    /// on `end` (not `-end`) and varies continuously when `end` moves across the equator of
    /// `self`. Squad and Nam-Kim blend with it (`quatcurve::reference`).
    ///
    /// Past the middle it is evaluated from the other end, `end * exp((1 - h) log(end^-1 self))`
    /// (the same curve, NK eq. 4), so the log, ill-conditioned when the endpoints are far apart,
    /// is always scaled by the smaller weight: this is what keeps f32 derivatives within 1e-4.
    #[must_use]
    pub fn geodesic(self, end: Self, h: R) -> Self {
        if h.value() <= 0.5 {
            self * Self::exp((self.conjugate() * end).log().mul_scalar(h))
        } else {
            end * Self::exp((end.conjugate() * self).log().mul_scalar(R::cst(1.0) - h))
        }
    }

    /// Rotates a vector: `self v self^-1` (for unit `self`).
    #[must_use]
    pub fn rotate(self, v: Vector3<R>) -> Vector3<R> {
        (self * Self::pure(v) * self.conjugate()).vec()
    }
}

impl QuatF64 {
    /// Builds from `[x, y, z, w]`.
    #[must_use]
    pub fn from_array(a: [f64; 4]) -> Self {
        Self::from_xyzw(a[0], a[1], a[2], a[3])
    }

    /// `[x, y, z, w]`.
    #[must_use]
    pub fn to_array(self) -> [f64; 4] {
        [self.x, self.y, self.z, self.w]
    }

    /// Euclidean 4D norm.
    #[must_use]
    pub fn length(self) -> f64 {
        self.dot(self).sqrt()
    }

    /// `self / |self|`.
    #[must_use]
    pub fn normalize(self) -> Self {
        self.mul_scalar(1.0 / self.length())
    }

    /// Whether every component is finite.
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite() && self.w.is_finite()
    }

    /// The physical rotation angle between two rotations, `4 atan2(|a - s b|, |a + s b|)`
    /// with `a`, `b` normalized and `s = sign(dot)` (+1 at 0). Exact near zero, unlike
    /// `2 acos|dot|` (DESIGN section 1); used for every error figure.
    #[must_use]
    pub fn angle_to(self, other: Self) -> f64 {
        let (apart, together) = self.chords(other);
        4.0 * apart.atan2(together)
    }

    /// Whether [`Self::angle_to`] `other` is at most the angle whose quarter's tangent is
    /// `tan_quarter` ([`tan_quarter`]): the same chords compared, without the arctangent (a
    /// seventh of a fit, which holds every sample to a bound and needs no angle).
    #[must_use]
    pub fn within(self, other: Self, tan_quarter: f64) -> bool {
        let (apart, together) = self.chords(other);
        apart <= tan_quarter * together
    }

    /// `|a - s b|` and `|a + s b|` of [`Self::angle_to`].
    fn chords(self, other: Self) -> (f64, f64) {
        let a = self.normalize();
        let b = other.normalize();
        let s = if a.dot(b) < 0.0 { -1.0 } else { 1.0 };
        let b = b.mul_scalar(s);
        ((a - b).length(), (a + b).length())
    }

    /// The unit quaternion of a rotation vector: its axis times its angle in radians (scipy's
    /// `from_rotvec`, datasets' axis-angle), `exp(v / 2)` in the papers' half angle.
    #[must_use]
    pub fn from_rotation_vector(v: Vec3F64) -> Self {
        Self::exp(v.scale(0.5))
    }

    /// The rotation vector of a unit quaternion, its angle in `[0, pi]` (scipy's `as_rotvec`):
    /// twice the log of the hemisphere with `w >= 0`.
    #[must_use]
    pub fn to_rotation_vector(self) -> Vec3F64 {
        self.aligned_with(Self::identity()).log().scale(2.0)
    }

    /// Row-major 3x3 rotation matrix of a unit quaternion (`R p = q p q^-1`).
    #[must_use]
    pub fn to_mat3(self) -> [[f64; 3]; 3] {
        let Self { x, y, z, w } = self;
        [
            [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
            [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
            [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
        ]
    }

    /// Unit quaternion of a row-major rotation matrix by Shoemake's method (P section 2):
    /// take the square root of the largest of `trace` and the three diagonal pivots, so the
    /// division is always by a number >= 1/2 and no precision is lost.
    #[must_use]
    pub fn from_mat3(m: [[f64; 3]; 3]) -> Self {
        let tr = m[0][0] + m[1][1] + m[2][2];
        let q = if tr >= m[0][0].max(m[1][1]).max(m[2][2]) {
            let r = (1.0 + tr).sqrt();
            let s = 0.5 / r;
            Self::from_xyzw((m[2][1] - m[1][2]) * s, (m[0][2] - m[2][0]) * s, (m[1][0] - m[0][1]) * s, 0.5 * r)
        } else if m[0][0] >= m[1][1] && m[0][0] >= m[2][2] {
            let r = (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt();
            let s = 0.5 / r;
            Self::from_xyzw(0.5 * r, (m[0][1] + m[1][0]) * s, (m[2][0] + m[0][2]) * s, (m[2][1] - m[1][2]) * s)
        } else if m[1][1] >= m[2][2] {
            let r = (1.0 + m[1][1] - m[2][2] - m[0][0]).sqrt();
            let s = 0.5 / r;
            Self::from_xyzw((m[0][1] + m[1][0]) * s, 0.5 * r, (m[1][2] + m[2][1]) * s, (m[0][2] - m[2][0]) * s)
        } else {
            let r = (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt();
            let s = 0.5 / r;
            Self::from_xyzw((m[2][0] + m[0][2]) * s, (m[1][2] + m[2][1]) * s, 0.5 * r, (m[1][0] - m[0][1]) * s)
        };
        q.normalize()
    }
}

impl From<glam::DQuat> for QuatF64 {
    fn from(q: glam::DQuat) -> Self {
        Self::from_xyzw(q.x, q.y, q.z, q.w)
    }
}

impl From<QuatF64> for glam::DQuat {
    fn from(q: QuatF64) -> Self {
        glam::DQuat::from_xyzw(q.x, q.y, q.z, q.w)
    }
}

impl From<glam::DVec3> for Vec3F64 {
    fn from(v: glam::DVec3) -> Self {
        Self::new(v.x, v.y, v.z)
    }
}

impl From<Vec3F64> for glam::DVec3 {
    fn from(v: Vec3F64) -> Self {
        glam::DVec3::new(v.x, v.y, v.z)
    }
}

/// The Hamilton product `a * b` of quaternions written `[x, y, z, w]`, over any scalar with
/// `+`, `-` and `*`: reals and jets here, SIMD lanes in the CPU path and the C2 solve, so every
/// Rust path multiplies quaternions by this one formula (and in the same order of operations,
/// so the same inputs give the same bits).
#[inline(always)]
pub fn hamilton<T>(a: [T; 4], b: [T; 4]) -> [T; 4]
where
    T: Copy + Add<Output = T> + Sub<Output = T> + Mul<Output = T>,
{
    let ([x, y, z, w], [ox, oy, oz, ow]) = (a, b);
    [
        w * ox + x * ow + y * oz - z * oy,
        w * oy - x * oz + y * ow + z * ox,
        w * oz + x * oy - y * ox + z * ow,
        w * ow - x * ox - y * oy - z * oz,
    ]
}

impl<R: Real> Mul for Quaternion<R> {
    type Output = Self;
    /// Hamilton product ([`hamilton`]).
    fn mul(self, o: Self) -> Self {
        let [x, y, z, w] = hamilton([self.x, self.y, self.z, self.w], [o.x, o.y, o.z, o.w]);
        Self::from_xyzw(x, y, z, w)
    }
}

impl<R: Real> Add for Quaternion<R> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self::from_xyzw(self.x + o.x, self.y + o.y, self.z + o.z, self.w + o.w)
    }
}

impl<R: Real> Sub for Quaternion<R> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self::from_xyzw(self.x - o.x, self.y - o.y, self.z - o.z, self.w - o.w)
    }
}

impl<R: Real> Neg for Quaternion<R> {
    type Output = Self;
    fn neg(self) -> Self {
        Self::from_xyzw(-self.x, -self.y, -self.z, -self.w)
    }
}

/// `log(a^-1 b)` with `b` folded into `a`'s hemisphere: the shortest relative rotation (the
/// step `w_i` of the cumulative form between consecutive keys).
#[must_use]
pub fn relative_log(a: QuatF64, b: QuatF64) -> Vec3F64 {
    (a.conjugate() * b.aligned_with(a)).log()
}

/// `tan(angle / 4)` of a bound on [`QuatF64::angle_to`], as [`QuatF64::within`] reads it;
/// infinite for a bound of a full turn or more, which every pair of rotations is within.
#[must_use]
pub fn tan_quarter(angle: f64) -> f64 {
    if angle >= 2.0 * std::f64::consts::PI {
        f64::INFINITY
    } else {
        (angle / 4.0).tan()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_4, PI};

    fn q(x: f64, y: f64, z: f64, w: f64) -> QuatF64 {
        QuatF64::from_xyzw(x, y, z, w).normalize()
    }

    #[test]
    fn product_matches_glam() {
        let a = q(0.1, -0.7, 0.3, 0.5);
        let b = q(-0.4, 0.2, 0.9, -0.1);
        let ours = (a * b).to_array();
        let theirs = glam::DQuat::from(a) * glam::DQuat::from(b);
        for (o, t) in ours.iter().zip(theirs.to_array()) {
            assert!((o - t).abs() < 1e-15);
        }
    }

    #[test]
    fn rotation_vectors_round_trip_through_the_half_angle_exp() {
        for v in [[0.0, 0.0, 0.0], [1e-9, -2e-9, 3e-9], [0.3, -1.2, 0.5], [0.0, 3.0, 0.0], [-1.0, 2.0, 2.0]] {
            let v = Vec3F64::from_array(v);
            let q = QuatF64::from_rotation_vector(v);
            // The angle is |v|: the rotation by it about v's axis.
            assert!((q.angle_to(QuatF64::identity()) - v.length()).abs() < 1e-15, "{v:?}");
            assert!((q.to_rotation_vector() - v).length() < 1e-15 * (1.0 + v.length()), "{v:?}");
            // Either sign of the quaternion gives the same vector.
            assert!((q.mul_scalar(-1.0).to_rotation_vector() - v).length() < 1e-15 * (1.0 + v.length()));
        }
    }

    #[test]
    fn exp_is_half_angle_and_matches_glam_full_angle() {
        // exp(th u) is the rotation by 2 th about u, which glam writes from_axis_angle(u, 2 th).
        let u = Vec3F64::new(1.0, 2.0, -2.0).scale(1.0 / 3.0);
        for &th in &[0.0, 1e-9, 1e-3, 0.499_999, 0.5, 0.7, 3.0, PI] {
            let ours = QuatF64::exp(u.scale(th));
            let theirs = glam::DQuat::from_axis_angle(glam::DVec3::from(u), 2.0 * th);
            assert!(ours.angle_to(theirs.into()) < 1e-15, "th {th}");
        }
    }

    #[test]
    fn log_inverts_exp_across_the_branch_thresholds() {
        let u = Vec3F64::new(0.6, 0.0, 0.8);
        for &th in
            &[0.0, 1e-12, 1e-6, 0.463, 0.4637, FRAC_PI_4 - 1e-9, FRAC_PI_4, FRAC_PI_4 + 1e-9, 1.0, 2.5, PI - 1e-9]
        {
            let back = QuatF64::exp(u.scale(th)).log();
            let err = (back - u.scale(th)).length();
            assert!(err <= 4e-16 * th.max(1.0), "th {th}: err {err}");
        }
    }

    #[test]
    fn log_at_pi_is_defined() {
        assert_eq!(q(0.0, 0.0, 0.0, -1.0).log(), Vec3F64::new(PI, 0.0, 0.0));
        assert_eq!(q(0.0, 0.0, 0.0, 1.0).log(), Vec3F64::zero());
    }

    #[test]
    fn slerp_takes_the_short_way_through_near_antipodal_keys() {
        let a = QuatF64::identity();
        // 179.9 degrees about z, given in the far hemisphere (w < 0).
        let half = (179.9f64).to_radians() / 2.0;
        let b = -QuatF64::exp(Vec3F64::new(0.0, 0.0, half));
        let mid = a.slerp(b, 0.5);
        let expected = QuatF64::exp(Vec3F64::new(0.0, 0.0, half / 2.0));
        assert!(mid.angle_to(expected) < 1e-14);
        assert!(a.slerp(b, 1.0).angle_to(b) < 1e-14);
    }

    #[test]
    fn matrix_round_trip_all_shoemake_branches() {
        // Rotations by ~pi about each axis exercise each diagonal pivot branch.
        for v in [
            Vec3F64::new(0.1, 0.2, 0.3),
            Vec3F64::new(1.55, 0.01, 0.02),
            Vec3F64::new(0.01, 1.55, 0.02),
            Vec3F64::new(0.02, 0.01, 1.55),
            Vec3F64::new(PI / 2.0, 0.0, 0.0),
        ] {
            let a = QuatF64::exp(v);
            let m = a.to_mat3();
            let b = QuatF64::from_mat3(m);
            assert!(a.angle_to(b) < 1e-14, "{v:?}");
            // The matrix rotates like q p q^-1.
            let p = Vec3F64::new(0.3, -1.0, 2.0);
            let mp = Vec3F64::new(
                m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z,
                m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z,
                m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z,
            );
            assert!((mp - a.rotate(p)).length() < 1e-14);
        }
    }

    #[test]
    fn angle_to_resolves_tiny_angles_and_ignores_sign() {
        let a = QuatF64::identity();
        let b = QuatF64::exp(Vec3F64::new(0.0, 5e-10, 0.0));
        assert!((a.angle_to(b) - 1e-9).abs() < 1e-22);
        assert!((a.angle_to(-b) - 1e-9).abs() < 1e-22);
    }

    /// `within` agrees with `angle_to` against a bound, for angles from a nanoradian to nearly
    /// half a turn, either sign, unnormalized inputs, bounds just either side and past a turn.
    #[test]
    fn within_holds_a_pair_to_a_bound_as_its_angle_does() {
        let a = QuatF64::exp(Vec3F64::new(0.3, -0.2, 0.5)).mul_scalar(1.7);
        for (i, angle) in [1e-9, 1e-4, 0.01, 0.5, 2.0, 3.0, 3.1, PI - 1e-6].into_iter().enumerate() {
            let turn = QuatF64::exp(Vec3F64::new(0.6, 0.0, -0.8).scale(angle / 2.0));
            let b = (a * turn).mul_scalar(if i % 2 == 0 { -0.4 } else { 2.5 });
            let measured = a.angle_to(b);
            assert!((measured - angle).abs() < 1e-9 * angle.max(1.0), "{angle}: {measured}");
            for bound in [measured * (1.0 + 1e-9), measured * (1.0 - 1e-9), 7.0] {
                assert_eq!(a.within(b, tan_quarter(bound)), measured <= bound, "{angle} against {bound}");
            }
        }
        assert!(a.within(-a, tan_quarter(0.0)), "the same rotation either sign");
    }

    #[test]
    fn powf_is_fractional_rotation() {
        let a = QuatF64::exp(Vec3F64::new(0.3, -0.2, 0.5));
        let half = a.powf(0.5);
        assert!((half * half).angle_to(a) < 1e-15);
    }
}
