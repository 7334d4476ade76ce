//! Host twins of the kernel's structs, and the conversion of a packed [`Batch`] into the f32
//! buffers the kernel reads, split into chunks that respect the device's binding limits.
//!
//! `GpuTrack` and `Params` mirror the WGSL structs of `shaders/eval.wgsl` field by field; a
//! test compares their offsets with naga's layout, so neither side can drift.

use crate::error::{GpuError, JobError, PackError};
use bytemuck::{Pod, Zeroable};
use quatcurve_core::curve::{Blend, Curve};
use quatcurve_eval::batch::Batch;
use quatcurve_eval::job::JobOptions;
use quatcurve_eval::sampling::{SampleTimes, TrackTimes};

/// One track as the kernel reads it (WGSL `GpuTrack`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTrack {
    /// Curve code (`CURVE_*` in the shader).
    pub curve: u32,
    /// B-spline order or Bezier degree.
    pub order: u32,
    /// Blend code (`BLEND_*`).
    pub blend: u32,
    /// [`FLAG_EXPLICIT_TIMES`], [`FLAG_HAS_LAST`] and [`FLAG_UNIFORM_KNOTS`], or'd.
    pub flags: u32,
    /// First entry in the chunk's points.
    pub point_offset: u32,
    /// Number of points.
    pub point_count: u32,
    /// First entry in the chunk's coefficients.
    pub coef_offset: u32,
    /// First entry in the chunk's knots.
    pub knot_offset: u32,
    /// Number of knots.
    pub knot_count: u32,
    /// First sample of the track in the chunk (track-major numbering).
    pub sample_offset: u32,
    /// Number of samples.
    pub sample_count: u32,
    /// First entry in the chunk's explicit times.
    pub time_offset: u32,
    /// Uniform sampling start, 32.32 fixed point, low word.
    pub start_lo: u32,
    /// High word (whole seconds, two's complement).
    pub start_hi: u32,
    /// Exact last sample (`--samples`), low word.
    pub last_lo: u32,
    /// High word.
    pub last_hi: u32,
    /// The sample step in 32.64 fixed point: whole seconds.
    pub step_whole: u32,
    /// Fraction, high word.
    pub step_frac_hi: u32,
    /// Fraction, low word.
    pub step_frac_lo: u32,
    /// Index in the whole track of this entry's first sample: 0, or for a piece of a track
    /// too long for one binding, where the piece starts (uniform times count from it).
    pub sample_base: u32,
}

/// Per-dispatch parameters (WGSL `Params`, a uniform).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Params {
    /// Samples in this chunk.
    pub sample_count: u32,
    /// Tracks in this chunk.
    pub track_count: u32,
    /// Floats per output sample.
    pub channels: u32,
    /// 1 for frame-major output.
    pub frame_major: u32,
    /// Workgroups per row of the 2D dispatch.
    pub groups_x: u32,
    /// Padding to 16 bytes.
    pub pad0: u32,
    /// Padding.
    pub pad1: u32,
    /// Padding.
    pub pad2: u32,
}

/// `FLAG_EXPLICIT_TIMES` in the shader.
pub const FLAG_EXPLICIT_TIMES: u32 = 1;
/// `FLAG_HAS_LAST` in the shader.
pub const FLAG_HAS_LAST: u32 = 2;
/// `FLAG_UNIFORM_KNOTS` in the shader: knots (a B-spline's, or the key times) equally spaced
/// ([`quatcurve_eval::batch::PackedTrack::uniform_knots`]), so the kernel finds spans by arithmetic
/// and a B-spline takes the fixed polynomial span bases.
pub const FLAG_UNIFORM_KNOTS: u32 = 4;

/// `ANY_CURVE` in the shader: no specialization.
pub const ANY_CURVE: u32 = 255;

/// `BSPLINE_FORMS` in the shader: tracks of either B-spline form, chosen per track, every other
/// family compiled out (a fitted clip mixes normalized cubics and slerped keys; on a software
/// adapter the generic kernel decoded it about 2x slower).
pub const BSPLINE_FORMS: u32 = 254;

