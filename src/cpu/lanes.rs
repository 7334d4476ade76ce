//! Eight samples at a time: structure-of-arrays quaternions and vectors on `wide::f32x8`
//! (AVX/AVX2 registers when the build targets them), and the KKS cumulative product with its
//! body derivatives, the twin of [`crate::reference::cumulative_product`].

use wide::f32x8;

/// Samples per SIMD group.
pub const LANES: usize = 8;

/// Eight 3-vectors.
#[derive(Clone, Copy, Debug)]
pub struct V8 {
    pub x: f32x8,
    pub y: f32x8,
    pub z: f32x8,
}

/// Eight quaternions `x, y, z, w`.
#[derive(Clone, Copy, Debug)]
pub struct Q8 {
    pub x: f32x8,
    pub y: f32x8,
    pub z: f32x8,
    pub w: f32x8,
}

impl V8 {
    /// All zero.
    pub const ZERO: Self = Self { x: f32x8::ZERO, y: f32x8::ZERO, z: f32x8::ZERO };

    /// Lane-wise gather from `[x, y, z, _]` rows.
    #[inline(always)]
    pub fn gather(rows: &[[f32; 4]; LANES]) -> Self {
        Self { x: f32x8::new(rows.map(|r| r[0])), y: f32x8::new(rows.map(|r| r[1])), z: f32x8::new(rows.map(|r| r[2])) }
    }

    /// The same `[x, y, z, _]` in every lane.
    #[inline(always)]
    pub fn splat(r: [f32; 4]) -> Self {
        Self { x: f32x8::splat(r[0]), y: f32x8::splat(r[1]), z: f32x8::splat(r[2]) }
    }

    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }

    #[inline(always)]
    fn scale(self, k: f32x8) -> Self {
        Self { x: self.x * k, y: self.y * k, z: self.z * k }
    }

    #[inline(always)]
    fn cross(self, o: Self) -> Self {
        Self { x: self.y * o.z - self.z * o.y, y: self.z * o.x - self.x * o.z, z: self.x * o.y - self.y * o.x }
    }
}

impl Q8 {
    /// Lane-wise gather from `[x, y, z, w]` rows.
    #[inline(always)]
    pub fn gather(rows: &[[f32; 4]; LANES]) -> Self {
        Self {
            x: f32x8::new(rows.map(|r| r[0])),
            y: f32x8::new(rows.map(|r| r[1])),
            z: f32x8::new(rows.map(|r| r[2])),
            w: f32x8::new(rows.map(|r| r[3])),
        }
    }

    /// The same `[x, y, z, w]` in every lane.
    #[inline(always)]
    pub fn splat(r: [f32; 4]) -> Self {
        Self { x: f32x8::splat(r[0]), y: f32x8::splat(r[1]), z: f32x8::splat(r[2]), w: f32x8::splat(r[3]) }
    }

    /// Hamilton product `self * o`.
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self {
            x: self.w * o.x + self.x * o.w + self.y * o.z - self.z * o.y,
            y: self.w * o.y - self.x * o.z + self.y * o.w + self.z * o.x,
            z: self.w * o.z + self.x * o.y - self.y * o.x + self.z * o.w,
            w: self.w * o.w - self.x * o.x - self.y * o.y - self.z * o.z,
        }
    }

    /// `self^-1 v self` for unit `self`: `v + 2 w (v x u) + 2 u x (u x v)` with `u = -vec`.
    #[inline(always)]
    fn rotate_inverse(self, v: V8) -> V8 {
        let u = V8 { x: -self.x, y: -self.y, z: -self.z };
        let t = u.cross(v).scale(f32x8::splat(2.0));
        v.add(t.scale(self.w)).add(u.cross(t))
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
pub fn sin_cos_small(x: f32x8) -> (f32x8, f32x8) {
    const S: [f32; 7] = [1.0, -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0, -1.0 / 39_916_800.0, 1.0 / 6_227_020_800.0];
    const C: [f32; 7] = [1.0, -0.5, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40_320.0, -1.0 / 3_628_800.0, 1.0 / 479_001_600.0];
    let x2 = x * x;
    let (mut s, mut c) = (f32x8::splat(S[6]), f32x8::splat(C[6]));
    for k in (0..6).rev() {
        s = s.mul_add(x2, f32x8::splat(S[k]));
        c = c.mul_add(x2, f32x8::splat(C[k]));
    }
    (s * x, c)
}

/// One factor `exp(v b(t))` of eight samples: `v = theta * axis` (half-angle vector, axis
/// unit or zero) and the basis jet `[b, b', b'']` in time units.
#[derive(Clone, Copy, Debug)]
pub struct Factor8 {
    pub axis: V8,
    pub theta: f32x8,
    pub b: [f32x8; 3],
}

/// `start * prod exp(v_j b_j)` and, with `derivatives`, the body angular velocity and
/// acceleration by DESIGN section 2's recursion (see the reference for the formulas).
/// `small`: every `|theta b|` is at most [`SMALL_ANGLE`], so [`sin_cos_small`] applies.
#[inline(always)]
pub fn cumulative_product(start: Q8, factors: &[Factor8], derivatives: bool, small: bool) -> (Q8, V8, V8) {
    let mut q = start;
    let (mut w, mut w_dot) = (V8::ZERO, V8::ZERO);
    for (i, f) in factors.iter().enumerate() {
        let angle = f.theta * f.b[0];
        let (sin, cos) = if small { sin_cos_small(angle) } else { angle.sin_cos() };
        let a = Q8 { x: f.axis.x * sin, y: f.axis.y * sin, z: f.axis.z * sin, w: cos };
        if derivatives {
            let spin = f.axis.scale(f.theta * f.b[1]);
            let accel = f.axis.scale(f.theta * f.b[2]);
            if i == 0 {
                // W and W' start at zero: nothing to carry through the first factor.
                (w, w_dot) = (spin, accel);
            } else {
                let carried = a.rotate_inverse(w);
                w_dot = a.rotate_inverse(w_dot).add(carried.cross(spin).scale(f32x8::splat(2.0))).add(accel);
                w = carried.add(spin);
            }
        }
        q = q.mul(a);
    }
    let two = f32x8::splat(2.0);
    (q, w.scale(two), w_dot.scale(two))
}

#[cfg(test)]
mod tests {
    use super::{sin_cos_small, SMALL_ANGLE};
    use wide::f32x8;

    #[test]
    fn small_sin_cos_is_accurate() {
        let mut worst = 0.0f64;
        for i in -20_000..=20_000 {
            let x = SMALL_ANGLE * i as f32 / 20_000.0;
            let (s, c) = sin_cos_small(f32x8::splat(x));
            let x = f64::from(x);
            worst = worst.max((f64::from(s.to_array()[0]) - x.sin()).abs()).max((f64::from(c.to_array()[0]) - x.cos()).abs());
        }
        assert!(worst < 2.5e-7, "worst error {worst:e}");
    }
}
