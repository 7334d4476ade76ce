//! Four `f64` lanes, one track each, and the vector, quaternion and 3x3 algebra the lane solve
//! ([`super::lanes`]) runs on them, generic over the lane type ([`Lanes64`]).
//!
//! Two lane types, as the CPU evaluator's (`crate::isa::Isa`): [`Avx2`], one AVX register,
//! made only inside functions built for AVX2 on CPUs that have it, and [`Portable`],
//! `wide::f64x4` at the build's baseline (two SSE2 registers on x86-64). Neither uses a fused
//! multiply-add, so both give the same bits. The transcendental functions are polynomials
//! (Cephes' `sin`, `cos` and `atan` coefficients) with the branches of their range reduction
//! taken per lane by masks, so every lane runs the same instructions.

use crate::quat::hamilton;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
use std::fmt::Debug;
use std::ops::{Add, AddAssign, BitAnd, BitOr, Div, Mul, Neg, Not, Sub, SubAssign};

/// Four `f64` lanes. Comparisons return masks (every bit set where true) of the same type,
/// which [`Lanes64::blend`], `&`, `|` and `!` take.
pub(super) trait Lanes64:
    Copy
    + Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Mul<f64, Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
    + Not<Output = Self>
{
    /// `v` in every lane.
    fn splat(v: f64) -> Self;
    fn from_array(v: [f64; 4]) -> Self;
    fn to_array(self) -> [f64; 4];
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    /// Mask of `self < o` (false where either is NaN, as every comparison here).
    fn lt(self, o: Self) -> Self;
    /// Mask of `self <= o`.
    fn le(self, o: Self) -> Self;
    /// Mask of `self > o`.
    fn gt(self, o: Self) -> Self;
    /// Per lane, `t` where the mask `self` is set, else `f`.
    fn blend(self, t: Self, f: Self) -> Self;
    /// Whether any lane of the mask `self` is set.
    fn any(self) -> bool;
    /// Whether every lane of the mask `self` is set.
    fn all(self) -> bool;

    /// Per lane, `t` where the mask `self` is set, else `f`, for any [`Select`] value.
    #[inline(always)]
    fn pick<T: Select<Self>>(self, t: T, f: T) -> T {
        T::select(self, t, f)
    }

    #[inline(always)]
    fn zero() -> Self {
        Self::splat(0.0)
    }

    /// The mask with no lane set.
    #[inline(always)]
    fn none() -> Self {
        Self::zero().lt(Self::zero())
    }

    #[inline(always)]
    fn max(self, o: Self) -> Self {
        self.gt(o).blend(self, o)
    }

    #[inline(always)]
    fn min(self, o: Self) -> Self {
        self.lt(o).blend(self, o)
    }

    /// Lanes that are neither infinite nor NaN.
    #[inline(always)]
    fn is_finite(self) -> Self {
        self.abs().le(Self::splat(f64::MAX))
    }

    /// The nearest integer (ties to even), for `|self| < 2^51`.
    #[inline(always)]
    fn round(self) -> Self {
        (self + Self::splat(ROUNDER)) - Self::splat(ROUNDER)
    }

    /// The largest integer not above `self`, for `|self| < 2^51`.
    #[inline(always)]
    fn floor(self) -> Self {
        let r = self.round();
        r.gt(self).blend(r - Self::splat(1.0), r)
    }

    /// `(sin self, cos self)`. Range reduced by quarter turns against `pi / 2` in three parts
    /// (Cody and Waite), then Cephes' polynomials on `[-pi/4, pi/4]`: within 2 ulp of libm's
    /// for `|self| < 1e6`, plus `1e-30 |self|` absolute near the zeros, where the third part's
    /// rounding shows (tested); far inside what a solve of keys given in `f64` can resolve.
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        // pi / 2 = PIO2_1 + PIO2_2 + PIO2_3; PIO2_1 has 27 significant bits, so its product
        // with a quadrant count below 2^26 is exact.
        const PIO2_1: f64 = 2.0 * 7.853_981_256_484_985E-1;
        const PIO2_2: f64 = 2.0 * 3.774_894_707_930_798E-8;
        const PIO2_3: f64 = 2.0 * 2.695_151_429_079_059_5E-15;
        const SIN: [f64; 6] = [
            1.589_623_015_765_465_6E-10,
            -2.505_074_776_285_780_7E-8,
            2.755_731_362_138_572_2E-6,
            -1.984_126_982_958_954E-4,
            8.333_333_333_322_118E-3,
            -1.666_666_666_666_663E-1,
        ];
        const COS: [f64; 6] = [
            -1.135_853_652_138_768_2E-11,
            2.087_570_084_197_473E-9,
            -2.755_731_417_929_674E-7,
            2.480_158_728_885_170_4E-5,
            -1.388_888_888_887_305_6E-3,
            4.166_666_666_666_659_5E-2,
        ];
        let s = Self::splat;
        let z = self * self;
        if self.abs().le(s(FRAC_PI_4)).all() {
            // Every lane in the first octant already (the common case: half angles of the
            // small rotations a solve ends with): no reduction. The same operations as below
            // with a quadrant of 0, so the same bits.
            return (self + self * z * horner(&SIN, z), s(1.0) - z * s(0.5) + z * z * horner(&COS, z));
        }
        let q = (self * s(2.0 / PI)).round();
        let r = ((self - q * s(PIO2_1)) - q * s(PIO2_2)) - q * s(PIO2_3);
        let z = r * r;
        let sin = r + r * z * horner(&SIN, z);
        let cos = s(1.0) - z * s(0.5) + z * z * horner(&COS, z);
        // Quadrant q mod 4: odd quadrants swap sine and cosine; sine is negative in 2 and 3,
        // cosine in 1 and 2.
        let k = q - (q * s(0.25)).floor() * s(4.0);
        let odd = (k - (k * s(0.5)).floor() * s(2.0)).gt(s(0.5));
        let (sin, cos) = (odd.blend(cos, sin), odd.blend(sin, cos));
        let sin_negative = k.gt(s(1.5));
        let cos_negative = k.gt(s(0.5)) & k.lt(s(2.5));
        (sin_negative.blend(-sin, sin), cos_negative.blend(-cos, cos))
    }

    /// The angle of `(x, self)` in `[-pi, pi]`: Cephes' `atan` of the smaller over the larger
    /// magnitude (in `[0, 1]`, reduced once more above 0.66), reflected into the quadrant.
    /// Within 2 ulp of libm's (tested), and relative accuracy is kept near zero, where the
    /// solve's logs of small rotations divide by the vector length. `atan2(0, 0)` is 0, and a
    /// zero of either sign counts as positive.
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        /// What `pi / 4` misses in `f64`.
        const PIO4_LO: f64 = 0.5 * 6.123_233_995_736_766E-17;
        let s = Self::splat;
        let (ay, ax) = (self.abs(), x.abs());
        let (small, large) = (ay.min(ax), ay.max(ax));
        let zero = large.le(Self::zero());
        let t = small / zero.blend(s(1.0), large);
        // Above tan(pi/8)-ish, atan t = pi/4 + atan((t - 1) / (t + 1)).
        let upper = t.gt(s(ATAN_REDUCED));
        let u = upper.blend((t - s(1.0)) / (t + s(1.0)), t);
        let z = u * u;
        let p = u + u * atan_ratio(z);
        let a = upper.blend(s(FRAC_PI_4) + (p + s(PIO4_LO)), p);
        let a = ay.gt(ax).blend(s(FRAC_PI_2) - a, a);
        let a = x.lt(Self::zero()).blend(s(PI) - a, a);
        self.lt(Self::zero()).blend(-a, a)
    }
}

