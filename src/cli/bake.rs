//! `quatcurve bake`: resample glTF/GLB and BVH files (or the built-in crowd) at a new rate.
//!
//! The flags fill a [`BakeJob`] (the library runs it: per input read, bake every clip, write
//! its outputs atomically; a failed input is reported and the others still finish); this
//! file draws the progress bar, prints the summary and exits non-zero if any input failed.

use super::{flag, names, print_stdout, CurveArgs, DeviceArgs, Failure};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use quatcurve::bake::budget::ErrorBudget;
use quatcurve::bake::image::{Format, DEFAULT_MAX_TEXTURE_SIZE};
use quatcurve::bake::root_motion::RootMotion;
use quatcurve::bake::texture::{Precision, TextureKind};
use quatcurve::bake::{crowd, BakeError, BakeJob, BakeReport, InputReport, LoopMode, Progress, Shard};
use quatcurve::{Curve, KnotMode};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

#[derive(Args, Debug)]
pub struct BakeArgs {
    /// Input files (.gltf, .glb, .bvh) or directories of them; without it, the built-in
    /// synthetic crowd.
    #[arg(long, num_args = 1..)]
    input: Vec<PathBuf>,
    /// Output rate in Hz, fitted per clip so that its first and last frames are its first and
    /// last keys (the clip's own rate is in the sidecar).
    #[arg(long, default_value_t = quatcurve::DEFAULT_RATE, allow_negative_numbers = true)]
    rate: f64,
    /// Bake open clips at exactly --rate: frames start + i / rate while not past the last
    /// key, so a clip's end off that grid is not baked (the summary warns how much).
    #[arg(long)]
    exact_rate: bool,
    /// Curve family; the default, bspline-interp, is C2 and passes through every key.
    #[arg(long, default_value = quatcurve::DEFAULT_CURVE.name(), value_parser = names::<Curve>())]
    curve: Curve,
    /// Which clips loop: auto (those whose rotation channels end on their first rotation),
    /// on (every clip; one that does not close is an error), off.
    #[arg(long = "loop", default_value = "auto", value_parser = names::<LoopMode>())]
    looping: LoopMode,
    #[command(flatten)]
    options: CurveArgs,
    #[command(flatten)]
    device: DeviceArgs,
    /// Read glTF buffers from anywhere the URI points (absolute paths, `..` out of the file's
    /// directory, `file:` URIs). Off by default: only data URIs and files beside the input.
    #[arg(long)]
    allow_external_uris: bool,
    /// Texture per clip: local (rotation, translation, scale of each joint relative to its
    /// parent), model (3x4 matrices relative to the scene root, by forward kinematics), skin
    /// (model times inverse bind matrix, one texture per glTF skin; BVH and the crowd: model),
    /// or model-trs and skin-trs (those transforms as rotation, translation, scale: what a
    /// shader interpolates between frames without shearing; `quatcurve shaders`), or vertex
    /// (glTF only: every skinned mesh primitive skinned at every frame on the device, positions
    /// and normals; images hold them encoded, and `<stem>.mesh.glb` is the mesh they play).
    #[arg(long, default_value = "local", value_parser = names::<TextureKind>())]
    texture: TextureKind,
    /// Texture element type: f32, or f16 (half the bytes, about 3 significant digits).
    #[arg(long, default_value = "f32", value_parser = names::<Precision>())]
    precision: Precision,
    /// Texture file format: npy arrays, or 2D RGBA images engines import: exr (float, or half
    /// with --precision f16) or png16 (16-bit, each channel remapped to its range in the sidecar).
    #[arg(long, default_value = "npy", value_parser = names::<Format>())]
    format: Format,
    /// Largest side of an image texture in texels (exr, png16); frames that do not fit are an error.
    #[arg(long, default_value_t = DEFAULT_MAX_TEXTURE_SIZE, value_name = "TEXELS")]
    max_texture_size: usize,
    /// One texture per input with every clip stacked along frames (`<stem>.npy`; each clip's
    /// rows from `first_row` in the sidecar), instead of one per clip.
    #[arg(long)]
    atlas: bool,
    /// Also draw each clip's skeleton at evenly spaced frames, front and side views, to
    /// `<stem>.<clip>.preview.png`.
    #[arg(long)]
    preview: bool,
    /// Output directory (created if missing).
    #[arg(long, default_value = "baked")]
    output: PathBuf,
    /// Characters in the built-in crowd.
    #[arg(long, default_value_t = crowd::CHARACTERS)]
    characters: usize,
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
    /// Rotation error budget in degrees: each clip at the lowest rate whose frames, blended
    /// as `quatcurve shaders` does, stay within it of the curve between frames (16 points
    /// per frame interval, every joint); replaces --rate. Textures local, model-trs, skin-trs.
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    max_error: Option<f64>,
    /// Position budget in millimetres, for joints in model space (local textures: errors
    /// accumulated down the hierarchy by forward kinematics); with or without --max-error.
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    max_error_mm: Option<f64>,
    /// Millimetres per unit of the input's positions (glTF: metres, 1000).
    #[arg(long, default_value_t = quatcurve::bake::budget::GLTF_UNIT_MM, value_name = "MM")]
    unit_mm: f64,
    /// keep: the root's horizontal translation and heading stay in the textures; extract: they
    /// go to a per-frame root track in the sidecar (position, heading, velocities; a loop's
    /// per-cycle displacement), and the textures play in place.
    #[arg(long, default_value = "keep", value_parser = names::<RootMotion>())]
    root_motion: RootMotion,
    /// The highest rate a budget may choose (Hz); a clip no rate up to it holds is refused.
    #[arg(long, default_value_t = quatcurve::bake::budget::DEFAULT_MAX_RATE, value_name = "HZ")]
    max_rate: f64,
}

