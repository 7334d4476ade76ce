//! `quatcurve bake`: resample glTF/GLB and BVH files (or the built-in crowd) at a new rate.
//!
//! The flags are the library's [`BakeOptions`] (derived from the type: one definition of each
//! option) and the job's inputs, output and share; they fill a [`BakeJob`] (the library runs
//! it: per input read, bake every clip, write its outputs atomically; a failed input is
//! reported and the others still finish); this file draws the progress bar, prints the
//! summary and exits non-zero if any input failed.

use super::{flag, print_stdout, Failure};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use quatcurve::bake::{BakeJob, BakeOptions, BakeReport, InputReport, Progress, Shard};
use quatcurve::files::FileJobError;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

#[derive(Args, Debug)]
pub struct BakeArgs {
    /// Input files (.gltf, .glb, .fbx, .usd/.usda/.usdc/.usdz, .bvh, .npz of SMPL poses, .qcf) or directories of them; without it, the built-in
    /// synthetic crowd.
    #[arg(long, num_args = 1..)]
    input: Vec<PathBuf>,
    /// Output directory (created if missing).
    #[arg(long, default_value = "baked")]
    output: PathBuf,
    #[command(flatten)]
    options: BakeOptions,
    /// Bake only this share of the inputs, I/N (0-based): inputs sorted by path, file k
    /// belongs to shard k mod N. Without it, the array index Slurm, Kubernetes, AWS Batch or
    /// Google Batch sets (docs/SCALE-OUT.md); else the whole job.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Skip inputs that this shard's manifest records as baked with the same options from
    /// the same bytes, whose outputs are still intact (size and SHA-256).
    #[arg(long)]
    resume: bool,
    /// Inputs read, baked and written at once (each bake also uses every core).
    #[arg(long, default_value_t = 1, value_name = "N")]
    jobs: usize,
}

impl From<FileJobError> for Failure {
    /// Option errors name the option as its flag (`max_rate must ...` becomes `--max-rate
    /// must ...`).
    fn from(e: FileJobError) -> Self {
        match e {
            FileJobError::Option { option, reason } => Failure::Input(format!("{} {reason}", flag(option))),
            FileJobError::Manifest(_) => Failure::Internal(e.to_string()),
            _ => Failure::Input(e.to_string()),
        }
    }
}

impl BakeArgs {
    fn job(&self) -> Result<BakeJob, Failure> {
        Ok(BakeJob {
            options: self.options.clone(),
            shard: self.shard.as_deref().map(Shard::parse).transpose()?,
            resume: self.resume,
            jobs: self.jobs,
            ..BakeJob::new(self.input.clone(), self.output.clone())
        })
    }
}

/// The progress bar: files done, and samples per second so far with the input being read.
struct Bar {
    bar: ProgressBar,
    started: Instant,
    samples: AtomicUsize,
}

impl Progress for Bar {
    fn start(&self, inputs: usize) {
        self.bar.set_length(inputs as u64);
    }

    fn begin(&self, source: &str) {
        let rate = self.samples.load(Ordering::Relaxed) as f64 / self.started.elapsed().as_secs_f64().max(1e-9) / 1e6;
        self.bar.set_message(format!("{rate:.1} M samples/s {source}"));
    }

    fn finish(&self, input: &InputReport) {
        self.samples.fetch_add(input.samples, Ordering::Relaxed);
        self.bar.inc(1);
    }

    fn measuring(&self, source: &str, clip: &str, rate: f64) {
        self.bar.set_message(format!("{source}: clip '{clip}', error budget at {rate:.1} Hz"));
    }
}

pub fn run(args: &BakeArgs) -> Result<(), Failure> {
    let job = args.job()?;
    job.validate()?;
    let device = super::open_device(args.options.device, "--device")?;
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} files, {per_sec} {elapsed} (eta {eta}) {msg}")
            .expect("valid template"),
    );
    let progress = Bar { bar, started: Instant::now(), samples: AtomicUsize::new(0) };
    let report = job.run(&device, &progress);
    progress.bar.finish_and_clear();
    let report = report?;
    print_stdout(|w| summary(w, &report, args))?;
    for input in &report.inputs {
        for warning in &input.warnings {
            eprintln!("warning: {}: {warning}", input.source);
        }
    }
    let failed: Vec<&InputReport> = report.failed().collect();
    if failed.is_empty() {
        return Ok(());
    }
    let mut counts = [0usize; 3];
    for input in &failed {
        if let Err(e) = &input.outcome {
            counts[Fault::of(e) as usize] += 1;
            eprintln!("error: {}: {e}", input.source);
        }
    }
    let kinds: Vec<String> = [Fault::Input, Fault::Output, Fault::Device]
        .iter()
        .filter(|&&f| counts[f as usize] > 0)
        .map(|&f| format!("{} {}", counts[f as usize], f.said()))
        .collect();
    let baked = report.inputs.len() - failed.len();
    let rest = match baked {
        0 => "nothing was baked",
        1 => "the other was baked",
        _ => "the others were baked",
    };
    let summary = format!("{} of {} inputs failed ({}); {rest}", failed.len(), report.inputs.len(), kinds.join(", "));
    // Exit code 1 when the machine is at fault (DESIGN section 6), else 2.
    Err(if counts[Fault::Input as usize] == failed.len() {
        Failure::Input(summary)
    } else {
        Failure::Internal(summary)
    })
}

