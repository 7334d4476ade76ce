//! `quatcurve` command line: see `quatcurve --help` and DESIGN section 5.
//!
//! Exit codes: 0 success, 2 bad usage or bad input (one line naming file, track and key),
//! 1 internal or device failure.

use clap::{Args, Parser, Subcommand, ValueEnum};
use quatcurve::io::{demo_tracks, read_track_file, write_atomic, ResultFile};
use quatcurve::gpu::{GpuError, GpuEvaluator, GpuOptions};
use quatcurve::{Batch, Blend, Curve, CurveSpec, EvalJob, KnotMode, Layout, Output, SampleTimes, Sampling, Tangents};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(name = "quatcurve", version, about = "Smooth rotation curves for batches of animation tracks")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Evaluate curves through the tracks of a JSON file and write the samples as JSON.
    Eval(EvalArgs),
}

#[derive(Args, Debug)]
struct EvalArgs {
    /// Input track file ({"tracks": [...]}); without it, a built-in three-joint demo.
    #[arg(long)]
    input: Option<PathBuf>,
    /// Output file (.json); without it, JSON goes to standard output.
    #[arg(long)]
    output: Option<PathBuf>,
    /// Curve family.
    #[arg(long, default_value = "bspline", value_parser = parse::<Curve>)]
    curve: Curve,
    /// B-spline order k (degree k - 1), 2..=8.
    #[arg(long, default_value_t = 4)]
    order: usize,
    /// B-spline knot mode.
    #[arg(long, default_value = "phantom", value_parser = parse::<KnotMode>)]
    knots: KnotMode,
    /// Tangent source for hermite and nam-kim.
    #[arg(long, default_value = "catmull-rom", value_parser = parse::<Tangents>)]
    tangents: Tangents,
    /// Nam-Kim blend function.
    #[arg(long, default_value = "cubic", value_parser = parse::<Blend>)]
    blend: Blend,
    /// N samples per track from domain start to end, both included.
    #[arg(long, conflicts_with = "rate")]
    samples: Option<usize>,
    /// Samples per second from the domain start (default 30).
    #[arg(long)]
    rate: Option<f64>,
    /// Also output body angular velocity and acceleration.
    #[arg(long)]
    derivatives: bool,
    /// Sample order for array outputs (JSON is always track-major, so this has no effect on it).
    #[arg(long, value_enum, default_value_t = LayoutArg::Track)]
    #[allow(dead_code)]
    layout: LayoutArg,
    /// Evaluation device.
    #[arg(long, value_enum, default_value_t = DeviceArg::Auto)]
    device: DeviceArg,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum LayoutArg {
    Track,
    Frame,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum DeviceArg {
    Auto,
    Gpu,
    Cpu,
    Reference,
}

fn parse<T: std::str::FromStr<Err = String>>(s: &str) -> Result<T, String> {
    s.parse()
}

/// A failure with the exit code it maps to.
enum Failure {
    /// Bad usage or bad input: exit 2.
    Input(String),
    /// Device or internal failure: exit 1.
    Internal(String),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Eval(args) => eval(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Input(msg)) => {
            eprintln!("error: {msg}");
            ExitCode::from(2)
        }
        Err(Failure::Internal(msg)) => {
            eprintln!("error: {msg}");
            ExitCode::from(1)
        }
    }
}

/// The device that evaluates: the f64 reference or the GPU kernel.
enum Device {
    Reference,
    Gpu(Box<GpuEvaluator>),
}

impl Device {
    /// Resolves `--device`: `gpu` needs an adapter (exit 1 without one, never a silent
    /// fallback); `auto` takes the GPU when there is one, else the reference.
    fn open(arg: DeviceArg) -> Result<Self, Failure> {
        match arg {
            DeviceArg::Reference => Ok(Device::Reference),
            DeviceArg::Gpu => GpuEvaluator::new()
                .map(|g| Device::Gpu(Box::new(g)))
                .map_err(|e| Failure::Internal(format!("--device gpu: {e}"))),
            DeviceArg::Auto => Ok(GpuEvaluator::new().map_or(Device::Reference, |g| Device::Gpu(Box::new(g)))),
            DeviceArg::Cpu => {
                Err(Failure::Internal("--device cpu is not available in this build yet; use gpu, reference or auto".into()))
            }
        }
    }