impl From<BakeError> for Failure {
    /// Option errors name the option as its flag (`max_rate must ...` becomes `--max-rate
    /// must ...`).
    fn from(e: BakeError) -> Self {
        match e {
            BakeError::Option { option, reason } => Failure::Input(format!("{} {reason}", flag(option))),
            BakeError::Manifest(_) => Failure::Internal(e.to_string()),
            _ => Failure::Input(e.to_string()),
        }
    }
}

impl BakeArgs {
    fn job(&self) -> Result<BakeJob, Failure> {
        Ok(BakeJob {
            rate: self.rate,
            exact_rate: self.exact_rate,
            spec: self.options.spec(self.curve, KnotMode::Phantom, false),
            looping: self.looping,
            device: self.device.device,
            allow_external_uris: self.allow_external_uris,
            texture: self.texture,
            precision: self.precision,
            format: self.format,
            max_texture_size: self.max_texture_size,
            atlas: self.atlas,
            preview: self.preview,
            characters: self.characters,
            shard: self.shard.as_deref().map(Shard::parse).transpose()?,
            resume: self.resume,
            jobs: self.jobs,
            max_error: ErrorBudget {
                degrees: self.max_error,
                millimetres: self.max_error_mm,
                unit_mm: self.unit_mm,
                max_rate: self.max_rate,
            },
            root_motion: self.root_motion,
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
}

pub fn run(args: &BakeArgs) -> Result<(), Failure> {
    let job = args.job()?;
    job.validate()?;
    let device = super::open_device(args.device.device, "--device")?;
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
    // Exit code 1 when the machine is at fault (DESIGN section 5b), else 2.
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
    fn of(e: &quatcurve::anim::error::InputError) -> Self {
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
    let (shard, rows) = (&report.shard, &report.inputs);
    let rate = if args.max_error.is_some() || args.max_error_mm.is_some() {
        let budget: Vec<String> = [(args.max_error, "degrees"), (args.max_error_mm, "mm")]
            .iter()
            .filter_map(|(v, unit)| v.map(|v| format!("{v} {unit}")))
            .collect();
        format!("rates chosen per clip for {} between frames", budget.join(" and "))
    } else if args.exact_rate {
        format!("exactly {} Hz", args.rate)
    } else {
        format!("{} Hz (fitted per clip)", args.rate)
    };
    let fitted = report.inputs.iter().any(|i| i.source.ends_with(&format!(".{}", quatcurve::anim::qcf::EXTENSION)));
    let curve =
        if fitted { format!("{} (fitted inputs: their own B-splines)", args.curve) } else { args.curve.to_string() };
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
                "  clip '{}': {:.3} Hz, {} frames, worst {:.3} deg ('{}', {:.3} s), {:.3} mm ('{}', {:.3} s); \
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
                args.rate,
                c.fixed_rate_bytes
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
