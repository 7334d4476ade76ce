//! Shared generators and oracles for the reference tests.

use quatcurve::synthetic::SplitMix;
use quatcurve::{Batch, CurveSpec, QuatF64, Sample, Track, Vec3F64};

/// The crate's SplitMix64 ([`SplitMix`]) with the shapes the tests draw from, so each
/// proptest case is one `u64` seed and adversarial track shapes are plain functions.
pub struct Gen(SplitMix);

impl Gen {
    pub fn new(seed: u64) -> Self {
        Self(SplitMix::new(seed))
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        self.0.unit()
    }
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.unit()
    }
    pub fn direction(&mut self) -> Vec3F64 {
        loop {
            let v = Vec3F64::new(self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0));
            let len = v.length();
            if len > 0.1 && len <= 1.0 {
                return v.scale(1.0 / len);
            }
        }
    }
    pub fn rotation(&mut self) -> QuatF64 {
        let d = self.direction();
        QuatF64::exp(d.scale(self.range(0.0, std::f64::consts::PI)))
    }
    pub fn coin(&mut self) -> bool {
        self.next_u64() & 1 == 1
    }
}

/// How consecutive keys relate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// Steps of 0 to 140 degrees about random axes.
    Random,
    /// Steps of 1e-9 to 1e-6 rad.
    NearIdentical,
    /// Steps of 170 to 179.9 degrees.
    NearAntipodal,
    /// Random steps, each key given with a random sign.
    SignFlipped,
}

pub const KINDS: [Kind; 4] = [Kind::Random, Kind::NearIdentical, Kind::NearAntipodal, Kind::SignFlipped];

/// `count` keys whose consecutive physical rotation steps follow `kind`.
pub fn keys(g: &mut Gen, count: usize, kind: Kind) -> Vec<[f64; 4]> {
    keys_scaled(g, count, kind, 1.0)
}

/// [`keys`] with every step's angle times `scale`.
pub fn keys_scaled(g: &mut Gen, count: usize, kind: Kind, scale: f64) -> Vec<[f64; 4]> {
    let mut q = g.rotation();
    let mut out = vec![q.to_array()];
    for _ in 1..count {
        let angle = match kind {
            Kind::Random | Kind::SignFlipped => g.range(0.0, 140f64.to_radians()),
            Kind::NearIdentical => 10f64.powf(g.range(-9.0, -6.0)),
            Kind::NearAntipodal => g.range(170f64.to_radians(), 179.9f64.to_radians()),
        } * scale;
        q = q * QuatF64::exp(g.direction().scale(angle / 2.0));
        let sign = if kind == Kind::SignFlipped && g.coin() { -1.0 } else { 1.0 };
        out.push(q.mul_scalar(sign).to_array());
    }
    if kind == Kind::SignFlipped && g.coin() {
        out[0] = QuatF64::from_array(out[0]).mul_scalar(-1.0).to_array();
    }
    out
}

/// Strictly increasing key times: uniform steps or random ones in [0.2, 1.5].
pub fn times(g: &mut Gen, count: usize, uniform: bool) -> Vec<f64> {
    let start = g.range(-1.0, 1.0);
    let dt = g.range(0.2, 1.5);
    let mut t = start;
    (0..count)
        .map(|i| {
            if i > 0 {
                t += if uniform { dt } else { g.range(0.2, 1.5) };
            }
            if uniform {
                start + dt * i as f64
            } else {
                t
            }
        })
        .collect()
}

/// Body angular velocities with magnitude up to `max` rad/s.
pub fn velocities(g: &mut Gen, count: usize, max: f64) -> Vec<[f64; 3]> {
    (0..count).map(|_| g.direction().scale(g.range(0.0, max)).to_array()).collect()
}