/// Pivot blocks of the Newton solve whose determinant is below this (or not finite) are
/// singular (`super::tridiagonal`).
pub(super) const SINGULAR: f64 = 1e-300;

/// Cephes' `atan` reduces arguments above this (`atan t = pi/4 + atan((t - 1) / (t + 1))`).
const ATAN_REDUCED: f64 = 0.66;

/// Cephes' `atan(t) = t + t z P(z) / Q(z)`, `z = t^2`, for `t` up to [`ATAN_REDUCED`].
const ATAN_P: [f64; 5] = [
    -8.750_608_600_031_904E-1,
    -1.615_753_718_733_365_2E1,
    -7.500_855_792_314_705E1,
    -1.228_866_684_490_136_1E2,
    -6.485_021_904_942_025E1,
];
const ATAN_Q: [f64; 6] = [
    1.0,
    2.485_846_490_142_306_2E1,
    1.650_270_098_316_988_5E2,
    4.328_810_604_912_902_7E2,
    4.853_903_996_359_137E2,
    1.945_506_571_482_614E2,
];

/// `atan t / t - 1 = z P(z) / Q(z)` at `z = t^2`.
#[inline(always)]
fn atan_ratio<L: Lanes64>(z: L) -> L {
    z * horner(&ATAN_P, z) / horner(&ATAN_Q, z)
}

