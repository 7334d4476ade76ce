//! Eight samples at a time: structure-of-arrays quaternions and vectors on any [`Lanes`] type
//! (module `simd`: AVX2 registers where the CPU has them), and the KKS cumulative product with
//! its body derivatives, the twin of [`crate::reference::cumulative_product`].

use super::simd::{sin_cos_small, Lanes};
use quatcurve_core::quat::hamilton;

/// Samples per SIMD group.
pub const LANES: usize = 8;

/// Most factors in one product: a B-spline of the highest order.
pub const MAX_FACTORS: usize = quatcurve_core::curve::MAX_ORDER - 1;

/// Eight 3-vectors.
#[derive(Clone, Copy, Debug)]
pub struct V8<S> {
    pub x: S,
    pub y: S,
    pub z: S,
}

/// Eight quaternions `x, y, z, w`.
#[derive(Clone, Copy, Debug)]
pub struct Q8<S> {
    pub x: S,
    pub y: S,
    pub z: S,
    pub w: S,
}

impl<S: Lanes> V8<S> {
    /// All zero.
    pub const ZERO: Self = Self { x: S::ZERO, y: S::ZERO, z: S::ZERO };

    /// The same `[x, y, z, _]` in every lane.
    #[inline(always)]
    pub fn splat(r: [f32; 4]) -> Self {
        Self { x: S::splat(r[0]), y: S::splat(r[1]), z: S::splat(r[2]) }
    }

    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }

    #[inline(always)]
    fn scale(self, k: S) -> Self {
        Self { x: self.x * k, y: self.y * k, z: self.z * k }
    }

    #[inline(always)]
    fn cross(self, o: Self) -> Self {
        Self { x: self.y * o.z - self.z * o.y, y: self.z * o.x - self.x * o.z, z: self.x * o.y - self.y * o.x }
    }
}

impl<S: Lanes> Q8<S> {
    /// All zero.
    pub const ZERO: Self = Self { x: S::ZERO, y: S::ZERO, z: S::ZERO, w: S::ZERO };

    /// Lane-wise gather from `[x, y, z, w]` rows.
    #[inline(always)]
    pub fn gather(rows: &[[f32; 4]; LANES]) -> Self {
        Self {
            x: S::new(rows.map(|r| r[0])),
            y: S::new(rows.map(|r| r[1])),
            z: S::new(rows.map(|r| r[2])),
            w: S::new(rows.map(|r| r[3])),
        }
    }

    /// The same `[x, y, z, w]` in every lane.
    #[inline(always)]
    pub fn splat(r: [f32; 4]) -> Self {
        Self { x: S::splat(r[0]), y: S::splat(r[1]), z: S::splat(r[2]), w: S::splat(r[3]) }
    }

    /// `cos * self + sin * lead`: with `lead = self * (axis, 0)`, the point
    /// `self * exp(angle * axis)` of the great arc, without a quaternion product.
    #[inline(always)]
    pub fn along(self, lead: Self, sin: S, cos: S) -> Self {
        Self {
            x: self.x.mul_add(cos, lead.x * sin),
            y: self.y.mul_add(cos, lead.y * sin),
            z: self.z.mul_add(cos, lead.z * sin),
            w: self.w.mul_add(cos, lead.w * sin),
        }
    }

    /// `self * k + acc`, lane by lane.
    #[inline(always)]
    fn scaled_add(self, k: S, acc: Self) -> Self {
        Self {
            x: self.x.mul_add(k, acc.x),
            y: self.y.mul_add(k, acc.y),
            z: self.z.mul_add(k, acc.z),
            w: self.w.mul_add(k, acc.w),
        }
    }

    /// `self * k`.
    #[inline(always)]
    fn scale(self, k: S) -> Self {
        Self { x: self.x * k, y: self.y * k, z: self.z * k, w: self.w * k }
    }

    /// The 4-vector dot product.
    #[inline(always)]
    fn dot(self, o: Self) -> S {
        self.x.mul_add(o.x, self.y.mul_add(o.y, self.z.mul_add(o.z, self.w * o.w)))
    }

