//! KKS section 6.1 rerun: "Our cubic quaternion curves generate a similar amount of torque (in
//! the range of +-5%) to that of Shoemake when the control unit quaternions have small angular
//! variations. However, our curves perform much better when the variations are large", and
//! they are C2, with no torque jump at the joints.
//!
//! The paper gives no data, so this builds its own: random key sequences (a uniformly random
//! first key, then each key turned from the previous one about a uniformly random axis by an
//! angle drawn uniformly from the regime's range), keys one second apart. Each sequence runs
//! through every curve of [`CURVES`]; torque energies are compared with squad's (Shoemake's
//! curve through the same keys) sequence by sequence and in total. A sequence some curve
//! cannot build (bspline-interp has no C2 interpolant for some keys far apart) is counted and
//! left out of every curve's figures, so all ratios compare the same sequences.

use super::{analyze, AnalysisError, AnalysisOptions, Metrics};
use quatcurve_core::curve::{Blend, Curve, CurveSpec, KnotMode, Tangents};
use quatcurve_core::quat::QuatF64;
use quatcurve_device::Device;
use quatcurve_eval::batch::Batch;
use quatcurve_eval::synthetic::SplitMix;
use quatcurve_eval::track::Track;

/// The curves compared, Shoemake's squad first (the baseline).
pub const CURVES: [(Curve, &str); 5] = [
    (Curve::Squad, "Shoemake's squad (baseline)"),
    (Curve::BSplineInterp, "KKS cubic B-spline through the keys (C2)"),
    (Curve::Hermite, "KKS cubic Hermite, Catmull-Rom tangents (C1)"),
    (Curve::BSpline, "KKS cubic B-spline, phantom ends (C2, approximating)"),
    (Curve::NamKim, "Nam-Kim great-arc blend, Catmull-Rom tangents (C1)"),
];

/// The curves KKS section 6.1 speaks for ("our cubic quaternion curves").
pub const KKS_CURVES: [Curve; 3] = [Curve::BSplineInterp, Curve::Hermite, Curve::BSpline];

/// A range of angles between consecutive keys.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Regime {
    /// "small" or "large".
    pub name: &'static str,
    /// Smallest and largest step between consecutive keys, degrees.
    pub degrees: [f64; 2],
}

/// The paper's two regimes: small variations (up to 20 degrees between keys) and large ones
/// (120 degrees and more; at most 170, away from the half turn, where "the shortest rotation
/// between two keys" is ill-conditioned).
pub const REGIMES: [Regime; 2] =
    [Regime { name: "small", degrees: [2.0, 20.0] }, Regime { name: "large", degrees: [120.0, 170.0] }];

/// How the experiment is run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaperSetup {
    /// Seed of the key sequences: the same seed gives the same table.
    pub seed: u64,
    /// Sequences per regime.
    pub sequences: usize,
    /// Keys per sequence.
    pub keys: usize,
    /// Inertia and integration step.
    pub options: AnalysisOptions,
}

impl Default for PaperSetup {
    fn default() -> Self {
        Self { seed: 1995, sequences: 300, keys: 8, options: AnalysisOptions::default() }
    }
}

/// One curve's row of the table for one regime.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CurveRow {
    /// The curve's CLI name.
    pub curve: String,
    /// What it is.
    pub label: String,
    /// Sum of torque energies over the sequences, divided by squad's sum.
    pub torque_ratio_total: f64,
    /// Median over sequences of (torque energy / squad's on the same sequence).
    pub torque_ratio_median: f64,
    /// Share of sequences whose torque energy is within 5% of squad's.
    pub within_5_percent: f64,
    /// Share of sequences with less torque energy than squad's.
    pub below_squad: f64,
    /// Sum of `integral |alpha|^2` over the sequences, divided by squad's sum.
    pub energy_ratio_total: f64,
    /// Median over sequences of the largest alpha jump at a joint (rad/s^2).
    pub alpha_jump_median: f64,
    /// Median over sequences of that jump over the sequence's largest |alpha|.
    pub alpha_jump_relative_median: f64,
}

/// The table of one regime.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RegimeTable {
    /// The regime.
    pub regime: Regime,
    /// Sequences compared (built by every curve).
    pub sequences: usize,
    /// Sequences left out because a curve could not be built through them.
    pub left_out: usize,
    /// One row per curve of [`CURVES`].
    pub curves: Vec<CurveRow>,
}

/// The random key sequences of one regime, reproducible from `seed`.
#[must_use]
pub fn sequences(regime: &Regime, seed: u64, count: usize, keys: usize) -> Vec<Track> {
    let mut rng = SplitMix::new(seed ^ regime.degrees[1].to_bits());
    (0..count)
        .map(|s| {
            let mut q = rng.rotation();
            let mut rotations = vec![q.to_array()];
            for _ in 1..keys {
                let [lo, hi] = regime.degrees;
                let angle = (lo + (hi - lo) * rng.unit()).to_radians();
                q = q * QuatF64::exp(rng.direction().scale(0.5 * angle));
                rotations.push(q.to_array());
            }
            Track { name: Some(format!("{}{s}", regime.name)), ..Track::from_rotations(rotations) }
        })
        .collect()
}

/// Runs the experiment on `device`: one table per regime of [`REGIMES`].
///
/// # Errors
/// The analysis's (options, device); sequences a curve cannot build are left out, not errors.
pub fn run(setup: &PaperSetup, device: &Device) -> Result<Vec<RegimeTable>, AnalysisError> {
    super::validate(&setup.options)?;
    REGIMES.iter().map(|regime| regime_table(regime, setup, device)).collect()
}

