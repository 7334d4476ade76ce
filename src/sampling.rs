//! Which times each track is sampled at (DESIGN section 5).

use crate::batch::Batch;
use crate::error::{Error, Result};

/// At most this many samples per track: a guard against a typo such as `--rate 1e9`
/// turning into an out-of-memory crash instead of an error.
pub const MAX_SAMPLES_PER_TRACK: usize = 100_000_000;

/// How to sample a track that has no `sample_times` of its own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sampling {
    /// `N` samples evenly from the start to the end of the domain, both included.
    Count(usize),
    /// `domain start + i / hz` for `i = 0, 1, ...` while not past the end (the end is not added).
    Rate(f64),
}

/// Sample times of every track, packed CSR style like the batch.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SampleTimes {
    /// `offsets[i]..offsets[i + 1]` indexes track `i`'s times; `len = tracks + 1`.
    pub offsets: Vec<usize>,
    /// All sample times, track after track.
    pub times: Vec<f64>,
}

impl Sampling {
    /// The sample times over `[start, end]`.
    ///
    /// # Errors
    /// [`Error::BadSampling`] for `Count(0)`, a rate that is not finite and positive, or more
    /// than [`MAX_SAMPLES_PER_TRACK`] samples.
    pub fn times(self, start: f64, end: f64) -> Result<Vec<f64>> {
        let span = end - start;
        match self {
            Sampling::Count(0) => Err(Error::BadSampling("--samples must be at least 1".into())),
            Sampling::Count(n) if n > MAX_SAMPLES_PER_TRACK => {
                Err(Error::BadSampling(format!("--samples {n} is more than {MAX_SAMPLES_PER_TRACK} per track")))
            }
            Sampling::Count(1) => Ok(vec![start]),
            Sampling::Count(n) => Ok((0..n)
                .map(|i| if i + 1 == n { end } else { start + span * i as f64 / (n - 1) as f64 })
                .collect()),
            Sampling::Rate(hz) if !(hz.is_finite() && hz > 0.0) => {
                Err(Error::BadSampling(format!("--rate must be a positive number of samples per second, got {hz}")))
            }
            Sampling::Rate(hz) => {
                // A relative slack of 1e-9 keeps the end when i / hz lands a rounding error past it.
                let count = (span * hz * (1.0 + 1e-9)).floor() + 1.0;
                if count > MAX_SAMPLES_PER_TRACK as f64 {
                    return Err(Error::BadSampling(format!(
                        "--rate {hz} gives {count} samples over a domain of {span}, more than {MAX_SAMPLES_PER_TRACK} per track"
                    )));
                }
                Ok((0..count as usize).map(|i| start + i as f64 / hz).collect())
            }
        }
    }
}

impl SampleTimes {
    /// Times for every track of `batch`: the track's own list where `overrides[i]` is `Some`,
    /// else `sampling` over the track's domain. `overrides` may be shorter than the batch.
    ///
    /// # Errors
    /// As [`Sampling::times`], and [`Error::NonFiniteSampleTime`] for a NaN or infinite
    /// override, naming the track and sample.
    pub fn new(batch: &Batch, overrides: &[Option<&[f64]>], sampling: Sampling) -> Result<Self> {
        let mut out = SampleTimes { offsets: vec![0], times: Vec::new() };
        for (index, track) in batch.tracks.iter().enumerate() {
            match overrides.get(index).copied().flatten() {
                Some(own) => {
                    if let Some(sample) = own.iter().position(|t| !t.is_finite()) {
                        let (track, value) = (batch.ids[index].clone(), own[sample]);
                        return Err(Error::NonFiniteSampleTime { track, sample, value });
                    }
                    out.times.extend_from_slice(own);
                }
                None => out.times.extend(sampling.times(track.domain[0], track.domain[1])?),
            }
            out.offsets.push(out.times.len());
        }
        Ok(out)
    }

    /// The same `sampling` for every track.
    ///
    /// # Errors
    /// As [`Sampling::times`].
    pub fn uniform(batch: &Batch, sampling: Sampling) -> Result<Self> {
        Self::new(batch, &[], sampling)
    }

    /// Track `index`'s times.
    #[must_use]
    pub fn track(&self, index: usize) -> &[f64] {
        &self.times[self.offsets[index]..self.offsets[index + 1]]
    }

    /// Number of tracks covered.
    #[must_use]
    pub fn track_count(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }
}