/// A random track for `spec`: key count within the curve's needs, times uniform where the
/// knot mode needs them, velocities up to 20 rad/s, explicit knots with repeats when asked. A
/// normalized B-spline's steps are `kind`'s over `k - 1`, so that a span's control points
/// (phantom points too) keep within its rule's half turn: near-antipodal steps reach its limit.
pub fn track(g: &mut Gen, spec: &CurveSpec, count: usize, kind: Kind) -> Track {
    use quatcurve::{Curve, KnotMode};
    let bspline = matches!(spec.curve, Curve::BSpline | Curve::NormalizedBSpline);
    let uniform = bspline && matches!(spec.knots, KnotMode::Phantom | KnotMode::Uniform);
    let times = times(g, count, uniform);
    let knots = (bspline && spec.knots == KnotMode::Explicit).then(|| explicit_knots(g, spec.order, count));
    let scale = if spec.curve == Curve::NormalizedBSpline { 1.0 / (spec.order - 1) as f64 } else { 1.0 };
    Track {
        name: Some(format!("{kind:?}")),
        times: Some(times),
        rotations: keys_scaled(g, count, kind, scale),
        angular_velocities: Some(velocities(g, count, 20.0)),
        knots,
        extra_turns: None,
        sample_times: None,
    }
}

/// A valid explicit knot vector for `count` control points of order `k`, with some interior
/// knots repeated (multiplicity up to k - 1) and clamped or open ends at random.
pub fn explicit_knots(g: &mut Gen, k: usize, count: usize) -> Vec<f64> {
    let len = count + k;
    let mut knots = Vec::with_capacity(len);
    let mut t = g.range(-1.0, 1.0);
    let clamp = g.coin();
    while knots.len() < len {
        let interior = knots.len() >= k && knots.len() < count;
        let run = if clamp && (knots.is_empty() || knots.len() + k >= len) {
            k.min(len - knots.len())
        } else if interior && g.range(0.0, 1.0) < 0.3 {
            (1 + (g.next_u64() % (k as u64 - 1)) as usize).min(len - knots.len())
        } else {
            1
        };
        for _ in 0..run {
            knots.push(t);
        }
        t += g.range(0.2, 1.2);
    }
    knots
}

/// Times strictly inside each segment `[b_j, b_{j+1}]` of `bounds` (non-empty ones only),
/// at fractions away from the ends so finite-difference stencils stay inside, and away from
/// the middle, where Nam-Kim's quadratic blend is only C1 by construction.
pub fn interior_times(bounds: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    for w in bounds.windows(2) {
        if w[1] > w[0] {
            for f in [0.07, 0.31, 0.45, 0.55, 0.77, 0.93] {
                out.push(w[0] + f * (w[1] - w[0]));
            }
        }
    }
    out
}

/// The segment boundaries inside a track's domain: key times, or distinct knots in the domain.
pub fn segment_bounds(batch: &Batch, index: usize) -> Vec<f64> {
    let view = batch.view(index);
    let [lo, hi] = view.track.domain();
    let mut b: Vec<f64> = view.knots.iter().copied().filter(|&t| t >= lo && t <= hi).collect();
    b.dedup();
    b
}

/// Body angular velocity and acceleration of `curve` at `t` from finite differences of the
/// quaternion (stencil aligned with q(t)): five-point central differences at `h` and `h/2`
/// combined by Richardson extrapolation (error O(h^6)), then `W = q^-1 q'`,
/// `W' = q^-1 q'' - W^2`.
pub fn finite_difference(curve: impl Fn(f64) -> QuatF64, t: f64, h: f64) -> (Vec3F64, Vec3F64) {
    let q0 = curve(t);
    let at = |dt: f64| curve(t + dt).aligned_with(q0);
    let stencil = |h: f64| {
        let (m2, m1, p1, p2) = (at(-2.0 * h), at(-h), at(h), at(2.0 * h));
        let d1 = (m2 - p2 + (p1 - m1).mul_scalar(8.0)).mul_scalar(1.0 / (12.0 * h));
        let d2 = ((p1 + m1).mul_scalar(16.0) - (p2 + m2) - q0.mul_scalar(30.0)).mul_scalar(1.0 / (12.0 * h * h));
        (d1, d2)
    };
    let ((a1, a2), (b1, b2)) = (stencil(h), stencil(h / 2.0));
    let richardson = |coarse: QuatF64, fine: QuatF64| (fine.mul_scalar(16.0) - coarse).mul_scalar(1.0 / 15.0);
    let (d1, d2) = (richardson(a1, b1), richardson(a2, b2));
    let w = q0.conjugate() * d1;
    let w_dot = q0.conjugate() * d2 - w * w;
    (w.vec().scale(2.0), w_dot.vec().scale(2.0))
}