    /// `vec(conj(self) r)`: `self.w r.v - r.w self.v - self.v x r.v`.
    #[inline(always)]
    fn conjugate_times(self, r: Self) -> V8<S> {
        let v = V8 { x: self.x, y: self.y, z: self.z };
        let rv = V8 { x: r.x, y: r.y, z: r.z };
        rv.scale(self.w).add(v.scale(-r.w)).add(rv.cross(v))
    }

    /// `(-x, -y, -z, w)`.
    #[inline(always)]
    pub fn conjugate(self) -> Self {
        Self { x: -self.x, y: -self.y, z: -self.z, w: self.w }
    }

    /// `self^-1 v self` for unit `self`: `v + 2 w (v x u) + 2 u x (u x v)` with `u = -vec`.
    #[inline(always)]
    fn rotate_inverse(self, v: V8<S>) -> V8<S> {
        let u = V8 { x: -self.x, y: -self.y, z: -self.z };
        let t = u.cross(v).scale(S::splat(2.0));
        v.add(t.scale(self.w)).add(u.cross(t))
    }
}

impl<S: Lanes> std::ops::Mul for Q8<S> {
    type Output = Self;

    /// Hamilton product `self * o` ([`hamilton`]).
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let [x, y, z, w] = hamilton([self.x, self.y, self.z, self.w], [o.x, o.y, o.z, o.w]);
        Self { x, y, z, w }
    }
}

/// Writes columns `col..col + width` (`width <= 4`) of the first `valid` rows of `rows` (rows of
/// `stride` floats): row `lane` gets `v[0][lane], v[1][lane], ...`, through the lane type's
/// transpose ([`Lanes::transpose`]).
#[inline(always)]
pub fn write_columns<S: Lanes>(v: [S; 4], rows: &mut [f32], stride: usize, col: usize, width: usize, valid: usize) {
    let quads = S::transpose(v);
    if stride == 4 && width == 4 {
        // Rows of one quaternion each (rotation-only output): whole rows, no per-row range.
        for (row, quad) in rows.chunks_exact_mut(4).zip(&quads).take(valid) {
            row.copy_from_slice(quad);
        }
        return;
    }
    for (lane, quad) in quads.iter().enumerate().take(valid) {
        let at = lane * stride + col;
        rows[at..at + width].copy_from_slice(&quad[..width]);
    }
}

/// One factor `exp(v b(t))` of eight samples: `v = theta * axis` (half-angle vector, axis
/// unit or zero) and the basis jet `[b, b', b'']` in time units.
#[derive(Clone, Copy, Debug)]
pub struct Factor8<S> {
    pub axis: V8<S>,
    pub theta: S,
    pub b: [S; 3],
}

impl<S: Lanes> Factor8<S> {
    /// The factors of eight lanes from their coefficients as stored, `[x, y, z, _]` rows in
    /// f32 (a lane's `theta axis`), with basis jets `b`: axes and angles eight lanes at once,
    /// as [`axis_angle`] computes them one at a time.
    #[inline(always)]
    pub fn from_rows(rows: &[[f32; 4]; LANES], b: [S; 3]) -> Self {
        let [x, y, z, _] = S::from_rows(rows);
        let theta = (x * x + y * y + z * z).sqrt();
        let inv = theta.cmp_gt(S::ZERO).blend(S::ONE / theta, S::ZERO);
        Self { axis: V8 { x: x * inv, y: y * inv, z: z * inv }, theta, b }
    }
}

/// A coefficient `[x, y, z, _]` as `[axis x, axis y, axis z, theta]`, axis unit (or zero with
/// theta 0): the scalar twin of [`Factor8::from_rows`], with the same f32 operations in the
/// same order, so that a lane gets the same bits either way.
#[inline(always)]
pub fn axis_angle([x, y, z, _]: [f32; 4]) -> [f32; 4] {
    let theta = (x * x + y * y + z * z).sqrt();
    let inv = if theta > 0.0 { 1.0 / theta } else { 0.0 };
    [x * inv, y * inv, z * inv, theta]
}

