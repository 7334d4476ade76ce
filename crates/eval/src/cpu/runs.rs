//! Runs of short tracks as one stream of samples: each SIMD group's eight lanes take the next
//! eight samples of the run, across track ends. A ten-sample track then costs a group and a
//! quarter, not two groups with six idle lanes, and the per-track setup of a [`Piece`] (its
//! shared-segment bookkeeping, its scan for large angles) is not paid per track.
//!
//! Only tracks of at most [`SHORT`] samples take it (longer ones gain from a [`Piece`]'s
//! groups that share one segment), and only families whose basis is one fitted polynomial of
//! the span parameter (slerp, Hermite, B-splines of either form on equally spaced knots),
//! which a group can evaluate for lanes of different tracks. A lane's result depends on its
//! own track and time alone, never on its neighbours (its sine and cosine included,
//! [`AngleRange::PerLane`]): outputs do not change with the batch a track is in.
//!
//! [`Piece`]: super::piece::Piece

use super::bases::{Bases, PolyBasis};
use super::lanes::{cumulative_product, normalized_sum, AngleRange, LANES};
use super::piece::{inv_step, locate_from, spans, write_group, LaneRows, Segments, Shared};
use super::simd::{Isa, Lanes, SMALL_ANGLE};
use crate::batch::Batch;
use crate::job::JobOptions;
use crate::sampling::{SampleTimes, TrackTimes};
use quatcurve_core::curve::{Curve, MIN_ORDER};
use std::ops::Range;

/// Most samples a track of a run has. Measured on 32-key tracks (`bench`'s): runs take about
/// 0.6x the time of per-track pieces at 10 samples and 0.8x at 16, as much at 32 to 64, more
/// beyond, where pieces' groups begin to share spans.
pub(super) const SHORT: usize = 64;

/// How many tracks ahead a run asks for its data ([`prefetch`]).
const AHEAD: usize = 4;

/// What the tracks of one run share: the family and order, which fix the basis and the
/// number of factors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Kind {
    curve: Curve,
    order: usize,
}

impl Kind {
    /// The kind of track `index` of `batch`, or `None` where it takes the per-track kernel:
    /// more than [`SHORT`] samples, a basis other than a fitted polynomial, or forward
    /// differences.
    pub(super) fn of(batch: &Batch, times: &SampleTimes, index: usize, options: &JobOptions) -> Option<Self> {
        let track = &batch.tracks()[index];
        if times.count(index) > SHORT
            || options.forward_difference.is_some() && super::forward::applies(batch.view(index), times, index, options)
        {
            return None;
        }
        match track.curve() {
            Curve::Slerp | Curve::Hermite => Some(Self { curve: track.curve(), order: 0 }),
            // bspline-interp is packed as a cubic B-spline: one kind with the others.
            Curve::BSpline | Curve::BSplineInterp if track.uniform_knots() => {
                Some(Self { curve: Curve::BSpline, order: track.order() })
            }
            Curve::NormalizedBSpline if track.uniform_knots() => {
                Some(Self { curve: track.curve(), order: track.order() })
            }
            _ => None,
        }
    }

    /// Factors per sample.
    fn factors(self) -> usize {
        match self.curve {
            Curve::Slerp => 1,
            Curve::Hermite => 3,
            _ => self.order - 1,
        }
    }

    /// The basis.
    fn basis(self, bases: &Bases) -> &PolyBasis {
        match self.curve {
            Curve::Slerp => &bases.slerp,
            Curve::Hermite => &bases.hermite,
            _ => &bases.bspline[self.order - MIN_ORDER],
        }
    }
}

/// Evaluates tracks `tracks` of `batch`, all of kind `kind`, into `out`: their rows back to
/// back, as [`super::track::evaluate`] writes them one track at a time.
pub(super) fn evaluate(
    shared: &Shared<'_>,
    batch: &Batch,
    kind: Kind,
    times: &SampleTimes,
    tracks: Range<usize>,
    options: &JobOptions,
    out: &mut [f32],
) {
    let normalized = kind.curve == Curve::NormalizedBSpline;
    let run = Run { shared, batch, basis: kind.basis(shared.bases), normalized, times, tracks, options };
    macro_rules! by_factors {
        ($d:literal) => {
            match kind.factors() {
                1 => run.lanes::<1, $d>(out),
                2 => run.lanes::<2, $d>(out),
                3 => run.lanes::<3, $d>(out),
                4 => run.lanes::<4, $d>(out),
                5 => run.lanes::<5, $d>(out),
                6 => run.lanes::<6, $d>(out),
                _ => run.lanes::<7, $d>(out),
            }
        };
    }
    if options.derivatives {
        by_factors!(true)
    } else {
        by_factors!(false)
    }
}

/// One run and what it needs.
struct Run<'a> {
    shared: &'a Shared<'a>,
    batch: &'a Batch,
    basis: &'a PolyBasis,
    /// Normalized B-splines: a sum of control points, no product.
    normalized: bool,
    times: &'a SampleTimes,
    tracks: Range<usize>,
    options: &'a JobOptions,
}

/// The track a run is reading: where its next sample is, and what its lanes need, worked
/// out once per track so that a lane is a few loads and compares.
struct Cursor<'a> {
    index: usize,
    /// The next sample, and the track's sample count.
    j: usize,
    count: usize,
    /// Samples `j < plain` are at `start + j step` (a grid's); the others are its exact
    /// last time or explicit times.
    plain: usize,
    start: f64,
    step: f64,
    knots: &'a [f64],
    first: usize,
    last: usize,
    /// The domain, `knots[first]` to `knots[last + 1]`.
    domain: [f64; 2],
    inv_step: f64,
    /// Equally spaced knots, and fewer samples than spans.
    sparse: bool,
    hint: usize,
    segments: Segments,
}

