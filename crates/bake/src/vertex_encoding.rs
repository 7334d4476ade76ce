//! How a vertex texture stores skinned vertices (DESIGN section 8): positions remapped into
//! the mesh's animated bounding box (`0..1` per axis, the range a 16-bit PNG holds and where
//! half floats are densest near the box's far side), normals folded onto the octahedron and
//! unfolded to a square (`0..1` in two channels; Cigolle et al. 2014). Each has its decoder
//! here, the formula a shader applies.

use quatcurve_eval::output::VERTEX_CHANNELS;

/// The box skinned positions are remapped to: per axis the smallest and largest coordinate
/// over every vertex and frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Smallest coordinate per axis.
    pub low: [f64; 3],
    /// Largest coordinate per axis.
    pub high: [f64; 3],
}

impl Bounds {
    /// The box of every position in `vertices` (`[.., VERTEX_CHANNELS]`: position, normal).
    /// `None` when there is no vertex or a coordinate is not finite.
    #[must_use]
    pub fn of(vertices: &[f64]) -> Option<Self> {
        Self::of_positions(vertices.chunks_exact(VERTEX_CHANNELS).map(|v| [v[0], v[1], v[2]]))
    }

    /// The box of `positions`; `None` when there is none or a coordinate is not finite.
    #[must_use]
    pub fn of_positions(positions: impl IntoIterator<Item = [f64; 3]>) -> Option<Self> {
        let mut low = [f64::INFINITY; 3];
        let mut high = [f64::NEG_INFINITY; 3];
        for v in positions {
            for c in 0..3 {
                if !v[c].is_finite() {
                    return None;
                }
                low[c] = low[c].min(v[c]);
                high[c] = high[c].max(v[c]);
            }
        }
        (low[0] <= high[0]).then_some(Self { low, high })
    }

    /// Per axis what a texel's `0..1` spans (the sidecar's `span`, beside `low`): `high - low`,
    /// or 1 along an axis the mesh is flat in, so decoding is always `low + texel * span`.
    #[must_use]
    pub fn span(&self) -> [f64; 3] {
        std::array::from_fn(|c| if self.high[c] > self.low[c] { self.high[c] - self.low[c] } else { 1.0 })
    }

    /// The diagonal of the box, the length position errors are stated against.
    #[must_use]
    pub fn diagonal(&self) -> f64 {
        (0..3).map(|c| (self.high[c] - self.low[c]).powi(2)).sum::<f64>().sqrt()
    }

    /// `p` as `0..1` per axis.
    #[must_use]
    pub fn encode(&self, p: [f64; 3]) -> [f64; 3] {
        let span = self.span();
        std::array::from_fn(|c| (p[c] - self.low[c]) / span[c])
    }

    /// The position of an encoded texel: `low + texel * span`.
    #[must_use]
    pub fn decode(&self, texel: [f64; 3]) -> [f64; 3] {
        let span = self.span();
        std::array::from_fn(|c| self.low[c] + texel[c] * span[c])
    }
}

/// A unit normal folded onto the octahedron `|x| + |y| + |z| = 1`, the lower half folded over
/// the upper, as two values in `0..1`. A zero normal (a mesh without normals) encodes as the
/// square's centre, which decodes to `+z`.
#[must_use]
pub fn encode_normal(n: [f64; 3]) -> [f64; 2] {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    if l1 == 0.0 {
        return [0.5, 0.5];
    }
    let (x, y, z) = (n[0] / l1, n[1] / l1, n[2] / l1);
    let sign = |v: f64| if v < 0.0 { -1.0 } else { 1.0 };
    let (u, v) = if z >= 0.0 { (x, y) } else { ((1.0 - y.abs()) * sign(x), (1.0 - x.abs()) * sign(y)) };
    [0.5 * u + 0.5, 0.5 * v + 0.5]
}

