//! `quatcurve bench`: one synthetic batch through every requested device in one process,
//! median samples per second side by side (DESIGN section 5).

use super::measure::{alternate_seconds, host, median_seconds, open_bench_device, run_seconds, Seconds};
use super::{names, print_stdout, CurveOptions, Failure};
use clap::Args;
use quatcurve::anim::loops::LoopMode;
use quatcurve::{
    synthetic, Batch, CpuEvaluator, Curve, CurveSpec, Device, DeviceChoice, EvalJob, GpuDevice, JobOptions,
    SampleTimes, Sampling,
};
use serde::Serialize;

#[derive(Args, Debug, Clone)]
pub struct BenchArgs {
    /// Tracks in the batch.
    #[arg(long, default_value_t = 10_000)]
    tracks: usize,
    /// Samples per track.
    #[arg(long, default_value_t = 1_000)]
    samples: usize,
    /// Keys per track (a Bezier track's degree is one less).
    #[arg(long, default_value_t = synthetic::WORKLOAD_KEYS)]
    keys: usize,
    /// Curve family (as eval's).
    #[arg(long, default_value_t = quatcurve::DEFAULT_CURVE, value_parser = names::<Curve>())]
    curve: Curve,
    #[command(flatten)]
    options: CurveOptions,
    /// Also compute angular velocity and acceleration.
    #[arg(long)]
    derivatives: bool,
    /// Which tracks loop (as eval's): on makes each one whole gait cycle on a periodic curve;
    /// the tracks are open otherwise, so auto loops none.
    #[arg(long = "loop", default_value_t = LoopMode::Auto, value_parser = names::<LoopMode>())]
    looping: LoopMode,
    /// Devices to time, comma-separated (reference, cpu, gpu). Default: every one available
    /// in this build; a device named here that is missing is an error (exit 1).
    #[arg(long, value_delimiter = ',', value_parser = names::<DeviceChoice>())]
    devices: Option<Vec<DeviceChoice>>,
    /// Timed runs per device (after one warm-up); the median is reported.
    #[arg(long, default_value_t = 5)]
    runs: usize,
    /// Samples the f64 reference evaluates per run: it times a leading slice of the batch
    /// (whole tracks), since it is the oracle, not a fast path.
    #[arg(long, default_value_t = 1_000_000)]
    reference_samples: usize,
    /// CPU: generate uniformly sampled slerp and nam-kim tracks by Nam & Kim's forward
    /// differences, seeding again every N steps (values only).
    #[arg(long, value_name = "N")]
    forward_difference: Option<usize>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
    /// Time every device across batch sizes from 10^3 samples up to --sweep-max, each size as
    /// a few long tracks (10 tracks) and as many short ones (10 samples each), instead of one
    /// batch: where fixed costs stop dominating and how cost grows with work.
    #[arg(long)]
    sweep: bool,
    /// Largest batch of the sweep, in samples (a power of ten).
    #[arg(long, default_value_t = 10_000_000, requires = "sweep")]
    sweep_max: usize,
    /// With --sweep: a log-log chart of samples/s against batch size, one line per device and
    /// track shape (.png or .svg).
    #[arg(long, value_name = "FILE", requires = "sweep")]
    plot: Option<std::path::PathBuf>,
    /// Time linear blend skinning instead (vertex textures, DESIGN section 8): every skinned
    /// primitive of this glTF at --samples frames of its first clip, on the CPU (f64, every
    /// core) and the GPU (`shaders/skin_mesh.wgsl`, upload and read-back included).
    #[arg(long, value_name = "GLTF", conflicts_with = "sweep")]
    skinning: Option<std::path::PathBuf>,
    /// Time decompression instead: the clips of these fitted containers (`quatcurve fit`),
    /// each --copies times, baked in memory at their source rates on each device; poses per
    /// second and nanoseconds per bone-pose beside ACL's published single-core figure.
    #[arg(long, value_name = "QCF", num_args = 1.., conflicts_with_all = ["sweep", "skinning"])]
    fitted: Vec<std::path::PathBuf>,
    /// With --fitted: copies of every clip in the batch.
    #[arg(long, default_value_t = 10)]
    copies: usize,
    /// Time crowd playback instead (`quatcurve play`): one frame of this file's clips (.gltf,
    /// .glb, .fbx, .usd, .usda, .usdc, .usdz, .bvh, .npz, .qcf) for --instances instances, each blending two clips,
    /// palettes out, on each device.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["sweep", "skinning", "fitted"])]
    playback: Option<std::path::PathBuf>,
    /// With --playback: crowd sizes, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1000,10000", requires = "playback")]
    instances: Vec<usize>,
}

