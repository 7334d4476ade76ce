//! Options as the library defines them, once each: a field's name is the option's name (the
//! Python keyword and the key in files; the command line's flag is `--` and the name with
//! dashes), its doc comment is the flag's help, and the type's `DEFAULT` holds its default.
//! The command line's flags are derived from these types (clap, with the `cli` feature) and
//! Python's keywords and the manifests are read and written through them (serde).

use crate::sampling::{Sampling, DEFAULT_RATE};
use quatcurve_core::curve::{names, Blend, Curve, CurveSpec, KnotMode, Tangents, DEFAULT_CURVE};
use serde::{Deserialize, Serialize};

/// The curve families' own options (the family is each job's option).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct CurveOptions {
    /// B-spline order k (degree k - 1), 2..=8.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = CurveOptions::DEFAULT.order))]
    pub order: usize,
    /// B-spline knot mode (default: phantom; bench: uniform).
    #[cfg_attr(feature = "cli", arg(long, value_parser = names::<KnotMode>()))]
    pub knots: Option<KnotMode>,
    /// Tangent source for hermite and nam-kim.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = CurveOptions::DEFAULT.tangents, value_parser = names::<Tangents>()))]
    pub tangents: Tangents,
    /// Nam-Kim blend function.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = CurveOptions::DEFAULT.blend, value_parser = names::<Blend>()))]
    pub blend: Blend,
}

impl CurveOptions {
    /// [`CurveSpec::DEFAULT`]'s, the knot mode left to the job.
    pub const DEFAULT: Self = Self {
        order: CurveSpec::DEFAULT.order,
        knots: None,
        tangents: CurveSpec::DEFAULT.tangents,
        blend: CurveSpec::DEFAULT.blend,
    };

    /// The spec of `curve` with these options; `knots` when none was given.
    #[must_use]
    pub fn spec(&self, curve: Curve, knots: KnotMode, looping: bool) -> CurveSpec {
        let knots = self.knots.unwrap_or(knots);
        CurveSpec { curve, order: self.order, knots, tangents: self.tangents, blend: self.blend, looping }
    }
}

impl Default for CurveOptions {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Which device evaluates (the option `device`; `quatcurve_device::Device::open` opens it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeviceChoice {
    /// A hardware GPU when there is one, else the fast CPU path (also over a software
    /// adapter such as lavapipe, which runs the kernel on the same CPU cores many times slower).
    #[default]
    Auto,
    /// The GPU; no adapter is an error, never a silent fallback.
    Gpu,
    /// The fast f32 SIMD CPU path.
    Cpu,
    /// The f64 reference.
    Reference,
}

names!(DeviceChoice, "device", Auto => "auto", Gpu => "gpu", Cpu => "cpu", Reference => "reference");

/// The options of an evaluation (`quatcurve eval`, Python's `evaluate`; DESIGN sections 5
/// and 9): the curve through the keys, where it is sampled, on which device. The tracks and
/// where the samples go are the caller's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct EvalOptions {
    /// Curve family; the default, bspline-interp, is C2 and passes through every key (a fitted
    /// container's curves are its own B-splines).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = EvalOptions::DEFAULT.curve, value_parser = names::<Curve>()))]
    pub curve: Curve,
    /// The family's options (knots: phantom unless given).
    #[serde(flatten)]
    #[cfg_attr(feature = "cli", command(flatten))]
    pub curve_options: CurveOptions,
    /// Periodic curves: each track's last key closes onto its first rotation, the curve keeps
    /// its continuity across that seam and sample times wrap by the period.
    #[serde(rename = "loop")]
    #[cfg_attr(feature = "cli", arg(long = "loop", help = loop_help()))]
    pub looping: bool,
    /// Evaluation device: auto is a hardware GPU if any, else the fast CPU path (also over a
    /// software adapter such as lavapipe; gpu still takes one).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = EvalOptions::DEFAULT.device, value_parser = names::<DeviceChoice>()))]
    pub device: DeviceChoice,
    /// N samples per track from its domain's start to its end, both included.
    #[cfg_attr(feature = "cli", arg(long, conflicts_with = "rate"))]
    pub samples: Option<usize>,
    /// Samples per second from each track's domain start (30 when neither this nor samples is
    /// given).
    #[cfg_attr(feature = "cli", arg(long, allow_negative_numbers = true))]
    pub rate: Option<f64>,
    /// Also the body angular velocity and acceleration at each sample.
    #[cfg_attr(feature = "cli", arg(long))]
    pub derivatives: bool,
}

impl EvalOptions {
    /// Every option at its default.
    pub const DEFAULT: Self = Self {
        curve: DEFAULT_CURVE,
        curve_options: CurveOptions::DEFAULT,
        looping: false,
        device: DeviceChoice::Auto,
        samples: None,
        rate: None,
        derivatives: false,
    };

    /// The curve these options ask for (B-spline knots phantom unless given).
    #[must_use]
    pub fn spec(&self) -> CurveSpec {
        self.curve_options.spec(self.curve, KnotMode::Phantom, self.looping)
    }