/// The shader's code for a curve family (`CURVE_*`).
#[must_use]
pub fn curve_code(curve: Curve) -> u32 {
    match curve {
        Curve::Slerp => 0,
        Curve::Squad => 1,
        Curve::Bezier => 2,
        Curve::Hermite => 3,
        Curve::NamKim => 4,
        // bspline-interp is packed as a cubic B-spline on explicit knots.
        Curve::BSpline | Curve::BSplineInterp => 5,
        Curve::NormalizedBSpline => 6,
    }
}

/// The shader's code for a blend (`BLEND_*`).
#[must_use]
pub fn blend_code(blend: Blend) -> u32 {
    match blend {
        Blend::Cubic => 0,
        Blend::Quadratic => 1,
    }
}

/// The kernel's time resolution: one tick of 32.32 fixed point, 2^-32 s.
pub const TIME_RESOLUTION: f64 = 1.0 / 4_294_967_296.0;

/// Seconds as 32.32 fixed point `[low word, high word]` (two's complement), rounded to the
/// nearest 2^-32 s. Times beyond +-2^31 s saturate.
#[must_use]
pub fn fixed_time(t: f64) -> [u32; 2] {
    let ticks = (t / TIME_RESOLUTION).round().clamp(i64::MIN as f64, i64::MAX as f64) as i64;
    [ticks as u32, (ticks >> 32) as u32]
}

/// The 2D grid of `groups` workgroups (at least one), past `max` (a device's
/// `max_compute_workgroups_per_dimension`) in x: `[x, y]` with `x * y >= groups`.
///
/// # Errors
/// [`GpuError::Job`] when even the 2D grid cannot hold them.
pub fn grid(groups: u64, max: u32) -> Result<[u32; 2], GpuError> {
    let max = u64::from(max);
    let x = groups.clamp(1, max);
    let y = groups.div_ceil(x).max(1);
    if y > max {
        return Err(JobError::Workgroups(groups).into());
    }
    Ok([x as u32, y as u32])
}

/// A non-negative step as 32.64 fixed point `[whole, fraction high, fraction low]`, so that
/// `j * step` stays exact to 2^-32 s for any 32-bit `j`.
#[must_use]
pub fn fixed_step(step: f64) -> [u32; 3] {
    let ticks = (step.max(0.0) * 2f64.powi(64)).round() as u128;
    [(ticks >> 64) as u32, (ticks >> 32) as u32, ticks as u32]
}

/// A contiguous range of tracks that fits every binding limit, or one piece of a track too
/// long for one binding (its samples from `sample_base` on): where [`pack`] takes its data
/// from, and how much. Planning copies nothing, so a batch is packed one chunk at a time.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ChunkPlan {
    /// First track of the batch in this chunk.
    pub first_track: usize,
    /// Tracks in the chunk (1 for a piece).
    pub tracks: usize,
    /// First sample of the first track in this chunk (non-zero only for a piece).
    pub sample_base: usize,
    /// Samples in the chunk.
    pub samples: usize,
    /// Entries of each packed array: points, coefficients, knots, explicit times.
    pub points: usize,
    /// Coefficients.
    pub coefs: usize,
    /// Knots.
    pub knots: usize,
    /// Explicit sample times.
    pub times: usize,
}

/// Bytes of one entry of each binding but `tracks`: points and coefficients are `vec4<f32>`,
/// knots and explicit sample times 32.32 fixed point (two `u32`), each output channel an `f32`.
pub const POINT_BYTES: usize = 16;
/// See [`POINT_BYTES`].
pub const COEF_BYTES: usize = 16;
/// See [`POINT_BYTES`].
pub const KNOT_BYTES: usize = 8;
/// See [`POINT_BYTES`].
pub const TIME_BYTES: usize = 8;
/// See [`POINT_BYTES`].
pub const CHANNEL_BYTES: usize = 4;

