//! One piece of one track on the CPU: per-lane segment lookup, basis, then the SIMD product.

use super::lanes::{cumulative_product, write_columns, Factor8, LANES, MAX_FACTORS, Q8, V8};
use super::cox_de_boor::SpanKnots;
use crate::basis::{bernstein_polynomials, fit_polynomials, uniform_bspline_polynomials};
use crate::batch::{Batch, TrackView};
use crate::curve::Curve;
use crate::job::EvalOptions;
use crate::output::Row;
use crate::reference;
use crate::sampling::{SampleTimes, TrackTimes};
use crate::segment::locate;
use crate::curve::{MAX_ORDER, MIN_ORDER};
use std::ops::Range;
use super::simd::{Isa, Lanes, SMALL_ANGLE};

/// A cumulative basis that is a fixed polynomial of the segment parameter `u in [0, 1]`:
/// `count` functions of degree `len - 1 < 8`, f32 coefficients lowest first.
#[derive(Clone, Debug)]
pub struct PolyBasis {
    count: usize,
    len: usize,
    coefs: Vec<[f32; 8]>,
}

impl PolyBasis {
    /// The f32 twin of `coefs`, polynomials of degree `degree`.
    fn new(degree: usize, coefs: Vec<[f64; 8]>) -> Self {
        Self { count: coefs.len(), len: degree + 1, coefs: coefs.into_iter().map(|c| c.map(|v| v as f32)).collect() }
    }

    /// `[p, p', p'']` of each of the `F` functions (of degree `F`) at `u`, derivatives in
    /// `u`; without `derivatives` only `p`, by Horner's rule.
    #[inline(always)]
    fn eval<S: Lanes, const F: usize>(&self, u: S, derivatives: bool, out: &mut [[S; 3]; F]) {
        debug_assert!(self.count == F && self.len == F + 1);
        for (c, out) in self.coefs.iter().zip(out.iter_mut()) {
            let (mut p, mut d1, mut d2) = (S::ZERO, S::ZERO, S::ZERO);
            for k in (0..=F).rev() {
                let ck = S::splat(c[k]);
                if derivatives {
                    d2 = d2.mul_add(u, d1);
                    d1 = d1.mul_add(u, p);
                }
                p = p.mul_add(u, ck);
            }
            *out = [p, d1, d2 * S::splat(2.0)];
        }
    }
}

/// The polynomial bases: they depend on nothing but the order, so the evaluator fits them
/// once.
#[derive(Clone, Debug)]
pub struct Bases {
    slerp: PolyBasis,
    hermite: PolyBasis,
    /// Uniform-knot B-spline bases, index `k - MIN_ORDER` for orders [`MIN_ORDER`]`..=`[`MAX_ORDER`].
    bspline: Vec<PolyBasis>,
}

impl Bases {
    /// Fits every basis from the reference's.
    pub fn new() -> Self {
        Self {
            slerp: PolyBasis::new(1, fit_polynomials(1, |u| vec![[u, 1.0, 0.0]])),
            hermite: PolyBasis::new(3, bernstein_polynomials(3)),
            bspline: (MIN_ORDER..=MAX_ORDER).map(|k| PolyBasis::new(k - 1, uniform_bspline_polynomials(k))).collect(),
        }
    }
}

/// What every piece of one evaluation shares: the evaluator's bases and lane type, and the
/// batch, whose f64 points and coefficients the kernels convert to f32 where they read them.
/// No batch-wide f32 copy: for a million short tracks it doubled the batch's memory and its
/// conversion took as long as the evaluation.
pub struct Context<'a> {
    /// The lane type the kernels run.
    isa: Isa,
    bases: &'a Bases,
    batch: &'a Batch,
}

impl<'a> Context<'a> {
    /// The context of evaluating `batch` with `bases` on `isa`.
    pub fn new(batch: &'a Batch, bases: &'a Bases, isa: Isa) -> Self {
        Self { isa, bases, batch }
    }

    /// Point `i` `[x, y, z, w]` in f32.
    #[inline(always)]
    fn point(&self, i: usize) -> [f32; 4] {
        self.batch.points[i].to_array().map(|v| v as f32)
    }