#[derive(Serialize)]
struct Report {
    /// The processor and its cores (each GPU's adapter and driver are its row's).
    host: String,
    workload: Workload,
    results: Vec<Timing>,
}

#[derive(Serialize)]
struct Workload {
    tracks: usize,
    samples_per_track: usize,
    keys_per_track: usize,
    curve: &'static str,
    order: usize,
    knots: &'static str,
    derivatives: bool,
    #[serde(rename = "loop")]
    looping: bool,
    runs: usize,
    /// Median seconds to build the batch from the tracks (for `bspline-interp`, the solve).
    build_seconds: f64,
    /// Keys per second of that build.
    build_keys_per_s: f64,
}

#[derive(Serialize)]
struct Timing {
    device: &'static str,
    adapter: String,
    /// GPU: the driver and its version, as the adapter reports them.
    #[serde(skip_serializing_if = "Option::is_none")]
    driver: Option<String>,
    samples_per_s: f64,
    /// The median of the runs, end to end.
    seconds: f64,
    /// The fastest and slowest runs.
    seconds_min: f64,
    seconds_max: f64,
    samples: usize,
    /// Its rate over the reference's (the f64 oracle's) on the same workload.
    #[serde(skip_serializing_if = "Option::is_none")]
    vs_reference: Option<f64>,
    /// With the inputs prepared on the device and the output buffer reused (GPU: dispatches
    /// alone, no upload or read-back; CPU: into a reused buffer, no allocation).
    #[serde(skip_serializing_if = "Option::is_none")]
    prepared_samples_per_s: Option<f64>,
    /// The fastest and slowest prepared runs, where they were timed in turns with the
    /// end-to-end ones (a GPU batch of several streamed pieces sums each piece's median).
    #[serde(skip_serializing_if = "Option::is_none")]
    prepared_seconds_min: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    prepared_seconds_max: Option<f64>,
    /// Where prepared is below end to end, which can only be noise: whether the two ranges of
    /// runs overlap ([`PreparedBelow`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    prepared_below_end_to_end: Option<PreparedBelow>,
    /// GPU: the write-only roofline kernel's rate over the same dispatches and output bytes.
    #[serde(skip_serializing_if = "Option::is_none")]
    roofline_samples_per_s: Option<f64>,
}

/// A prepared figure below its end-to-end one: prepared does less of the same work, so it is
/// the machine's noise, told by the runs' spread.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
enum PreparedBelow {
    /// The two ranges of runs overlap: noise.
    WithinSpread,
    /// Every prepared run was slower than every end-to-end run: not this run's noise.
    OutsideSpread,
    /// Not timed in turns (a GPU batch of several streamed pieces): no spread to tell by.
    NotInTurns,
}

impl PreparedBelow {
    /// Whether, and how, prepared `prepared` (median, and min-max where timed in turns) is
    /// below end to end `seconds` (median and max).
    fn of(seconds: [f64; 2], prepared: f64, range: Option<[f64; 2]>) -> Option<Self> {
        let [median, max] = seconds;
        let below = match range {
            Some([fastest, _]) if fastest <= max => Self::WithinSpread,
            Some(_) => Self::OutsideSpread,
            None => Self::NotInTurns,
        };
        (prepared > median).then_some(below)
    }

    /// The table's mark after the prepared figure.
    fn mark(self) -> &'static str {
        match self {
            Self::WithinSpread => "~",
            Self::OutsideSpread => "!",
            Self::NotInTurns => "?",
        }
    }

    /// The line under the table that explains the mark.
    fn explained(self) -> String {
        let why = match self {
            Self::WithinSpread => "within the runs' spread (their ranges overlap): noise",
            Self::OutsideSpread => "outside the runs' spread: not this run's noise; run again",
            Self::NotInTurns => "its pieces not timed in turns with it: no spread to tell by",
        };
        format!("{} prepared below end to end, {why}", self.mark())
    }
}