impl ChunkPlan {
    /// Bytes each binding of the chunk holds, in binding order: tracks, points, coefficients,
    /// knots, explicit times, output (of `channels` per sample). The one count of device bytes
    /// that planning, buffer creation and `bench` use.
    #[must_use]
    pub fn binding_bytes(&self, channels: usize) -> [u64; 6] {
        [
            self.tracks * std::mem::size_of::<GpuTrack>(),
            self.points * POINT_BYTES,
            self.coefs * COEF_BYTES,
            self.knots * KNOT_BYTES,
            self.times * TIME_BYTES,
            self.samples * channels * CHANNEL_BYTES,
        ]
        .map(|b| b as u64)
    }
}

/// Where [`pack`] writes a chunk's arrays, as bytes: on the device path, its buffers mapped at
/// creation, so that the packed data is written once, straight into memory the kernel reads
/// (no host copy of the chunk beside them). Each view holds at least the plan's entries.
pub struct ChunkTargets<'a> {
    /// Points `[x, y, z, w]` as f32.
    pub points: wgpu::WriteOnly<'a, [u8]>,
    /// Coefficients as f32.
    pub coefs: wgpu::WriteOnly<'a, [u8]>,
    /// Knots in 32.32 fixed point (one copy per run of tracks sharing a knot vector).
    pub knots: wgpu::WriteOnly<'a, [u8]>,
    /// Explicit sample times in 32.32 fixed point.
    pub times: wgpu::WriteOnly<'a, [u8]>,
}

/// The first non-empty span of `knots` that is empty in fixed point, as its start index.
pub(crate) fn collapsed_span(knots: &[f64]) -> Option<usize> {
    knots.windows(2).position(|w| w[1] > w[0] && fixed_time(w[1]) == fixed_time(w[0]))
}

/// Whether track `index` has the knot vector of the track before it (the builder shares one
/// entry between consecutive tracks keyed at the same times). Within a chunk such a track
/// reads the same packed knots too: a million tracks sharing 36 knots pack 0.3 GB less.
fn shares_knots(batch: &Batch, index: usize) -> bool {
    index > 0 && {
        let (previous, track) = (&batch.tracks()[index - 1], &batch.tracks()[index]);
        previous.knot_offset() == track.knot_offset() && previous.knot_count() == track.knot_count()
    }
}

/// Whether track `index` packs its own knots into its chunk: it does not share the previous
/// track's, or it starts the chunk. The one rule [`plan_chunks`] counts by and [`pack`] writes by.
fn packs_own_knots(batch: &Batch, index: usize, starts_chunk: bool) -> bool {
    starts_chunk || !shares_knots(batch, index)
}

/// Largest Bezier degree the shader evaluates (`MAX_BEZIER_DEGREE`, checked by a test).
pub const MAX_BEZIER_DEGREE: usize = 32;
/// First function of the cubic Hermite (Bernstein) basis in [`polynomial_table`]
/// (`POLY_HERMITE`, checked by a test); before it, the uniform B-spline bases of orders 2..=8,
/// order `k` from function `(k - 2)(k - 1) / 2`.
pub const POLY_HERMITE: u32 = 28;

/// The span bases that are the same on every span, as polynomials in the span parameter
/// (fitted once by the crate's `basis` module, the CPU path's too): two `vec4f` per function, lowest
/// coefficient first. The kernel evaluates these with Horner's rule instead of running the
/// Cox-de Boor or de Casteljau triangle per sample, whose small arrays lavapipe keeps in
/// memory (half the kernel's time).
#[must_use]
pub fn polynomial_table() -> Vec<[f32; 4]> {
    let functions = (quatcurve_core::curve::MIN_ORDER..=quatcurve_core::curve::MAX_ORDER)
        .flat_map(quatcurve_core::basis::uniform_bspline_polynomials)
        .chain(quatcurve_core::basis::bernstein_polynomials(3));
    functions.flat_map(|c| [[c[0], c[1], c[2], c[3]], [c[4], c[5], c[6], c[7]]].map(|v| v.map(|x| x as f32))).collect()
}

/// Samples per track the kernel indexes with one `u32`.
pub const MAX_SAMPLES_PER_TRACK: usize = u32::MAX as usize;

