//! Track JSON -> batch builder (every curve, open and looping) -> fast CPU evaluation with
//! derivatives, in memory.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quatcurve::{Batch, Curve, CurveSpec, Device, DeviceChoice, EvalJob, SampleTimes, Sampling, TrackFile};

fuzz_target!(|bytes: &[u8]| {
    let Ok(file) = serde_json::from_slice::<TrackFile>(bytes) else { return };
    let device = Device::open(DeviceChoice::Cpu).unwrap();
    for curve in [Curve::Slerp, Curve::Squad, Curve::Hermite, Curve::NamKim, Curve::BSpline, Curve::BSplineInterp] {
        for looping in [false, true] {
            let Ok(batch) = Batch::from_tracks(&file.tracks, &CurveSpec { looping, ..CurveSpec::new(curve) }) else {
                continue;
            };
            let overrides: Vec<Option<&[f64]>> = file.tracks.iter().map(|t| t.sample_times.as_deref()).collect();
            let Ok(times) = SampleTimes::new(&batch, &overrides, Sampling::Count(7)) else { continue };
            let _ = device.evaluate(&EvalJob::new(&batch, &times).derivatives(true));
        }
    }
});