/// `2^52 + 2^51`: adding and subtracting it rounds an `f64` below `2^51` in magnitude to the
/// nearest integer (ties to even), the same on every instruction set.
const ROUNDER: f64 = 6_755_399_441_055_744.0;

/// `c[0] z^(m-1) + ... + c[m-1]` (highest coefficient first, as Cephes lists them).
#[inline(always)]
fn horner<L: Lanes64, const M: usize>(c: &[f64; M], z: L) -> L {
    // A loop, not a fold: closures are not inlined into the AVX2 entry point reliably, and
    // an AVX instruction left in one becomes a call.
    let mut p = L::splat(c[0]);
    let mut i = 1;
    while i < M {
        p = p * z + L::splat(c[i]);
        i += 1;
    }
    p
}

/// `wide::f64x4` at the build's baseline.
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub(super) struct Portable(wide::f64x4);

macro_rules! operators {
    ($t:ty, $a:ident, $b:ident, add: $add:expr, sub: $sub:expr, mul: $mul:expr, div: $div:expr,
     and: $and:expr, or: $or:expr, xor: $xor:expr) => {
        operators!(@binary $t, Add, add, $a, $b, $add);
        operators!(@binary $t, Sub, sub, $a, $b, $sub);
        operators!(@binary $t, Mul, mul, $a, $b, $mul);
        operators!(@binary $t, Div, div, $a, $b, $div);
        operators!(@binary $t, BitAnd, bitand, $a, $b, $and);
        operators!(@binary $t, BitOr, bitor, $a, $b, $or);
        impl Mul<f64> for $t {
            type Output = Self;
            #[inline(always)]
            fn mul(self, k: f64) -> Self {
                self * <$t as Lanes64>::splat(k)
            }
        }
        impl Neg for $t {
            type Output = Self;
            #[inline(always)]
            fn neg(self) -> Self {
                let ($a, $b) = (self.0, <$t as Lanes64>::splat(-0.0).0);
                Self($xor)
            }
        }
        impl Not for $t {
            type Output = Self;
            #[inline(always)]
            fn not(self) -> Self {
                let ($a, $b) = (self.0, <$t as Lanes64>::splat(f64::from_bits(u64::MAX)).0);
                Self($xor)
            }
        }
    };
    (@binary $t:ty, $trait:ident, $method:ident, $a:ident, $b:ident, $e:expr) => {
        impl $trait for $t {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: Self) -> Self {
                let ($a, $b) = (self.0, o.0);
                Self($e)
            }
        }
    };
}

operators!(Portable, a, b, add: a + b, sub: a - b, mul: a * b, div: a / b, and: a & b, or: a | b, xor: a ^ b);

impl Lanes64 for Portable {
    #[inline(always)]
    fn splat(v: f64) -> Self {
        Self(wide::f64x4::splat(v))
    }
    #[inline(always)]
    fn from_array(v: [f64; 4]) -> Self {
        Self(wide::f64x4::new(v))
    }
    #[inline(always)]
    fn to_array(self) -> [f64; 4] {
        self.0.to_array()
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Self(self.0.sqrt())
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Self(self.0.abs())
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self {
        Self(wide::CmpLt::cmp_lt(self.0, o.0))
    }
    #[inline(always)]
    fn le(self, o: Self) -> Self {
        Self(wide::CmpLe::cmp_le(self.0, o.0))
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self {
        Self(wide::CmpGt::cmp_gt(self.0, o.0))
    }
    #[inline(always)]
    fn blend(self, t: Self, f: Self) -> Self {
        Self(self.0.blend(t.0, f.0))
    }
    #[inline(always)]
    fn any(self) -> bool {
        self.0.any()
    }
    #[inline(always)]
    fn all(self) -> bool {
        self.0.all()
    }
}

#[cfg(target_arch = "x86_64")]
pub(super) use avx2::Avx2;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Add, BitAnd, BitOr, Div, Lanes64, Mul, Neg, Not, Sub};
    #[allow(clippy::wildcard_imports)]
    use std::arch::x86_64::*;

