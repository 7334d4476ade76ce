//! The evaluation job: borrowed inputs, `validate()`, then `run()` (the ozz-animation shape).

use crate::batch::Batch;
use crate::error::{Error, Result};
use crate::reference;
use crate::sampling::{SampleTimes, TrackTimes};

/// Order of samples in the output arrays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Layout {
    /// Track 0's samples, then track 1's, ...
    #[default]
    Track,
    /// All tracks at frame 0, then all at frame 1, ... (an animation texture). Needs the same
    /// sample count in every track.
    Frame,
}

impl Layout {
    /// Where sample `j` of track `track` lands in the output, counted in samples.
    #[must_use]
    pub fn slot(self, times: &SampleTimes, track: usize, j: usize) -> usize {
        match self {
            Layout::Track => times.offsets[track] + j,
            Layout::Frame => j * times.track_count() + track,
        }
    }
}

/// Evaluated samples; derivative arrays are empty unless requested.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Output {
    /// Unit rotations `[x, y, z, w]`, sign-continuous within each track.
    pub rotations: Vec<[f64; 4]>,
    /// Body angular velocities (rad per unit time).
    pub angular_velocity: Vec<[f64; 3]>,
    /// Body angular accelerations.
    pub angular_acceleration: Vec<[f64; 3]>,
}

/// Floats per output sample of the fast paths: rotation `x, y, z, w` (4), then with
/// derivatives omega and alpha (6), then with a matrix its 9 entries, row-major.
#[must_use]
pub fn channels(derivatives: bool, matrix: bool) -> usize {
    4 + if derivatives { 6 } else { 0 } + if matrix { 9 } else { 0 }
}

/// Float32 samples of the fast paths (GPU, CPU): `samples x channels` in the requested layout. Per sample: rotation
/// `x, y, z, w`, then with derivatives `omega`, `alpha`, then with a matrix its 9 entries.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FloatOutput {
    /// Floats per sample.
    pub channels: usize,
    /// The samples.
    pub data: Vec<f32>,
}

impl FloatOutput {
    /// `samples x channels` zeros, backed by huge pages where the OS offers them.
    #[must_use]
    pub fn zeroed(samples: usize, channels: usize) -> Self {
        let mut data = vec![0.0f32; samples * channels];
        prefault(&mut data);
        Self { channels, data }
    }

    /// The rows of an f64 [`Output`], rounded to f32 (rotation, then omega and alpha when the
    /// output has them).
    #[must_use]
    pub fn from_output(out: &Output) -> Self {
        let derivatives = !out.angular_velocity.is_empty();
        let channels = channels(derivatives, false);
        let mut data = Vec::with_capacity(out.rotations.len() * channels);
        for (i, q) in out.rotations.iter().enumerate() {
            data.extend(q.iter().map(|&v| v as f32));
            if derivatives {
                data.extend(out.angular_velocity[i].iter().chain(&out.angular_acceleration[i]).map(|&v| v as f32));
            }
        }
        Self { channels, data }
    }

    /// Converts to the reference's [`Output`] (f64, rotations and derivatives).
    #[must_use]
    pub fn to_output(&self, derivatives: bool) -> Output {
        let mut out = Output::default();
        for row in self.data.chunks_exact(self.channels) {
            let r = |i: usize| f64::from(row[i]);
            out.rotations.push([r(0), r(1), r(2), r(3)]);
            if derivatives {
                out.angular_velocity.push([r(4), r(5), r(6)]);
                out.angular_acceleration.push([r(7), r(8), r(9)]);
            }
        }
        out
    }
}

/// Backs a large, fresh output with transparent huge pages and faults it in now, from every
/// core at once. The allocation is lazily zeroed memory: touched 4 KiB page by page by the
/// evaluation, it cost a page fault each, as much time as the evaluation itself for a 160 MB
/// output; huge pages touched by one thread (the GPU path's copy-out) sometimes stalled for
/// 300 ms. `MADV_POPULATE_WRITE` in parallel pieces faults 160 MB in about 4 ms here. Both
/// are hints: on an older kernel they fail harmlessly and the pages fault in lazily.
#[allow(unsafe_code)]
fn prefault(data: &mut [f32]) {
    #[cfg(target_os = "linux")]
    {
        use rayon::prelude::*;
        const HUGE: usize = 2 << 20;
        let (start, len) = (data.as_mut_ptr() as usize, std::mem::size_of_val(data));
        if len < 4 * HUGE {
            return;
        }
        let aligned = start.next_multiple_of(HUGE);
        let end = (start + len) / HUGE * HUGE;
        // SAFETY: every range below lies inside `data`, which we own mutably and which holds
        // zeros; MADV_HUGEPAGE changes how the kernel backs the pages and MADV_POPULATE_WRITE
        // only faults them in (contents stay zero). Failures leave the memory as it was.
        unsafe {
            libc::madvise(aligned as *mut libc::c_void, end - aligned, libc::MADV_HUGEPAGE);
        }
        let pieces = (end - aligned) / HUGE;
        let per = pieces.div_ceil(4 * rayon::current_num_threads()).max(1);
        (0..pieces.div_ceil(per)).into_par_iter().for_each(|i| {
            let from = aligned + i * per * HUGE;
            let to = (from + per * HUGE).min(end);
            // SAFETY: as above.
            unsafe {
                libc::madvise(from as *mut libc::c_void, to - from, libc::MADV_POPULATE_WRITE);
            }
        });
    }
    #[cfg(not(target_os = "linux"))]
    let _ = data;
}

