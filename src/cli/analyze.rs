//! `quatcurve analyze`: energy, torque and smoothness of several curves through the same keys
//! (DESIGN section 14), and `--paper`, the rerun of KKS section 6.1.

use super::{names, print_stdout, read_tracks, CurveOptions, Failure};
use clap::Args;
use quatcurve::analysis::paper::{self, PaperSetup, RegimeTable, KKS_CURVES};
use quatcurve::analysis::{analyze, profile, AnalysisError, AnalysisOptions, Metrics};
use quatcurve::anim::loops::LoopMode;
use quatcurve::plot::{self, Series};
use quatcurve::{Batch, Curve, Device, DeviceChoice, Track};
use std::io::Write;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct AnalyzeArgs {
    /// Input tracks, as for eval (JSON, .npz or .npy); without it, the built-in demo.
    #[arg(long, conflicts_with = "paper")]
    input: Option<PathBuf>,
    /// Key times of .npz/.npy input without a times array: this many keys per second.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    key_rate: Option<f64>,
    /// Curves to compare, comma-separated; ratios are to squad (Shoemake's curve) when listed.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "bspline-interp,hermite,squad,nam-kim,slerp",
        value_parser = names::<Curve>(),
        conflicts_with = "paper"
    )]
    curves: Vec<Curve>,
    /// Which tracks loop (as eval's): auto, on, off; a loop's seam counts as a joint.
    #[arg(long = "loop", default_value_t = LoopMode::Auto, value_parser = names::<LoopMode>(), conflicts_with = "paper")]
    looping: LoopMode,
    #[command(flatten)]
    options: CurveOptions,
    /// Principal moments of inertia of the body, for the torque tau = I alpha + omega x (I omega).
    #[arg(
        long,
        value_name = "IXX,IYY,IZZ",
        value_delimiter = ',',
        num_args = 1,
        default_value = "1,1,1",
        allow_negative_numbers = true
    )]
    inertia: Vec<f64>,
    /// Simpson step in seconds (default: 1/1000 of each track's shortest span).
    #[arg(long, allow_negative_numbers = true)]
    step: Option<f64>,
    /// Evaluation device for the derivatives.
    #[arg(long, default_value = "reference", value_parser = names::<DeviceChoice>())]
    device: DeviceChoice,
    /// Print JSON (DESIGN section 14) instead of tables.
    #[arg(long)]
    json: bool,
    /// Draw |omega| and |alpha| against time, one line per curve, to a .png or .svg: the first
    /// track (with --paper, the first large-step sequence).
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
    /// Rerun KKS section 6.1: torque of each curve against Shoemake's on random key sequences
    /// with small (<= 20 degrees) and large (>= 120 degrees) steps between keys.
    #[arg(long)]
    paper: bool,
    /// Seed of --paper's key sequences.
    #[arg(long, default_value_t = PaperSetup::default().seed, requires = "paper")]
    seed: u64,
    /// Sequences per regime for --paper.
    #[arg(long, default_value_t = PaperSetup::default().sequences, requires = "paper")]
    sequences: usize,
    /// Keys per sequence for --paper.
    #[arg(long, default_value_t = PaperSetup::default().keys, requires = "paper")]
    keys: usize,
}

impl AnalyzeArgs {
    fn analysis_options(&self) -> Result<AnalysisOptions, Failure> {
        let inertia: [f64; 3] = self.inertia.as_slice().try_into().map_err(|_| {
            Failure::Input(format!("--inertia takes three moments IXX,IYY,IZZ, got {}", self.inertia.len()))
        })?;
        let options = AnalysisOptions { inertia, step: self.step };
        quatcurve::analysis::validate(&options).map_err(|e| Failure::Input(format!("--inertia/--step: {e}")))?;
        Ok(options)
    }
}

impl From<AnalysisError> for Failure {
    fn from(e: AnalysisError) -> Self {
        match e {
            AnalysisError::Device(d) => d.into(),
            other => Failure::Input(other.to_string()),
        }
    }
}

