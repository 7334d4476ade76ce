//! `quatcurve bench --fitted`: decompression speed. Fitted containers' clips (copied to make a
//! batch) baked in memory at each clip's source rate on each device, as a bake evaluates them:
//! rotations in the packed batch, vectors beside it. A bone-pose is one joint's transform at one
//! frame (ACL's unit; its published single-core figure is 30-45 ns per bone-pose). The CPU path
//! is timed on every thread and on one.

use super::measure::{median_seconds, open_bench_device, run_seconds};
use super::{print_stdout, Failure};
use quatcurve::anim::curves::CurveChoice;
use quatcurve::anim::loops::LoopMode;
use quatcurve::anim::Animation;
use quatcurve::bake::{self, ClipRate, Reuse};
use quatcurve::qcf::decoder::{Clip, ClipDecoder, Decoder};
use quatcurve::qcf::Container;
use quatcurve::{Device, DeviceChoice};
use serde::Serialize;
use std::path::PathBuf;

/// ACL's published decompression cost per bone-pose on one core, ns (its lowest and highest;
/// a cold cache, on its authors' machines). `examples/acl/run.sh` measures ACL beside this
/// bench on the machine at hand.
pub const ACL_NS_PER_BONE_POSE: [f64; 2] = [30.0, 45.0];

#[derive(Serialize)]
pub struct FittedReport {
    files: Vec<String>,
    copies: usize,
    clips: usize,
    poses: usize,
    bone_poses: usize,
    runs: usize,
    acl_ns_per_bone_pose: [f64; 2],
    /// Reading the containers' bytes into the model a bake starts from, once per copy.
    load: FittedLoad,
    /// Checking a container whole before its clips are opened (every field, code and the
    /// checksum), once per copy: what a player pays once per file it loads.
    check: FittedLoad,
    /// The runtime's way: each clip opened from its checked container's runtime form, then
    /// every frame's local pose in order, one thread.
    decoder: FittedLoad,
    /// Opening a clip alone, microseconds a clip (the median of the runs).
    open_us_per_clip: f64,
    /// What the runtime decoders hold ([`Decoder::bytes`]: the clips' runtime form and the rest
    /// pose), per bone-pose of one copy.
    held_bytes_per_bone_pose: f64,
    /// What one clip being decoded holds besides them (its cursors and pose), the largest.
    state_bytes_per_clip: usize,
    /// Each clip of the containers alone, opened and decoded `copies` times.
    per_clip: Vec<FittedClipTiming>,
    results: Vec<FittedTiming>,
}

#[derive(Serialize)]
struct FittedLoad {
    seconds: f64,
    /// Per bone-pose of one decode of every clip.
    ns_per_bone_pose: f64,
}

impl FittedLoad {
    fn of(seconds: f64, bone_poses: usize) -> Self {
        Self { seconds, ns_per_bone_pose: seconds * 1e9 / bone_poses as f64 }
    }
}

#[derive(Serialize)]
struct FittedClipTiming {
    file: String,
    clip: String,
    frames: usize,
    joints: usize,
    /// Its runtime form ([`Decoder::clip_bytes`]), and that per bone-pose of one decode.
    held_bytes: usize,
    held_bytes_per_bone_pose: f64,
    /// Opening it and decoding every frame, per bone-pose (the median of the runs).
    ns_per_bone_pose: f64,
}

#[derive(Serialize)]
struct FittedTiming {
    device: String,
    threads: Option<usize>,
    /// The median of the runs, with the fastest and slowest.
    seconds: f64,
    seconds_min: f64,
    seconds_max: f64,
    poses_per_s: f64,
    ns_per_bone_pose: f64,
}