    /// The name the output reports: `reference` or `gpu: <adapter>`.
    fn name(&self) -> String {
        match self {
            Device::Reference => "reference".into(),
            Device::Gpu(g) => format!("gpu: {}", g.adapter_name()),
        }
    }

    /// Evaluates; results in f64 whatever the device computed in.
    fn run(&self, job: &EvalJob<'_>) -> Result<Output, Failure> {
        match self {
            Device::Reference => job.run().map_err(|e| Failure::Input(e.to_string())),
            Device::Gpu(g) => {
                let options = GpuOptions { layout: job.layout, derivatives: job.derivatives, ..GpuOptions::default() };
                let out = g.evaluate(job.batch, job.times, &options).map_err(|e| match e {
                    GpuError::Pack(_) | GpuError::Job(_) => Failure::Input(e.to_string()),
                    _ => Failure::Internal(e.to_string()),
                })?;
                Ok(out.to_output(job.derivatives))
            }
        }
    }
}

fn eval(args: &EvalArgs) -> Result<(), Failure> {
    if let Some(out) = &args.output {
        if out.extension().and_then(|e| e.to_str()) != Some("json") {
            return Err(Failure::Input(format!("{}: only .json output is supported so far", out.display())));
        }
    }
    let (source, tracks) = match &args.input {
        Some(path) => {
            let file = read_track_file(path).map_err(|e| Failure::Input(e.to_string()))?;
            (path.display().to_string(), file.tracks)
        }
        None => ("built-in demo".to_string(), demo_tracks()),
    };
    let spec = CurveSpec { curve: args.curve, order: args.order, knots: args.knots, tangents: args.tangents, blend: args.blend };
    let input_err = |e: quatcurve::Error| Failure::Input(format!("{source}: {e}"));
    let batch = Batch::from_tracks(&tracks, &spec).map_err(input_err)?;
    let sampling = match (args.samples, args.rate) {
        (Some(n), _) => Sampling::Count(n),
        (None, rate) => Sampling::Rate(rate.unwrap_or(30.0)),
    };
    let overrides: Vec<Option<&[f64]>> = tracks.iter().map(|t| t.sample_times.as_deref()).collect();
    let times = SampleTimes::new(&batch, &overrides, sampling).map_err(input_err)?;
    // JSON output is always track-major (DESIGN section 5); --layout shapes array outputs only.
    let job = EvalJob { batch: &batch, times: &times, layout: Layout::Track, derivatives: args.derivatives };
    job.validate().map_err(input_err)?;
    let device = Device::open(args.device)?;
    let out = device.run(&job).map_err(|e| match e {
        Failure::Input(msg) => Failure::Input(format!("{source}: {msg}")),
        other => other,
    })?;
    let device = device.name();
    let doc = ResultFile::new(args.curve.name(), &device, &tracks, &times, &out);
    match &args.output {
        Some(path) => {
            write_atomic(path, |w| serde_json::to_writer(&mut *w, &doc).map_err(std::io::Error::other))
                .map_err(|e| Failure::Internal(e.to_string()))?;
            eprintln!(
                "evaluated {} tracks, {} samples ({} on {device}) from {source} -> {}",
                batch.len(),
                times.total(),
                args.curve,
                path.display()
            );
        }
        None => {
            let mut stdout = std::io::stdout().lock();
            let written = serde_json::to_writer(&mut stdout, &doc)
                .map_err(|e| e.io_error_kind().map_or_else(|| std::io::Error::other(e), std::io::Error::from))
                .and_then(|()| writeln!(stdout))
                .and_then(|()| stdout.flush());
            match written {
                // A reader that stops early (`| head`) is not a failure of ours.
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {}
                Err(e) => return Err(Failure::Internal(format!("standard output: {e}"))),
                Ok(()) => {}
            }
        }
    }
    Ok(())
}
