//! The fast CPU path: f32, eight samples per SIMD group (module `lanes`, on the lane type
//! [`Isa`] names, chosen at run time), tracks spread over all
//! cores with rayon. It evaluates the same packed [`crate::Batch`] as the reference and the GPU and
//! returns the same [`FloatOutput`] as the GPU.
//!
//! What is vectorized: every family's rotation, eight samples per group. Slerp, cubic
//! Hermite and B-splines on equally spaced knots (phantom, uniform) evaluate a polynomial
//! basis fitted once per order; B-splines on other knots run the Cox-de Boor triangle over
//! the lanes (module `cox_de_boor`); Bezier curves up to degree 7 a de Casteljau triangle.
//! All of them then take the SIMD cumulative product and its derivative recursion. Squad and
//! Nam-Kim rotations are two great arcs and a geodesic (module `arcs`). Not vectorized:
//! squad and Nam-Kim derivatives and Bezier curves of degree 8 and up, which run the f64
//! reference per sample, in parallel.

mod arcs;
mod bases;
mod cox_de_boor;
mod forward;
mod lanes;
mod piece;
mod simd;
mod track;

pub use simd::Isa;

use crate::error::Result;
use crate::job::EvalJob;
use crate::output::{FloatOutput, Layout};
use rayon::prelude::*;
use bases::Bases;
use piece::Context;

/// Samples per parallel work item (a piece of one track).
const PIECE: usize = 4096;

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

    /// `f32x8 (<instruction set>), <threads> threads`, for outputs and benchmarks.
    #[must_use]
    pub fn name(&self) -> String {
        format!("f32x8 ({}), {} threads", self.isa.name(), rayon::current_num_threads())
    }

    /// Evaluates every track of `job` at its sample times: `samples x channels` floats, each
    /// sample a [`crate::Row`] (the GPU's layout).
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
    /// As [`EvalJob::validate`], and [`crate::Error::BadJob`] for a buffer of the wrong size.
    pub fn evaluate_into(&self, job: &EvalJob<'_>, data: &mut [f32]) -> Result<()> {
        job.validate()?;
        let EvalJob { batch, times, options } = *job;
        let channels = options.row().channels();
        if data.len() != times.total() * channels {
            return Err(crate::error::JobError::BufferSize { floats: data.len(), samples: times.total(), channels }.into());
        }
        let tables = Context::new(batch, &self.bases, self.isa);
        // Work items: pieces of at most PIECE samples of one track.
        let pieces: Vec<(usize, usize, usize)> = (0..batch.len())
            .flat_map(|i| {
                let n = times.count(i);
                (0..n.div_ceil(PIECE)).map(move |p| (i, p * PIECE, ((p + 1) * PIECE).min(n)))
            })
            .collect();
        let run = |&(track, from, to): &(usize, usize, usize), out: &mut [f32]| {
            track::evaluate(&tables, batch.view(track), times, track, from..to, &options, out);
        };
        match options.layout {
            Layout::Track => {
                let mut slices = Vec::with_capacity(pieces.len());
                let mut rest = data;
                for &(_, from, to) in &pieces {
                    let (head, tail) = rest.split_at_mut((to - from) * channels);
                    slices.push(head);
                    rest = tail;
                }
                // At least PIECE samples per task: a million 10-sample tracks are not a million
                // tasks.
                let per_task = (PIECE * pieces.len()).div_ceil(times.total().max(1)).max(1);
                pieces.par_iter().zip(slices).with_min_len(per_task).for_each(|(piece, out)| run(piece, out));
            }
            Layout::Frame => {
                let results: Vec<Vec<f32>> = pieces
                    .par_iter()
                    .map(|piece| {
                        let mut out = vec![0.0f32; (piece.2 - piece.1) * channels];
                        run(piece, &mut out);
                        out
                    })
                    .collect();
                for (&(track, from, _), out) in pieces.iter().zip(&results) {
                    for (k, row) in out.chunks_exact(channels).enumerate() {
                        let slot = Layout::Frame.slot(times, track, from + k);
                        data[slot * channels..(slot + 1) * channels].copy_from_slice(row);
                    }
                }
            }
        }
        Ok(())
    }
}