/// A prepared rate's cell, marked where it is below end to end, and the marks used so far.
fn prepared_cell(r: &Timing, marks: &mut Vec<PreparedBelow>) -> String {
    let Some(rate) = r.prepared_samples_per_s else { return "-".to_string() };
    match r.prepared_below_end_to_end {
        Some(below) => {
            if !marks.contains(&below) {
                marks.push(below);
            }
            format!("{:.2} {}", rate / 1e6, below.mark())
        }
        None => format!("{:.2}", rate / 1e6),
    }
}

impl Timing {
    /// `samples` timed end to end in `seconds`, with no other figure yet.
    fn end_to_end(
        device: &'static str,
        adapter: String,
        driver: Option<String>,
        samples: usize,
        seconds: Seconds,
    ) -> Self {
        Self {
            device,
            adapter,
            driver,
            samples_per_s: samples as f64 / seconds.median,
            seconds: seconds.median,
            seconds_min: seconds.min,
            seconds_max: seconds.max,
            samples,
            vs_reference: None,
            prepared_samples_per_s: None,
            prepared_seconds_min: None,
            prepared_seconds_max: None,
            prepared_below_end_to_end: None,
            roofline_samples_per_s: None,
        }
    }

    /// Sets the prepared figures from `samples` and the prepared runs' median (and range, where
    /// timed in turns), labelling a prepared figure below end to end.
    fn with_prepared(mut self, median: f64, range: Option<[f64; 2]>) -> Self {
        self.prepared_samples_per_s = Some(self.samples as f64 / median);
        (self.prepared_seconds_min, self.prepared_seconds_max) = (range.map(|r| r[0]), range.map(|r| r[1]));
        self.prepared_below_end_to_end = PreparedBelow::of([self.seconds, self.seconds_max], median, range);
        self
    }
}

pub fn run(args: &BenchArgs) -> Result<(), Failure> {
    if args.tracks == 0 || args.samples == 0 || args.runs == 0 {
        return Err(Failure::Input("bench: --tracks, --samples and --runs must be at least 1".into()));
    }
    if args.sweep {
        return sweep(args);
    }
    if let Some(file) = &args.playback {
        return super::bench_playback::run(file, &args.instances, args.runs, args.devices.as_deref(), args.json);
    }
    if !args.fitted.is_empty() {
        if args.copies == 0 {
            return Err(Failure::Input("bench: --copies must be at least 1".into()));
        }
        return super::bench_fitted::run(&args.fitted, args.copies, args.runs, args.devices.as_deref(), args.json);
    }
    if let Some(file) = &args.skinning {
        let report = skinning(args, file)?;
        return print_stdout(|w| {
            if args.json {
                writeln!(w, "{}", serde_json::to_string(&report)?)
            } else {
                skinning_table(w, &report)
            }
        });
    }
    let report = measure(args)?;
    print_stdout(|w| if args.json { writeln!(w, "{}", serde_json::to_string(&report)?) } else { table(w, &report) })
}

/// One point of `--sweep`.
#[derive(Serialize)]
struct SweepPoint {
    /// "long" (10 tracks) or "short" (10 samples per track).
    shape: &'static str,
    tracks: usize,
    samples_per_track: usize,
    #[serde(flatten)]
    row: Timing,
}

