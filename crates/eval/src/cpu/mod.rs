//! The fast CPU path: f32, eight samples per SIMD group (module `lanes`, on the lane type
//! [`Isa`] names, chosen at run time), tracks spread over all cores with rayon; runs of short
//! tracks share groups across track ends (module `runs`). It evaluates the same packed
//! [`crate::batch::Batch`] as the reference and the GPU and returns the same [`FloatOutput`] as the
//! GPU.
//!
//! What is vectorized: every family's rotation, eight samples per group. Slerp, cubic
//! Hermite and B-splines on equally spaced knots (phantom, uniform) evaluate a polynomial
//! basis fitted once per order; B-splines on other knots run the Cox-de Boor triangle over
//! the lanes (module `cox_de_boor`); Bezier curves up to degree 7 a de Casteljau triangle.
//! All of them then take the SIMD cumulative product and its derivative recursion, except
//! normalized B-splines, which sum their control points on the same cumulative basis and
//! normalize (`lanes::normalized_sum`). Squad and Nam-Kim rotations are two great arcs and a
//! geodesic (module `arcs`). Not vectorized: squad and Nam-Kim derivatives and Bezier curves
//! of degree 8 and up, which run the f64 reference per sample, in parallel.

mod arcs;
mod bases;
mod cox_de_boor;
mod forward;
mod lanes;
mod piece;
mod runs;
mod simd;
pub use simd::HALF_PI_PARTS;
mod track;

pub use simd::Isa;

use crate::error::Result;
use crate::job::EvalJob;
use crate::output::{FloatOutput, Layout};
use bases::Bases;
use piece::Shared;
use rayon::prelude::*;

/// Samples per parallel work item: a run of whole tracks, or a piece of one longer track.
const TASK_SAMPLES: usize = 4096;

/// One parallel work item of [`CpuEvaluator::evaluate_into`]: tracks `tracks`, all their
/// samples, or one piece of a single track longer than [`TASK_SAMPLES`].
struct Task {
    tracks: std::ops::Range<usize>,
    /// The piece's samples, for a piece.
    piece: Option<std::ops::Range<usize>>,
    /// Samples in the task.
    len: usize,
}

impl Task {
    /// The samples of `track` (one of the task's) that the task evaluates.
    fn samples(&self, track: usize, times: &crate::sampling::SampleTimes) -> std::ops::Range<usize> {
        self.piece.clone().unwrap_or(0..times.count(track))
    }
}

/// The batch's samples in tasks of about [`TASK_SAMPLES`] samples, in output order. A few per
/// [`TASK_SAMPLES`] samples, not one per track: a million 10-sample tracks are not a million tasks,
/// nor 40 MB of task list and output slices.
fn tasks(times: &crate::sampling::SampleTimes) -> Vec<Task> {
    let tracks = times.tracks().len();
    let mut tasks = Vec::with_capacity(times.total() / TASK_SAMPLES + 1);
    let mut i = 0;
    while i < tracks {
        let n = times.count(i);
        if n > TASK_SAMPLES {
            tasks.extend((0..n.div_ceil(TASK_SAMPLES)).map(|p| {
                let piece = p * TASK_SAMPLES..((p + 1) * TASK_SAMPLES).min(n);
                Task { tracks: i..i + 1, len: piece.len(), piece: Some(piece) }
            }));
            i += 1;
            continue;
        }
        let (first, mut len) = (i, 0);
        while i < tracks && times.count(i) <= TASK_SAMPLES && len + times.count(i) <= TASK_SAMPLES {
            len += times.count(i);
            i += 1;
        }
        tasks.push(Task { tracks: first..i, piece: None, len });
    }
    tasks
}

/// The fast CPU evaluator: holds the fitted polynomial bases; uses rayon's global thread
/// pool. Create once and reuse.
#[derive(Clone, Debug)]
pub struct CpuEvaluator {
    bases: Bases,
    /// The lane type, chosen for this CPU when the evaluator is created.
    isa: Isa,
}

impl Default for CpuEvaluator {
    fn default() -> Self {
        Self::new()
    }
}

impl CpuEvaluator {
    /// A new evaluator on the best lane type this CPU has ([`Isa::detect`]); fits the bases
    /// (microseconds).
    #[must_use]
    pub fn new() -> Self {
        Self { bases: Bases::new(), isa: Isa::detect() }
    }