    /// Coefficient `c` as `[axis x, axis y, axis z, theta]` in f32 (axis unit, or zero with
    /// theta 0).
    #[inline(always)]
    fn axis(&self, c: usize) -> [f32; 4] {
        let c = &self.batch.coefs[c];
        let theta = angle(c);
        if theta > 0.0 {
            [(c[0] / theta) as f32, (c[1] / theta) as f32, (c[2] / theta) as f32, theta as f32]
        } else {
            [0.0; 4]
        }
    }
}

/// The length of a coefficient's vector part: the angle of its factor.
#[inline(always)]
fn angle(c: &[f64; 4]) -> f64 {
    (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
}

/// How a track's basis is computed.
enum Basis<'a> {
    /// SIMD polynomial in the segment parameter.
    Poly(&'a PolyBasis),
    /// SIMD Cox-de Boor triangle (B-splines on unequal knots).
    CoxDeBoor,
    /// SIMD de Casteljau triangle (Bezier curves, whose degree varies per track).
    Bernstein,
}

/// `locate`, first trying the previous span and the next (sample times usually increase).
#[inline(always)]
fn locate_from(hint: &mut usize, knots: &[f64], first: usize, last: usize, t: f64) -> (usize, f64) {
    let h = *hint;
    if h >= first && h <= last && knots[h] <= t && t < knots[h + 1] {
        return (h, t);
    }
    // Or the next one.
    let h = h + 1;
    if h >= first && h <= last && knots[h] <= t && t < knots[h + 1] {
        *hint = h;
        return (h, t);
    }
    let (span, t) = locate(knots, first, last, t);
    *hint = span;
    (span, t)
}

/// Evaluates samples `range` of track `index` into `out` (`range.len()` [`Row`]s).
pub fn evaluate(tables: &Context<'_>, view: TrackView<'_>, times: &SampleTimes, index: usize, range: Range<usize>, options: &EvalOptions, out: &mut [f32]) {
    let row = options.row();
    let channels = row.channels();
    if super::forward::applies(view, times, index, options) {
        super::forward::evaluate(view, times, index, range, options, out);
        return;
    }
    let track = view.track;
    let knots = view.knots;
    let (basis, factors, first, last) = match track.curve {
        Curve::Slerp => (Basis::Poly(&tables.bases.slerp), 1, 0, knots.len() - 2),
        Curve::Hermite => (Basis::Poly(&tables.bases.hermite), 3, 0, knots.len() - 2),
        // bspline-interp is packed as a cubic B-spline on explicit knots.
        Curve::BSpline | Curve::BSplineInterp => {
            let k = track.order;
            let basis = if track.uniform_knots { Basis::Poly(&tables.bases.bspline[k - MIN_ORDER]) } else { Basis::CoxDeBoor };
            (basis, k - 1, k - 1, view.points.len() - 1)
        }
        // One segment; degrees beyond the product's capacity take the reference below.
        Curve::Bezier if (1..=MAX_FACTORS).contains(&track.order) => (Basis::Bernstein, track.order, 0, 0),
        Curve::Squad | Curve::NamKim if !options.derivatives => {
            super::arcs::evaluate(tables.isa, view, times, index, range.start, range.len(), channels, out);
            out.chunks_exact_mut(channels).for_each(|r| row.fill_matrix(r));
            return;
        }
        Curve::Squad | Curve::NamKim | Curve::Bezier => {
            for (dst, j) in out.chunks_exact_mut(channels).zip(range) {
                let t = times.time(index, j);
                if options.derivatives {
                    let s = reference::evaluate(view, t);
                    let f = |v: crate::quat::DVec3| v.to_array().map(|c| c as f32);
                    row.write(dst, s.rotation.to_array().map(|v| v as f32), f(s.angular_velocity), f(s.angular_acceleration));
                } else {
                    row.write(dst, reference::evaluate_rotation(view, t).to_array().map(|v| v as f32), [0.0; 3], [0.0; 3]);
                }
            }
            return;
        }
    };
    // Every basis here stays within [0, 1] on the domain, so every angle is at most its
    // coefficient's: shortest-path keys (all of them below pi / 2) need no range reduction.
    let small = view.coefs.iter().all(|c| angle(c) as f32 <= SMALL_ANGLE * 0.99);
    let piece = Piece { tables, view, times, index, from: range.start, options, channels, basis, first, last };
    // Constant factor counts and flags let the compiler unroll the basis and the product,
    // keep them in registers and drop the branches.
    macro_rules! by_factors {
        ($d:literal, $s:literal) => {
            match factors {
                1 => piece.run::<1, $d, $s>(range.len(), out),
                2 => piece.run::<2, $d, $s>(range.len(), out),
                3 => piece.run::<3, $d, $s>(range.len(), out),
                4 => piece.run::<4, $d, $s>(range.len(), out),
                5 => piece.run::<5, $d, $s>(range.len(), out),
                6 => piece.run::<6, $d, $s>(range.len(), out),
                _ => piece.run::<7, $d, $s>(range.len(), out),
            }
        };
    }
    match (options.derivatives, small) {
        (false, true) => by_factors!(false, true),
        (false, false) => by_factors!(false, false),
        (true, true) => by_factors!(true, true),
        (true, false) => by_factors!(true, false),
    }
}

/// One segment's data as the kernels read it ([`Piece::segment`]).
#[derive(Clone, Copy)]
struct Segment<const F: usize> {
    span: usize,
    start: [f32; 4],
    /// `[axis x, axis y, axis z, theta]` of each factor.
    axes: [[f32; 4]; F],
}

/// One piece of a vectorized track, and what it needs.
struct Piece<'a> {
    tables: &'a Context<'a>,
    view: TrackView<'a>,
    times: &'a SampleTimes,
    index: usize,
    /// First sample of the piece.
    from: usize,
    options: &'a EvalOptions,
    channels: usize,
    basis: Basis<'a>,
    /// Spans the domain covers.
    first: usize,
    last: usize,
}