    /// Four lanes in one AVX register.
    ///
    /// Only the lane solve's AVX2 entry point makes these, after `crate::isa::Isa::Avx2` was
    /// detected: every method below runs AVX instructions, which is what makes their `unsafe`
    /// blocks sound. The methods are `inline(always)` so that they compile inside that entry
    /// point's `#[target_feature(enable = "avx2,fma")]`.
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub(in crate::interp) struct Avx2(__m256d);

    // SAFETY (every block below): see the type.
    operators!(
        Avx2, a, b,
        add: unsafe { _mm256_add_pd(a, b) },
        sub: unsafe { _mm256_sub_pd(a, b) },
        mul: unsafe { _mm256_mul_pd(a, b) },
        div: unsafe { _mm256_div_pd(a, b) },
        and: unsafe { _mm256_and_pd(a, b) },
        or: unsafe { _mm256_or_pd(a, b) },
        xor: unsafe { _mm256_xor_pd(a, b) }
    );

    impl Lanes64 for Avx2 {
        #[inline(always)]
        fn splat(v: f64) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_set1_pd(v) })
        }
        #[inline(always)]
        fn from_array(v: [f64; 4]) -> Self {
            // SAFETY: see the type; the load reads the four doubles of `v`.
            Self(unsafe { _mm256_loadu_pd(v.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f64; 4] {
            let mut out = [0.0; 4];
            // SAFETY: see the type; the store writes the four doubles of `out`.
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), self.0) };
            out
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_sqrt_pd(self.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: see the type. Clears the sign bits.
            Self(unsafe { _mm256_andnot_pd(_mm256_set1_pd(-0.0), self.0) })
        }
        #[inline(always)]
        fn lt(self, o: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_cmp_pd::<_CMP_LT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn le(self, o: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_cmp_pd::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn gt(self, o: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_cmp_pd::<_CMP_GT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn blend(self, t: Self, f: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_blendv_pd(f.0, t.0, self.0) })
        }
        #[inline(always)]
        fn any(self) -> bool {
            // SAFETY: see the type.
            unsafe { _mm256_movemask_pd(self.0) != 0 }
        }
        #[inline(always)]
        fn all(self) -> bool {
            // SAFETY: see the type.
            unsafe { _mm256_movemask_pd(self.0) == 0b1111 }
        }
    }
}

/// Values chosen lane by lane by a mask.
pub(super) trait Select<L>: Copy {
    /// Per lane, `t` where `mask` is set, else `f`.
    fn select(mask: L, t: Self, f: Self) -> Self;
}

impl<L: Lanes64> Select<L> for L {
    #[inline(always)]
    fn select(m: L, t: Self, f: Self) -> Self {
        m.blend(t, f)
    }
}

/// Three-vectors, one per lane.
#[derive(Clone, Copy, Debug)]
pub(super) struct V4<L> {
    pub(super) x: L,
    pub(super) y: L,
    pub(super) z: L,
}

impl<L: Lanes64> V4<L> {
    #[inline(always)]
    pub(super) fn zero() -> Self {
        V4 { x: L::zero(), y: L::zero(), z: L::zero() }
    }

    #[inline(always)]
    pub(super) fn dot(self, o: Self) -> L {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    pub(super) fn cross(self, o: Self) -> Self {
        V4 { x: self.y * o.z - o.y * self.z, y: self.z * o.x - o.z * self.x, z: self.x * o.y - o.x * self.y }
    }

    #[inline(always)]
    pub(super) fn length_squared(self) -> L {
        self.dot(self)
    }

    #[inline(always)]
    pub(super) fn length(self) -> L {
        self.length_squared().sqrt()
    }

    /// Lane `lane` as an array.
    #[cfg(test)]
    pub(super) fn lane(self, lane: usize) -> [f64; 3] {
        [self.x, self.y, self.z].map(|c| c.to_array()[lane])
    }

    /// Sets lane `lane`.
    #[cfg(test)]
    pub(super) fn set_lane(&mut self, lane: usize, v: [f64; 3]) {
        for (c, v) in [&mut self.x, &mut self.y, &mut self.z].into_iter().zip(v) {
            set(c, lane, v);
        }
    }
}

impl<L: Lanes64> Add for V4<L> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        V4 { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
}

impl<L: Lanes64> Sub for V4<L> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        V4 { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
}

impl<L: Lanes64> AddAssign for V4<L> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<L: Lanes64> SubAssign for V4<L> {
    #[inline(always)]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}

impl<L: Lanes64> Neg for V4<L> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        V4 { x: -self.x, y: -self.y, z: -self.z }
    }
}