/// Splits `batch` into chunks whose every buffer stays within `binding_limit` bytes. A track
/// whose samples alone overflow a binding is cut into pieces of consecutive samples, one
/// chunk each (so no track is refused for its length; its keys travel with every piece).
/// Constant work per track (and one pass over each knot vector that consecutive tracks do not
/// share), nothing copied: [`pack`] fills each chunk when it is needed.
///
/// # Errors
/// [`PackError`] naming the track: a Bezier degree the kernel cannot take, more than
/// [`MAX_SAMPLES_PER_TRACK`] samples, distinct knots closer than [`TIME_RESOLUTION`], or keys
/// that alone overflow a binding.
pub fn plan_chunks(
    batch: &Batch,
    times: &SampleTimes,
    channels: usize,
    binding_limit: u64,
) -> Result<Vec<ChunkPlan>, PackError> {
    let mut chunks = vec![ChunkPlan::default()];
    for index in 0..batch.len() {
        let track = &batch.tracks()[index];
        let count = times.count(index);
        let explicit = matches!(times.tracks()[index], TrackTimes::Explicit { .. });
        let name = || batch.id(index).to_string();
        if track.curve() == Curve::Bezier && track.bezier_degree() > MAX_BEZIER_DEGREE {
            return Err(PackError::BezierTooLong {
                track: name(),
                degree: track.bezier_degree(),
                max: MAX_BEZIER_DEGREE,
            });
        }
        if count >= MAX_SAMPLES_PER_TRACK {
            return Err(PackError::TooManySamples { track: name(), count, max: MAX_SAMPLES_PER_TRACK - 1 });
        }
        if !shares_knots(batch, index) {
            let knots = &batch.knots()[track.knot_offset()..track.knot_offset() + track.knot_count()];
            if let Some(knot) = collapsed_span(knots) {
                return Err(PackError::KnotsTooClose {
                    track: name(),
                    knot,
                    gap: knots[knot + 1] - knots[knot],
                    resolution: TIME_RESOLUTION,
                });
            }
        }
        // Chunk `c` with `samples` more samples of this track.
        let grown = |c: &ChunkPlan, samples: usize| ChunkPlan {
            tracks: c.tracks + 1,
            samples: c.samples + samples,
            points: c.points + track.point_count(),
            coefs: c.coefs + track.coef_count(),
            knots: c.knots + if packs_own_knots(batch, index, c.tracks == 0) { track.knot_count() } else { 0 },
            times: c.times + if explicit { samples } else { 0 },
            ..c.clone()
        };
        let needs = |c: &ChunkPlan| c.binding_bytes(channels);
        let fits = |c: &ChunkPlan| needs(c).iter().all(|&b| b <= binding_limit) && c.samples < u32::MAX as usize;
        let last = chunks.last_mut().expect("one chunk at least");
        let with = grown(last, count);
        if fits(&with) {
            *last = with;
            continue;
        }
        let fresh = grown(&ChunkPlan { first_track: index, ..ChunkPlan::default() }, count);
        if fits(&fresh) {
            chunks.push(fresh);
            continue;
        }
        // Too long for one binding: pieces as large as a fresh chunk takes.
        let per_sample = (channels * CHANNEL_BYTES + if explicit { TIME_BYTES } else { 0 }) as u64;
        let piece = (binding_limit / per_sample).min(u32::MAX as u64 / 2) as usize;
        let one = grown(&ChunkPlan { first_track: index, ..ChunkPlan::default() }, piece.min(count));
        if piece == 0 || !fits(&one) {
            let bytes = *needs(&grown(&ChunkPlan::default(), 1)).iter().max().unwrap();
            return Err(PackError::TrackTooLarge { track: name(), bytes, limit: binding_limit });
        }
        for start in (0..count).step_by(piece) {
            chunks.push(grown(
                &ChunkPlan { first_track: index, sample_base: start, ..ChunkPlan::default() },
                (start + piece).min(count) - start,
            ));
        }
        // Later tracks start a chunk of their own (a piece's chunk holds that piece only).
        chunks.push(ChunkPlan { first_track: index + 1, ..ChunkPlan::default() });
    }
    chunks.retain(|c| c.tracks > 0);
    Ok(chunks)
}