pub fn run(args: &AnalyzeArgs) -> Result<(), Failure> {
    let options = args.analysis_options()?;
    let device = super::open_device(args.device, "--device")?;
    if args.paper {
        return run_paper(args, options, &device);
    }
    let (source, tracks) = read_tracks(args.input.as_deref(), args.key_rate)?;
    let mut curves = args.curves.clone();
    curves.dedup();
    let mut results = Vec::new();
    for &curve in &curves {
        let batch = (args.options.batch(curve, args.looping, &tracks))
            .map_err(|e| Failure::Input(format!("{source}: {curve}: {e}")))?;
        let metrics =
            analyze(&batch, &device, &options).map_err(|e| Failure::from(e).context(&format!("{source}: {curve}")))?;
        results.push((curve, batch, metrics));
    }
    let squad = results.iter().find(|(c, ..)| *c == Curve::Squad).map(|(_, _, m)| Metrics::total(m));
    if let Some(path) = &args.plot {
        let series = results
            .iter()
            .map(|(curve, batch, _)| rates_series(curve.name(), batch, 0, &device))
            .collect::<Result<Vec<_>, _>>()?;
        let name = tracks[0].name.clone().unwrap_or_else(|| "track 0".into());
        plot::rates(path, &format!("{name}: angular velocity and acceleration"), &series, &key_times(&tracks[0]))
            .map_err(|e| Failure::Input(e.to_string()))?;
        super::wrote(path);
    }
    let names: Vec<String> =
        tracks.iter().enumerate().map(|(i, t)| t.name.clone().unwrap_or_else(|| format!("track {i}"))).collect();
    if args.json {
        let curves: Vec<serde_json::Value> = results
            .iter()
            .map(|(curve, _, metrics)| {
                let total = Metrics::total(metrics);
                let tracks: Vec<serde_json::Value> = metrics
                    .iter()
                    .zip(&names)
                    .map(|(m, name)| {
                        let mut row = serde_json::to_value(m).unwrap_or_default();
                        row["name"] = name.clone().into();
                        row
                    })
                    .collect();
                let ratio = squad.map(|s| serde_json::json!({"energy": total.energy / s.energy, "torque_energy": total.torque_energy / s.torque_energy}));
                serde_json::json!({"curve": curve.name(), "tracks": tracks, "total": total, "ratio_to_squad": ratio})
            })
            .collect();
        let doc = serde_json::json!({"source": source, "device": device.name(), "inertia": options.inertia, "curves": curves});
        return print_stdout(|w| writeln!(w, "{doc}"));
    }
    print_stdout(|w| {
        writeln!(
            w,
            "{} tracks from {source}; derivatives on {}; inertia {:?}; Simpson step {}",
            tracks.len(),
            device.name(),
            options.inertia,
            step_text(options.step)
        )?;
        writeln!(
            w,
            "{:<16} {:<12} {:>12} {:>13} {:>10} {:>10} {:>10} {:>10} {:>10} {:>8} {:>8}",
            "curve",
            "track",
            "energy",
            "torque_energy",
            "max_omega",
            "max_alpha",
            "arc_length",
            "alpha_jump",
            "omega_jump",
            "E/squad",
            "T/squad"
        )?;
        let per_track = tracks.len() > 1 && tracks.len() <= 12;
        for (curve, _, metrics) in &results {
            if per_track {
                for (m, name) in metrics.iter().zip(&names) {
                    row(w, curve.name(), name, m, None)?;
                }
            }
            let total = Metrics::total(metrics);
            row(
                w,
                curve.name(),
                if tracks.len() == 1 { &names[0] } else { "total" },
                &total,
                squad.map(|s| [total.energy / s.energy, total.torque_energy / s.torque_energy]),
            )?;
        }
        if tracks.len() > 12 {
            writeln!(w, "(totals over {} tracks; --json gives every track)", tracks.len())?;
        }
        if results.iter().any(|(_, _, m)| Metrics::total(m).omega_jump > 1e-6) {
            writeln!(
                w,
                "(where omega jumps, as slerp's does at every key, alpha holds an impulse that energy does not count)"
            )?;
        }
        Ok(())
    })
}

fn row(w: &mut dyn Write, curve: &str, track: &str, m: &Metrics, ratios: Option<[f64; 2]>) -> std::io::Result<()> {
    let [e, t] = ratios.map_or([String::new(), String::new()], |r| r.map(|x| format!("{x:.4}")));
    writeln!(
        w,
        "{curve:<16} {track:<12} {:>12.5e} {:>13.5e} {:>10.4} {:>10.4} {:>10.4} {:>10.3e} {:>10.3e} {e:>8} {t:>8}",
        m.energy, m.torque_energy, m.max_omega, m.max_alpha, m.arc_length, m.alpha_jump, m.omega_jump
    )
}

