//! Which times each track is sampled at (DESIGN section 5).
//!
//! Uniform sampling is kept as `(start, step, count)` rather than a list of times, so that a
//! batch of millions of samples costs nothing to describe and a GPU can generate its own
//! times; tracks with their own `sample_times` keep an explicit list.

use crate::batch::Batch;
use crate::error::{Error, JobError, Result, SamplingError};

/// At most this many samples per track: a guard against a typo such as `--rate 1e9`
/// turning into an out-of-memory crash instead of an error.
pub const MAX_SAMPLES_PER_TRACK: usize = 100_000_000;

/// Samples (frames) per second that the front ends use when no rate is given (`eval`,
/// `bake`, Python's `bake`).
pub const DEFAULT_RATE: f64 = 30.0;

/// How to sample a track that has no `sample_times` of its own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sampling {
    /// `N` samples evenly from the start to the end of the domain, both included.
    Count(usize),
    /// `domain start + i / hz` for `i = 0, 1, ...` while not past the end (the end is not added).
    Rate(f64),
}

/// One track's sample times.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TrackTimes {
    /// `start + j * step` for `j < count`; with `last` set, the final sample is exactly `last`.
    Uniform {
        /// First sample time.
        start: f64,
        /// Spacing.
        step: f64,
        /// Number of samples.
        count: usize,
        /// Exact time of the final sample when it must land on the domain end (`--samples`).
        last: Option<f64>,
    },
    /// `SampleTimes::explicit[offset..offset + count]`.
    Explicit {
        /// First entry in the explicit list.
        offset: usize,
        /// Number of samples.
        count: usize,
    },
}

impl TrackTimes {
    /// Number of samples.
    #[must_use]
    pub fn count(&self) -> usize {
        match *self {
            TrackTimes::Uniform { count, .. } | TrackTimes::Explicit { count, .. } => count,
        }
    }

    /// Sample `j` of a uniform grid (`None` for a list, whose times live in
    /// [`SampleTimes::explicit`]). The one formula every path's uniform times follow.
    #[must_use]
    pub fn grid_time(&self, j: usize) -> Option<f64> {
        match *self {
            TrackTimes::Uniform { last: Some(end), count, .. } if j + 1 == count => Some(end),
            TrackTimes::Uniform { start, step, .. } => Some(start + j as f64 * step),
            TrackTimes::Explicit { .. } => None,
        }
    }
}

/// Sample times of every track of a batch, made by [`SampleTimes::new`] and its siblings
/// from the batch (so there is one entry per track and the offsets add up); read-only.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleTimes {
    tracks: Vec<TrackTimes>,
    offsets: Vec<usize>,
    explicit: Vec<f64>,
}

impl Sampling {
    /// The uniform sampling of `[start, end]`.
    ///
    /// # Errors
    /// [`Error::BadSampling`] for `Count(0)`, a rate that is not finite and positive, or more
    /// than [`MAX_SAMPLES_PER_TRACK`] samples.
    pub fn over(self, start: f64, end: f64) -> Result<TrackTimes> {
        let span = end - start;
        match self {
            Sampling::Count(0) => Err(SamplingError::ZeroCount.into()),
            Sampling::Count(n) if n > MAX_SAMPLES_PER_TRACK => {
                Err(SamplingError::TooMany { count: n, limit: MAX_SAMPLES_PER_TRACK }.into())
            }
            Sampling::Count(1) => Ok(TrackTimes::Uniform { start, step: 0.0, count: 1, last: None }),
            Sampling::Count(n) => {
                Ok(TrackTimes::Uniform { start, step: span / (n - 1) as f64, count: n, last: Some(end) })
            }
            Sampling::Rate(hz) if !(hz.is_finite() && hz > 0.0) => Err(SamplingError::BadRate(hz).into()),
            Sampling::Rate(hz) => {
                // A relative slack of 1e-9 keeps the end when j / hz lands a rounding error past it.
                let count = (span * hz * (1.0 + 1e-9)).floor() + 1.0;
                if count > MAX_SAMPLES_PER_TRACK as f64 {
                    return Err(SamplingError::RateTooHigh { hz, count, span, limit: MAX_SAMPLES_PER_TRACK }.into());
                }
                Ok(TrackTimes::Uniform { start, step: 1.0 / hz, count: count as usize, last: None })
            }
        }
    }
}

/// How [`SampleTimes::per_track`] samples one track.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PerTrack<'a> {
    /// A uniform grid ([`TrackTimes::Uniform`]).
    Grid(TrackTimes),
    /// These times (wrapped into the period for looping tracks).
    List(&'a [f64]),
}

impl SampleTimes {
    /// Times for every track of `batch`: the track's own list where `overrides[i]` is `Some`
    /// (wrapped into the period for looping tracks), else `sampling` over the track's domain.
    /// `overrides` may be shorter than the batch.
    ///
    /// # Errors
    /// As [`Sampling::over`], and [`Error::NonFiniteSampleTime`] for a NaN or infinite
    /// override, naming the track and sample.
    pub fn new(batch: &Batch, overrides: &[Option<&[f64]>], sampling: Sampling) -> Result<Self> {
        Self::per_track(batch, |index, domain| match overrides.get(index).copied().flatten() {
            Some(own) => Ok(PerTrack::List(own)),
            None => sampling.over(domain[0], domain[1]).map(PerTrack::Grid),
        })
    }