/// Tracks [`pack`] gives one task.
const PACK_TASK: usize = 1 << 12;

/// Entries a task converts before copying them to their target (64 KiB of points): small
/// enough to stay in cache between the conversion and the copy.
const STAGE_ENTRIES: usize = 1 << 12;

/// Packs `plan`'s tracks into `targets` on every core (each task into its own ranges of the
/// targets, converted through a small staging buffer) and returns their records, for the
/// `tracks` binding and for choosing the kernel.
#[must_use]
pub fn pack(plan: &ChunkPlan, batch: &Batch, times: &SampleTimes, targets: ChunkTargets<'_>) -> Vec<GpuTrack> {
    use rayon::prelude::*;
    let mut records = vec![GpuTrack::default(); plan.tracks];
    // Each task's tracks and where their entries start: (first track, tracks, offsets).
    let mut tasks = Vec::with_capacity(plan.tracks.div_ceil(PACK_TASK));
    let mut at = Offsets::default();
    for first in (0..plan.tracks).step_by(PACK_TASK) {
        let n = PACK_TASK.min(plan.tracks - first);
        tasks.push((first, n, at));
        for i in first..first + n {
            at = at.after(batch, times, plan, i);
        }
    }
    // Every task's records and byte ranges of the four targets, split off in order.
    let ChunkTargets { mut points, mut coefs, mut knots, times: mut sample_times } = targets;
    let mut rest = &mut records[..];
    let ends: Vec<Offsets> = tasks.iter().skip(1).map(|t| t.2).chain([at]).collect();
    let mut work = Vec::with_capacity(tasks.len());
    for (&(first, n, start), end) in tasks.iter().zip(&ends) {
        let (t, tail) = std::mem::take(&mut rest).split_at_mut(n);
        rest = tail;
        let p = split_bytes(&mut points, (end.points - start.points) * 16);
        let c = split_bytes(&mut coefs, (end.coefs - start.coefs) * 16);
        let k = split_bytes(&mut knots, (end.knots - start.knots) * 8);
        let s = split_bytes(&mut sample_times, (end.times - start.times) * 8);
        work.push((first, n, start, t, [Target(p), Target(c)], [Target(k), Target(s)]));
    }
    work.into_par_iter().for_each(|(first, n, mut at, t, [p, c], [k, s])| {
        let (mut p, mut c, mut k, mut s) = (Staged::new(p.0), Staged::new(c.0), Staged::new(k.0), Staged::new(s.0));
        for (i, record) in (first..first + n).zip(t.iter_mut()) {
            let index = plan.first_track + i;
            let view = batch.view(index);
            let range = piece_range(plan, times, index);
            *record = track_entry(&view, times, index, range.clone(), &at, at.knots_of(batch, plan, i));
            p.extend(view.points.iter().map(|q| q.to_array().map(|v| v as f32)));
            c.extend(view.coefs.iter().map(|w| w.map(|v| v as f32)));
            if Offsets::owns_knots(batch, plan, i) {
                k.extend(view.knots.iter().map(|&knot| fixed_time(knot)));
            }
            if let TrackTimes::Explicit { offset, .. } = times.tracks()[index] {
                s.extend(
                    times.explicit()[offset + range.start..offset + range.end].iter().map(|&time| fixed_time(time)),
                );
            }
            at = at.after(batch, times, plan, i);
        }
        p.flush();
        c.flush();
        k.flush();
        s.flush();
    });
    records
}

/// A task's range of a target, handed to the thread that packs it. `WriteOnly<[u8]>` is
/// exclusive access to plain bytes, like `&mut [u8]` (which is `Send`); wgpu's own `Send` impl
/// misses it only because it asks for a sized `T`.
struct Target<'a>(wgpu::WriteOnly<'a, [u8]>);

// SAFETY: the view is the only access to its bytes (split ranges never overlap), and bytes
// carry no thread affinity.
unsafe impl Send for Target<'_> {}

/// The first `bytes` of `view`, split off its front.
fn split_bytes<'a>(view: &mut wgpu::WriteOnly<'a, [u8]>, bytes: usize) -> wgpu::WriteOnly<'a, [u8]> {
    let (head, tail) = std::mem::take(view).split_at(bytes);
    *view = tail;
    head
}