impl<L: Lanes64> Mul<L> for V4<L> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, k: L) -> Self {
        V4 { x: self.x * k, y: self.y * k, z: self.z * k }
    }
}

impl<L: Lanes64> Select<L> for V4<L> {
    #[inline(always)]
    fn select(m: L, t: Self, f: Self) -> Self {
        V4 { x: m.blend(t.x, f.x), y: m.blend(t.y, f.y), z: m.blend(t.z, f.z) }
    }
}

/// Sets lane `lane` of `c` to `v`.
#[cfg(test)]
fn set<L: Lanes64>(c: &mut L, lane: usize, v: f64) {
    let mut a = c.to_array();
    a[lane] = v;
    *c = L::from_array(a);
}

/// Quaternions, one per lane (`w` the scalar part).
#[derive(Clone, Copy, Debug)]
pub(super) struct Q4<L> {
    pub(super) x: L,
    pub(super) y: L,
    pub(super) z: L,
    pub(super) w: L,
}

impl<L: Lanes64> Q4<L> {
    #[inline(always)]
    pub(super) fn identity() -> Self {
        Q4 { x: L::zero(), y: L::zero(), z: L::zero(), w: L::splat(1.0) }
    }

    #[inline(always)]
    fn vec(self) -> V4<L> {
        V4 { x: self.x, y: self.y, z: self.z }
    }

    #[inline(always)]
    pub(super) fn conjugate(self) -> Self {
        Q4 { x: -self.x, y: -self.y, z: -self.z, w: self.w }
    }

    #[inline(always)]
    fn dot(self, o: Self) -> L {
        self.x * o.x + self.y * o.y + self.z * o.z + self.w * o.w
    }

    /// `self` or `-self`, whichever is in `reference`'s hemisphere.
    #[inline(always)]
    pub(super) fn aligned_with(self, reference: Self) -> Self {
        let flip = self.dot(reference).lt(L::zero());
        Q4::select(flip, Q4 { x: -self.x, y: -self.y, z: -self.z, w: -self.w }, self)
    }

    /// Half-angle exponential `(cos|v|, sin|v| v / |v|)`.
    #[inline(always)]
    pub(super) fn exp(v: V4<L>) -> Self {
        let h = v.length();
        let (s, c) = h.sin_cos();
        let zero = h.le(L::zero());
        let sinc = zero.blend(L::splat(1.0), s / zero.blend(L::splat(1.0), h));
        Q4 { x: v.x * sinc, y: v.y * sinc, z: v.z * sinc, w: c }
    }

    /// Half-angle logarithm `th u` of `(cos th, sin th u)`, `th` in `[0, pi]` (only the
    /// direction of `self` matters). At `th = pi` with no vector part the axis is undefined;
    /// the result is `(pi, 0, 0)`, as [`crate::quat::QuatF64::log`]'s.
    #[inline(always)]
    pub(super) fn log(self) -> V4<L> {
        let v = self.vec();
        let s2 = v.length_squared();
        let w = self.w;
        // Lanes below the angle where `atan` reduces its argument take `atan t / t` with
        // `t^2 = s^2 / w^2`: no square root and one division fewer. Each lane's formula
        // depends on its own value only, so a track's result never depends on its lane mates.
        let near = w.gt(L::zero()) & s2.lt(w * w * (ATAN_REDUCED * ATAN_REDUCED));
        let z = s2 / (w * w);
        let fast = v * ((L::splat(1.0) + atan_ratio(z)) / w);
        if near.all() {
            return fast;
        }
        let s = s2.sqrt();
        let zero = s.le(L::zero());
        let th = s.atan2(self.w);
        // Near the identity atan2(s, w) / s -> 1 / w.
        let factor = zero.blend(L::splat(1.0) / self.w, th / zero.blend(L::splat(1.0), s));
        let half_turn = zero & self.w.le(L::zero());
        let general = V4::select(half_turn, V4 { x: L::splat(PI), y: L::zero(), z: L::zero() }, v * factor);
        V4::select(near, fast, general)
    }
}

impl<L: Lanes64> Mul for Q4<L> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let [x, y, z, w] = hamilton([self.x, self.y, self.z, self.w], [o.x, o.y, o.z, o.w]);
        Q4 { x, y, z, w }
    }
}

impl<L: Lanes64> Select<L> for Q4<L> {
    #[inline(always)]
    fn select(m: L, t: Self, f: Self) -> Self {
        Q4 { x: m.blend(t.x, f.x), y: m.blend(t.y, f.y), z: m.blend(t.z, f.z), w: m.blend(t.w, f.w) }
    }
}