    /// Times for every track of `batch` as `each(index, domain)` says: a uniform grid over any
    /// range (stored as three numbers, not as a list: a bake samples thousands of channels on
    /// one frame grid), or a list.
    ///
    /// # Errors
    /// `each`'s errors; [`Error::NonFiniteSampleTime`] for a NaN or infinite listed time;
    /// [`Error::BadJob`] for a grid given as `TrackTimes::Explicit`.
    pub fn per_track<'a>(batch: &Batch, mut each: impl FnMut(usize, [f64; 2]) -> Result<PerTrack<'a>>) -> Result<Self> {
        let mut out = SampleTimes { tracks: Vec::new(), offsets: vec![0], explicit: Vec::new() };
        for (index, track) in batch.tracks().iter().enumerate() {
            let times = match each(index, track.domain())? {
                PerTrack::List(own) => {
                    if let Some(sample) = own.iter().position(|t| !t.is_finite()) {
                        let (track, value) = (batch.id(index), own[sample]);
                        return Err(Error::NonFiniteSampleTime { track, sample, value });
                    }
                    let offset = out.explicit.len();
                    if track.looping() {
                        // Evaluators see times inside the period (DESIGN section 3, "Loops");
                        // outputs echo the track's own list.
                        out.explicit.extend(own.iter().map(|&t| quatcurve_core::segment::wrap(t, track.domain())));
                    } else {
                        out.explicit.extend_from_slice(own);
                    }
                    TrackTimes::Explicit { offset, count: own.len() }
                }
                PerTrack::Grid(grid @ TrackTimes::Uniform { .. }) => grid,
                PerTrack::Grid(TrackTimes::Explicit { .. }) => {
                    return Err(JobError::GridNotUniform { track: batch.id(index) }.into());
                }
            };
            out.offsets.push(out.offsets[index] + times.count());
            out.tracks.push(times);
        }
        Ok(out)
    }

    /// The same `sampling` for every track.
    ///
    /// # Errors
    /// As [`Sampling::over`].
    pub fn uniform(batch: &Batch, sampling: Sampling) -> Result<Self> {
        Self::new(batch, &[], sampling)
    }

    /// Per-track description, in batch order.
    #[must_use]
    pub fn tracks(&self) -> &[TrackTimes] {
        &self.tracks
    }

    /// `offsets()[i]..offsets()[i + 1]` is track `i`'s range in track-major output (one more
    /// entry than tracks).
    #[must_use]
    pub fn offsets(&self) -> &[usize] {
        &self.offsets
    }

    /// Times of tracks with their own lists ([`TrackTimes::Explicit`] indexes them).
    #[must_use]
    pub fn explicit(&self) -> &[f64] {
        &self.explicit
    }

    /// The times of the tracks in `range` alone, for the batch's [`Batch::subset`] of the same
    /// range (grids kept as they are, lists copied).
    ///
    /// # Panics
    /// When `range` reaches past the end, like slice indexing.
    #[must_use]
    pub fn subset(&self, range: std::ops::Range<usize>) -> SampleTimes {
        let mut out = SampleTimes { tracks: Vec::with_capacity(range.len()), offsets: vec![0], explicit: Vec::new() };
        for times in &self.tracks[range] {
            out.tracks.push(match *times {
                grid @ TrackTimes::Uniform { .. } => grid,
                TrackTimes::Explicit { offset, count } => {
                    let start = out.explicit.len();
                    out.explicit.extend_from_slice(&self.explicit[offset..offset + count]);
                    TrackTimes::Explicit { offset: start, count }
                }
            });
            out.offsets.push(out.offsets[out.offsets.len() - 1] + times.count());
        }
        out
    }

    /// Sample `j` of track `index`.
    #[must_use]
    pub fn time(&self, index: usize, j: usize) -> f64 {
        match self.tracks[index] {
            TrackTimes::Explicit { offset, .. } => self.explicit[offset + j],
            grid => grid.grid_time(j).unwrap_or_default(),
        }
    }

    /// All of track `index`'s times.
    #[must_use]
    pub fn track_times(&self, index: usize) -> Vec<f64> {
        (0..self.count(index)).map(|j| self.time(index, j)).collect()
    }

    /// Number of samples of track `index`.
    #[must_use]
    pub fn count(&self, index: usize) -> usize {
        self.tracks[index].count()
    }

    /// The one sample count of every track of `batch` (0 for none), for outputs that hold
    /// all tracks in one array.
    ///
    /// # Errors
    /// [`JobError::UnequalCounts`] naming the first track and the first that differs, and
    /// `needed_by` (what needs one count: "a frame-major layout", ".npy output").
    pub fn equal_counts(&self, batch: &Batch, needed_by: &'static str) -> std::result::Result<usize, JobError> {
        let first = if self.tracks.is_empty() { 0 } else { self.count(0) };
        match (0..self.tracks.len()).find(|&i| self.count(i) != first) {
            None => Ok(first),
            Some(index) => Err(JobError::UnequalCounts {
                first: batch.id(0),
                count: first,
                other: batch.id(index),
                other_count: self.count(index),
                needed_by,
            }),
        }
    }

    /// Number of tracks covered.
    #[must_use]
    pub fn track_count(&self) -> usize {
        self.tracks.len()
    }

    /// Total number of samples.
    #[must_use]
    pub fn total(&self) -> usize {
        self.offsets.last().copied().unwrap_or(0)
    }
}