    /// An evaluator on lane type `isa`, or `None` where this CPU lacks it: to compare the
    /// paths in tests and benchmarks.
    #[must_use]
    pub fn with_isa(isa: Isa) -> Option<Self> {
        isa.available().then(|| Self { bases: Bases::new(), isa })
    }

    /// The lane type it runs.
    #[must_use]
    pub fn isa(&self) -> Isa {
        self.isa
    }

    /// `f32x8 (<instruction set>), <threads> threads` (`1 thread`), for outputs and benchmarks.
    #[must_use]
    pub fn name(&self) -> String {
        let threads = rayon::current_num_threads();
        format!("f32x8 ({}), {threads} thread{}", self.isa.name(), if threads == 1 { "" } else { "s" })
    }

    /// Evaluates every track of `job` at its sample times: `samples x channels` floats, each
    /// sample a [`crate::output::Row`] (the GPU's layout).
    ///
    /// # Errors
    /// As [`EvalJob::validate`].
    pub fn evaluate(&self, job: &EvalJob<'_>) -> Result<FloatOutput> {
        let mut out = FloatOutput::zeroed(job.times.total(), job.options.row().channels());
        self.evaluate_into(job, &mut out.data)?;
        Ok(out)
    }

    /// As [`CpuEvaluator::evaluate`], into a caller's buffer of exactly `samples x channels`
    /// floats: reusing it saves the allocation and first-touch page faults of a new output,
    /// which cost as much as the arithmetic for large batches.
    ///
    /// # Errors
    /// As [`EvalJob::validate`], and [`crate::error::Error::BadJob`] for a buffer of the wrong size.
    pub fn evaluate_into(&self, job: &EvalJob<'_>, data: &mut [f32]) -> Result<()> {
        job.validate()?;
        let EvalJob { batch, times, options } = *job;
        let channels = options.row().channels();
        if data.len() != times.total() * channels {
            return Err(
                crate::error::JobError::BufferSize { floats: data.len(), samples: times.total(), channels }.into()
            );
        }
        let shared = Shared::new(batch, &self.bases, self.isa);
        let tasks = tasks(times);
        // A task's samples into `out` (its own rows, track-major): a run of short tracks of
        // one kind at a time, or one track or piece.
        let run = |task: &Task, out: &mut [f32]| {
            let mut rest = out;
            let mut track = task.tracks.start;
            while track < task.tracks.end {
                let kind = task.piece.is_none().then(|| runs::Kind::of(batch, times, track, &options)).flatten();
                let (end, samples) = match kind {
                    Some(kind) => {
                        let mut end = track + 1;
                        while end < task.tracks.end && runs::Kind::of(batch, times, end, &options) == Some(kind) {
                            end += 1;
                        }
                        (end, times.offsets()[end] - times.offsets()[track])
                    }
                    None => (track + 1, task.samples(track, times).len()),
                };
                let (head, tail) = std::mem::take(&mut rest).split_at_mut(samples * channels);
                rest = tail;
                match kind {
                    Some(kind) => runs::evaluate(&shared, batch, kind, times, track..end, &options, head),
                    None => track::evaluate(
                        &shared,
                        batch.view(track),
                        times,
                        track,
                        task.samples(track, times),
                        &options,
                        head,
                    ),
                }
                track = end;
            }
        };
        match options.layout {
            Layout::Track => {
                let mut slices = Vec::with_capacity(tasks.len());
                let mut rest = data;
                for task in &tasks {
                    let (head, tail) = rest.split_at_mut(task.len * channels);
                    slices.push(head);
                    rest = tail;
                }
                tasks.par_iter().zip(slices).for_each(|(task, out)| run(task, out));
            }
            Layout::Frame => {
                let results: Vec<Vec<f32>> = tasks
                    .par_iter()
                    .map(|task| {
                        let mut out = vec![0.0f32; task.len * channels];
                        run(task, &mut out);
                        out
                    })
                    .collect();
                for (task, out) in tasks.iter().zip(&results) {
                    let mut rows = out.chunks_exact(channels);
                    for track in task.tracks.clone() {
                        for (j, row) in task.samples(track, times).zip(&mut rows) {
                            let slot = Layout::Frame.slot(times, track, j);
                            data[slot * channels..(slot + 1) * channels].copy_from_slice(row);
                        }
                    }
                }
            }
        }
        Ok(())
    }
}
