//! One piece of one vectorized track: per-lane span lookup, the basis, the SIMD cumulative
//! product and the rows' columns, eight samples at a time.

use super::bases::{bernstein_cumulative_lanes, Bases, Basis};
use super::cox_de_boor::CoxDeBoor;
use super::lanes::{axis_angle, cumulative_product, normalized_sum, write_columns, AngleRange, Factor8, LANES, Q8, V8};
use super::simd::{Isa, Lanes, SMALL_ANGLE};
use crate::batch::{Batch, PackedTrack, TrackView};
use crate::job::JobOptions;
use crate::output::Row;
use crate::sampling::{SampleTimes, TrackTimes};
use quatcurve_core::curve::Curve;
use quatcurve_core::segment::locate;

/// What every piece of one evaluation shares: the evaluator's bases and lane type, and the
/// batch, whose f64 points and coefficients the kernels convert to f32 where they read them.
/// No batch-wide f32 copy: for a million short tracks it doubled the batch's memory and its
/// conversion took as long as the evaluation.
pub struct Shared<'a> {
    /// The lane type the kernels run.
    pub(super) isa: Isa,
    pub(super) bases: &'a Bases,
    batch: &'a Batch,
}

impl<'a> Shared<'a> {
    /// The context of evaluating `batch` with `bases` on `isa`.
    pub fn new(batch: &'a Batch, bases: &'a Bases, isa: Isa) -> Self {
        Self { isa, bases, batch }
    }

    /// Point `i` `[x, y, z, w]` in f32.
    #[inline(always)]
    fn point(&self, i: usize) -> [f32; 4] {
        self.batch.points()[i].to_array().map(|v| v as f32)
    }

    /// Coefficient `c` as stored, `[x, y, z, w]`, in f32.
    #[inline(always)]
    fn coef(&self, c: usize) -> [f32; 4] {
        self.batch.coefs()[c].map(|v| v as f32)
    }
}

/// A segment's first point and its `F` coefficients (a normalized B-spline's: its next `F`
/// control points), in f32 ([`Segments::rows`]).
pub(super) type Rows<const F: usize> = ([f32; 4], [[f32; 4]; F]);

/// Where one track's segments lie in the batch: segment `span` starts at point
/// `point + span - shift`, and its factors are the coefficients from
/// `coef + stride * span - shift` on (a B-spline's span `k - 1` is its first segment).
#[derive(Clone, Copy, Debug)]
pub(super) struct Segments {
    point: usize,
    coef: usize,
    stride: usize,
    shift: usize,
    /// A Hermite segment's start takes the sign its middle coefficient's `w` keeps.
    hermite: bool,
    /// A normalized B-spline: no coefficients; its rows are the span's control points.
    pub(super) normalized: bool,
}

impl Segments {
    /// The segments of `track`.
    pub(super) fn of(track: &PackedTrack) -> Self {
        let (point, coef) = (track.point_offset(), track.coef_offset());
        match track.curve() {
            Curve::Slerp => Self { point, coef, stride: 1, shift: 0, hermite: false, normalized: false },
            Curve::Bezier => Self { point, coef, stride: 0, shift: 0, hermite: false, normalized: false },
            Curve::Hermite => Self { point, coef, stride: 3, shift: 0, hermite: true, normalized: false },
            curve => Self {
                point,
                coef,
                stride: 1,
                shift: track.order() - 1,
                hermite: false,
                normalized: curve == Curve::NormalizedBSpline,
            },
        }
    }

