//! `quatcurve eval`: tracks from a JSON file (or the built-in demo) to samples as JSON or `.npy`.

use super::{flag, print_stdout, read_tracks, CurveOptions, Failure};
use clap::{Args, ValueEnum};
use quatcurve::anim::loops::LoopMode;
use quatcurve::io::{write_atomic, write_npy, ResultFile};
use quatcurve::options::{EvalOptions, OptionError};
use quatcurve::{Batch, Device, EvalJob, FloatOutput, Layout, Output, SampleTimes};
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Input tracks: JSON ({"tracks": [...]}), or numpy arrays for large batches: .npz with
    /// rotations [tracks, keys, 4] (x, y, z, w) and optional times [keys] or [tracks, keys],
    /// names [tracks], angular_velocities [tracks, keys, 3]; .npy with rotations alone; or a
    /// fitted container (.qcf from `quatcurve fit`): every clip's rotation channels, named
    /// <clip>/<joint>. Without it, a built-in three-joint demo.
    #[arg(long)]
    input: Option<PathBuf>,
    /// Key times of .npz/.npy input without a times array: this many keys per second from 0
    /// (default: keys at 0, 1, 2, ...).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    key_rate: Option<f64>,
    /// Output file, .json or .npy (float32); without it, JSON goes to standard output.
    #[arg(long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    options: EvalOptions,
    /// Sample order of .npy output: [tracks, samples, C] or [samples, tracks, C]. JSON is
    /// always track-major.
    #[arg(long, value_enum, default_value_t = LayoutArg::Track)]
    layout: LayoutArg,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum LayoutArg {
    Track,
    Frame,
}

/// Output format, from the file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Json,
    Npy,
}

fn format_of(path: &Path) -> Result<Format, Failure> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("json") => Ok(Format::Json),
        Some("npy") => Ok(Format::Npy),
        _ => Err(Failure::Input(format!("{}: output must end in .json or .npy", path.display()))),
    }
}

pub fn run(args: &EvalArgs) -> Result<(), Failure> {
    let format = args.output.as_deref().map(format_of).transpose()?.unwrap_or(Format::Json);
    // A fitted container's tracks are on its own curve.
    let (source, tracks, fitted) = match &args.input {
        Some(path) if super::is_container(Some(path)) => {
            let curve = container_curve(args)?;
            let (source, tracks) = super::read_container_tracks(path)?;
            (source, tracks, Some(curve))
        }
        input => {
            let (source, tracks) = read_tracks(input.as_deref(), args.key_rate)?;
            (source, tracks, None)
        }
    };
    let input_err = |e: quatcurve::Error| Failure::Input(format!("{source}: {e}"));
    let batch = if fitted.is_some() {
        // Each fitted track's order is its own (a cubic, or keys slerped between).
        Batch::from_tracks_each(&tracks, |i| quatcurve::qcf::fitted::track_spec(&tracks[i]))
    } else {
        args.options.batch(&tracks)
    }
    .map_err(input_err)?;
    let sampling = args.options.sampling().map_err(|e| match e {
        OptionError::Value { name, reason } => Failure::Input(format!("{}: {reason}", flag(&name))),
        other => Failure::Input(other.to_string()),
    })?;
    let overrides: Vec<Option<&[f64]>> = tracks.iter().map(|t| t.sample_times.as_deref()).collect();
    // The library's sampling errors name no option; say which flag.
    let given = if args.options.samples.is_some() { "--samples" } else { "--rate" };
    let times = SampleTimes::new(&batch, &overrides, sampling).map_err(|e| match e {
        quatcurve::Error::BadSampling(msg) => Failure::Input(format!("{given}: {msg}")),
        other => input_err(other),
    })?;
    // JSON is always track-major (DESIGN section 5); --layout shapes .npy output.
    let layout = match (format, args.layout) {
        (Format::Npy, LayoutArg::Frame) => Layout::Frame,
        _ => Layout::Track,
    };
    if format == Format::Npy {
        times.equal_counts(&batch, ".npy output").map_err(|e| input_err(e.into()))?;
    }
    let job = EvalJob::new(&batch, &times).layout(layout).derivatives(args.options.derivatives);
    job.validate().map_err(input_err)?;
    let device = super::open_device(args.options.device, "--device")?;
    let mut out = Output::default();
    let device_name = device.evaluate_into(&job, &mut out).map_err(|e| Failure::from(e).context(&source))?;
    let f32 = !matches!(device, Device::Reference);
    let device = device_name;
    let curve = fitted.unwrap_or(args.options.curve);
    let json = || ResultFile::new(curve.name(), &device, &tracks, &times, &out, f32);
    let Some(path) = &args.output else {
        return print_stdout(|w| {
            serde_json::to_writer(&mut *w, &json()).map_err(std::io::Error::from)?;
            writeln!(w)
        });
    };
    let written = match format {
        Format::Json => write_atomic(path, |w| serde_json::to_writer(&mut *w, &json()).map_err(std::io::Error::from)),
        Format::Npy => {
            let (tracks, samples) = (batch.len() as u64, times.count(0) as u64);
            let (data, channels) = npy_rows(&out);
            let shape = match layout {
                Layout::Track => [tracks, samples, channels],
                Layout::Frame => [samples, tracks, channels],
            };
            write_npy(path, &shape, &data)
        }
    };
    // An output that cannot be written is the caller's to fix: exit 2.
    written.map_err(|e| Failure::Input(e.to_string()))?;
    eprintln!(
        "evaluated {} tracks, {} samples ({} on {device}) from {source} -> {}",
        batch.len(),
        times.total(),
        curve,
        path.display()
    );
    Ok(())
}

/// A fitted container's curves are its own ([`quatcurve::qcf::fitted::spline_spec`], cubic or keys
/// per channel): a curve option that would change them is refused (the default curve stands for
/// them). Its family, as outputs name it.
fn container_curve(args: &EvalArgs) -> Result<quatcurve::Curve, Failure> {
    let spec = quatcurve::qcf::fitted::spline_spec(quatcurve::qcf::fitted::ORDER);
    let (options, curve) = (&args.options.curve_options, args.options.curve);
    let refused = [
        (curve != spec.curve && curve != EvalOptions::DEFAULT.curve, "--curve"),
        (options.order != spec.order, "--order"),
        (options.knots != spec.knots && options.knots != CurveOptions::DEFAULT.knots, "--knots"),
        (args.options.looping == LoopMode::On, "--loop"),
        (args.key_rate.is_some(), "--key-rate"),
    ];
    match refused.iter().find(|(given, _)| *given) {
        Some((_, flag)) => {
            let keys = quatcurve::qcf::fitted::spline_spec(quatcurve::qcf::fitted::KEYS_ORDER);
            Err(Failure::Input(format!(
                "{flag}: a fitted container's curves are its own (on its knots, per channel: {} of order {} or {} of \
                 order {})",
                spec.curve, spec.order, keys.curve, keys.order
            )))
        }
        None => Ok(spec.curve),
    }
}

/// Float32 rows of DESIGN section 5's `.npy` ([`quatcurve::Row`]s without matrices).
/// Returns the data and the channel count.
fn npy_rows(out: &Output) -> (Vec<f32>, u64) {
    let FloatOutput { channels, data } = FloatOutput::from_output(out, false);
    (data, channels as u64)
}