impl Cursor<'_> {
    /// The next sample's time, clamped to the domain, and its span, as
    /// [`quatcurve_core::segment::locate`] finds them.
    #[inline(always)]
    fn next(&mut self, times: &SampleTimes) -> (f64, usize) {
        let j = self.j;
        self.j += 1;
        // A grid's plain samples in line (as `TrackTimes::grid_time`), the others as stored.
        let t = if j < self.plain { self.start + j as f64 * self.step } else { times.time(self.index, j) };
        // Sparse samples of equally spaced knots: straight to the arithmetic; else the last
        // span first (dense samples share spans).
        let (span, t) = if self.sparse {
            quatcurve_core::segment::locate_uniform(self.knots, self.first, self.last, self.domain, t, self.inv_step)
        } else {
            locate_from(&mut self.hint, self.knots, self.first, self.last, t, self.inv_step)
        };
        (t, span)
    }
}

impl Run<'_> {
    /// [`Run::stream`] on the evaluator's lane type.
    fn lanes<const F: usize, const DERIVATIVES: bool>(&self, out: &mut [f32]) {
        match self.shared.isa {
            // SAFETY: `Isa::Avx2` is only chosen where the CPU has AVX2 and FMA.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { stream_avx2::<F, DERIVATIVES>(self, out) },
            _ => self.stream::<F, DERIVATIVES, wide::f32x8>(out),
        }
    }

    /// The cursor at the first sample of track `index`.
    fn cursor(&self, index: usize) -> Cursor<'_> {
        let view = self.batch.view(index);
        let (first, last) = spans(view);
        let grid = self.times.tracks()[index];
        let (plain, start, step) = match grid {
            TrackTimes::Uniform { start, step, count, last } => {
                (if last.is_some() { count - 1 } else { count }, start, step)
            }
            TrackTimes::Explicit { .. } => (0, 0.0, 0.0),
        };
        let inv_step = inv_step(view);
        Cursor {
            index,
            j: 0,
            count: grid.count(),
            plain,
            start,
            step,
            knots: view.knots,
            first,
            last,
            domain: [view.knots[first], view.knots[last + 1]],
            inv_step,
            sparse: inv_step > 0.0 && grid.count() < last - first + 1,
            hint: first,
            segments: Segments::of(view.track),
        }
    }

    /// Evaluates the run's samples, eight at a time on lanes `S`, `F` factors each. Inlined
    /// into [`Run::lanes`]'s instances, so that the AVX2 one compiles for AVX2.
    #[inline(always)]
    fn stream<const F: usize, const DERIVATIVES: bool, S: Lanes>(&self, out: &mut [f32]) {
        let channels = self.options.row().channels();
        let total = out.len() / channels;
        let mut cursor = self.cursor(self.tracks.start);
        let mut lanes = LaneRows::<F>::new();
        let mut jets = [[S::ZERO; 3]; F];
        let limit = S::splat(SMALL_ANGLE * 0.99);
        for g in (0..total).step_by(LANES) {
            let valid = LANES.min(total - g);
            for lane in 0..valid {
                // The run's tracks hold `total` samples: a next track exists while samples remain.
                while cursor.j == cursor.count {
                    cursor = self.cursor(cursor.index + 1);
                    if cursor.index + AHEAD < self.tracks.end {
                        let ahead = self.batch.view(cursor.index + AHEAD);
                        prefetch(ahead.points);
                        prefetch(ahead.coefs);
                    }
                }
                let (t, span) = cursor.next(self.times);
                lanes.set(
                    lane,
                    t,
                    [cursor.knots[span], cursor.knots[span + 1]],
                    cursor.segments.rows::<F>(self.shared, span),
                );
            }
            let (u, inv) = lanes.params::<S>();
            self.basis.eval::<S, F>(u, DERIVATIVES, &mut jets);
            if DERIVATIVES {
                for jet in &mut jets {
                    jet[1] = jet[1] * inv;
                    jet[2] = jet[2] * (inv * inv);
                }
            }
            let (q, w, a) = if self.normalized {
                normalized_sum(lanes.start(), &lanes.points(), &jets, DERIVATIVES)
            } else {
                let factors = lanes.factors(&jets);
                // Each lane's own choice: all of its angles within the small range, or not.
                let mut small = S::ZERO.cmp_le(S::ZERO);
                for factor in &factors {
                    small = small & factor.theta.cmp_le(limit);
                }
                let range = if small.all() { AngleRange::Small } else { AngleRange::PerLane(small) };
                cumulative_product(lanes.start(), None, &factors, DERIVATIVES, range)
            };
            write_group::<S, DERIVATIVES>(
                self.options.row(),
                q,
                [w, a],
                &mut out[g * channels..(g + valid) * channels],
                valid,
            );
        }
    }
}

/// [`Run::stream`] on AVX2 registers, compiled for them.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn stream_avx2<const F: usize, const DERIVATIVES: bool>(run: &Run<'_>, out: &mut [f32]) {
    run.stream::<F, DERIVATIVES, super::simd::Avx2>(out);
}

/// Asks the CPU to start loading `data` into its caches (nothing where there is no prefetch
/// instruction). A run reads each track once, about 150 bytes per sample for 10-sample
/// tracks, faster than the hardware prefetcher follows: measured, a million 10-sample tracks
/// ran about 15% faster asking [`AHEAD`] tracks ahead (2 and 8 gained less).
#[inline(always)]
fn prefetch<T>(data: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = data.as_ptr().cast::<i8>();
        for offset in (0..std::mem::size_of_val(data)).step_by(64) {
            // SAFETY: every x86-64 CPU has SSE; a prefetch reads nothing and cannot fault.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(offset)) };
        }
    }
}