    /// Segment `span`'s first point (sign-aligned for Hermite) and its `F` coefficients, in
    /// f32 as stored: loads and conversions only, per lane; axes and angles come later,
    /// eight lanes at once ([`Factor8::from_rows`]).
    #[inline(always)]
    pub(super) fn rows<const F: usize>(self, shared: &Shared<'_>, span: usize) -> Rows<F> {
        let first = self.point + span - self.shift;
        if self.normalized {
            let mut points = [[0.0f32; 4]; F];
            for (f, row) in points.iter_mut().enumerate() {
                *row = shared.point(first + 1 + f);
            }
            return (shared.point(first), points);
        }
        let coef = self.coef + self.stride * span - self.shift;
        let mut start = shared.point(first);
        if self.hermite {
            let sign = shared.batch.coefs()[coef + 1][3] as f32;
            start = start.map(|v| v * sign);
        }
        // Loops, not `array::from_fn`, here and below: its closures do not inherit the AVX2
        // entry point's target features, so they stay calls.
        let mut coefs = [[0.0f32; 4]; F];
        for (f, row) in coefs.iter_mut().enumerate() {
            *row = shared.coef(coef + f);
        }
        (start, coefs)
    }

    /// Segment `span` as the shared groups broadcast it: its rows, with each factor's axis
    /// and angle by [`axis_angle`] (the same bits [`LaneRows::factors`] gives a lane); a
    /// normalized B-spline's points as read.
    #[inline(always)]
    fn broadcast<const F: usize>(self, shared: &Shared<'_>, span: usize) -> Segment<F> {
        let (start, rows) = self.rows::<F>(shared, span);
        Segment { span, start, rows: if self.normalized { rows } else { rows.map(axis_angle) } }
    }
}

/// One group's lanes as read, before any SIMD: each lane's time and span knots, and its
/// segment's rows ([`Segments::rows`]). Lanes a group leaves unset keep finite values.
pub(super) struct LaneRows<const F: usize> {
    t: [f64; LANES],
    k0: [f64; LANES],
    k1: [f64; LANES],
    starts: [[f32; 4]; LANES],
    /// Factor-major, so that each factor's eight rows are one [`Factor8::from_rows`].
    coefs: [[[f32; 4]; LANES]; F],
}

impl<const F: usize> LaneRows<F> {
    /// Zero rows on unit spans.
    pub(super) fn new() -> Self {
        Self {
            t: [0.0; LANES],
            k0: [0.0; LANES],
            k1: [1.0; LANES],
            starts: [[0.0; 4]; LANES],
            coefs: [[[0.0; 4]; LANES]; F],
        }
    }

    /// Lane `lane`: time `t` in the span `[k0, k1)` whose rows are `rows`.
    #[inline(always)]
    pub(super) fn set(&mut self, lane: usize, t: f64, [k0, k1]: [f64; 2], (start, coefs): Rows<F>) {
        (self.t[lane], self.k0[lane], self.k1[lane], self.starts[lane]) = (t, k0, k1, start);
        for (f, coef) in coefs.into_iter().enumerate() {
            self.coefs[f][lane] = coef;
        }
    }

    /// Each lane's span parameter `u` and inverse span length (for derivatives in time), as
    /// the shared groups compute them.
    #[inline(always)]
    pub(super) fn params<S: Lanes>(&self) -> (S, S) {
        let (mut u, mut inv) = ([0.0f32; LANES], [0.0f32; LANES]);
        for lane in 0..LANES {
            let inv_len = 1.0 / (self.k1[lane] - self.k0[lane]);
            u[lane] = ((self.t[lane] - self.k0[lane]) * inv_len) as f32;
            inv[lane] = inv_len as f32;
        }
        (S::new(u), S::new(inv))
    }

    /// The lanes' first points.
    #[inline(always)]
    pub(super) fn start<S: Lanes>(&self) -> Q8<S> {
        let [x, y, z, w] = S::from_rows(&self.starts);
        Q8 { x, y, z, w }
    }

    /// The lanes' rows as points: a normalized B-spline's control points after the first.
    #[inline(always)]
    pub(super) fn points<S: Lanes>(&self) -> [Q8<S>; F] {
        let mut points = [Q8::ZERO; F];
        for (f, point) in points.iter_mut().enumerate() {
            let [x, y, z, w] = S::from_rows(&self.coefs[f]);
            *point = Q8 { x, y, z, w };
        }
        points
    }

