//! `quatcurve fit`: glTF, FBX or BVH clips to fitted containers (`<stem>.qcf`), each clip's curves
//! within an error budget in centimetres (DESIGN section 16), and a report per clip.

use super::{print_stdout, Failure};
use clap::Args;
use quatcurve::fit::job::{FitJob, FitOptions, FitReport};
use std::io::Write;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct FitArgs {
    /// Input files (.gltf, .glb, .fbx, .usd/.usda/.usdc/.usdz, .bvh) or directories of them.
    #[arg(long, num_args = 1.., required = true)]
    input: Vec<PathBuf>,
    /// Output directory (created if missing): one `<stem>.qcf` per input, or the library.
    #[arg(long, default_value = "fitted")]
    output: PathBuf,
    #[command(flatten)]
    options: FitOptions,
    /// Fit the source frames alone: the curve may swing between them (reported all the same);
    /// the command line's spelling of no between-frames error.
    #[arg(long, conflicts_with = "between_error_cm")]
    no_between_check: bool,
    /// Print the report as JSON (DESIGN section 16) instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(args: &FitArgs) -> Result<(), Failure> {
    let mut options = args.options.clone();
    if args.no_between_check {
        options.between_error_cm = None;
    }
    let job = FitJob { inputs: args.input.clone(), output: args.output.clone(), options };
    let report = job.run(&|input, clip| {
        eprintln!("{input}: clip '{}' {:.1}:1 in {:.1} s", clip.clip, clip.ratio, clip.seconds);
    })?;
    if args.json {
        print_stdout(|w| {
            serde_json::to_writer_pretty(&mut *w, &report).map_err(std::io::Error::from)?;
            writeln!(w)
        })?;
    } else {
        print_stdout(|w| table(w, &report))?;
    }
    let failed: Vec<String> =
        report.inputs.iter().filter_map(|i| i.error.as_ref().map(|e| format!("{}: {e}", i.input))).collect();
    match failed.len() {
        0 => Ok(()),
        n => Err(Failure::Input(format!(
            "{n} of {} inputs failed (no container written for them): {}",
            report.inputs.len(),
            failed.join("; ")
        ))),
    }
}

fn table(w: &mut dyn Write, report: &FitReport) -> std::io::Result<()> {
    let between = report.between_error_cm.map_or_else(|| "not checked".into(), |cm| format!("{cm} cm"));
    writeln!(
        w,
        "within {} cm at every source frame, between frames {between}, virtual vertices {} cm from each joint",
        report.max_error_cm, report.vertex_distance_cm
    )?;
    writeln!(w, "| input | clip | frames | raw KB | fitted KB | ratio | worst at frames | worst between | s |")?;
    writeln!(w, "|---|---|---:|---:|---:|---:|---|---|---:|")?;
    for input in &report.inputs {
        if let Some(e) = &input.error {
            writeln!(w, "| {} | failed: {e} | | | | | | | |", input.input)?;
        }
        for c in &input.clips {
            writeln!(
                w,
                "| {} | {} | {} | {:.1} | {:.1} | {:.1}:1 | {:.5} cm ({}, {:.3} s) | {:.4} cm ({}, {:.3} s) | {:.1} |",
                input.input,
                c.clip,
                c.frames,
                c.raw_bytes as f64 / 1024.0,
                c.compressed_bytes as f64 / 1024.0,
                c.ratio,
                c.at_frames.error_cm,
                c.at_frames.joint,
                c.at_frames.time,
                c.between_frames.error_cm,
                c.between_frames.joint,
                c.between_frames.time,
                c.seconds
            )?;
        }
    }
    // The whole file's ratio beside the clips': the skeleton (and a BVH's hierarchy) stored
    // once per container.
    let whole = |output: &Option<String>, bytes: usize, ratio: f64, clips: usize| match output {
        Some(path) => format!("{path}: {clips} clips, {:.1} KB, {ratio:.1}:1 as a whole file", bytes as f64 / 1024.0),
        None => String::new(),
    };
    match &report.clip_library {
        Some(l) => writeln!(
            w,
            "{} (clips alone {:.1}:1)",
            whole(&l.output, l.container_bytes, l.whole_file_ratio, l.clips),
            l.ratio
        )?,
        None => {
            for input in report.inputs.iter().filter(|i| i.output.is_some()) {
                writeln!(
                    w,
                    "{}",
                    whole(&input.output, input.container_bytes, input.whole_file_ratio, input.clips.len())
                )?;
            }
        }
    }
    Ok(())
}