/// Derivative of a vector function by Richardson-extrapolated five-point central differences.
pub fn derivative(f: impl Fn(f64) -> Vec3F64, t: f64, h: f64) -> Vec3F64 {
    let stencil = |h: f64| (f(t - 2.0 * h) - f(t + 2.0 * h) + (f(t + h) - f(t - h)).scale(8.0)).scale(1.0 / (12.0 * h));
    (stencil(h / 2.0).scale(16.0) - stencil(h)).scale(1.0 / 15.0)
}

/// DESIGN section 18 relative error: `max|a - b| / max(1, max|b|)`.
pub fn rel_err(a: Vec3F64, b: Vec3F64) -> f64 {
    (a - b).max_abs() / b.max_abs().max(1.0)
}

/// Evaluates track `index` of `batch` at `t`.
pub fn eval(batch: &Batch, index: usize, t: f64) -> Sample {
    quatcurve::evaluate(batch.view(index), t)
}

/// Every curve spec the reference supports: all families, tangent sources, blends, and
/// B-spline orders 2..=8 with every knot mode (the normalized form's orders on explicit knots).
pub fn all_specs() -> Vec<CurveSpec> {
    use quatcurve::{Blend, Curve, KnotMode, Tangents};
    let mut specs = vec![CurveSpec::new(Curve::Slerp), CurveSpec::new(Curve::Squad), CurveSpec::new(Curve::Bezier)];
    for tangents in [Tangents::CatmullRom, Tangents::Zero, Tangents::Given] {
        specs.push(CurveSpec { tangents, ..CurveSpec::new(Curve::Hermite) });
        for blend in [Blend::Cubic, Blend::Quadratic] {
            specs.push(CurveSpec { tangents, blend, ..CurveSpec::new(Curve::NamKim) });
        }
    }
    specs.push(CurveSpec::new(Curve::BSpline));
    for order in 2..=8 {
        for knots in [KnotMode::Uniform, KnotMode::Clamped, KnotMode::Explicit] {
            specs.push(CurveSpec { order, knots, ..CurveSpec::new(Curve::BSpline) });
        }
    }
    // The normalized form on each knot mode, and its orders on explicit knots.
    specs.push(CurveSpec::new(Curve::NormalizedBSpline));
    for knots in [KnotMode::Uniform, KnotMode::Clamped] {
        specs.push(CurveSpec { knots, ..CurveSpec::new(Curve::NormalizedBSpline) });
    }
    for order in 2..=8 {
        specs.push(CurveSpec { order, knots: KnotMode::Explicit, ..CurveSpec::new(Curve::NormalizedBSpline) });
    }
    specs
}

/// A readable name for a spec in failure messages.
pub fn describe(spec: &CurveSpec) -> String {
    format!("{} k={} knots={} tangents={} blend={}", spec.curve, spec.order, spec.knots, spec.tangents, spec.blend)
}

/// A `.npy` file's bytes: version 1.0 header for `descr` and `shape`, then `data` as is.
pub fn npy_bytes(descr: &str, shape: &[u64], data: &[u8]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(u64::to_string).collect();
    let shape = if dims.len() == 1 { format!("({},)", dims[0]) } else { format!("({})", dims.join(", ")) };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((header.len() as u16).to_le_bytes());
    out.extend(header.as_bytes());
    out.extend(data);
    out
}

/// Little-endian f64 bytes, as a `<f8` array stores them.
pub fn f64_bytes(values: &[f64]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// A `.npz` (zip of `.npy` members, deflated as numpy's savez_compressed does).
pub fn npz_bytes(members: &[(&str, Vec<u8>)]) -> Vec<u8> {
    use std::io::Write;
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    for (name, bytes) in members {
        zip.start_file(
            format!("{name}.npy"),
            zip::write::FileOptions::default().compression_method(zip::CompressionMethod::Deflated),
        )
        .unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap().into_inner()
}

/// [`npz_bytes`] written to `path`.
pub fn write_npz(path: &std::path::Path, members: &[(&str, Vec<u8>)]) {
    std::fs::write(path, npz_bytes(members)).unwrap();
}