/// Entries converted into a buffer and copied to a write-only target in runs of
/// [`STAGE_ENTRIES`].
struct Staged<'a, T> {
    buffer: Vec<T>,
    target: wgpu::WriteOnly<'a, [u8]>,
}

impl<'a, T: Pod> Staged<'a, T> {
    fn new(target: wgpu::WriteOnly<'a, [u8]>) -> Self {
        Self { buffer: Vec::new(), target }
    }

    fn extend(&mut self, entries: impl IntoIterator<Item = T>) {
        self.buffer.extend(entries);
        if self.buffer.len() >= STAGE_ENTRIES {
            self.flush();
        }
    }

    /// Copies the staged entries to the front of the target, which then starts after them.
    fn flush(&mut self) {
        let bytes: &[u8] = bytemuck::cast_slice(&self.buffer);
        split_bytes(&mut self.target, bytes.len()).copy_from_slice(bytes);
        self.buffer.clear();
    }
}

/// Where a track's entries start in its chunk's arrays.
#[derive(Clone, Copy, Debug, Default)]
struct Offsets {
    points: usize,
    coefs: usize,
    /// The next free knot entry.
    knots: usize,
    times: usize,
    samples: usize,
    /// Where the previous track's knots start (a track sharing them reads them there).
    previous_knots: usize,
}

impl Offsets {
    /// Whether chunk track `i` packs its own knots ([`packs_own_knots`]).
    fn owns_knots(batch: &Batch, plan: &ChunkPlan, i: usize) -> bool {
        packs_own_knots(batch, plan.first_track + i, i == 0)
    }

    /// Where chunk track `i` reads its knots: its own from `knots`, or the previous track's.
    fn knots_of(&self, batch: &Batch, plan: &ChunkPlan, i: usize) -> usize {
        if Self::owns_knots(batch, plan, i) {
            self.knots
        } else {
            self.previous_knots
        }
    }

    /// The offsets after chunk track `i`.
    fn after(self, batch: &Batch, times: &SampleTimes, plan: &ChunkPlan, i: usize) -> Self {
        let index = plan.first_track + i;
        let track = &batch.tracks()[index];
        let samples = piece_range(plan, times, index).len();
        let explicit = matches!(times.tracks()[index], TrackTimes::Explicit { .. });
        Self {
            points: self.points + track.point_count(),
            coefs: self.coefs + track.coef_count(),
            knots: self.knots + if Self::owns_knots(batch, plan, i) { track.knot_count() } else { 0 },
            times: self.times + if explicit { samples } else { 0 },
            samples: self.samples + samples,
            previous_knots: self.knots_of(batch, plan, i),
        }
    }
}

/// The samples of track `index` that chunk `plan` holds: all, or its piece (a piece is the
/// only track of its chunk, and so is a whole track with the chunk's every sample).
fn piece_range(plan: &ChunkPlan, times: &SampleTimes, index: usize) -> std::ops::Range<usize> {
    if plan.tracks == 1 {
        plan.sample_base..plan.sample_base + plan.samples
    } else {
        0..times.count(index)
    }
}