impl Piece<'_> {
    /// The segment of `span` in f32: its first point (sign-aligned for Hermite) and its `F`
    /// factors' axes and angles. Converted once per span a group meets (the kernels keep the
    /// last one), not once per batch: no f32 copy of the whole batch.
    #[inline(always)]
    fn segment<const F: usize>(&self, span: usize) -> Segment<F> {
        let (track, p0, c0) = (self.view.track, self.view.track.point_offset, self.view.track.coef_offset);
        let (start, coef) = match track.curve {
            Curve::Slerp => (self.tables.point(p0 + span), c0 + span),
            Curve::Bezier => (self.tables.point(p0), c0),
            Curve::Hermite => {
                let sign = self.view.coefs[3 * span + 1][3] as f32;
                (self.tables.point(p0 + span).map(|v| v * sign), c0 + 3 * span)
            }
            _ => (self.tables.point(p0 + span + 1 - track.order), c0 + span + 1 - track.order),
        };
        Segment { span, start, axes: std::array::from_fn(|f| self.tables.axis(coef + f)) }
    }

    /// [`Piece::groups`] on the evaluator's lane type.
    fn run<const F: usize, const DERIVATIVES: bool, const SMALL: bool>(&self, n: usize, out: &mut [f32]) {
        match self.tables.isa {
            // SAFETY: `Isa::Avx2` is only chosen where the CPU has AVX2 and FMA.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { groups_avx2::<F, DERIVATIVES, SMALL>(self, n, out) },
            _ => self.groups::<F, DERIVATIVES, SMALL, wide::f32x8>(n, out),
        }
    }

    /// Evaluates the piece's `n` samples, `F` factors each, eight at a time on lanes `S`;
    /// `SMALL`: every angle is within [`SMALL_ANGLE`]. Inlined into [`Piece::run`]'s
    /// instances, so that the AVX2 one compiles for AVX2.
    #[inline(always)]
    fn groups<const F: usize, const DERIVATIVES: bool, const SMALL: bool, S: Lanes>(&self, n: usize, out: &mut [f32]) {
        let (knots, options, channels) = (self.view.knots, self.options, self.channels);
        let (first, last) = (self.first, self.last);
        let mut hint = first;
        let mut jets = [[S::ZERO; 3]; F];
        // `start + j step` for samples `j < plain` (as `SampleTimes::time`): the final sample
        // of a `--samples` grid is the exact domain end instead.
        let uniform = match self.times.tracks[self.index] {
            TrackTimes::Uniform { start, step, count, last } => Some((start, step, if last.is_some() { count - 1 } else { count })),
            TrackTimes::Explicit { .. } => None,
        };
        // The knot constants of the last span Cox-de Boor needed.
        let mut span_knots: Option<SpanKnots> = None;
        // The segment the last shared group was on, and its `start * (axis_0, 0)`.
        let mut shared_segment: Option<(Segment<F>, [f32; 4])> = None;
        // Each lane's segment start and factors in a group that is not shared (set there
        // before they are read; kept across groups so that they are not cleared per group).
        let mut starts = [[0.0f32; 4]; LANES];
        let mut axes = [[[0.0f32; 4]; F]; LANES];
        for g in (0..n).step_by(LANES) {
            let valid = LANES.min(n - g);
            // Lanes past the end repeat the last sample and are not written.
            let mut t = [0.0f64; LANES];
            let j = self.from + g;
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
            let mut spans = [hint; LANES];
            let mut u = [0.0f32; LANES];
            // Usually all eight samples lie in the span of the previous group: one lookup, one
            // division, and the segment's data broadcast instead of gathered.
            let h = hint;
            let shared = h >= first && h <= last && {
                let (k0, k1) = (knots[h], knots[h + 1]);
                t.iter().fold(true, |inside, &t| inside & (k0 <= t) & (t < k1))
            };
            let inv = if shared {
                let inv_len = 1.0 / (knots[h + 1] - knots[h]);
                for (u, t) in u.iter_mut().zip(&t) {
                    *u = ((t - knots[h]) * inv_len) as f32;
                }
                if shared_segment.as_ref().map(|s| s.0.span) != Some(h) {
                    let segment = self.segment::<F>(h);
                    shared_segment = Some((segment, times_axis(segment.start, segment.axes[0])));
                }
                S::splat(inv_len as f32)
            } else {
                let mut inv = [0.0f32; LANES];
                // Consecutive lanes in one span share one conversion (every distinct span
                // once when the times are sorted, as grids are).
                let mut current: Option<(Segment<F>, f64)> = None;
                for lane in 0..LANES {
                    let (span, tl) = locate_from(&mut hint, knots, first, last, t[lane]);
                    let (segment, inv_len) = match current {
                        Some(c) if c.0.span == span => c,
                        _ => *current.insert((self.segment::<F>(span), 1.0 / (knots[span + 1] - knots[span]))),
                    };
                    (spans[lane], t[lane]) = (span, tl);
                    u[lane] = ((tl - knots[span]) * inv_len) as f32;
                    inv[lane] = inv_len as f32;
                    (starts[lane], axes[lane]) = (segment.start, segment.axes);
                }
                S::new(inv)
            };
            match self.basis {
                Basis::Poly(poly) => poly.eval::<S, F>(S::new(u), DERIVATIVES, &mut jets),
                Basis::Bernstein => bernstein_cumulative_lanes::<S, F>(S::new(u), &mut jets),
                Basis::CoxDeBoor => {
                    // Once per distinct span among the lanes: one, or two where the group
                    // straddles a knot; lanes of other spans are blended out.
                    let mut done = [false; LANES];
                    for lane in 0..LANES {
                        if done[lane] {
                            continue;
                        }
                        let span = spans[lane];
                        if span_knots.as_ref().map(|c| c.span) != Some(span) {
                            span_knots = None;
                        }
                        let constants = span_knots.get_or_insert_with(|| SpanKnots::new(knots, F + 1, span));
                        if shared {
                            constants.jets::<S, F, DERIVATIVES>(&t, &mut jets);
                            break;
                        }
                        let mut these = [[S::ZERO; 3]; F];
                        constants.jets::<S, F, DERIVATIVES>(&t, &mut these);
                        let mut mask = [0.0f32; LANES];
                        for (l, m) in mask.iter_mut().enumerate() {
                            if spans[l] == span {
                                *m = f32::from_bits(u32::MAX);
                                done[l] = true;
                            }
                        }
                        let mask = S::new(mask);
                        for (jet, this) in jets.iter_mut().zip(&these) {
                            for d in 0..3 {
                                jet[d] = mask.blend(this[d], jet[d]);
                            }
                        }
                    }
                }
            }
            // The span-parameter bases have derivatives in u; Cox-de Boor's are in time.
            if DERIVATIVES && !matches!(self.basis, Basis::CoxDeBoor) {
                for jet in &mut jets {
                    jet[1] = jet[1] * inv;
                    jet[2] = jet[2] * (inv * inv);
                }
            }
            let mut factors = [Factor8 { axis: V8::ZERO, theta: S::ZERO, b: [S::ZERO; 3] }; F];
            for (f, factor) in factors.iter_mut().enumerate() {
                let (axis, theta) = match &shared_segment {
                    Some((segment, _)) if shared => (V8::splat(segment.axes[f]), S::splat(segment.axes[f][3])),
                    _ => {
                        let rows: [[f32; 4]; LANES] = std::array::from_fn(|lane| axes[lane][f]);
                        (V8::gather(&rows), S::new(rows.map(|r| r[3])))
                    }
                };
                *factor = Factor8 { axis, theta, b: jets[f] };
            }
            let (start, lead) = match &shared_segment {
                Some((segment, lead)) if shared => (Q8::splat(segment.start), Some(Q8::splat(*lead))),
                _ => (Q8::gather(&starts), None),
            };
            let (q, w, a) = cumulative_product(start, lead, &factors, DERIVATIVES, SMALL);
            let rows = &mut out[g * channels..(g + valid) * channels];
            // Row's columns: the rotation, then omega and alpha back to back.
            write_columns([q.x, q.y, q.z, q.w], rows, channels, Row::ROTATION.start, 4, valid);
            if DERIVATIVES {
                write_columns([w.x, w.y, w.z, a.x], rows, channels, Row::OMEGA.start, 4, valid);
                write_columns([a.y, a.z, S::ZERO, S::ZERO], rows, channels, Row::ALPHA.start + 1, 2, valid);
            }
            if options.matrix {
                rows.chunks_exact_mut(channels).for_each(|r| options.row().fill_matrix(r));
            }
        }
    }
}