/// Times the decompression of `files`' clips, each `copies` times, on `devices`.
pub fn measure(
    files: &[PathBuf],
    copies: usize,
    runs: usize,
    devices: Option<&[DeviceChoice]>,
) -> Result<FittedReport, Failure> {
    let mut animations: Vec<(Animation, Vec<ClipRate>)> = Vec::new();
    let mut files_bytes = Vec::with_capacity(files.len());
    for file in files {
        let input = |e: String| Failure::Input(format!("bench --fitted {}: {e}", file.display()));
        let bytes = std::fs::read(file).map_err(|e| input(e.to_string()))?;
        let container = Container::from_bytes(&bytes).map_err(|e| input(format!("fitted container {e}")))?;
        files_bytes.push(bytes);
        let mut animation = container.animation();
        let rates: Vec<ClipRate> = container.clips.iter().map(|c| ClipRate::Fit(c.source_rate())).collect();
        animation.clips = animation.clips.iter().cycle().take(animation.clips.len() * copies).cloned().collect();
        let rates = rates.iter().cycle().take(rates.len() * copies).copied().collect();
        animations.push((animation, rates));
    }
    // Every fitted channel is evaluated as the fit's own curve.
    let curve = CurveChoice::Source;
    // Poses and bone-poses decompressed; each container's buffers kept from run to run, as a
    // decoder keeps them from clip to clip.
    let mut reuse: Vec<Reuse> = animations.iter().map(|_| Reuse::default()).collect();
    let mut bake_all = |device: &Device| -> Result<(usize, usize), Failure> {
        let (mut poses, mut bone_poses) = (0, 0);
        for ((animation, rates), reuse) in animations.iter().zip(&mut reuse) {
            let baked = bake::bake_reusing(animation, &curve, rates, LoopMode::Off, device, reuse)
                .map_err(|e| Failure::Internal(e.to_string()))?;
            let frames: usize = baked.clips.iter().map(|c| c.times.len()).sum();
            poses += frames;
            bone_poses += frames * animation.joints.len();
            reuse.keep(baked);
        }
        Ok((poses, bone_poses))
    };
    let explicit = devices.is_some();
    let devices = devices.map_or_else(|| vec![DeviceChoice::Cpu, DeviceChoice::Gpu], <[DeviceChoice]>::to_vec);
    let (mut poses, mut bone_poses) = (0, 0);
    let mut results = Vec::new();
    let mut time = |device: &Device| -> Result<(), Failure> {
        let seconds = run_seconds(runs, || {
            (poses, bone_poses) = bake_all(device)?;
            Ok(())
        })?;
        // The host threads that bake: the GPU's work is its own, so its row has none.
        let threads = match device {
            Device::Reference => Some(1),
            Device::Cpu(_) => Some(rayon::current_num_threads()),
            _ => None,
        };
        results.push(FittedTiming {
            device: device.name(),
            threads,
            seconds: seconds.median,
            seconds_min: seconds.min,
            seconds_max: seconds.max,
            poses_per_s: poses as f64 / seconds.median,
            ns_per_bone_pose: seconds.median * 1e9 / bone_poses as f64,
        });
        Ok(())
    };
    for choice in devices {
        let Some(device) = open_bench_device(choice, explicit)? else { continue };
        time(&device)?;
        // The CPU path on one thread as well: the figure to set beside a one-core one.
        if matches!(device, Device::Cpu(_)) && rayon::current_num_threads() > 1 {
            let one = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .map_err(|e| Failure::Internal(format!("a one-thread pool: {e}")))?;
            one.install(|| time(&device))?;
        }
    }
    // Loading: the container's bytes read into the model a bake starts from (codes unpacked,
    // control points dequantized), on one thread, once per copy.
    let load_seconds = median_seconds(runs, || {
        for bytes in &files_bytes {
            for _ in 0..copies {
                let container = Container::from_bytes(bytes).map_err(|e| Failure::Internal(e.to_string()))?;
                std::hint::black_box(container.animation());
            }
        }
        Ok(())
    })?;
    // The runtime's way ([`Decoder`]): each container checked once, as a player loads a file;
    // then each copy of each clip opened and every frame's local pose decoded in order into
    // one pose buffer, as a player keeps one.
    let check_seconds = median_seconds(runs, || {
        for bytes in &files_bytes {
            for _ in 0..copies {
                std::hint::black_box(Decoder::from_bytes(bytes).map_err(|e| Failure::Internal(e.to_string()))?);
            }
        }
        Ok(())
    })?;
    let decoders = files_bytes
        .iter()
        .map(|bytes| Decoder::from_bytes(bytes).map_err(|e| Failure::Internal(e.to_string())))
        .collect::<Result<Vec<_>, _>>()?;
    // Each clip with its file, its decoder and its frame times.
    let clips: Vec<(&PathBuf, &Decoder, usize, Vec<f64>)> = files
        .iter()
        .zip(&decoders)
        .flat_map(|(file, decoder)| (0..decoder.clips().len()).map(move |index| (file, decoder, index)))
        .map(|(file, decoder, index)| Ok((file, decoder, index, frame_times(&decoder.clips()[index])?)))
        .collect::<Result<_, Failure>>()?;
    let mut pose = Vec::new();
    let decoder_seconds = median_seconds(runs, || {
        for _ in 0..copies {
            for (_, decoder, index, times) in &clips {
                play(&mut open(decoder, *index)?, times, &mut pose)?;
            }
        }
        Ok(())
    })?;
    let open_seconds = median_seconds(runs, || {
        for _ in 0..copies {
            for (_, decoder, index, _) in &clips {
                std::hint::black_box(open(decoder, *index)?);
            }
        }
        Ok(())
    })?;
    let mut state_bytes = 0;
    for (_, decoder, index, _) in &clips {
        state_bytes = state_bytes.max(open(decoder, *index)?.state_bytes());
    }
    let held: usize = decoders.iter().map(Decoder::bytes).sum();
    let mut per_clip = Vec::with_capacity(clips.len());
    for (file, decoder, index, times) in &clips {
        let seconds = median_seconds(runs, || {
            for _ in 0..copies {
                play(&mut open(decoder, *index)?, times, &mut pose)?;
            }
            Ok(())
        })?;
        let (frames, joints, held_bytes) = (times.len(), decoder.joints.len(), decoder.clip_bytes(*index));
        let bone_poses = (frames * joints).max(1) as f64;
        per_clip.push(FittedClipTiming {
            file: file.display().to_string(),
            clip: decoder.clips()[*index].name.clone(),
            frames,
            joints,
            held_bytes,
            held_bytes_per_bone_pose: held_bytes as f64 / bone_poses,
            ns_per_bone_pose: seconds * 1e9 / (bone_poses * copies as f64),
        });
    }
    Ok(FittedReport {
        check: FittedLoad::of(check_seconds, bone_poses),
        decoder: FittedLoad::of(decoder_seconds, bone_poses),
        open_us_per_clip: open_seconds * 1e6 / (copies * clips.len()) as f64,
        held_bytes_per_bone_pose: (held * copies) as f64 / bone_poses as f64,
        state_bytes_per_clip: state_bytes,
        per_clip,
        load: FittedLoad::of(load_seconds, bone_poses),
        files: files.iter().map(|f| f.display().to_string()).collect(),
        copies,
        clips: animations.iter().map(|(a, _)| a.clips.len()).sum(),
        poses,
        bone_poses,
        runs,
        acl_ns_per_bone_pose: ACL_NS_PER_BONE_POSE,
        results,
    })
}