/// Which sine and cosine [`cumulative_product`] takes.
#[derive(Clone, Copy, Debug)]
pub enum AngleRange<S> {
    /// Every `|theta b|` is at most [`super::simd::SMALL_ANGLE`]: [`sin_cos_small`].
    Small,
    /// Any angle: the range-reduced [`Lanes::sin_cos`].
    Any,
    /// [`sin_cos_small`] in the lanes this mask sets, [`Lanes::sin_cos`] in the others: each
    /// lane's choice its own, whatever its neighbours are.
    PerLane(S),
}

/// `start * prod exp(v_j b_j)` and, with `derivatives`, the body angular velocity and
/// acceleration by DESIGN section 2's recursion (see the reference for the formulas).
/// `range`: which sine and cosine apply.
/// `lead`: `start * (axis_0, 0)` when the caller has it (all lanes on one segment), which
/// turns the first product into `cos * start + sin * lead`.
#[inline(always)]
pub fn cumulative_product<S: Lanes, const F: usize>(
    start: Q8<S>,
    lead: Option<Q8<S>>,
    factors: &[Factor8<S>; F],
    derivatives: bool,
    range: AngleRange<S>,
) -> (Q8<S>, V8<S>, V8<S>) {
    #[inline(always)]
    fn sin_cos<S: Lanes>(f: &Factor8<S>, range: AngleRange<S>) -> (S, S) {
        let angle = f.theta * f.b[0];
        match range {
            AngleRange::Small => sin_cos_small(angle),
            AngleRange::Any => angle.sin_cos(),
            AngleRange::PerLane(small) => {
                let ((s, c), (s_any, c_any)) = (sin_cos_small(angle), angle.sin_cos());
                (small.blend(s, s_any), small.blend(c, c_any))
            }
        }
    }
    let Some((head, rest)) = factors.split_first() else {
        return (start, V8::ZERO, V8::ZERO);
    };
    let (sin, cos) = sin_cos(head, range);
    let mut q = match lead {
        Some(lead) => start.along(lead, sin, cos),
        None => start * Q8 { x: head.axis.x * sin, y: head.axis.y * sin, z: head.axis.z * sin, w: cos },
    };
    // W and W' start at zero: nothing to carry through the first factor.
    let (mut w, mut w_dot) = if derivatives {
        (head.axis.scale(head.theta * head.b[1]), head.axis.scale(head.theta * head.b[2]))
    } else {
        (V8::ZERO, V8::ZERO)
    };
    for f in rest {
        let (sin, cos) = sin_cos(f, range);
        let a = Q8 { x: f.axis.x * sin, y: f.axis.y * sin, z: f.axis.z * sin, w: cos };
        if derivatives {
            let spin = f.axis.scale(f.theta * f.b[1]);
            let accel = f.axis.scale(f.theta * f.b[2]);
            let carried = a.rotate_inverse(w);
            w_dot = a.rotate_inverse(w_dot).add(carried.cross(spin).scale(S::splat(2.0))).add(accel);
            w = carried.add(spin);
        }
        q = q * a;
    }
    let two = S::splat(2.0);
    (q, w.scale(two), w_dot.scale(two))
}