/// Whose fault a failed input is: the file's, the output's (a write that failed: disk full,
/// a file in the way) or the device's (or quatcurve's own).
#[derive(Clone, Copy)]
enum Fault {
    Input,
    Output,
    Device,
}

impl Fault {
    fn of(e: &quatcurve::bake::error::BakeError) -> Self {
        if e.is_internal_failure() {
            Fault::Device
        } else if e.is_output_failure() {
            Fault::Output
        } else {
            Fault::Input
        }
    }

    /// The status column's word, and the closing line's.
    fn word(self) -> &'static str {
        match self {
            Fault::Input => "input",
            Fault::Output => "output",
            Fault::Device => "device",
        }
    }

    fn said(self) -> &'static str {
        match self {
            Fault::Input => "bad input",
            Fault::Output => "output not written",
            Fault::Device => "device failure",
        }
    }
}

fn summary(w: &mut dyn std::io::Write, report: &BakeReport, args: &BakeArgs) -> std::io::Result<()> {
    let (shard, rows, options) = (&report.shard, &report.inputs, &args.options);
    let rate = if options.max_error_deg.is_some() || options.max_error_cm.is_some() {
        let budget: Vec<String> = [(options.max_error_deg, "degrees"), (options.max_error_cm, "cm")]
            .iter()
            .filter_map(|(v, unit)| v.map(|v| format!("{v} {unit}")))
            .collect();
        format!("rates chosen per clip for {} between frames", budget.join(" and "))
    } else if options.exact_rate {
        format!("exactly {} Hz", options.rate)
    } else {
        format!("{} Hz (fitted per clip)", options.rate)
    };
    let any = |extension: &str| report.inputs.iter().any(|i| i.source.ends_with(&format!(".{extension}")));
    let mut curve = match options.curve {
        Some(curve) => curve.to_string(),
        None if args.input.is_empty() => quatcurve::DEFAULT_CURVE.to_string(),
        None => "each source's own interpolation (glTF's samplers, other frames slerped)".to_string(),
    };
    if any(quatcurve::qcf::EXTENSION) {
        curve.push_str(" (fitted inputs: their own B-splines)");
    }
    writeln!(w, "baked at {rate} with {curve} on {} -> {}", report.device, args.output.display())?;
    if shard.count > 1 {
        writeln!(
            w,
            "shard {} of {} ({}): {} of {} inputs",
            shard.index,
            shard.count,
            shard.source,
            rows.len(),
            report.job_inputs
        )?;
    }
    if report.stale_removed > 0 {
        writeln!(w, "removed {} temporary files a killed run of this shard left", report.stale_removed)?;
    }
    writeln!(
        w,
        "{:<44} {:>5} {:>8} {:>9} {:>11} {:>8} {:>14}  status",
        "input", "clips", "channels", "keys in", "samples out", "seconds", "key error rad"
    )?;
    for r in rows {
        let error = r.max_key_error.map_or_else(|| "-".to_string(), |e| format!("{e:.2e}"));
        let status = match &r.outcome {
            Ok(files) if r.resumed => format!("ok (resumed: {} files intact)", files.len()),
            Ok(files) => format!("ok ({} files)", files.len()),
            Err(e) => format!("FAILED ({})", Fault::of(e).word()),
        };
        let chars = r.source.chars().count();
        let name = if chars > 44 {
            format!("...{}", r.source.chars().skip(chars - 41).collect::<String>())
        } else {
            r.source.clone()
        };
        writeln!(
            w,
            "{name:<44} {:>5} {:>8} {:>9} {:>11} {:>8.2} {:>14}  {status}",
            r.clips, r.channels, r.keys, r.samples, r.seconds, error
        )?;
        for c in &r.rates {
            let (rot, pos) = (&c.measured.rotation, &c.measured.position);
            writeln!(
                w,
                "  clip '{}': {:.3} Hz, {} frames, worst {:.3} deg ('{}', {:.3} s), {:.3} cm ('{}', {:.3} s); \
                 {} bytes, {:.0}% of {} Hz's {}",
                c.clip,
                c.measured.rate,
                c.measured.frames,
                rot.value,
                rot.joint,
                rot.time,
                pos.value,
                pos.joint,
                pos.time,
                c.bytes,
                100.0 * c.bytes as f64 / c.fixed_rate_bytes.max(1) as f64,
                options.rate,
                c.fixed_rate_bytes
            )?;
        }
        if let Some([x, y, z]) = r.rig.filter(|_| r.outcome.is_ok() && !r.resumed) {
            writeln!(
                w,
                "  rig at rest {y:.3} tall: its joints span {x:.3} x {y:.3} x {z:.3} (the file's units; glTF: m)"
            )?;
        }
        if let Some((vertex_frames, seconds)) = r.skinning {
            writeln!(
                w,
                "  skinned {:.2} M vertex-frames in {seconds:.3} s: {:.1} M vertex-frames/s on {}",
                vertex_frames as f64 / 1e6,
                vertex_frames as f64 / seconds.max(1e-9) / 1e6,
                report.device
            )?;
        }
    }
    Ok(())
}