fn sweep(args: &BenchArgs) -> Result<(), Failure> {
    let mut points = Vec::new();
    let mut total = 1_000;
    while total <= args.sweep_max {
        for (shape, tracks) in [("long", 10), ("short", total / 10)] {
            let point = BenchArgs {
                tracks,
                samples: total / tracks,
                sweep: false,
                reference_samples: args.reference_samples.min(total),
                ..args.clone()
            };
            let report = measure(&point)?;
            points.extend(report.results.into_iter().map(|row| SweepPoint {
                shape,
                tracks,
                samples_per_track: point.samples,
                row,
            }));
        }
        total *= 10;
    }
    if let Some(path) = &args.plot {
        let mut lines: Vec<quatcurve::plot::Line> = Vec::new();
        for p in &points {
            let label = format!(
                "{} {} ({})",
                p.row.device,
                p.shape,
                if p.shape == "long" { "10 tracks" } else { "10 samples each" }
            );
            let at = ((p.tracks * p.samples_per_track) as f64, p.row.samples_per_s);
            match lines.iter_mut().find(|l| l.label == label) {
                Some(line) => line.points.push(at),
                None => lines.push(quatcurve::plot::Line { label, points: vec![at] }),
            }
        }
        let title = format!(
            "quatcurve bench --sweep: {} {}, end to end",
            args.curve,
            if args.derivatives { "with derivatives" } else { "rotation only" }
        );
        quatcurve::plot::log_log(path, &title, "samples in the batch", "samples/s", &lines)
            .map_err(|e| Failure::Input(e.to_string()))?;
        super::wrote(path);
    }
    print_stdout(|w| {
        if args.json {
            return writeln!(
                w,
                "{}",
                serde_json::json!({ "curve": args.curve.name(), "derivatives": args.derivatives, "sweep": points })
            );
        }
        writeln!(w, "(the reference times at most --reference-samples of each batch)")?;
        writeln!(
            w,
            "{:<7} {:>10} {:>9} {:>12} {:<10} {:>14} {:>16}",
            "shape", "tracks", "per track", "batch", "device", "M samples/s", "prepared M/s"
        )?;
        let mut marks = Vec::new();
        for p in &points {
            let kernel = prepared_cell(&p.row, &mut marks);
            writeln!(
                w,
                "{:<7} {:>10} {:>9} {:>12} {:<10} {:>14.2} {:>16}",
                p.shape,
                p.tracks,
                p.samples_per_track,
                p.tracks * p.samples_per_track,
                p.row.device,
                p.row.samples_per_s / 1e6,
                kernel
            )?;
        }
        marks.iter().try_for_each(|m| writeln!(w, "{}", m.explained()))
    })
}

/// Times one batch on every requested device.
fn measure(args: &BenchArgs) -> Result<Report, Failure> {
    let spec = args.options.spec(args.curve, args.looping == LoopMode::On);
    // The build, timed on its own: the cost a caller pays once per set of keys. The batch of
    // the last run is the one evaluated; one batch is alive at a time.
    let mut batch = None;
    let mut builds = Vec::with_capacity(args.runs);
    for _ in 0..args.runs {
        drop(batch.take());
        let (built, seconds) = synthetic::workload_batch(args.tracks, args.keys, &spec)
            .map_err(|e| Failure::Input(format!("bench: {e}")))?;
        builds.push(seconds);
        batch = Some(built);
    }
    let batch = batch.ok_or_else(|| Failure::Input("bench: --runs must be at least 1".into()))?;
    builds.sort_by(f64::total_cmp);
    let build_seconds = builds[builds.len() / 2];
    let times = SampleTimes::uniform(&batch, Sampling::Count(args.samples))
        .map_err(|e| Failure::Input(format!("bench: {e}")))?;
    let explicit = args.devices.is_some();
    let devices =
        args.devices.clone().unwrap_or_else(|| vec![DeviceChoice::Reference, DeviceChoice::Cpu, DeviceChoice::Gpu]);
    let mut results = Vec::new();
    for choice in devices {
        let Some(device) = open_bench_device(choice, explicit)? else { continue };
        results.push(match &device {
            Device::Reference => time_reference(args, &spec)?,
            Device::Gpu(gpu) | Device::Auto(gpu, _) => time_gpu(args, gpu, &batch, &times)?,
            Device::Cpu(cpu) => time_cpu(args, cpu, &batch, &times)?,
        });
    }
    if let Some(reference) = results.iter().find(|r| r.device == "reference").map(|r| r.samples_per_s) {
        for r in &mut results {
            r.vs_reference = Some(r.samples_per_s / reference);
        }
    }
    let report = Report {
        host: host(),
        workload: Workload {
            tracks: args.tracks,
            samples_per_track: args.samples,
            keys_per_track: args.keys,
            curve: args.curve.name(),
            order: args.options.order,
            knots: spec.knots.name(),
            derivatives: args.derivatives,
            looping: spec.looping,
            runs: args.runs,
            build_seconds,
            build_keys_per_s: (args.tracks * args.keys) as f64 / build_seconds,
        },
        results,
    };
    Ok(report)
}