/// A clip's frame times at its source rate, as a bake of it takes them.
fn frame_times(clip: &Clip) -> Result<Vec<f64>, Failure> {
    let [start, end] = clip.span;
    let (grid, _) = bake::fitted_frame_grid(start, end, clip.rate).map_err(|e| Failure::Internal(e.to_string()))?;
    Ok(bake::grid_times(grid))
}

/// Clip `index` of `decoder` opened.
fn open(decoder: &Decoder, index: usize) -> Result<ClipDecoder<'_>, Failure> {
    decoder.open(index).map_err(|e| Failure::Internal(e.to_string()))
}

/// Every pose of `clip` at `times`, in order, into one pose buffer as a player keeps one.
fn play(clip: &mut ClipDecoder, times: &[f64], pose: &mut Vec<f32>) -> Result<(), Failure> {
    pose.resize(clip.pose_floats(), 0.0);
    for &t in times {
        clip.pose(t, pose).map_err(|e| Failure::Internal(e.to_string()))?;
        std::hint::black_box(&pose);
    }
    Ok(())
}

/// The report as a table.
pub fn table(w: &mut dyn std::io::Write, report: &FittedReport) -> std::io::Result<()> {
    writeln!(
        w,
        "decompression: {} clips ({} copies of {}), {} poses, {} bone-poses; median of {} runs; ACL's published \
         figure: {}-{} ns a bone-pose on one core of its own machines (examples/acl/run.sh runs ACL here)",
        report.clips,
        report.copies,
        report.files.join(", "),
        report.poses,
        report.bone_poses,
        report.runs,
        report.acl_ns_per_bone_pose[0],
        report.acl_ns_per_bone_pose[1]
    )?;
    writeln!(
        w,
        "loading the containers (bytes to control points, one thread): {:.4} s, {:.2} ns a bone-pose; then decoding:",
        report.load.seconds, report.load.ns_per_bone_pose
    )?;
    writeln!(
        w,
        "checking the containers (every field and code, once a file, one thread): {:.4} s, {:.2} ns a bone-pose",
        report.check.seconds, report.check.ns_per_bone_pose
    )?;
    writeln!(
        w,
        "the runtime decoder (each clip opened, then every frame's local pose in order, one thread): {:.4} s, {:.2} ns \
         a bone-pose; opening {:.2} us a clip; it holds the containers ({:.2} bytes a bone-pose) and up to {} bytes a \
         clip being decoded",
        report.decoder.seconds,
        report.decoder.ns_per_bone_pose,
        report.open_us_per_clip,
        report.held_bytes_per_bone_pose,
        report.state_bytes_per_clip
    )?;
    writeln!(w, "each clip alone (opened and decoded {} times):", report.copies)?;
    writeln!(w, "| file | clip | frames | joints | held KB | bytes/bone-pose | ns/bone-pose |")?;
    writeln!(w, "|---|---|---:|---:|---:|---:|---:|")?;
    for c in &report.per_clip {
        writeln!(
            w,
            "| {} | {} | {} | {} | {:.1} | {:.2} | {:.2} |",
            c.file,
            c.clip,
            c.frames,
            c.joints,
            c.held_bytes as f64 / 1024.0,
            c.held_bytes_per_bone_pose,
            c.ns_per_bone_pose
        )?;
    }
    writeln!(w, "baking them:")?;
    writeln!(w, "{:<44} {:>8} {:>22} {:>14} {:>12}", "device", "threads", "s min-med-max", "poses/s", "ns/bone-pose")?;
    for r in &report.results {
        writeln!(
            w,
            "{:<44} {:>8} {:>22} {:>14.0} {:>12.2}",
            r.device,
            r.threads.map_or_else(|| "-".to_string(), |t| t.to_string()),
            format!("{:.4}-{:.4}-{:.4}", r.seconds_min, r.seconds, r.seconds_max),
            r.poses_per_s,
            r.ns_per_bone_pose
        )?;
    }
    Ok(())
}

/// Runs `bench --fitted`.
pub fn run(
    files: &[PathBuf],
    copies: usize,
    runs: usize,
    devices: Option<&[DeviceChoice]>,
    json: bool,
) -> Result<(), Failure> {
    let report = measure(files, copies, runs, devices)?;
    print_stdout(|w| if json { writeln!(w, "{}", serde_json::to_string(&report)?) } else { table(w, &report) })
}