/// `log(a^-1 b)` the short way (`b` aligned with `a` first), per lane.
#[inline(always)]
pub(super) fn relative_log<L: Lanes64>(a: Q4<L>, b: Q4<L>) -> V4<L> {
    (a.conjugate() * b.aligned_with(a)).log()
}

/// 3x3 matrices, one per lane, by columns.
#[derive(Clone, Copy, Debug)]
pub(super) struct M4<L> {
    pub(super) cols: [V4<L>; 3],
}

impl<L: Lanes64> M4<L> {
    #[inline(always)]
    pub(super) fn zero() -> Self {
        M4 { cols: [V4::zero(); 3] }
    }

    /// `k I`.
    #[inline(always)]
    pub(super) fn diagonal(k: L) -> Self {
        let z = L::zero();
        M4 { cols: [V4 { x: k, y: z, z }, V4 { x: z, y: k, z }, V4 { x: z, y: z, z: k }] }
    }

    /// `[v]x`: `skew(v) u = v x u`.
    #[inline(always)]
    pub(super) fn skew(v: V4<L>) -> Self {
        let z = L::zero();
        M4 { cols: [V4 { x: z, y: v.z, z: -v.y }, V4 { x: -v.z, y: z, z: v.x }, V4 { x: v.y, y: -v.x, z }] }
    }

    /// The rotation matrix of unit `q`, as glam's `DMat3::from_quat` computes it.
    #[inline(always)]
    pub(super) fn from_quat(q: Q4<L>) -> Self {
        let (x2, y2, z2) = (q.x + q.x, q.y + q.y, q.z + q.z);
        let (xx, xy, xz) = (q.x * x2, q.x * y2, q.x * z2);
        let (yy, yz, zz) = (q.y * y2, q.y * z2, q.z * z2);
        let (wx, wy, wz) = (q.w * x2, q.w * y2, q.w * z2);
        let one = L::splat(1.0);
        M4 {
            cols: [
                V4 { x: one - (yy + zz), y: xy + wz, z: xz - wy },
                V4 { x: xy - wz, y: one - (xx + zz), z: yz + wx },
                V4 { x: xz + wy, y: yz - wx, z: one - (xx + yy) },
            ],
        }
    }

    /// The determinant and the inverse (adjugate over determinant, as glam's), and the lanes
    /// whose determinant is too small or not finite to invert.
    #[inline(always)]
    pub(super) fn inverse(self) -> (Self, L) {
        let [a, b, c] = self.cols;
        let (t0, t1, t2) = (b.cross(c), c.cross(a), a.cross(b));
        let det = c.dot(t2);
        let singular = !(det.is_finite() & det.abs().gt(L::splat(SINGULAR)));
        let inv = L::splat(1.0) / det;
        let (r0, r1, r2) = (t0 * inv, t1 * inv, t2 * inv);
        // Rows r0, r1, r2; by columns:
        let cols =
            [V4 { x: r0.x, y: r1.x, z: r2.x }, V4 { x: r0.y, y: r1.y, z: r2.y }, V4 { x: r0.z, y: r1.z, z: r2.z }];
        (M4 { cols }, singular)
    }
}

impl<L: Lanes64> Mul<V4<L>> for M4<L> {
    type Output = V4<L>;
    #[inline(always)]
    fn mul(self, v: V4<L>) -> V4<L> {
        self.cols[0] * v.x + self.cols[1] * v.y + self.cols[2] * v.z
    }
}

impl<L: Lanes64> Mul for M4<L> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        M4 { cols: [self * o.cols[0], self * o.cols[1], self * o.cols[2]] }
    }
}

impl<L: Lanes64> Add for M4<L> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        M4 { cols: [self.cols[0] + o.cols[0], self.cols[1] + o.cols[1], self.cols[2] + o.cols[2]] }
    }
}

impl<L: Lanes64> Sub for M4<L> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        M4 { cols: [self.cols[0] - o.cols[0], self.cols[1] - o.cols[1], self.cols[2] - o.cols[2]] }
    }
}

impl<L: Lanes64> Neg for M4<L> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        M4 { cols: [-self.cols[0], -self.cols[1], -self.cols[2]] }
    }
}

impl<L: Lanes64> Mul<L> for M4<L> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, k: L) -> Self {
        M4 { cols: [self.cols[0] * k, self.cols[1] * k, self.cols[2] * k] }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lane type the tests read; the solve's test checks that `Avx2` gives its bits.
    type F4 = Portable;