/// The reference times the batch's first tracks (the synthetic batch is a pure function of
/// the track index, so the slice is exactly those tracks).
fn time_reference(args: &BenchArgs, spec: &CurveSpec) -> Result<Timing, Failure> {
    let tracks = args.reference_samples.div_ceil(args.samples).clamp(1, args.tracks);
    let (slice, slice_times) =
        synthetic::workload(tracks, args.samples, args.keys, spec).map_err(|e| Failure::Input(e.to_string()))?;
    let job = EvalJob::new(&slice, &slice_times).derivatives(args.derivatives);
    let seconds = run_seconds(args.runs, || job.run().map(drop).map_err(|e| Failure::Input(e.to_string())))?;
    Ok(Timing::end_to_end("reference", "f64, one thread".into(), None, slice_times.total(), seconds))
}

fn time_gpu(args: &BenchArgs, gpu: &GpuDevice, batch: &Batch, times: &SampleTimes) -> Result<Timing, Failure> {
    let job = EvalJob::new(batch, times).derivatives(args.derivatives);
    let device_err = |e: quatcurve::gpu::GpuError| Failure::Internal(format!("gpu: {e}"));
    let evaluate = || gpu.evaluate(&job).map(drop).map_err(device_err);
    // Dispatch-only and roofline a piece of tracks at a time, each piece about one streamed
    // chunk on the device, the pieces' medians summed: the dispatches `evaluate` streams,
    // without holding the whole batch on the device (on a software adapter, device memory is
    // host memory: a million short tracks held 3 GB more). A batch of one piece is timed in
    // turns with the end-to-end runs.
    let pieces = device_pieces(batch, times, job.options.row().channels(), gpu.stream_chunk_bytes());
    let (mut dispatch, mut roofline, mut seconds, mut spread) = (0.0, 0.0, None, None);
    for range in &pieces {
        let (piece, piece_times) = (batch.subset(range.clone()), times.subset(range.clone()));
        let prepared = gpu.prepare(&EvalJob::new(&piece, &piece_times).with(job.options)).map_err(device_err)?;
        let dispatched = || gpu.dispatch(&prepared).map_err(device_err);
        if pieces.len() == 1 {
            let (whole, alone) = alternate_seconds(args.runs, evaluate, dispatched)?;
            (seconds, dispatch, spread) = (Some(whole), alone.median, Some([alone.min, alone.max]));
        } else {
            dispatch += median_seconds(args.runs, dispatched)?;
        }
        roofline += median_seconds(args.runs, || gpu.roofline(&prepared).map_err(device_err))?;
    }
    let seconds = match seconds {
        Some(seconds) => seconds,
        None => run_seconds(args.runs, evaluate)?,
    };
    let driver = Some(gpu.context().driver().to_string());
    let timing = Timing::end_to_end("gpu", gpu.adapter_name().to_string(), driver, times.total(), seconds);
    Ok(Timing {
        roofline_samples_per_s: Some(times.total() as f64 / roofline),
        ..timing.with_prepared(dispatch, spread)
    })
}

/// Ranges of tracks that the GPU packs as one streamed chunk (`chunk` bytes per binding) each,
/// as its own planning counts them (a track cut into pieces is one range).
fn device_pieces(batch: &Batch, times: &SampleTimes, channels: usize, chunk: u64) -> Vec<std::ops::Range<usize>> {
    // A batch the GPU cannot plan fails in `prepare` with its message.
    let plans = quatcurve::gpu::layout::plan_chunks(batch, times, channels, chunk).unwrap_or_default();
    let mut ranges: Vec<std::ops::Range<usize>> =
        plans.iter().map(|p| p.first_track..p.first_track + p.tracks).collect();
    ranges.dedup();
    ranges
}

fn time_cpu(args: &BenchArgs, cpu: &CpuEvaluator, batch: &Batch, times: &SampleTimes) -> Result<Timing, Failure> {
    let options = JobOptions {
        derivatives: args.derivatives,
        forward_difference: args.forward_difference,
        ..JobOptions::default()
    };
    let job = EvalJob::new(batch, times).with(options);
    let input = |e: quatcurve::Error| Failure::Input(e.to_string());
    // The CPU's analogue of dispatch-only: into a reused buffer (no allocation, no page faults).
    let mut buffer = vec![0.0f32; times.total() * options.row().channels()];
    let (seconds, compute) = alternate_seconds(
        args.runs,
        || cpu.evaluate(&job).map(drop).map_err(input),
        || cpu.evaluate_into(&job, &mut buffer).map_err(input),
    )?;
    let adapter = match args.forward_difference {
        Some(n) => format!("{}, forward differences every {n}", cpu.name()),
        None => cpu.name(),
    };
    let timing = Timing::end_to_end("cpu", adapter, None, times.total(), seconds);
    Ok(timing.with_prepared(compute.median, Some([compute.min, compute.max])))
}