    /// The lanes' factors, with basis jets `jets`.
    #[inline(always)]
    pub(super) fn factors<S: Lanes>(&self, jets: &[[S; 3]; F]) -> [Factor8<S>; F] {
        let mut factors = [Factor8 { axis: V8::ZERO, theta: S::ZERO, b: [S::ZERO; 3] }; F];
        for (f, factor) in factors.iter_mut().enumerate() {
            *factor = Factor8::from_rows(&self.coefs[f], jets[f]);
        }
        factors
    }
}

/// The spans a vectorized track's domain covers, first and last: its key segments (slerp,
/// Hermite), a B-spline's spans from `k - 1` to its last control point, a Bezier curve's one.
pub(super) fn spans(view: TrackView<'_>) -> (usize, usize) {
    match view.track.curve() {
        Curve::Slerp | Curve::Hermite => (0, view.knots.len() - 2),
        Curve::BSpline | Curve::NormalizedBSpline | Curve::BSplineInterp => {
            (view.track.order() - 1, view.points.len() - 1)
        }
        _ => (0, 0),
    }
}

/// The inverse mean knot spacing of `view`'s spans for span lookup by arithmetic first
/// ([`quatcurve_core::segment::arithmetic_span_step`]), else 0.
pub(super) fn inv_step(view: TrackView<'_>) -> f64 {
    let (first, last) = spans(view);
    if last + 1 >= view.knots.len() {
        return 0.0;
    }
    quatcurve_core::segment::arithmetic_span_step(&view.knots[first..=last + 1])
}

/// Spans [`locate_from`] steps through before it searches.
const SCAN_AHEAD: usize = 4;

/// `locate`, first trying the previous span and the next few (sample times usually increase);
/// on about equally spaced knots (`inv_step` their inverse mean spacing, else 0) by
/// arithmetic, else by bisection. Short tracks land on a new span at almost every sample.
#[inline(always)]
pub(super) fn locate_from(
    hint: &mut usize,
    knots: &[f64],
    first: usize,
    last: usize,
    t: f64,
    inv_step: f64,
) -> (usize, f64) {
    let h = *hint;
    if h >= first && h <= last && knots[h] <= t && t < knots[h + 1] {
        return (h, t);
    }
    // Or one of the next few: on a knot every frame, a sample that rounding put just before
    // a knot is followed by one two spans on.
    if h >= first && knots[h] <= t {
        let mut h = h;
        for _ in 0..SCAN_AHEAD {
            h += 1;
            if h > last {
                break;
            }
            if t < knots[h + 1] {
                *hint = h;
                return (h, t);
            }
        }
    }
    let (span, t) =
        if inv_step > 0.0 { locate_uniform(knots, first, last, t, inv_step) } else { locate(knots, first, last, t) };
    *hint = span;
    (span, t)
}

/// [`locate`] on about equally spaced knots ([`quatcurve_core::segment::locate_uniform`]),
/// its domain read from the knots.
#[inline(always)]
pub(super) fn locate_uniform(knots: &[f64], first: usize, last: usize, t: f64, inv_step: f64) -> (usize, f64) {
    quatcurve_core::segment::locate_uniform(knots, first, last, [knots[first], knots[last + 1]], t, inv_step)
}

/// One segment's data as the kernels read it ([`Segments::broadcast`]).
#[derive(Clone, Copy)]
struct Segment<const F: usize> {
    span: usize,
    start: [f32; 4],
    /// `[axis x, axis y, axis z, theta]` of each factor; a normalized B-spline's next `F`
    /// control points.
    rows: [[f32; 4]; F],
}

/// One piece of a vectorized track, and what it needs.
pub(super) struct Piece<'a> {
    pub(super) shared: &'a Shared<'a>,
    pub(super) view: TrackView<'a>,
    pub(super) times: &'a SampleTimes,
    pub(super) index: usize,
    /// First sample of the piece.
    pub(super) from: usize,
    pub(super) options: &'a JobOptions,
    pub(super) basis: Basis<'a>,
    /// Factors per sample.
    pub(super) factors: usize,
    /// Spans the domain covers.
    pub(super) first: usize,
    pub(super) last: usize,
}