/// `normalize(c_0 + sum_j B~_j (c_j - c_{j-1}))`, the normalized B-spline of eight samples
/// from their span's control points `first` and `rest` and cumulative basis jets `jets`
/// (Abel's sum of `sum B_i c_i`: one difference per jet, no plain basis), with its body
/// derivatives: for `p` the sum, `s = p.p` and `V(r) = vec(conj(p) r)`,
/// `omega = 2 V(p') / s` and `alpha = (2 / s) (V(p'') - 2 (p.p') / s V(p'))`, the twin of
/// `crate::reference::sample_from_jets` on the reference's normalized jets.
#[inline(always)]
pub fn normalized_sum<S: Lanes, const F: usize>(
    first: Q8<S>,
    rest: &[Q8<S>; F],
    jets: &[[S; 3]; F],
    derivatives: bool,
) -> (Q8<S>, V8<S>, V8<S>) {
    let (mut p, mut d, mut e) = (first, Q8::ZERO, Q8::ZERO);
    let mut previous = first;
    for (point, jet) in rest.iter().zip(jets) {
        let step =
            Q8 { x: point.x - previous.x, y: point.y - previous.y, z: point.z - previous.z, w: point.w - previous.w };
        p = step.scaled_add(jet[0], p);
        if derivatives {
            d = step.scaled_add(jet[1], d);
            e = step.scaled_add(jet[2], e);
        }
        previous = *point;
    }
    let s = p.dot(p);
    let q = p.scale(S::ONE / s.sqrt());
    if !derivatives {
        return (q, V8::ZERO, V8::ZERO);
    }
    let inv = S::ONE / s;
    let (spin, accel) = (p.conjugate_times(d), p.conjugate_times(e));
    let two_inv = S::splat(2.0) * inv;
    let drift = S::splat(2.0) * p.dot(d) * inv;
    (q, spin.scale(two_inv), accel.add(spin.scale(-drift)).scale(two_inv))
}

#[cfg(test)]
mod sin_cos_tests {
    use crate::cpu::simd::{sin_cos_small, SMALL_ANGLE};
    use wide::f32x8;

    #[test]
    fn small_sin_cos_is_accurate() {
        let mut worst = 0.0f64;
        for i in -20_000..=20_000 {
            let x = SMALL_ANGLE * i as f32 / 20_000.0;
            let (s, c) = sin_cos_small(f32x8::splat(x));
            let x = f64::from(x);
            worst = worst
                .max((f64::from(s.to_array()[0]) - x.sin()).abs())
                .max((f64::from(c.to_array()[0]) - x.cos()).abs());
        }
        assert!(worst < 2.5e-7, "worst error {worst:e}");
    }
}

#[cfg(test)]
mod axis_angle_tests {
    use super::{axis_angle, Factor8, LANES};
    use wide::f32x8;

    /// The eight-lane split of coefficients into axis and angle gives each lane the bits of
    /// the scalar one (shared groups broadcast the scalar one's): zero, tiny, ordinary and
    /// large vectors.
    #[test]
    fn lanes_split_coefficients_as_the_scalar_twin_does() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = |scale: f32| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * scale
        };
        for round in 0..500 {
            let scale = [0.0, 1e-30, 1e-6, 1.0, 3.0, 400.0][round % 6];
            let rows: [[f32; 4]; LANES] = std::array::from_fn(|_| [next(scale), next(scale), next(scale), next(1.0)]);
            let lanes = Factor8::<f32x8>::from_rows(&rows, [f32x8::ZERO; 3]);
            let (x, y, z, theta) =
                (lanes.axis.x.to_array(), lanes.axis.y.to_array(), lanes.axis.z.to_array(), lanes.theta.to_array());
            for (lane, row) in rows.iter().enumerate() {
                let got = [x[lane], y[lane], z[lane], theta[lane]].map(f32::to_bits);
                assert_eq!(got, axis_angle(*row).map(f32::to_bits), "{row:?}");
            }
        }
    }
}

#[cfg(test)]
mod transpose_tests {
    use super::write_columns;
    use wide::f32x8;

    #[test]
    fn columns_land_in_their_rows() {
        let v = [0.0, 1.0, 2.0, 3.0].map(|c: f32| f32x8::new(std::array::from_fn(|lane| 10.0 * lane as f32 + c)));
        let mut rows = vec![-1.0; 8 * 10];
        write_columns(v, &mut rows, 10, 4, 3, 7);
        for lane in 0..8 {
            for c in 0..10 {
                let want = if lane < 7 && (4..7).contains(&c) { 10.0 * lane as f32 + (c - 4) as f32 } else { -1.0 };
                assert_eq!(rows[lane * 10 + c], want, "row {lane} column {c}");
            }
        }
    }
}