fn table(w: &mut dyn std::io::Write, report: &Report) -> std::io::Result<()> {
    let l = &report.workload;
    writeln!(
        w,
        "workload: {} tracks x {} samples ({} keys each), {}{}{}, {}; median of {} runs",
        l.tracks,
        l.samples_per_track,
        l.keys_per_track,
        l.curve,
        if l.curve == Curve::BSpline.name() { format!(" order {} {} knots", l.order, l.knots) } else { String::new() },
        if l.looping { ", looping" } else { "" },
        if l.derivatives { "with angular velocity and acceleration" } else { "rotation only" },
        l.runs
    )?;
    writeln!(w, "host: {}", report.host)?;
    writeln!(w, "build: {:.4} s ({:.2} M keys/s)", l.build_seconds, l.build_keys_per_s / 1e6)?;
    writeln!(
        w,
        "{:<10} {:>10} {:>20} {:>12} {:>7} {:>12} {:>12}  adapter (driver)",
        "device", "samples", "s min-med-max", "M samples/s", "x ref", "prepared M/s", "roofline M/s"
    )?;
    let rate = |s: Option<f64>| s.map_or_else(|| "-".to_string(), |s| format!("{:.2}", s / 1e6));
    let mut marks = Vec::new();
    for r in &report.results {
        let (prepared, roofline) = (prepared_cell(r, &mut marks), rate(r.roofline_samples_per_s));
        let spread = format!("{:.4}-{:.4}-{:.4}", r.seconds_min, r.seconds, r.seconds_max);
        let times = r.vs_reference.map_or_else(|| "-".to_string(), |x| format!("{x:.1}"));
        let driver = r.driver.as_ref().map_or_else(String::new, |d| format!(" ({d})"));
        writeln!(
            w,
            "{:<10} {:>10} {:>20} {:>12.2} {:>7} {:>12} {:>12}  {}{driver}",
            r.device,
            r.samples,
            spread,
            r.samples_per_s / 1e6,
            times,
            prepared,
            roofline,
            r.adapter
        )?;
    }
    marks.iter().try_for_each(|m| writeln!(w, "{}", m.explained()))
}

/// `--skinning`: what was skinned and how fast on each device.
#[derive(Serialize)]
struct SkinningReport {
    file: String,
    primitives: usize,
    vertices: usize,
    frames: usize,
    runs: usize,
    results: Vec<SkinningTiming>,
}

#[derive(Serialize)]
struct SkinningTiming {
    device: &'static str,
    adapter: String,
    vertex_frames_per_s: f64,
    /// The median of the runs, with the fastest and slowest.
    seconds: f64,
    seconds_min: f64,
    seconds_max: f64,
    vertex_frames: usize,
}