impl Piece<'_> {
    /// Evaluates the piece's `n` samples into `out`, on the kernel instance for its factor
    /// count, derivatives and angle range.
    pub(super) fn evaluate(&self, n: usize, out: &mut [f32]) {
        // Every basis here stays within [0, 1] on the domain, so every angle is at most its
        // coefficient's: shortest-path keys (all of them below pi / 2) need no range reduction.
        // Squared, without a square root per coefficient (a cost that short tracks felt).
        let limit = f64::from(SMALL_ANGLE * 0.99);
        let small = self.view.coefs.iter().all(|c| c[0] * c[0] + c[1] * c[1] + c[2] * c[2] <= limit * limit);
        // Constant factor counts and flags let the compiler unroll the basis and the product,
        // keep them in registers and drop the branches.
        macro_rules! by_factors {
            ($d:literal, $s:literal) => {
                match self.factors {
                    1 => self.run::<1, $d, $s>(n, out),
                    2 => self.run::<2, $d, $s>(n, out),
                    3 => self.run::<3, $d, $s>(n, out),
                    4 => self.run::<4, $d, $s>(n, out),
                    5 => self.run::<5, $d, $s>(n, out),
                    6 => self.run::<6, $d, $s>(n, out),
                    _ => self.run::<7, $d, $s>(n, out),
                }
            };
        }
        match (self.options.derivatives, small) {
            (false, true) => by_factors!(false, true),
            (false, false) => by_factors!(false, false),
            (true, true) => by_factors!(true, true),
            (true, false) => by_factors!(true, false),
        }
    }

    /// [`Piece::groups`] on the evaluator's lane type.
    fn run<const F: usize, const DERIVATIVES: bool, const SMALL: bool>(&self, n: usize, out: &mut [f32]) {
        match self.shared.isa {
            // SAFETY: `Isa::Avx2` is only chosen where the CPU has AVX2 and FMA.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { groups_avx2::<F, DERIVATIVES, SMALL>(self, n, out) },
            _ => self.groups::<F, DERIVATIVES, SMALL, wide::f32x8>(n, out),
        }
    }

    /// Evaluates the piece's `n` samples, `F` factors each, eight at a time on lanes `S`;
    /// `SMALL`: every angle is within [`SMALL_ANGLE`]. Inlined into [`Piece::run`]'s
    /// instances, so that the AVX2 one compiles for AVX2. It stays one loop of about 90 lines
    /// on purpose: the state carried from group to group (span hint, shared segment, Cox-de
    /// Boor constants, the lanes of the last unshared group) lives in registers and on this
    /// frame; the steps that carry none are inline helpers below.
    #[inline(always)]
    fn groups<const F: usize, const DERIVATIVES: bool, const SMALL: bool, S: Lanes>(&self, n: usize, out: &mut [f32]) {
        let (knots, options) = (self.view.knots, self.options);
        let channels = options.row().channels();
        let (first, last) = (self.first, self.last);
        let mut hint = first;
        let inv_step = inv_step(self.view);
        let segments = Segments::of(self.view.track);
        let mut jets = [[S::ZERO; 3]; F];
        // `start + j step` for samples `j < plain` (as `SampleTimes::time`): the final sample
        // of a `--samples` grid is the exact domain end instead.
        let uniform = match self.times.tracks()[self.index] {
            TrackTimes::Uniform { start, step, count, last } => {
                Some((start, step, if last.is_some() { count - 1 } else { count }))
            }
            TrackTimes::Explicit { .. } => None,
        };
        // The knot constants of the last group's spans.
        let mut cox_de_boor = CoxDeBoor::new(F + 1);
        // The segment the last shared group was on, and its `start * (axis_0, 0)`.
        let mut shared_segment: Option<(Segment<F>, [f32; 4])> = None;
        // The lanes of a group that is not shared (kept across groups, so that they are not
        // cleared per group).
        let mut lanes = LaneRows::<F>::new();
        for g in (0..n).step_by(LANES) {
            let valid = LANES.min(n - g);
            let mut t = self.group_times(uniform, self.from + g, valid);
            let mut spans = [hint; LANES];
            // Usually all eight samples lie in the span of the previous group: one lookup, one
            // division, and the segment's data broadcast instead of gathered.
            let h = hint;
            let shared = h >= first && h <= last && {
                let (k0, k1) = (knots[h], knots[h + 1]);
                t.iter().fold(true, |inside, &t| inside & (k0 <= t) & (t < k1))
            };
            let (u, inv) = if shared {
                let inv_len = 1.0 / (knots[h + 1] - knots[h]);
                let mut u = [0.0f32; LANES];
                for (u, t) in u.iter_mut().zip(&t) {
                    *u = ((t - knots[h]) * inv_len) as f32;
                }
                if shared_segment.as_ref().map(|s| s.0.span) != Some(h) {
                    let segment = segments.broadcast::<F>(self.shared, h);
                    shared_segment = Some((segment, times_axis(segment.start, segment.rows[0])));
                }
                (S::new(u), S::splat(inv_len as f32))
            } else {
                // Neighbouring lanes mostly share a span: its rows are read once.
                let mut read: Option<(usize, Rows<F>)> = None;
                for lane in 0..LANES {
                    let (span, tl) = locate_from(&mut hint, knots, first, last, t[lane], inv_step);
                    (spans[lane], t[lane]) = (span, tl);
                    let rows = match read {
                        Some((s, rows)) if s == span => rows,
                        _ => read.insert((span, segments.rows::<F>(self.shared, span))).1,
                    };
                    lanes.set(lane, tl, [knots[span], knots[span + 1]], rows);
                }
                // Cox-de Boor takes the times themselves.
                if matches!(self.basis, Basis::CoxDeBoor) {
                    (S::ZERO, S::ZERO)
                } else {
                    lanes.params::<S>()
                }
            };
            match self.basis {
                Basis::Poly(poly) => poly.eval::<S, F>(u, DERIVATIVES, &mut jets),
                Basis::Bernstein => bernstein_cumulative_lanes::<S, F>(u, &mut jets),
                Basis::CoxDeBoor => cox_de_boor.jets::<S, F, DERIVATIVES>(knots, &spans, &t, &mut jets),
            }
            // The span-parameter bases have derivatives in u; Cox-de Boor's are in time.
            if DERIVATIVES && !matches!(self.basis, Basis::CoxDeBoor) {
                for jet in &mut jets {
                    jet[1] = jet[1] * inv;
                    jet[2] = jet[2] * (inv * inv);
                }
            }
            let segment = shared_segment.as_ref().filter(|_| shared);
            let (q, w, a) = if segments.normalized {
                let (first, rest) = match segment {
                    Some((segment, _)) => (Q8::splat(segment.start), segment.rows.map(Q8::splat)),
                    None => (lanes.start(), lanes.points()),
                };
                normalized_sum(first, &rest, &jets, DERIVATIVES)
            } else {
                let (start, lead, factors) = match segment {
                    Some((segment, lead)) => {
                        let mut factors = [Factor8 { axis: V8::ZERO, theta: S::ZERO, b: [S::ZERO; 3] }; F];
                        for (f, factor) in factors.iter_mut().enumerate() {
                            *factor = Factor8 {
                                axis: V8::splat(segment.rows[f]),
                                theta: S::splat(segment.rows[f][3]),
                                b: jets[f],
                            };
                        }
                        (Q8::splat(segment.start), Some(Q8::splat(*lead)), factors)
                    }
                    None => (lanes.start(), None, lanes.factors(&jets)),
                };
                let range = if SMALL { AngleRange::Small } else { AngleRange::Any };
                cumulative_product(start, lead, &factors, DERIVATIVES, range)
            };
            write_group::<S, DERIVATIVES>(
                options.row(),
                q,
                [w, a],
                &mut out[g * channels..(g + valid) * channels],
                valid,
            );
        }
    }

    /// The times of the group of `valid` samples from sample `j`; lanes past the end repeat
    /// the last sample (they are not written).
    #[inline(always)]
    fn group_times(&self, uniform: Option<(f64, f64, usize)>, j: usize, valid: usize) -> [f64; LANES] {
        let mut t = [0.0f64; LANES];
        match uniform {
            // The loops below are branch-free so that the compiler vectorizes them.
            Some((start, step, plain)) if j + LANES <= plain => {
                for (lane, t) in t.iter_mut().enumerate() {
                    *t = start + (j + lane) as f64 * step;
                }
            }
            _ => {
                for (lane, t) in t.iter_mut().enumerate() {
                    *t = self.times.time(self.index, j + lane.min(valid - 1));
                }
            }
        }
        t
    }
}