fn step_text(step: Option<f64>) -> String {
    step.map_or("1/1000 of the shortest span".into(), |s| format!("{s} s"))
}

/// The chart line of one curve over track `index` of its batch.
fn rates_series(label: &str, batch: &Batch, index: usize, device: &Device) -> Result<Series, Failure> {
    let [times, omega, alpha] = profile(batch, index, device, 2000)?;
    Ok(Series { label: label.to_string(), times, omega, alpha })
}

/// A track's key times (default 0, 1, ..., n).
fn key_times(track: &Track) -> Vec<f64> {
    track.times.clone().unwrap_or_else(|| (0..track.rotations.len()).map(|i| i as f64).collect())
}

fn run_paper(args: &AnalyzeArgs, options: AnalysisOptions, device: &Device) -> Result<(), Failure> {
    if args.sequences == 0 || args.keys < 3 {
        return Err(Failure::Input(format!(
            "--paper needs at least 1 sequence and 3 keys, got --sequences {} --keys {}",
            args.sequences, args.keys
        )));
    }
    let setup = PaperSetup { seed: args.seed, sequences: args.sequences, keys: args.keys, options };
    let tables = paper::run(&setup, device)?;
    if let Some(path) = &args.plot {
        let large = &paper::REGIMES[1];
        let tracks = paper::sequences(large, setup.seed, 1, setup.keys);
        let series = paper::CURVES
            .iter()
            .map(|&(curve, _)| {
                let spec = args.options.spec(curve, false);
                let batch =
                    Batch::from_tracks(&tracks, &spec).map_err(|e| Failure::Input(format!("--paper plot: {e}")))?;
                rates_series(curve.name(), &batch, 0, device)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let title = format!(
            "KKS 6.1 rerun: first large-step sequence (seed {}), {}-{} degrees between keys",
            setup.seed, large.degrees[0], large.degrees[1]
        );
        plot::rates(path, &title, &series, &key_times(&tracks[0])).map_err(|e| Failure::Input(e.to_string()))?;
        super::wrote(path);
    }
    if args.json {
        let doc = serde_json::json!({
            "seed": setup.seed, "sequences": setup.sequences, "keys": setup.keys, "key_spacing_s": 1.0,
            "inertia": options.inertia, "device": device.name(), "regimes": tables,
        });
        return print_stdout(|w| writeln!(w, "{doc}"));
    }
    print_stdout(|w| write_paper(w, &setup, device, &tables))
}

fn write_paper(w: &mut dyn Write, setup: &PaperSetup, device: &Device, tables: &[RegimeTable]) -> std::io::Result<()> {
    writeln!(
        w,
        "KKS section 6.1 rerun: {} random sequences per regime, {} keys 1 s apart, seed {}, inertia {:?}, \
            derivatives on {}, Simpson step {}",
        setup.sequences,
        setup.keys,
        setup.seed,
        setup.options.inertia,
        device.name(),
        step_text(setup.options.step)
    )?;
    for table in tables {
        let [lo, hi] = table.regime.degrees;
        writeln!(
            w,
            "\n{} steps ({lo}-{hi} degrees between keys): {} sequences, {} left out (a curve could not be built)",
            table.regime.name, table.sequences, table.left_out
        )?;
        writeln!(
            w,
            "{:<16} {:>12} {:>12} {:>10} {:>12} {:>12} {:>14}",
            "curve", "torque/squad", "median ratio", "within 5%", "below squad", "energy/squad", "median jump"
        )?;
        for r in &table.curves {
            writeln!(
                w,
                "{:<16} {:>12.4} {:>12.4} {:>9.1}% {:>11.1}% {:>12.4} {:>14.3e}",
                r.curve,
                r.torque_ratio_total,
                r.torque_ratio_median,
                100.0 * r.within_5_percent,
                100.0 * r.below_squad,
                r.energy_ratio_total,
                r.alpha_jump_median
            )?;
        }
    }
    writeln!(w, "\nThe paper's claims, for its cubic curves ({}):", KKS_CURVES.map(|c| c.name()).join(", "))?;
    for claim in paper::verdicts(tables) {
        writeln!(w, "- {claim}")?;
    }
    Ok(())
}