    /// Where each track is sampled when no sample times are given: `samples` per domain, or
    /// `rate` Hz ([`DEFAULT_RATE`] when neither is given).
    ///
    /// # Errors
    /// [`OptionError::Value`] when both are given.
    pub fn sampling(&self) -> Result<Sampling, OptionError> {
        match (self.samples, self.rate) {
            (Some(_), Some(_)) => {
                Err(OptionError::Value { name: "samples".into(), reason: "give samples or rate, not both".into() })
            }
            (Some(n), None) => Ok(Sampling::Count(n)),
            (None, rate) => Ok(Sampling::Rate(rate.unwrap_or(DEFAULT_RATE))),
        }
    }
}

impl Default for EvalOptions {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The help of `--loop` for `eval`: the doc comment, with the curves that loop.
#[cfg(feature = "cli")]
fn loop_help() -> String {
    format!(
        "Periodic curves: each track's last key closes onto its first rotation, the curve keeps its continuity \
         across that seam and sample times wrap by the period ({})",
        CurveSpec::looping_curves()
    )
}

/// Parses one of `T`'s names; `--help` and errors list them ("possible values: ...").
#[cfg(feature = "cli")]
#[must_use]
pub fn names<T: quatcurve_core::curve::Named>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::TypedValueParser;
    // Only listed names reach the map, and each of them parses.
    clap::builder::PossibleValuesParser::new(T::NAMES)
        .map(|name| name.parse::<T>().unwrap_or_else(|_| unreachable!("{name} is listed")))
}

/// Why options given by name could not be read.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum OptionError {
    /// A name that is none of the options.
    #[error("unknown option '{name}' (the options are {known})")]
    Unknown {
        /// The name given.
        name: String,
        /// The options' names, comma-separated.
        known: String,
    },
    /// A value its option does not take.
    #[error("{name}: {reason}")]
    Value {
        /// The option.
        name: String,
        /// What is wrong with the value.
        reason: String,
    },
}

/// Options given by name, as Python's keywords give them, read into `T` (whose fields take
/// their defaults where not given): every name must be one of `T`'s options, and a value that
/// does not fit its option is an error naming the option.
///
/// # Errors
/// [`OptionError`]: an unknown name, or a value its option does not take.
pub fn from_named<T>(given: &serde_json::Map<String, serde_json::Value>) -> Result<T, OptionError>
where
    T: Default + Serialize + for<'de> Deserialize<'de>,
{
    let known = match serde_json::to_value(T::default()) {
        Ok(serde_json::Value::Object(map)) => map,
        _ => unreachable!("options serialize as a map"),
    };
    for (name, value) in given {
        if !known.contains_key(name) {
            let known = known.keys().map(String::as_str).collect::<Vec<_>>().join(", ");
            return Err(OptionError::Unknown { name: name.clone(), known });
        }
        // One at a time, so that a bad value is named by its option.
        let one = serde_json::Map::from_iter([(name.clone(), value.clone())]);
        if let Err(e) = serde_json::from_value::<T>(serde_json::Value::Object(one)) {
            return Err(OptionError::Value { name: name.clone(), reason: e.to_string() });
        }
    }
    serde_json::from_value(serde_json::Value::Object(given.clone()))
        .map_err(|e| OptionError::Value { name: "options".into(), reason: e.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every eval option is a flag of the command line, spelled from its name, and reads back
    /// by name as Python gives it.
    #[cfg(feature = "cli")]
    #[test]
    fn every_eval_option_is_a_flag_named_after_it_and_reads_by_name() {
        use clap::Args;
        let command = EvalOptions::augment_args(clap::Command::new("eval"));
        let mut flags: Vec<String> = command.get_arguments().filter_map(|a| a.get_long().map(str::to_string)).collect();
        let serde_json::Value::Object(names) = serde_json::to_value(EvalOptions::DEFAULT).unwrap() else { panic!() };
        let mut names: Vec<String> = names.keys().map(|n| n.replace('_', "-")).collect();
        names.sort();
        flags.sort();
        assert_eq!(flags, names);
        let given = serde_json::from_str(r#"{"curve": "squad", "loop": true, "samples": 7, "device": "cpu"}"#).unwrap();
        let options: EvalOptions = from_named(&given).unwrap();
        let expected = EvalOptions {
            curve: Curve::Squad,
            looping: true,
            samples: Some(7),
            device: DeviceChoice::Cpu,
            ..EvalOptions::DEFAULT
        };
        assert_eq!(options, expected);
    }

    #[test]
    fn sampling_is_samples_or_rate_and_never_both() {
        let with = |samples, rate| EvalOptions { samples, rate, ..EvalOptions::DEFAULT }.sampling();
        assert_eq!(with(None, None), Ok(Sampling::Rate(DEFAULT_RATE)));
        assert_eq!(with(Some(5), None), Ok(Sampling::Count(5)));
        assert_eq!(with(None, Some(12.0)), Ok(Sampling::Rate(12.0)));
        assert_eq!(with(Some(5), Some(12.0)).unwrap_err().to_string(), "samples: give samples or rate, not both");
    }
}