/// A group's rows (`valid` of them): the [`Row`] columns, rotation then omega and alpha back
/// to back, then the matrix when the row has one.
#[inline(always)]
pub(super) fn write_group<S: Lanes, const DERIVATIVES: bool>(
    row: Row,
    q: Q8<S>,
    [w, a]: [V8<S>; 2],
    rows: &mut [f32],
    valid: usize,
) {
    let channels = row.channels();
    write_columns([q.x, q.y, q.z, q.w], rows, channels, Row::ROTATION.start, 4, valid);
    if DERIVATIVES {
        write_columns([w.x, w.y, w.z, a.x], rows, channels, Row::OMEGA.start, 4, valid);
        write_columns([a.y, a.z, S::ZERO, S::ZERO], rows, channels, Row::ALPHA.start + 1, 2, valid);
    }
    if row.matrix {
        rows.chunks_exact_mut(channels).for_each(|r| row.fill_matrix(r));
    }
}

/// [`Piece::groups`] on AVX2 registers, compiled for them.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn groups_avx2<const F: usize, const DERIVATIVES: bool, const SMALL: bool>(
    piece: &Piece<'_>,
    n: usize,
    out: &mut [f32],
) {
    piece.groups::<F, DERIVATIVES, SMALL, super::simd::Avx2>(n, out);
}