/// The unit normal of two `0..1` values: [`encode_normal`] undone.
#[must_use]
pub fn decode_normal(texel: [f64; 2]) -> [f64; 3] {
    let (u, v) = (2.0 * texel[0] - 1.0, 2.0 * texel[1] - 1.0);
    let z = 1.0 - u.abs() - v.abs();
    let fold = (-z).max(0.0);
    let x = u + if u >= 0.0 { -fold } else { fold };
    let y = v + if v >= 0.0 { -fold } else { fold };
    let length = (x * x + y * y + z * z).sqrt();
    [x / length, y / length, z / length]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unit normals over the sphere: a Fibonacci lattice, the axes and the folds' edges.
    fn normals() -> Vec<[f64; 3]> {
        let mut out: Vec<[f64; 3]> = (0..20_000)
            .map(|i| {
                let z = 1.0 - 2.0 * (f64::from(i) + 0.5) / 20_000.0;
                let r = (1.0 - z * z).sqrt();
                let a = f64::from(i) * 2.399_963_229_728_653;
                [r * a.cos(), r * a.sin(), z]
            })
            .collect();
        let h = std::f64::consts::FRAC_1_SQRT_2;
        for s in [1.0, -1.0] {
            out.extend([[s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s]]);
            out.extend([[s * 0.6, 0.8, 0.0], [0.8, s * 0.6, 0.0], [s * h, 0.0, -h], [0.0, s * h, -h]]);
        }
        out
    }

    fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
        let dot: f64 = (0..3).map(|c| a[c] * b[c]).sum();
        let cross = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
        (cross.iter().map(|c| c * c).sum::<f64>().sqrt()).atan2(dot)
    }

    /// The worst angle after the two values are stored with `store` (a rounding to a format).
    fn worst_normal(store: impl Fn(f64) -> f64) -> f64 {
        normals().into_iter().map(|n| angle(n, decode_normal(encode_normal(n).map(&store)))).fold(0.0, f64::max)
    }

    #[test]
    fn normals_survive_each_format_within_its_stated_angle() {
        let exact = worst_normal(|v| v);
        assert!(exact < 1e-14, "{exact}");
        // f32 (EXR float): 3e-7 rad; 16-bit unorm (PNG16): 1e-4 rad; half (EXR half): 2e-3 rad.
        let f32_worst = worst_normal(|v| f64::from(v as f32));
        let png16 = worst_normal(|v| (v * 65535.0).round() / 65535.0);
        let half = worst_normal(|v| f64::from(half::f16::from_f64(v)));
        assert!(f32_worst < 3e-7, "f32 {f32_worst}");
        eprintln!("worst normal angle: f32 {f32_worst:e}, png16 {png16:e}, half {half:e}");
        assert!(png16 < 1e-4, "png16 {png16}");
        assert!(half < 2e-3, "half {half}");
        // Every encoding lies in the square a texture holds.
        for n in normals() {
            assert!(encode_normal(n).iter().all(|v| (0.0..=1.0).contains(v)), "{n:?}");
        }
        assert_eq!(decode_normal(encode_normal([0.0; 3])), [0.0, 0.0, 1.0]);
    }

    #[test]
    fn positions_decode_to_themselves_within_the_box() {
        let vertices: Vec<f64> = (0..500)
            .flat_map(|i| {
                let t = f64::from(i);
                [3.0 + (0.37 * t).sin(), -2.0 + 0.5 * (0.11 * t).cos(), 7.25, 0.0, 0.0, 1.0]
            })
            .collect();
        let bounds = Bounds::of(&vertices).unwrap();
        let span = bounds.span();
        assert_eq!(span[2], 1.0, "a flat axis keeps a unit span");
        let diagonal = bounds.diagonal();
        assert!((diagonal - (span[0].powi(2) + span[1].powi(2)).sqrt()).abs() < 1e-15);
        let mut worst: [f64; 3] = [0.0; 3];
        for v in vertices.chunks_exact(VERTEX_CHANNELS) {
            let p = [v[0], v[1], v[2]];
            let texel = bounds.encode(p);
            assert!(texel.iter().all(|c| (0.0..=1.0).contains(c)), "{texel:?}");
            for (w, store) in worst.iter_mut().zip([
                |v: f64| f64::from(v as f32),
                |v: f64| (v * 65535.0).round() / 65535.0,
                |v: f64| f64::from(half::f16::from_f64(v)),
            ]) {
                let back = bounds.decode(texel.map(store));
                let error = (0..3).map(|c| (back[c] - p[c]).powi(2)).sum::<f64>().sqrt() / diagonal;
                *w = w.max(error);
            }
        }
        // Stated precision, as a fraction of the box's diagonal: f32 1e-7, PNG16 1e-5, half 5e-4.
        eprintln!("worst position error / diagonal: f32, png16, half {worst:?}");
        assert!(worst[0] < 1e-7 && worst[1] < 1e-5 && worst[2] < 5e-4, "{worst:?}");
        assert!(Bounds::of(&[]).is_none());
        assert!(Bounds::of(&[f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0]).is_none());
    }
}
