//! Deterministic synthetic tracks for benchmarks and demos: smooth, walk-like rotations with
//! a little per-track variation, and [`SplitMix`], the one random generator of the crate and
//! its tests (no randomness crate needed).

use crate::batch::{Batch, BatchBuilder};
use crate::error::Result;
use crate::sampling::{SampleTimes, Sampling};
use crate::track::Track;
use quatcurve_core::curve::CurveSpec;
use quatcurve_core::quat::{QuatF64, Vec3F64};
use std::ops::Range;

/// `tracks` tracks of `keys` keys each at `rate` keys per second: each joint swings about a
/// tilted axis with a per-track phase, amplitude and twist (up to about 80 degrees).
#[must_use]
pub fn walk_tracks(tracks: usize, keys: usize, rate: f64) -> Vec<Track> {
    swings(0..tracks, keys, rate, |h| 0.8 + 0.6 * h)
}

/// Like [`walk_tracks`], but each track is one whole gait cycle: its last key is its first
/// pose again, as in a looping clip (the `--loop` workload).
#[must_use]
pub fn walk_cycles(tracks: usize, keys: usize, rate: f64) -> Vec<Track> {
    swings(0..tracks, keys, rate, |_| rate / (keys - 1).max(1) as f64)
}

/// The swings of [`walk_tracks`] with indices `tracks`, at the frequency `frequency(h)` picks
/// from a hash in [0, 1).
fn swings(tracks: Range<usize>, keys: usize, rate: f64, frequency: impl Fn(f64) -> f64) -> Vec<Track> {
    tracks
        .map(|i| {
            // A cheap hash of the track index for variety.
            let h =
                |k: u64| ((i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15 ^ k) >> 40) as f64 / (1u64 << 24) as f64;
            let (phase, amplitude, twist) = (6.3 * h(1), 0.2 + 0.5 * h(2), 0.3 * h(3) - 0.15);
            let frequency = frequency(h(4));
            let times: Vec<f64> = (0..keys).map(|j| j as f64 / rate).collect();
            let rotations = times
                .iter()
                .map(|&t| {
                    let a = (std::f64::consts::TAU * frequency * t + phase).sin();
                    QuatF64::exp(Vec3F64::new(amplitude * a, 0.3 * amplitude * (2.0 * a).cos(), twist)).to_array()
                })
                .collect();
            Track { name: Some(format!("joint{i}")), times: Some(times), ..Track::from_rotations(rotations) }
        })
        .collect()
}

/// Keys per track of [`workload`]: a few seconds of animation keyed at 30 Hz.
pub const WORKLOAD_KEYS: usize = 32;

/// The tracks of [`workload`]: [`walk_tracks`], or [`walk_cycles`] when `spec` loops.
#[must_use]
pub fn workload_tracks(tracks: usize, keys: usize, spec: &CurveSpec) -> Vec<Track> {
    workload_slice(0..tracks, keys, spec)
}

/// Tracks `range` of [`workload_tracks`] (each track is a function of its index alone).
fn workload_slice(range: Range<usize>, keys: usize, spec: &CurveSpec) -> Vec<Track> {
    const RATE: f64 = 30.0;
    if spec.looping {
        swings(range, keys, RATE, |_| RATE / (keys - 1).max(1) as f64)
    } else {
        swings(range, keys, RATE, |h| 0.8 + 0.6 * h)
    }
}

/// The batch of [`workload_tracks`], built from slices of [`SLICE`] tracks generated one at a
/// time, so the tracks of the whole batch never sit in memory beside it; with the seconds
/// spent in [`BatchBuilder::extend`] (validation and coefficients, generation not counted).
///
/// # Errors
/// As [`workload`].
pub fn workload_batch(tracks: usize, keys: usize, spec: &CurveSpec) -> Result<(Batch, f64)> {
    let mut builder = BatchBuilder::new();
    let mut seconds = 0.0;
    for start in (0..tracks).step_by(SLICE) {
        let slice = workload_slice(start..(start + SLICE).min(tracks), keys, spec);
        let timer = std::time::Instant::now();
        builder.extend(&slice, |_| *spec)?;
        seconds += timer.elapsed().as_secs_f64();
    }
    Ok((builder.build()?, seconds))
}

/// Tracks [`workload_batch`] generates at once.
pub const SLICE: usize = 1 << 16;

/// The benchmark workload shared by `quatcurve bench` and the criterion benches:
/// `tracks` [`workload_tracks`] of `keys` keys ([`WORKLOAD_KEYS`] by default) at 30 Hz,
/// `samples` samples per track from domain start to end.
///
/// # Errors
/// The spec's errors (an order outside 2..=8, phantom knots with order other than 4).
pub fn workload(tracks: usize, samples: usize, keys: usize, spec: &CurveSpec) -> Result<(Batch, SampleTimes)> {
    let (batch, _) = workload_batch(tracks, keys, spec)?;
    let times = SampleTimes::uniform(&batch, Sampling::Count(samples))?;
    Ok((batch, times))
}

/// SplitMix64 (Steele, Lea & Flood 2014): a small, well-mixed generator, so that a seed means
/// the same sequences on every machine and version of the dependencies.
#[derive(Clone, Debug)]
pub struct SplitMix(u64);

impl SplitMix {
    /// The generator started from `seed`.
    #[must_use]
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform on the unit sphere.
    pub fn direction(&mut self) -> Vec3F64 {
        let z = 2.0 * self.unit() - 1.0;
        let phi = std::f64::consts::TAU * self.unit();
        let r = (1.0 - z * z).sqrt();
        Vec3F64::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Uniform on SO(3) (Shoemake, Graphics Gems III: uniform random rotations).
    pub fn rotation(&mut self) -> QuatF64 {
        let (u1, u2, u3) = (self.unit(), std::f64::consts::TAU * self.unit(), std::f64::consts::TAU * self.unit());
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        QuatF64::from_xyzw(a * u2.sin(), a * u2.cos(), b * u3.sin(), b * u3.cos())
    }
}