/// `p * (a, 0)`: a quaternion times a pure one, `(p.w a + p.v x a, -p.v . a)`.
fn times_axis(p: [f32; 4], a: [f32; 4]) -> [f32; 4] {
    let [x, y, z, w] = p;
    [
        w * a[0] + y * a[2] - z * a[1],
        w * a[1] + z * a[0] - x * a[2],
        w * a[2] + x * a[1] - y * a[0],
        -(x * a[0] + y * a[1] + z * a[2]),
    ]
}

#[cfg(test)]
mod tests {
    use super::{locate, locate_uniform};

    /// The arithmetic lookup gives `locate`'s span and clamped time on equally spaced knots,
    /// also where the spacing is only equal to the builder's tolerance, at every knot, just
    /// beside it, outside the domain and for NaN.
    #[test]
    fn uniform_lookup_is_locate() {
        // The last: a domain so short that the spacing's inverse overflows to infinity.
        for (k, count, t0, dt) in
            [(4, 37, 0.0, 1.0 / 30.0), (2, 12, -3.5, 0.1), (6, 40, 1e6, 0.013), (4, 8, 0.25, 7.0), (4, 9, 0.0, 1e-310)]
        {
            // Knots as the builder would accept them: equal spacing with a 1e-10 wobble.
            let knots: Vec<f64> =
                (0..count).map(|i| t0 + dt * i as f64 * (1.0 + 1e-10 * ((i * 7919) % 13) as f64 / 13.0)).collect();
            let (first, last) = (k - 1, count - k);
            let inv = (count - 1) as f64 / (knots[count - 1] - knots[0]);
            let mut times: Vec<f64> =
                vec![f64::NAN, f64::NEG_INFINITY, f64::INFINITY, t0 - 1.0, knots[count - 1] + 1.0];
            for &knot in &knots {
                times.extend([knot, knot.next_up(), knot.next_down(), knot + 0.5 * dt]);
            }
            for t in times {
                let (a, b) = (locate_uniform(&knots, first, last, t, inv), locate(&knots, first, last, t));
                assert!(a.0 == b.0 && a.1.to_bits() == b.1.to_bits(), "order {k}, t {t}: {a:?} vs {b:?}");
            }
        }
    }
}