/// [`Piece::groups`] on AVX2 registers, compiled for them.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn groups_avx2<const F: usize, const DERIVATIVES: bool, const SMALL: bool>(piece: &Piece<'_>, n: usize, out: &mut [f32]) {
    piece.groups::<F, DERIVATIVES, SMALL, super::simd::Avx2>(n, out);
}

/// The cumulative Bernstein basis of degree `F` and its `u` derivatives, eight parameters at
/// a time: the SIMD twin of [`crate::basis::bernstein_cumulative`] (de Casteljau rows `F - 2`,
/// `F - 1`, `F`; sums from the top).
#[inline(always)]
fn bernstein_cumulative_lanes<S: Lanes, const F: usize>(u: S, out: &mut [[S; 3]; F]) {
    let v = S::ONE - u;
    let zero = [S::ZERO; MAX_FACTORS + 1];
    let (mut row, mut prev, mut prev2) = (zero, zero, zero);
    row[0] = S::ONE;
    for m in 1..=F {
        let mut next = zero;
        next[0] = v * row[0];
        for j in 1..m {
            next[j] = v.mul_add(row[j], u * row[j - 1]);
        }
        next[m] = u * row[m - 1];
        (prev2, prev, row) = (prev, row, next);
    }
    let n = F as f32;
    let mut tail = S::ZERO;
    for i in (1..=F).rev() {
        tail = tail + row[i];
        let below = if i >= 2 { prev2[i - 2] } else { S::ZERO };
        out[i - 1] = [tail, prev[i - 1] * S::splat(n), (below - prev2[i - 1]) * S::splat(n * (n - 1.0))];
    }
}

/// `p * (a, 0)`: a quaternion times a pure one, `(p.w a + p.v x a, -p.v . a)`.
fn times_axis(p: [f32; 4], a: [f32; 4]) -> [f32; 4] {
    let [x, y, z, w] = p;
    [w * a[0] + y * a[2] - z * a[1], w * a[1] + z * a[0] - x * a[2], w * a[2] + x * a[1] - y * a[0], -(x * a[0] + y * a[1] + z * a[2])]
}
