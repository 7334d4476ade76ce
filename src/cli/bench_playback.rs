//! `quatcurve bench --playback`: crowd playback speed (DESIGN section 17). One frame of `play`'s
//! schedule, every instance blended between two clips (the full cost of a frame), timed per
//! device and crowd size: the skin palettes of every instance, in milliseconds a frame and
//! instance-joints per second.

use super::measure::{open_bench_device, run_seconds};
use super::{print_stdout, Failure};
use quatcurve::anim::curves::CurveChoice;
use quatcurve::anim::loops::LoopMode;
use quatcurve::formats::source::Source;
use quatcurve::options::CurveOptions;
use quatcurve::play::schedule::Schedule;
use quatcurve::play::Playback;
use quatcurve::DeviceChoice;
use serde::Serialize;
use std::path::Path;

/// The blend weight every instance is timed with: a blend evaluates two poses per instance.
pub const BENCH_BLEND: f32 = 0.5;

#[derive(Serialize)]
pub struct PlaybackReport {
    input: String,
    joints: usize,
    runs: usize,
    blend_weight: f32,
    results: Vec<PlaybackTiming>,
}

#[derive(Serialize)]
struct PlaybackTiming {
    device: String,
    instances: usize,
    /// The median of the runs, with the fastest and slowest.
    ms_per_frame: f64,
    ms_per_frame_min: f64,
    ms_per_frame_max: f64,
    instance_joints_per_s: f64,
}

/// Times one frame of `instances` instances of `file`'s clips on `devices`.
pub fn measure(
    file: &Path,
    instances: &[usize],
    runs: usize,
    devices: Option<&[DeviceChoice]>,
) -> Result<PlaybackReport, Failure> {
    let input = file.display().to_string();
    let source =
        Source::read(file, Default::default()).map_err(|e| Failure::Input(format!("bench --playback {input}: {e}")))?;
    let curve = CurveChoice::new(source.default_curve(), &CurveOptions::DEFAULT);
    let playback = Playback::new(source.animation().clone(), &curve, LoopMode::Auto, None)
        .map_err(|e| Failure::Input(format!("bench --playback {input}: {e}")))?;
    let joints = playback.palette_joints();
    let explicit = devices.is_some();
    let devices = devices.map_or_else(|| vec![DeviceChoice::Cpu, DeviceChoice::Gpu], <[DeviceChoice]>::to_vec);
    let mut results = Vec::new();
    for choice in devices {
        let Some(device) = open_bench_device(choice, explicit)? else { continue };
        // Clips go to the device once; a frame sends only its instances.
        let player = playback.player(&device).map_err(|e| Failure::Internal(format!("{input}: {e}")))?;
        for &count in instances {
            let schedule = Schedule { instances: count, rate: 30.0, blend: Some(BENCH_BLEND), blend_clip: None };
            let frame = schedule.frame(&playback, 7);
            let seconds = run_seconds(runs, || {
                let palettes = player.palettes(&frame).map_err(|e| Failure::Internal(format!("{input}: {e}")))?;
                std::hint::black_box(palettes);
                Ok(())
            })?;
            results.push(PlaybackTiming {
                device: device.name(),
                instances: count,
                ms_per_frame: seconds.median * 1e3,
                ms_per_frame_min: seconds.min * 1e3,
                ms_per_frame_max: seconds.max * 1e3,
                instance_joints_per_s: (count * joints) as f64 / seconds.median,
            });
        }
    }
    Ok(PlaybackReport { input, joints, runs, blend_weight: BENCH_BLEND, results })
}

/// The report as a table.
pub fn table(w: &mut dyn std::io::Write, report: &PlaybackReport) -> std::io::Result<()> {
    writeln!(
        w,
        "playback: {} ({} palette joints), every instance blending two clips at weight {}; median of {} runs",
        report.input, report.joints, report.blend_weight, report.runs
    )?;
    writeln!(w, "{:<44} {:>10} {:>24} {:>20}", "device", "instances", "ms/frame min-med-max", "instance-joints/s")?;
    for r in &report.results {
        let ms = format!("{:.3}-{:.3}-{:.3}", r.ms_per_frame_min, r.ms_per_frame, r.ms_per_frame_max);
        writeln!(w, "{:<44} {:>10} {:>24} {:>20.3e}", r.device, r.instances, ms, r.instance_joints_per_s)?;
    }
    Ok(())
}

/// Runs `bench --playback`.
pub fn run(
    file: &Path,
    instances: &[usize],
    runs: usize,
    devices: Option<&[DeviceChoice]>,
    json: bool,
) -> Result<(), Failure> {
    let report = measure(file, instances, runs, devices)?;
    print_stdout(|w| if json { writeln!(w, "{}", serde_json::to_string(&report)?) } else { table(w, &report) })
}
