//! The eight-lane float type the fast CPU path computes with, chosen when the evaluator is
//! created rather than when the crate is built: `Avx2` (AVX2 registers and FMA) on x86-64
//! CPUs that have them, else `wide::f32x8` at the build's baseline (SSE2 on x86-64, NEON on
//! aarch64). So dependents, portable binaries and Python wheels built once get the fast path
//! wherever it exists, without build flags.
//!
//! `wide` fixes its implementation by the build's target features, so the AVX2 path cannot
//! be `wide` compiled twice: it is its own type. The kernels are generic over [`Lanes`]; each
//! entry point is instantiated once per lane type, the AVX2 one inside a
//! `#[target_feature(enable = "avx2,fma")]` function with everything below it inlined.

use std::ops::{Add, BitAnd, Div, Mul, Neg, Not, Sub};

/// Eight `f32` lanes: what the kernels need of a SIMD type. Comparisons return masks (all
/// bits set where true) that [`Lanes::blend`] and `&` take.
pub trait Lanes:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + BitAnd<Output = Self>
    + Not<Output = Self>
{
    /// All zero.
    const ZERO: Self;
    /// All one.
    const ONE: Self;
    /// `v` in every lane.
    fn splat(v: f32) -> Self;
    /// The lanes of `v`.
    fn new(v: [f32; 8]) -> Self;
    /// The lanes as an array (the tests read lanes back).
    #[cfg(test)]
    fn to_array(self) -> [f32; 8];
    /// `self * m + a`, fused where the hardware fuses.
    fn mul_add(self, m: Self, a: Self) -> Self;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Rounded to the nearest integer (ties to even).
    fn round(self) -> Self;
    /// `(sin self, cos self)` for any argument (range reduced).
    fn sin_cos(self) -> (Self, Self);
    /// The angle of `(x, self)`, in `[-pi, pi]`.
    fn atan2(self, x: Self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Lane-wise minimum.
    fn min(self, o: Self) -> Self;
    /// Lane-wise maximum.
    fn max(self, o: Self) -> Self;
    /// Mask of `self > o`.
    fn cmp_gt(self, o: Self) -> Self;
    /// Mask of `self < o`.
    fn cmp_lt(self, o: Self) -> Self;
    /// Mask of `self <= o`.
    fn cmp_le(self, o: Self) -> Self;
    /// Per lane, `t` where the mask `self` is set, else `f`.
    fn blend(self, t: Self, f: Self) -> Self;
    /// The eight lanes' `[v0, v1, v2, v3]`: four vectors of eight samples as eight rows.
    fn transpose(v: [Self; 4]) -> [[f32; 4]; 8];
    /// Four vectors of eight samples from eight rows `[v0, v1, v2, v3]`: the inverse of
    /// [`Lanes::transpose`].
    fn from_rows(rows: &[[f32; 4]; 8]) -> [Self; 4];
    /// Whether every lane of the mask `self` is set.
    fn all(self) -> bool;
}

pub use quatcurve_core::isa::Isa;

impl Lanes for wide::f32x8 {
    const ZERO: Self = wide::f32x8::ZERO;
    const ONE: Self = wide::f32x8::ONE;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        wide::f32x8::splat(v)
    }
    #[inline(always)]
    fn new(v: [f32; 8]) -> Self {
        wide::f32x8::new(v)
    }
    #[cfg(test)]
    fn to_array(self) -> [f32; 8] {
        wide::f32x8::to_array(self)
    }
    #[inline(always)]
    fn mul_add(self, m: Self, a: Self) -> Self {
        wide::f32x8::mul_add(self, m, a)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        wide::f32x8::sqrt(self)
    }
    #[inline(always)]
    fn round(self) -> Self {
        wide::f32x8::round(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        wide::f32x8::sin_cos(self)
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        wide::f32x8::atan2(self, x)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        wide::f32x8::abs(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        wide::f32x8::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        wide::f32x8::max(self, o)
    }
    #[inline(always)]
    fn cmp_gt(self, o: Self) -> Self {
        wide::CmpGt::cmp_gt(self, o)
    }
    #[inline(always)]
    fn cmp_lt(self, o: Self) -> Self {
        wide::CmpLt::cmp_lt(self, o)
    }
    #[inline(always)]
    fn cmp_le(self, o: Self) -> Self {
        wide::CmpLe::cmp_le(self, o)
    }
    #[inline(always)]
    fn blend(self, t: Self, f: Self) -> Self {
        wide::f32x8::blend(self, t, f)
    }
    #[inline(always)]
    fn transpose(v: [Self; 4]) -> [[f32; 4]; 8] {
        let a = v.map(wide::f32x8::to_array);
        std::array::from_fn(|lane| [a[0][lane], a[1][lane], a[2][lane], a[3][lane]])
    }
    #[inline(always)]
    fn from_rows(rows: &[[f32; 4]; 8]) -> [Self; 4] {
        std::array::from_fn(|c| wide::f32x8::new(rows.map(|r| r[c])))
    }
    #[inline(always)]
    fn all(self) -> bool {
        self.move_mask() == 0xFF
    }
}

/// Largest `|x|` that [`sin_cos_small`] takes: a little over `pi / 2`, the half-angle of every
/// shortest-path key step, so that keyed tracks never need range reduction.
pub const SMALL_ANGLE: f32 = 1.6;

/// `(sin x, cos x)` for `|x| <= SMALL_ANGLE`, by Taylor polynomials through `x^13` and `x^12`:
/// truncation error below 1e-9 there, so the f32 result is within a few ulps (test
/// `small_sin_cos_is_accurate`). Half the work of a general `sin_cos`, which must first
/// reduce its argument modulo `pi / 2`.
#[inline(always)]
pub fn sin_cos_small<S: Lanes>(x: S) -> (S, S) {
    const SIN: [f32; 7] =
        [1.0, -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0, -1.0 / 39_916_800.0, 1.0 / 6_227_020_800.0];
    const COS: [f32; 7] =
        [1.0, -0.5, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40_320.0, -1.0 / 3_628_800.0, 1.0 / 479_001_600.0];
    let x2 = x * x;
    let (mut s, mut c) = (S::splat(SIN[6]), S::splat(COS[6]));
    for k in (0..6).rev() {
        s = s.mul_add(x2, S::splat(SIN[k]));
        c = c.mul_add(x2, S::splat(COS[k]));
    }
    (s * x, c)
}

/// `pi / 2` in three parts for Cody-Waite reduction, the first with few enough bits that
/// `k * part` is exact for `|k| < 2^16`: the shader's `HALF_PI_1..3` (`shaders/real.wgsl`),
/// tied by the test `sin_cos_reduction_is_the_rusts`.
pub const HALF_PI_PARTS: [f32; 3] = [1.570_312_5, 4.837_513e-4, 7.549_79e-8];

/// `(sin x, cos x)` from [`Lanes`] arithmetic alone: Cody-Waite reduction by `pi / 2` in three
/// parts (as `shaders/real.wgsl`: `k * HALF_PI_1` is exact for `|k| < 2^16`), the Taylor
/// polynomials of [`sin_cos_small`] on `[-pi/4, pi/4]`, then the quadrant by
/// masks. Absolute error about 1e-7 for `|x| < 1e4`, as the shader's.
#[inline(always)]
pub fn reduced_sin_cos<S: Lanes>(x: S) -> (S, S) {
    let [p1, p2, p3] = HALF_PI_PARTS.map(S::splat);
    let k = (x * S::splat(std::f32::consts::FRAC_2_PI)).round();
    let r = (-k).mul_add(p3, (-k).mul_add(p2, (-k).mul_add(p1, x)));
    let (s, c) = sin_cos_small(r);
    // The quadrant k mod 4 in 0..=3, from exact float integers: k / 4 has a fractional part
    // of 0, 1/4, 1/2 or 3/4, which the -3/8 makes round down.
    let q = k - S::splat(4.0) * (k * S::splat(0.25) - S::splat(0.375)).round();
    let odd = (q - S::splat(2.0) * (q * S::splat(0.5) - S::splat(0.25)).round()).cmp_gt(S::splat(0.5));
    let (sin, cos) = (odd.blend(c, s), odd.blend(s, c));
    let negate_sin = q.cmp_gt(S::splat(1.5));
    let negate_cos = q.cmp_gt(S::splat(0.5)) & q.cmp_lt(S::splat(2.5));
    (negate_sin.blend(-sin, sin), negate_cos.blend(-cos, cos))
}

/// The angle of `(x, y)` from [`Lanes`] arithmetic alone: `atan` of the smaller of `|x|, |y|`
/// over the larger (at most 1), folded about `pi / 4` above `tan(pi / 8)`, with Cephes' `atanf`
/// polynomial (relative error about 1e-7), then placed in its octant and quadrant by masks.
#[inline(always)]
pub fn reduced_atan2<S: Lanes>(y: S, x: S) -> S {
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = (ax.min(ay), ax.max(ay));
    let t = large.cmp_gt(S::ZERO).blend(small / large, S::ZERO);
    let fold = t.cmp_gt(S::splat(0.414_213_57));
    let z = fold.blend((t - S::ONE) / (t + S::ONE), t);
    let z2 = z * z;
    let p = S::splat(8.053_744_5e-2)
        .mul_add(z2, S::splat(-1.387_768_5e-1))
        .mul_add(z2, S::splat(1.997_771_1e-1))
        .mul_add(z2, S::splat(-3.333_295e-1));
    let a = (p * z2).mul_add(z, z) + (fold & S::splat(std::f32::consts::FRAC_PI_4));
    let a = ay.cmp_gt(ax).blend(S::splat(std::f32::consts::FRAC_PI_2) - a, a);
    let a = x.cmp_lt(S::ZERO).blend(S::splat(std::f32::consts::PI) - a, a);
    y.cmp_lt(S::ZERO).blend(-a, a)
}

#[cfg(target_arch = "x86_64")]
pub use avx2::Avx2;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::Lanes;
    use std::arch::x86_64::{
        __m256, _mm256_add_ps, _mm256_and_ps, _mm256_andnot_ps, _mm256_blendv_ps, _mm256_castps256_ps128,
        _mm256_cmp_ps, _mm256_div_ps, _mm256_extractf128_ps, _mm256_fmadd_ps, _mm256_loadu2_m128, _mm256_loadu_ps,
        _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps, _mm256_round_ps, _mm256_set1_ps,
        _mm256_shuffle_ps, _mm256_sqrt_ps, _mm256_sub_ps, _mm256_unpackhi_ps, _mm256_unpacklo_ps, _mm256_xor_ps,
        _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _MM_FROUND_NO_EXC, _MM_FROUND_TO_NEAREST_INT,
    };
    use std::ops::{Add, BitAnd, Div, Mul, Neg, Not, Sub};

    /// Eight lanes in one AVX register, with AVX2/FMA instructions.
    ///
    /// Only the CPU path's AVX2 entry points make these, after [`super::Isa::Avx2`] was
    /// detected (`Isa::available`): every method below runs AVX/FMA instructions, which is
    /// what makes their `unsafe` blocks sound. The methods are `inline(always)` so that they
    /// compile inside the entry points' `#[target_feature(enable = "avx2,fma")]`.
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub struct Avx2(__m256);

    /// `[f32; 8]` as a register, in a constant (`__m256` is plain bits of the same size).
    const fn constant(v: [f32; 8]) -> Avx2 {
        // SAFETY: `__m256` is 32 bytes of floats; every bit pattern is valid.
        Avx2(unsafe { std::mem::transmute::<[f32; 8], __m256>(v) })
    }

    macro_rules! binary {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for Avx2 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, o: Self) -> Self {
                    // SAFETY: see the type.
                    Self(unsafe { $intrinsic(self.0, o.0) })
                }
            }
        };
    }
    binary!(Add, add, _mm256_add_ps);
    binary!(Sub, sub, _mm256_sub_ps);
    binary!(Mul, mul, _mm256_mul_ps);
    binary!(Div, div, _mm256_div_ps);
    binary!(BitAnd, bitand, _mm256_and_ps);

    impl Neg for Avx2 {
        type Output = Self;
        #[inline(always)]
        fn neg(self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_xor_ps(self.0, constant([-0.0; 8]).0) })
        }
    }

    impl Not for Avx2 {
        type Output = Self;
        #[inline(always)]
        fn not(self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_xor_ps(self.0, constant([f32::from_bits(u32::MAX); 8]).0) })
        }
    }

    impl Lanes for Avx2 {
        const ZERO: Self = constant([0.0; 8]);
        const ONE: Self = constant([1.0; 8]);
        #[inline(always)]
        fn splat(v: f32) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_set1_ps(v) })
        }
        #[inline(always)]
        fn new(v: [f32; 8]) -> Self {
            // SAFETY: see the type; the load reads the eight floats of `v`.
            Self(unsafe { _mm256_loadu_ps(v.as_ptr()) })
        }
        #[cfg(test)]
        fn to_array(self) -> [f32; 8] {
            let mut out = [0.0; 8];
            // SAFETY: see the type; the store writes the eight floats of `out`.
            unsafe { std::arch::x86_64::_mm256_storeu_ps(out.as_mut_ptr(), self.0) };
            out
        }
        #[inline(always)]
        fn mul_add(self, m: Self, a: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_fmadd_ps(self.0, m.0, a.0) })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn round(self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_round_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(self.0) })
        }
        #[inline(always)]
        fn sin_cos(self) -> (Self, Self) {
            super::reduced_sin_cos(self)
        }
        #[inline(always)]
        fn atan2(self, x: Self) -> Self {
            super::reduced_atan2(self, x)
        }
        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: see the type. Clears the sign bits.
            Self(unsafe { _mm256_andnot_ps(constant([-0.0; 8]).0, self.0) })
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn cmp_gt(self, o: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn cmp_lt(self, o: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn cmp_le(self, o: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn blend(self, t: Self, f: Self) -> Self {
            // SAFETY: see the type.
            Self(unsafe { _mm256_blendv_ps(f.0, t.0, self.0) })
        }
        /// A 4x8 transpose in registers: scattering lanes one float at a time cost a fifth of
        /// the evaluation.
        #[inline(always)]
        fn transpose(v: [Self; 4]) -> [[f32; 4]; 8] {
            // SAFETY: see the type; `__m128` and `[f32; 4]` are 16 bytes with every bit
            // pattern valid.
            unsafe {
                let [x, y, z, w] = v.map(|v| v.0);
                let (t0, t1) = (_mm256_unpacklo_ps(x, y), _mm256_unpackhi_ps(x, y));
                let (t2, t3) = (_mm256_unpacklo_ps(z, w), _mm256_unpackhi_ps(z, w));
                // u0 = lanes 0 | 4, u1 = 1 | 5, u2 = 2 | 6, u3 = 3 | 7.
                let (u0, u1) = (_mm256_shuffle_ps::<0x44>(t0, t2), _mm256_shuffle_ps::<0xEE>(t0, t2));
                let (u2, u3) = (_mm256_shuffle_ps::<0x44>(t1, t3), _mm256_shuffle_ps::<0xEE>(t1, t3));
                // The intrinsics are called here, not inside closures, so that they compile
                // inside the target-feature function.
                let row = |q: std::arch::x86_64::__m128| std::mem::transmute::<std::arch::x86_64::__m128, [f32; 4]>(q);
                [
                    row(_mm256_castps256_ps128(u0)),
                    row(_mm256_castps256_ps128(u1)),
                    row(_mm256_castps256_ps128(u2)),
                    row(_mm256_castps256_ps128(u3)),
                    row(_mm256_extractf128_ps::<1>(u0)),
                    row(_mm256_extractf128_ps::<1>(u1)),
                    row(_mm256_extractf128_ps::<1>(u2)),
                    row(_mm256_extractf128_ps::<1>(u3)),
                ]
            }
        }
        /// [`Avx2::transpose`] backwards: rows `i` and `i + 4` loaded into one register, then
        /// the same 4x4 transposes of both halves.
        #[inline(always)]
        fn from_rows(rows: &[[f32; 4]; 8]) -> [Self; 4] {
            // SAFETY: see the type; each load reads the four floats of two rows.
            unsafe {
                let a0 = _mm256_loadu2_m128(rows[4].as_ptr(), rows[0].as_ptr());
                let a1 = _mm256_loadu2_m128(rows[5].as_ptr(), rows[1].as_ptr());
                let a2 = _mm256_loadu2_m128(rows[6].as_ptr(), rows[2].as_ptr());
                let a3 = _mm256_loadu2_m128(rows[7].as_ptr(), rows[3].as_ptr());
                let (t0, t1) = (_mm256_unpacklo_ps(a0, a1), _mm256_unpackhi_ps(a0, a1));
                let (t2, t3) = (_mm256_unpacklo_ps(a2, a3), _mm256_unpackhi_ps(a2, a3));
                [
                    Self(_mm256_shuffle_ps::<0x44>(t0, t2)),
                    Self(_mm256_shuffle_ps::<0xEE>(t0, t2)),
                    Self(_mm256_shuffle_ps::<0x44>(t1, t3)),
                    Self(_mm256_shuffle_ps::<0xEE>(t1, t3)),
                ]
            }
        }
        #[inline(always)]
        fn all(self) -> bool {
            // SAFETY: see the type.
            unsafe { _mm256_movemask_ps(self.0) == 0xFF }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{reduced_atan2, reduced_sin_cos, Isa, Lanes};
    use wide::f32x8;

    /// Arguments across quadrants, their boundaries, zero and large multiples of pi / 2.
    fn angles() -> Vec<f32> {
        let mut xs: Vec<f32> = (-4000..=4000).map(|i| i as f32 * 0.001_7).collect();
        xs.extend((-64..=64).map(|k| k as f32 * std::f32::consts::FRAC_PI_2));
        xs.extend([1e3, -2.5e3, 9_999.0, 0.0, -0.0, 1e-30]);
        xs
    }

    #[test]
    fn reduced_sin_cos_is_accurate_in_every_quadrant() {
        let mut worst = 0.0f64;
        for x in angles() {
            let (s, c) = reduced_sin_cos(f32x8::splat(x));
            let (s, c) = (f64::from(s.to_array()[0]), f64::from(c.to_array()[0]));
            let x = f64::from(x);
            worst = worst.max((s - x.sin()).abs()).max((c - x.cos()).abs());
        }
        // f32 rounding of x itself is up to 5e-4 at 1e4, but the reference takes the f32 x.
        assert!(worst < 1e-6, "worst error {worst:e}");
    }

    #[test]
    fn reduced_atan2_is_accurate_around_the_circle() {
        let mut worst = 0.0f64;
        for i in 0..=20_000 {
            let a = -std::f64::consts::PI + std::f64::consts::TAU * f64::from(i) / 20_000.0;
            for r in [1e-3, 0.7, 1.0, 250.0] {
                let (y, x) = ((r * a.sin()) as f32, (r * a.cos()) as f32);
                let got = f64::from(reduced_atan2(f32x8::splat(y), f32x8::splat(x)).to_array()[0]);
                let want = f64::from(y).atan2(f64::from(x));
                // The two ends of the circle are the same angle.
                let diff = (got - want).abs();
                worst = worst.max(diff.min((diff - std::f64::consts::TAU).abs()));
            }
        }
        assert!(worst < 5e-7, "worst error {worst:e}");
        let zero = reduced_atan2(f32x8::ZERO, f32x8::ZERO).to_array()[0];
        assert_eq!(zero, 0.0);
    }

    /// Every operation of the AVX2 lanes gives the baseline's bits (where this CPU has AVX2),
    /// except `mul_add`, which is fused (checked against std's fused f32), the sign of a
    /// zero from `round`, and sin_cos and atan2, computed differently (within 1e-6).
    #[test]
    fn avx2_lanes_agree_with_the_baseline() {
        if !Isa::Avx2.available() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        {
            use super::Avx2;
            // SAFETY: AVX2 and FMA are present (checked above).
            unsafe { agree() };
            #[target_feature(enable = "avx2,fma")]
            unsafe fn agree() {
                let mut state = 0x2545_f491_4f6c_dd1du64;
                let mut next = || {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 20.0
                };
                for _ in 0..2000 {
                    let (a, b, c): ([f32; 8], [f32; 8], [f32; 8]) = (
                        std::array::from_fn(|_| next()),
                        std::array::from_fn(|_| next()),
                        std::array::from_fn(|_| next()),
                    );
                    let (wa, wb, wc) = (f32x8::new(a), f32x8::new(b), f32x8::new(c));
                    let (va, vb, vc) = (Avx2::new(a), Avx2::new(b), Avx2::new(c));
                    let same = |w: f32x8, v: Avx2, op: &str| {
                        assert_eq!(
                            w.to_array().map(f32::to_bits),
                            v.to_array().map(f32::to_bits),
                            "{op} of {a:?}, {b:?}"
                        )
                    };
                    same(wa + wb, va + vb, "+");
                    same(wa - wb, va - vb, "-");
                    same(wa * wb, va * vb, "*");
                    same(wa / wb, va / vb, "/");
                    same(-wa, -va, "neg");
                    // Fused here, rounded twice in the SSE2 baseline: against std's fused f32.
                    let fused: [f32; 8] = std::array::from_fn(|i| a[i].mul_add(b[i], c[i]));
                    assert_eq!(fused.map(f32::to_bits), va.mul_add(vb, vc).to_array().map(f32::to_bits), "mul_add");
                    same(Lanes::sqrt(wa.abs()), va.abs().sqrt(), "sqrt");
                    // Equal values; the SSE2 baseline rounds -0.4 to +0.
                    assert_eq!(Lanes::round(wa).to_array(), va.round().to_array(), "round");
                    same(Lanes::min(wa, wb), va.min(vb), "min");
                    same(Lanes::max(wa, wb), va.max(vb), "max");
                    for (w, v, op) in [
                        (Lanes::cmp_gt(wa, wb), va.cmp_gt(vb), ">"),
                        (Lanes::cmp_lt(wa, wb), va.cmp_lt(vb), "<"),
                        (Lanes::cmp_le(wa, wa), va.cmp_le(va), "<="),
                    ] {
                        same(w, v, op);
                        same(Lanes::blend(w, wa, wb), v.blend(va, vb), "blend");
                        same(w & !Lanes::cmp_gt(wc, wa) & f32x8::ONE, v & !vc.cmp_gt(va) & Avx2::ONE, "mask logic");
                    }
                    assert_eq!(
                        <f32x8 as Lanes>::transpose([wa, wb, wc, wa]),
                        Avx2::transpose([va, vb, vc, va]),
                        "transpose"
                    );
                    let rows = Avx2::transpose([va, vb, vc, va]);
                    for (w, v) in <f32x8 as Lanes>::from_rows(&rows).into_iter().zip(Avx2::from_rows(&rows)) {
                        same(w, v, "from_rows");
                    }
                    assert_eq!(
                        Avx2::from_rows(&rows).map(|v| v.to_array()),
                        [a, b, c, a],
                        "from_rows inverts transpose"
                    );
                    assert_eq!(Lanes::all(Lanes::cmp_gt(wa, wb)), va.cmp_gt(vb).all(), "all");
                    assert!(va.cmp_le(va).all() && Lanes::all(Lanes::cmp_le(wa, wa)), "all of a full mask");
                    let ((ws, wc2), (vs, vc2)) = (Lanes::sin_cos(wa), va.sin_cos());
                    let close = |w: f32x8, v: Avx2, op: &str| {
                        for (w, v) in w.to_array().into_iter().zip(v.to_array()) {
                            assert!((w - v).abs() <= 1e-6, "{op}: {w} against {v}");
                        }
                    };
                    close(ws, vs, "sin");
                    close(wc2, vc2, "cos");
                    close(Lanes::atan2(wa, wb), va.atan2(vb), "atan2");
                }
                assert_eq!(Avx2::ZERO.to_array(), [0.0; 8]);
                assert_eq!(Avx2::ONE.to_array(), [1.0; 8]);
                assert_eq!(Avx2::splat(2.5).to_array(), [2.5; 8]);
            }
        }
    }
}
