//! What every bench shares: a device opened to be timed, and the median of timed runs.

use super::Failure;
use quatcurve::{Device, DeviceChoice};
use std::time::Instant;

/// Device `choice` for a bench: `None` (skipped, said on stderr) when it is missing and the
/// devices were not named; an error when they were.
pub fn open_bench_device(choice: DeviceChoice, explicit: bool) -> Result<Option<Device>, Failure> {
    match (choice, super::open_device(choice, "--devices")) {
        (DeviceChoice::Auto, _) => Err(Failure::Input("bench: name devices (reference, cpu, gpu), not auto".into())),
        (_, Ok(device)) => Ok(Some(device)),
        (_, Err(e)) if explicit => Err(e),
        (_, Err(Failure::Input(e) | Failure::Internal(e))) => {
            eprintln!("skipped {choice}: {e}");
            Ok(None)
        }
    }
}

/// The fastest, median and slowest wall time of timed runs.
#[derive(Clone, Copy, Debug)]
pub struct Seconds {
    pub min: f64,
    pub median: f64,
    pub max: f64,
}

impl Seconds {
    /// Of the wall times of timed runs (at least one).
    fn of(mut times: Vec<f64>) -> Self {
        times.sort_by(f64::total_cmp);
        Self { min: times[0], median: times[times.len() / 2], max: times[times.len() - 1] }
    }
}

/// The wall time of one call of `f`.
fn timed(f: &mut dyn FnMut() -> Result<(), Failure>) -> Result<f64, Failure> {
    let start = Instant::now();
    f()?;
    Ok(start.elapsed().as_secs_f64())
}

/// Wall times of `runs` calls after one warm-up.
pub fn run_seconds(runs: usize, mut f: impl FnMut() -> Result<(), Failure>) -> Result<Seconds, Failure> {
    f()?;
    Ok(Seconds::of((0..runs).map(|_| timed(&mut f)).collect::<Result<_, _>>()?))
}

/// Wall times of `runs` calls of `a` and of `b` after one warm-up each, taken in turns, so that
/// the two see the same moments of a shared, noisy machine: two figures of one workload timed
/// one after the other can trade places on noise alone.
pub fn alternate_seconds(
    runs: usize,
    mut a: impl FnMut() -> Result<(), Failure>,
    mut b: impl FnMut() -> Result<(), Failure>,
) -> Result<(Seconds, Seconds), Failure> {
    // One warm-up each.
    a()?;
    b()?;
    let (mut first, mut second) = (Vec::with_capacity(runs), Vec::with_capacity(runs));
    for _ in 0..runs {
        first.push(timed(&mut a)?);
        second.push(timed(&mut b)?);
    }
    Ok((Seconds::of(first), Seconds::of(second)))
}

/// Median wall time of `runs` calls after one warm-up ([`run_seconds`]).
pub fn median_seconds(runs: usize, f: impl FnMut() -> Result<(), Failure>) -> Result<f64, Failure> {
    Ok(run_seconds(runs, f)?.median)
}

/// The host's processor, as `/proc/cpuinfo` names it, and its logical cores.
pub fn host() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find_map(|l| l.strip_prefix("model name").map(|v| v.trim_start_matches([' ', '\t', ':']).to_string()))
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    format!("{model}, {cores} logical cores")
}