fn regime_table(regime: &Regime, setup: &PaperSetup, device: &Device) -> Result<RegimeTable, AnalysisError> {
    let tracks = sequences(regime, setup.seed, setup.sequences, setup.keys.max(2));
    let spec = |curve: Curve| CurveSpec {
        curve,
        order: 4,
        knots: KnotMode::Phantom,
        tangents: Tangents::CatmullRom,
        blend: Blend::Cubic,
        looping: false,
    };
    // Keep the sequences every curve builds.
    let kept: Vec<Track> = tracks
        .into_iter()
        .filter(|t| CURVES.iter().all(|&(c, _)| Batch::from_tracks(std::slice::from_ref(t), &spec(c)).is_ok()))
        .collect();
    let left_out = setup.sequences - kept.len();
    let mut per_curve: Vec<Vec<Metrics>> = Vec::new();
    for &(curve, _) in &CURVES {
        if kept.is_empty() {
            per_curve.push(Vec::new());
            continue;
        }
        let batch = Batch::from_tracks(&kept, &spec(curve))?;
        per_curve.push(analyze(&batch, device, &setup.options)?);
    }
    let squad = &per_curve[0];
    let squad_total = Metrics::total(squad);
    let curves = CURVES
        .iter()
        .zip(&per_curve)
        .map(|(&(curve, label), metrics)| {
            let total = Metrics::total(metrics);
            let ratios: Vec<f64> = metrics.iter().zip(squad).map(|(m, s)| m.torque_energy / s.torque_energy).collect();
            let share = |keep: &dyn Fn(f64) -> bool| {
                ratios.iter().filter(|&&r| keep(r)).count() as f64 / ratios.len().max(1) as f64
            };
            CurveRow {
                curve: curve.name().to_string(),
                label: label.to_string(),
                torque_ratio_total: total.torque_energy / squad_total.torque_energy,
                torque_ratio_median: median(ratios.clone()),
                within_5_percent: share(&|r| (r - 1.0).abs() <= 0.05),
                below_squad: share(&|r| r < 1.0),
                energy_ratio_total: total.energy / squad_total.energy,
                alpha_jump_median: median(metrics.iter().map(|m| m.alpha_jump).collect()),
                alpha_jump_relative_median: median(metrics.iter().map(|m| m.alpha_jump / m.max_alpha).collect()),
            }
        })
        .collect();
    Ok(RegimeTable { regime: *regime, sequences: kept.len(), left_out, curves })
}

/// Largest |median ratio - 1| for "a similar amount of torque (in the range of +-5%)".
pub const SIMILAR: f64 = 0.05;
/// Largest total torque ratio read as "much better" (at least a fifth less torque).
pub const MUCH_BETTER: f64 = 0.8;
/// Largest median relative alpha jump read as "no torque jump" (f32 devices round to ~1e-6).
pub const NO_JUMP: f64 = 1e-4;

/// The paper's three claims checked against `tables` (small regime first, as [`run`] returns
/// them), one sentence each, with the figures and thresholds that decide them.
#[must_use]
pub fn verdicts(tables: &[RegimeTable]) -> Vec<String> {
    let verdict = |ok: bool| if ok { "holds" } else { "does not hold" };
    let rows = |table: &RegimeTable| -> Vec<CurveRow> {
        table.curves.iter().filter(|r| KKS_CURVES.iter().any(|c| c.name() == r.curve)).cloned().collect()
    };
    let mut out = Vec::new();
    if let Some(small) = tables.iter().find(|t| t.regime.name == "small") {
        let parts: Vec<String> = rows(small)
            .iter()
            .map(|r| {
                let m = r.torque_ratio_median;
                let reading = if (m - 1.0).abs() <= SIMILAR {
                    "holds".to_string()
                } else if m < 1.0 {
                    format!("does not hold: {:.0}% less torque, better than claimed", 100.0 * (1.0 - m))
                } else {
                    format!("does not hold: {:.0}% more torque", 100.0 * (m - 1.0))
                };
                format!("{} median {m:.3} ({reading})", r.curve)
            })
            .collect();
        out.push(format!(
            "small variations, torque within +-5% of Shoemake's (median ratio in [0.95, 1.05]): {}",
            parts.join("; ")
        ));
    }
    if let Some(large) = tables.iter().find(|t| t.regime.name == "large") {
        let parts: Vec<String> = rows(large)
            .iter()
            .map(|r| {
                format!(
                    "{} total {:.3}, below squad in {:.0}% of sequences ({})",
                    r.curve,
                    r.torque_ratio_total,
                    100.0 * r.below_squad,
                    verdict(r.torque_ratio_total <= MUCH_BETTER)
                )
            })
            .collect();
        out.push(format!(
            "large variations, much less torque than Shoemake's (total ratio <= {MUCH_BETTER}): {}",
            parts.join("; ")
        ));
    }
    let c2: Vec<String> = tables
        .iter()
        .flat_map(|t| rows(t).into_iter().map(move |r| (t.regime.name, r)))
        .filter(|(_, r)| r.curve != Curve::Hermite.name())
        .map(|(regime, r)| {
            format!(
                "{} {regime} {:.1e} ({})",
                r.curve,
                r.alpha_jump_relative_median,
                verdict(r.alpha_jump_relative_median <= NO_JUMP)
            )
        })
        .collect();
    out.push(format!(
        "C2, no torque jump at the joints (median jump / max |alpha| <= {NO_JUMP:.0e}; Hermite is C1 and jumps): {}",
        c2.join("; ")
    ));
    out
}

fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}