/// Evaluates every track of a batch at its sample times with the f64 reference.
#[derive(Clone, Copy, Debug)]
pub struct EvalJob<'a> {
    /// The packed tracks.
    pub batch: &'a Batch,
    /// Per-track sample times.
    pub times: &'a SampleTimes,
    /// Output order.
    pub layout: Layout,
    /// Whether to fill the derivative arrays.
    pub derivatives: bool,
}

impl EvalJob<'_> {
    /// Checks that the inputs fit together, before any work.
    ///
    /// # Errors
    /// [`Error::EmptyBatch`], [`Error::BadJob`] when the sample lists do not match the batch or
    /// a frame-major layout meets unequal sample counts, [`Error::NonFiniteSampleTime`].
    pub fn validate(&self) -> Result<()> {
        if self.batch.is_empty() {
            return Err(Error::EmptyBatch);
        }
        if self.times.track_count() != self.batch.len() || self.times.offsets.len() != self.batch.len() + 1 {
            return Err(Error::BadJob(format!(
                "sample times cover {} tracks but the batch has {}",
                self.times.track_count(),
                self.batch.len()
            )));
        }
        for (index, times) in self.times.tracks.iter().enumerate() {
            let track = &self.batch.tracks[index];
            if let TrackTimes::Uniform { start, step, count, last } = *times {
                // The fast paths generate uniform times themselves and do not wrap them.
                let end = last.unwrap_or(start + step * count.saturating_sub(1) as f64);
                let [lo, hi] = track.domain;
                if track.looping && count > 0 && (start < lo || end > hi + 1e-9 * (hi - lo)) {
                    return Err(Error::BadJob(format!(
                        "{}: a looping track's uniform sample times must stay within its period [{lo}, {hi}]; give other times as an explicit list (SampleTimes::new wraps them)",
                        self.batch.ids[index]
                    )));
                }
            }
            if let TrackTimes::Explicit { offset, count } = *times {
                let own = self.times.explicit.get(offset..offset + count).ok_or_else(|| {
                    Error::BadJob(format!("{}: explicit sample times out of range", self.batch.ids[index]))
                })?;
                if let Some(sample) = own.iter().position(|t| !t.is_finite()) {
                    let track = self.batch.ids[index].clone();
                    return Err(Error::NonFiniteSampleTime { track, sample, value: own[sample] });
                }
            }
        }
        let first = self.times.count(0);
        if self.layout == Layout::Frame {
            if let Some(index) = (0..self.batch.len()).find(|&i| self.times.count(i) != first) {
                return Err(Error::BadJob(format!(
                    "frame-major layout needs the same sample count in every track: {} has {first}, {} has {}",
                    self.batch.ids[0],
                    self.batch.ids[index],
                    self.times.count(index)
                )));
            }
        }
        Ok(())
    }

    /// Validates, then evaluates. Tracks run on every core when the layout is track-major
    /// (each track owns one contiguous slice of the output).
    ///
    /// # Errors
    /// As [`EvalJob::validate`].
    pub fn run(&self) -> Result<Output> {
        use rayon::prelude::*;
        self.validate()?;
        let total = self.times.total();
        let tracks = self.batch.len();
        let mut out = Output { rotations: vec![[0.0; 4]; total], ..Output::default() };
        if self.derivatives {
            out.angular_velocity = vec![[0.0; 3]; total];
            out.angular_acceleration = vec![[0.0; 3]; total];
        }
        let evaluate = |index: usize, j: usize| reference::evaluate(self.batch.view(index), self.times.time(index, j));
        if self.layout == Layout::Track {
            let rotations = split_at_offsets(&mut out.rotations, &self.times.offsets);
            let omega = split_at_offsets(&mut out.angular_velocity, &self.times.offsets);
            let alpha = split_at_offsets(&mut out.angular_acceleration, &self.times.offsets);
            rotations.into_par_iter().zip(omega).zip(alpha).enumerate().for_each(|(index, ((rotations, omega), alpha))| {
                for (j, q) in rotations.iter_mut().enumerate() {
                    let sample = evaluate(index, j);
                    *q = sample.rotation.to_array();
                    if self.derivatives {
                        omega[j] = sample.angular_velocity.to_array();
                        alpha[j] = sample.angular_acceleration.to_array();
                    }
                }
            });
            return Ok(out);
        }
        for index in 0..tracks {
            for j in 0..self.times.count(index) {
                let slot = self.layout.slot(self.times, index, j);
                let sample = evaluate(index, j);
                out.rotations[slot] = sample.rotation.to_array();
                if self.derivatives {
                    out.angular_velocity[slot] = sample.angular_velocity.to_array();
                    out.angular_acceleration[slot] = sample.angular_acceleration.to_array();
                }
            }
        }
        Ok(out)
    }
}

/// `data` cut at `offsets` (`offsets[i]..offsets[i + 1]` per track); an empty `data` (an
/// output not requested) gives an empty slice per track.
fn split_at_offsets<'a, T>(mut data: &'a mut [T], offsets: &[usize]) -> Vec<&'a mut [T]> {
    offsets
        .windows(2)
        .map(|w| {
            let len = if data.is_empty() { 0 } else { w[1] - w[0] };
            let (head, tail) = std::mem::take(&mut data).split_at_mut(len);
            data = tail;
            head
        })
        .collect()
}