/// Skins every skinned primitive of `file` at `args.samples` frames of its first clip (the
/// skin matrices baked once, before the timing) on the CPU and the GPU.
fn skinning(args: &BenchArgs, file: &std::path::Path) -> Result<SkinningReport, Failure> {
    use quatcurve::bake::{self, texture};
    use quatcurve::formats::{gltf, mesh};
    use quatcurve::skeleton;
    let input = |e: String| Failure::Input(format!("bench --skinning {}: {e}", file.display()));
    let source = gltf::read(file, gltf::UriPolicy::default()).map_err(|e| input(e.to_string()))?;
    let animation = &source.animation;
    let primitives = mesh::skinned_primitives(&source).map_err(|e| input(e.to_string()))?.primitives;
    let clip = animation.clips.first().ok_or_else(|| input("no clip to skin by".into()))?;
    let [start, end] = clip.span();
    let rate = (args.samples.saturating_sub(1)).max(1) as f64 / (end - start).max(1e-9);
    let baked = bake::bake(
        animation,
        &quatcurve::anim::curves::CurveChoice::Source,
        bake::ClipRate::Fit(rate),
        quatcurve::anim::loops::LoopMode::Auto,
        &Device::Reference,
    )
    .map_err(|e| input(e.to_string()))?;
    let order = animation.parents_first().map_err(|e| input(e.to_string()))?;
    let model = skeleton::forward_kinematics(&animation.parents(), &order, &texture::local(animation, &baked, 0));
    let skins: Vec<Vec<f32>> =
        animation.skins.iter().map(|s| texture::skin(s, animation.joints.len(), &model)).collect();
    let frames = baked.clips[0].times.len();
    let vertices: usize = primitives.iter().map(mesh::SkinnedPrimitive::vertices).sum();
    let joints = |p: &mesh::SkinnedPrimitive| animation.skins[p.skin].joints.len();
    let explicit = args.devices.is_some();
    let devices = args.devices.clone().unwrap_or_else(|| vec![DeviceChoice::Cpu, DeviceChoice::Gpu]);
    let mut results = Vec::new();
    for choice in devices {
        let device = match (choice, super::open_device(choice, "--devices")) {
            (DeviceChoice::Auto | DeviceChoice::Reference, _) => {
                return Err(Failure::Input(
                    "bench --skinning: name devices cpu and gpu (skinning's CPU path is f64 already)".into(),
                ))
            }
            (_, Ok(device)) => device,
            (_, Err(e)) if explicit => return Err(e),
            (_, Err(Failure::Input(e) | Failure::Internal(e))) => {
                eprintln!("skipped {choice}: {e}");
                continue;
            }
        };
        let seconds = run_seconds(args.runs, || {
            for p in &primitives {
                device
                    .skin(&p.bind, joints(p), &skins[p.skin])
                    .map_err(|e| Failure::Internal(format!("{choice}: {e}")))?;
            }
            Ok(())
        })?;
        let (name, adapter) = match choice {
            DeviceChoice::Gpu => ("gpu", device.name().trim_start_matches("gpu: ").to_string()),
            _ => ("cpu", format!("f64, {} threads", rayon::current_num_threads())),
        };
        let vertex_frames = vertices * frames;
        results.push(SkinningTiming {
            device: name,
            adapter,
            vertex_frames_per_s: vertex_frames as f64 / seconds.median,
            seconds: seconds.median,
            seconds_min: seconds.min,
            seconds_max: seconds.max,
            vertex_frames,
        });
    }
    Ok(SkinningReport {
        file: file.display().to_string(),
        primitives: primitives.len(),
        vertices,
        frames,
        runs: args.runs,
        results,
    })
}

fn skinning_table(w: &mut dyn std::io::Write, report: &SkinningReport) -> std::io::Result<()> {
    writeln!(
        w,
        "skinning: {}, {} primitives, {} vertices x {} frames; median of {} runs",
        report.file, report.primitives, report.vertices, report.frames, report.runs
    )?;
    writeln!(
        w,
        "{:<10} {:>14} {:>22} {:>20}  adapter",
        "device", "vertex-frames", "s min-med-max", "M vertex-frames/s"
    )?;
    for r in &report.results {
        writeln!(
            w,
            "{:<10} {:>14} {:>22} {:>20.2}  {}",
            r.device,
            r.vertex_frames,
            format!("{:.4}-{:.4}-{:.4}", r.seconds_min, r.seconds, r.seconds_max),
            r.vertex_frames_per_s / 1e6,
            r.adapter
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::PreparedBelow;

    #[test]
    fn a_prepared_figure_below_end_to_end_is_labelled_by_the_runs_spread() {
        // End to end: a median of 1.0 s, the slowest run 1.2 s.
        let e2e = [1.0, 1.2];
        assert_eq!(PreparedBelow::of(e2e, 0.9, Some([0.8, 1.0])), None, "prepared faster: as it should be");
        assert_eq!(PreparedBelow::of(e2e, 1.1, Some([1.05, 1.3])), Some(PreparedBelow::WithinSpread));
        assert_eq!(PreparedBelow::of(e2e, 1.5, Some([1.3, 1.6])), Some(PreparedBelow::OutsideSpread));
        assert_eq!(PreparedBelow::of(e2e, 1.1, None), Some(PreparedBelow::NotInTurns));
        let marks: Vec<&str> = [PreparedBelow::WithinSpread, PreparedBelow::OutsideSpread, PreparedBelow::NotInTurns]
            .map(PreparedBelow::mark)
            .to_vec();
        assert_eq!(marks, ["~", "!", "?"]);
    }
}
