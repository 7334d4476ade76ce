//! `quatcurve` command line: see `quatcurve --help` and DESIGN section 5.
//!
//! Exit codes: 0 success, 2 bad usage or bad input (one line naming file, track and key),
//! 1 internal or device failure.

mod cli;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use cli::Failure;
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(name = "quatcurve", version, about = "Smooth rotation curves for batches of animation tracks")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Evaluate curves through tracks (JSON, .npz or .npy arrays, or a fitted .qcf); write
    /// samples as JSON or .npy.
    Eval(cli::eval::EvalArgs),
    /// Resample glTF/GLB, FBX, USD (.usd/.usda/.usdc/.usdz), BVH, SMPL .npz or fitted .qcf animation (or a built-in
    /// synthetic crowd) at a new rate.
    Bake(cli::bake::BakeArgs),
    /// Fit glTF/GLB, FBX, USD (.usd/.usda/.usdc/.usdz) or BVH clips as the fewest quantized B-spline control points within
    /// an error budget (cm), one .qcf container per input, which bake reads as it reads the
    /// source.
    Fit(cli::fit::FitArgs),
    /// Play a crowd straight from a file's curves (glTF/GLB, FBX, USD (.usd/.usda/.usdc/.usdz), BVH, SMPL .npz, .qcf): every
    /// instance at its own time, two clips blended, skin palettes per frame written as one .npy.
    Play(cli::play::PlayArgs),
    /// Time the same synthetic batch on every available device, side by side; or decoding
    /// (.qcf), skinning (glTF/GLB) or crowd playback (glTF/GLB, FBX, USD (.usd/.usda/.usdc/.usdz), BVH, SMPL .npz, .qcf).
    Bench(cli::bench::BenchArgs),
    /// Energy, torque and smoothness of curves through the same keys (JSON, .npz or .npy
    /// tracks); --paper reruns KKS 6.1.
    Analyze(cli::analyze::AnalyzeArgs),
    /// The shaders that read baked bone textures (--format exr|png16): WGSL, or GLSL and HLSL
    /// generated from it.
    Shaders(cli::shaders::ShadersArgs),
    /// Serve a baked directory to a page that plays it as a crowd: its curves through WebGPU,
    /// its textures through WebGL2 (127.0.0.1 only unless --address says otherwise).
    View(cli::view::ViewArgs),
}

fn main() -> ExitCode {
    let command = cli::vocabulary::with_refused(Cli::command());
    let matches = command.clone().get_matches();
    if let Some(message) = cli::vocabulary::refused_given(&command, &matches) {
        eprintln!("error: {message}");
        return ExitCode::from(2);
    }
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let result = match cli.command {
        Command::Eval(args) => cli::eval::run(&args),
        Command::Bake(args) => cli::bake::run(&args),
        Command::Fit(args) => cli::fit::run(&args),
        Command::Play(args) => cli::play::run(&args),
        Command::Bench(args) => cli::bench::run(&args),
        Command::Analyze(args) => cli::analyze::run(&args),
        Command::Shaders(args) => cli::shaders::run(&args),
        Command::View(args) => cli::view::run(&args),
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
