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

/// Median wall time of `runs` calls after one warm-up.
pub fn median_seconds(runs: usize, mut f: impl FnMut() -> Result<(), Failure>) -> Result<f64, Failure> {
    f()?;
    let mut seconds = Vec::with_capacity(runs);
    for _ in 0..runs {
        let start = Instant::now();
        f()?;
        seconds.push(start.elapsed().as_secs_f64());
    }
    seconds.sort_by(f64::total_cmp);
    Ok(seconds[runs / 2])
}