    /// Distance between `a` and libm's `b` in units in the last place of `b`, less `slack`
    /// absolute.
    fn ulps(a: f64, b: f64, slack: f64) -> f64 {
        let ulp = (b.abs() * f64::EPSILON).max(f64::MIN_POSITIVE);
        ((a - b).abs() - slack).max(0.0) / ulp
    }

    /// Arguments across the range: a sweep, a log-spaced run from 1e-300 to 1e6 with both
    /// signs, and the points near multiples of pi / 2 where reduction loses digits.
    fn arguments() -> Vec<f64> {
        let mut x: Vec<f64> = (-20_000..=20_000).map(|i| f64::from(i) * 1e-3).collect();
        let mut e = -300.0;
        while e <= 6.0 {
            x.extend([10f64.powf(e), -(10f64.powf(e))]);
            e += 0.01;
        }
        for k in -1000..=1000 {
            let centre = f64::from(k) * FRAC_PI_2;
            for d in [0.0, 1e-15, -1e-15, 1e-12, -1e-12, 1e-8, 1e-4] {
                x.push(centre + d);
                // The neighbouring doubles too.
                x.push(f64::from_bits(centre.to_bits().wrapping_add(1)));
                x.push(f64::from_bits(centre.to_bits().wrapping_sub(1)));
            }
        }
        x.extend([0.0, -0.0, PI, -PI, 2.0 * PI, 1e-310, 5e-324]);
        x
    }

    fn lanes(x: &[f64], f: impl Fn(F4) -> [F4; 2]) -> Vec<[f64; 2]> {
        x.chunks(4)
            .flat_map(|c| {
                let mut a = [c[0]; 4];
                a[..c.len()].copy_from_slice(c);
                let [p, q] = f(F4::from_array(a)).map(F4::to_array);
                (0..c.len()).map(move |i| [p[i], q[i]])
            })
            .collect()
    }

    /// Sine and cosine within 2 ulp of libm's, plus `1e-30 |x|` absolute (the reduction's
    /// third part, seen only near the zeros at multiples of `pi / 2`).
    #[test]
    fn sin_cos_match_libm_across_the_range() {
        let x = arguments();
        let got = lanes(&x, |v| {
            let (s, c) = v.sin_cos();
            [s, c]
        });
        let mut worst = [0.0f64; 2];
        for (&x, [s, c]) in x.iter().zip(got) {
            let slack = 1e-30 * x.abs();
            let (es, ec) = (ulps(s, x.sin(), slack), ulps(c, x.cos(), slack));
            assert!(
                es <= 2.0 && ec <= 2.0,
                "x = {x:e}: sin {s:e} vs {:e} ({es} ulp), cos {c:e} vs {:e} ({ec} ulp)",
                x.sin(),
                x.cos()
            );
            worst = [worst[0].max(es), worst[1].max(ec)];
        }
        eprintln!("sin_cos: worst {} / {} ulp over {} arguments", worst[0], worst[1], x.len());
    }