/// The kernel's record of samples `range` of track `index` (the whole track, or one piece),
/// its entries from `at` in the chunk's arrays and its knots from `knot_offset`.
fn track_entry(
    view: &quatcurve_eval::batch::TrackView<'_>,
    times: &SampleTimes,
    index: usize,
    range: std::ops::Range<usize>,
    at: &Offsets,
    knot_offset: usize,
) -> GpuTrack {
    let mut gpu = GpuTrack {
        curve: curve_code(view.track.curve()),
        // The kernel's one field: a B-spline's order or a Bezier curve's degree.
        order: (view.track.order() + view.track.bezier_degree()) as u32,
        blend: blend_code(view.track.blend()),
        point_offset: at.points as u32,
        point_count: view.points.len() as u32,
        coef_offset: at.coefs as u32,
        knot_offset: knot_offset as u32,
        knot_count: view.knots.len() as u32,
        sample_offset: at.samples as u32,
        sample_count: range.len() as u32,
        time_offset: at.times as u32,
        sample_base: range.start as u32,
        ..GpuTrack::default()
    };
    if view.track.uniform_knots() {
        gpu.flags |= FLAG_UNIFORM_KNOTS;
    }
    match times.tracks()[index] {
        TrackTimes::Explicit { .. } => gpu.flags |= FLAG_EXPLICIT_TIMES,
        TrackTimes::Uniform { start, step, last, count: total } => {
            [gpu.start_lo, gpu.start_hi] = fixed_time(start);
            [gpu.step_whole, gpu.step_frac_hi, gpu.step_frac_lo] = fixed_step(step);
            // The exact last sample belongs to the piece that ends the track.
            if let (Some(last), true) = (last, range.end == total) {
                gpu.flags |= FLAG_HAS_LAST;
                [gpu.last_lo, gpu.last_hi] = fixed_time(last);
            }
        }
    }
    gpu
}

/// Pipelines are specialized by these override constants (WGSL `ONLY_CURVE`, ...).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct PipelineKey {
    /// The curve code every track of the chunk has, [`BSPLINE_FORMS`] when they are B-splines
    /// of both forms, or [`ANY_CURVE`].
    pub(crate) only_curve: u32,
    /// The B-spline order every track of the chunk has (of either form), or 0.
    pub(crate) only_order: u32,
    /// Every track of the chunk has equally spaced knots (`FLAG_UNIFORM_KNOTS`).
    pub(crate) uniform_knots_only: bool,
    /// Angular velocity and acceleration are written.
    pub(crate) derivatives: bool,
    /// The rotation matrix is written.
    pub(crate) matrix: bool,
}

impl PipelineKey {
    /// The narrowest kernel that evaluates every track of `tracks` (the generic one when
    /// `options.generic_kernel` asks for it). On a software adapter every branch of the
    /// kernel runs, so what a chunk never takes is best compiled out.
    pub(crate) fn for_chunk(tracks: &[GpuTrack], options: &JobOptions) -> Self {
        let first = tracks.first().copied().unwrap_or_default();
        let specialize = !options.generic_kernel && !tracks.is_empty();
        let same = |f: fn(&GpuTrack) -> u32| specialize && tracks.iter().all(|t| f(t) == f(&first));
        let forms = [Curve::BSpline, Curve::NormalizedBSpline].map(curve_code);
        let only_curve = if same(|t| t.curve) {
            first.curve
        } else if specialize && tracks.iter().all(|t| forms.contains(&t.curve)) {
            BSPLINE_FORMS
        } else {
            ANY_CURVE
        };
        let bspline = only_curve == BSPLINE_FORMS || forms.contains(&only_curve);
        Self {
            only_curve,
            only_order: if bspline && same(|t| t.order) { first.order } else { 0 },
            uniform_knots_only: specialize && tracks.iter().all(|t| t.flags & FLAG_UNIFORM_KNOTS != 0),
            derivatives: options.derivatives,
            matrix: options.matrix,
        }
    }

    /// The override constants of this key, by the shader's names.
    pub(crate) fn constants(&self) -> [(&'static str, f64); 5] {
        [
            ("ONLY_CURVE", f64::from(self.only_curve)),
            ("DERIVATIVES", f64::from(u8::from(self.derivatives))),
            ("MATRIX", f64::from(u8::from(self.matrix))),
            ("ONLY_ORDER", f64::from(self.only_order)),
            ("UNIFORM_KNOTS_ONLY", f64::from(u8::from(self.uniform_knots_only))),
        ]
    }
}

/// The override constants of the narrowest kernel for `tracks`, values only (no derivatives,
/// no matrix): what playback's pose evaluation is specialized by.
pub(crate) fn value_specialization(tracks: &[GpuTrack]) -> [(&'static str, f64); 5] {
    let options = JobOptions { derivatives: false, matrix: false, generic_kernel: false, ..JobOptions::default() };
    PipelineKey::for_chunk(tracks, &options).constants()
}