    /// `atan2` within 2 ulp of libm's over every quadrant, at tiny and huge ratios, on the
    /// axes, and at the half turn (`y` near zero, `x < 0`).
    #[test]
    fn atan2_matches_libm_in_every_quadrant() {
        let magnitudes: Vec<f64> = {
            let mut m =
                vec![0.0, 1e-300, 1e-30, 1e-16, 1e-8, 1e-3, 0.3, 0.66, 0.7, 1.0, 1.5, 2.4142, 3.0, 1e3, 1e8, 1e30];
            m.extend((1..200).map(|i| f64::from(i) * 0.0137));
            m
        };
        let mut pairs = Vec::new();
        for &a in &magnitudes {
            for &b in &magnitudes {
                for (sy, sx) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                    pairs.push((sy * a, sx * b));
                }
            }
        }
        let mut worst = 0.0f64;
        for chunk in pairs.chunks(4) {
            let mut y = [chunk[0].0; 4];
            let mut x = [chunk[0].1; 4];
            for (i, &(a, b)) in chunk.iter().enumerate() {
                (y[i], x[i]) = (a, b);
            }
            let got = F4::from_array(y).atan2(F4::from_array(x)).to_array();
            for (i, &(y, x)) in chunk.iter().enumerate() {
                // A zero of either sign counts as +0 (documented); libm's atan2(0, 0) is 0 too.
                let unsigned = |v: f64| if v == 0.0 { 0.0 } else { v };
                let want = unsigned(y).atan2(unsigned(x));
                let e = ulps(got[i], want, 0.0);
                assert!(e <= 2.0, "atan2({y:e}, {x:e}) = {:e}, libm {want:e} ({e} ulp)", got[i]);
                worst = worst.max(e);
            }
        }
        eprintln!("atan2: worst {worst} ulp over {} pairs", pairs.len());
    }

    /// The log inverts the exp up to the half turn, including near the identity (where both
    /// divide by a small length) and near the half turn.
    #[test]
    fn exp_and_log_invert_each_other() {
        let mut worst = 0.0f64;
        for h in [0.0, 1e-300, 1e-200, 1e-20, 1e-9, 1e-4, 0.1, 1.0, 2.0, 3.0, PI - 1e-6, PI - 1e-12] {
            for (i, axis) in [[1.0, 0.0, 0.0], [0.6, -0.8, 0.0], [0.48, 0.6, -0.64]].into_iter().enumerate() {
                let mut v = V4::<F4>::zero();
                for lane in 0..4 {
                    let k = h * (1.0 - 0.1 * lane as f64 * (i as f64));
                    v.set_lane(lane, axis.map(|a| a * k));
                }
                let back = Q4::exp(v).log();
                let err = (back - v).length();
                for lane in 0..4 {
                    let e = err.to_array()[lane] / v.lane(lane).iter().map(|a| a * a).sum::<f64>().sqrt().max(1e-300);
                    let want = crate::quat::QuatF64::exp(crate::quat::Vec3F64::from_array(v.lane(lane))).log();
                    let libm_e =
                        (want.to_array().iter().zip(v.lane(lane)).map(|(a, b)| (a - b) * (a - b)).sum::<f64>()).sqrt()
                            / v.lane(lane).iter().map(|a| a * a).sum::<f64>().sqrt().max(1e-300);
                    assert!(e <= 4.0 * f64::EPSILON + 2.0 * libm_e, "h {h:e} axis {axis:?}: relative error {e:e}");
                    worst = worst.max(e);
                }
            }
        }
        eprintln!("exp/log round trip: worst relative error {worst:e}");
    }

    /// The identity and its negation are a zero log; the half turn is `(pi, 0, 0)`.
    #[test]
    fn log_edge_cases_match_the_scalar_log() {
        let q = Q4 { x: F4::zero(), y: F4::zero(), z: F4::zero(), w: F4::from_array([1.0, 0.5, -1.0, 1e-300]) };
        let v = q.log();
        assert_eq!(v.lane(0), [0.0; 3]);
        assert_eq!(v.lane(1), [0.0; 3]);
        assert_eq!(v.lane(2), [PI, 0.0, 0.0]);
        assert_eq!(v.lane(3), [0.0; 3]);
    }

    /// Products, inverses and rotation matrices against glam's.
    #[test]
    fn matrices_match_glam() {
        use glam::{DMat3, DQuat, DVec3};
        let m = DMat3::from_cols(DVec3::new(1.2, -0.3, 0.5), DVec3::new(0.1, 0.9, -0.7), DVec3::new(-0.4, 0.2, 1.1));
        let lift = |m: DMat3| M4 {
            cols: [0, 1, 2].map(|j| {
                let c = m.col(j);
                V4 { x: F4::splat(c.x), y: F4::splat(c.y), z: F4::splat(c.z) }
            }),
        };
        let close =
            |a: M4<F4>, b: DMat3| (0..3).all(|j| (0..3).all(|i| (a.cols[j].lane(1)[i] - b.col(j)[i]).abs() < 1e-15));
        let (inv, singular) = lift(m).inverse();
        assert!(close(inv, m.inverse()) && !singular.any());
        assert!(close(lift(m) * lift(m.transpose()), m * m.transpose()));
        let q = DQuat::from_xyzw(0.1, -0.5, 0.3, 0.8).normalize();
        let q4 = Q4 { x: F4::splat(q.x), y: F4::splat(q.y), z: F4::splat(q.z), w: F4::splat(q.w) };
        assert!(close(M4::from_quat(q4), DMat3::from_quat(q)));
        let (_, singular) = lift(DMat3::from_cols(m.col(0), m.col(0), m.col(2))).inverse();
        assert!(singular.to_array().iter().all(|m| m.to_bits() == u64::MAX));
    }
}
