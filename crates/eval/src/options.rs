//! Options as the library defines them, once each: a field's name is the option's name (the
//! Python keyword and the key in files; the command line's flag is `--` and the name with
//! dashes), its doc comment is the flag's help, and the type's `DEFAULT` holds its default.
//! The command line's flags are derived from these types (clap, with the `cli` feature) and
//! Python's keywords and the manifests are read and written through them (serde).

use crate::batch::{loop_gap, Batch};
use crate::sampling::{Sampling, DEFAULT_RATE};
use crate::track::Track;
use quatcurve_core::curve::{names, Blend, Curve, CurveSpec, KnotMode, Tangents, DEFAULT_CURVE};
use quatcurve_core::quat::QuatF64;
use serde::{Deserialize, Serialize};

/// The curve families' own options (the family is each job's option).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct CurveOptions {
    /// B-spline order k (degree k - 1), 2..=8.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = CurveOptions::DEFAULT.order))]
    pub order: usize,
    /// B-spline knot mode.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = CurveOptions::DEFAULT.knots, value_parser = names::<KnotMode>()))]
    pub knots: KnotMode,
    /// Tangent source for hermite and nam-kim.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = CurveOptions::DEFAULT.tangents, value_parser = names::<Tangents>()))]
    pub tangents: Tangents,
    /// Nam-Kim blend function.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = CurveOptions::DEFAULT.blend_function, value_parser = names::<Blend>()))]
    pub blend_function: Blend,
}

impl CurveOptions {
    /// [`CurveSpec::DEFAULT`]'s.
    pub const DEFAULT: Self = Self {
        order: CurveSpec::DEFAULT.order,
        knots: CurveSpec::DEFAULT.knots,
        tangents: CurveSpec::DEFAULT.tangents,
        blend_function: CurveSpec::DEFAULT.blend,
    };

    /// The spec of `curve` with these options.
    #[must_use]
    pub fn spec(&self, curve: Curve, looping: bool) -> CurveSpec {
        let (order, knots, tangents, blend) = (self.order, self.knots, self.tangents, self.blend_function);
        CurveSpec { curve, order, knots, tangents, blend, looping }
    }

    /// The spec of `curve` through `track`, looping as `mode` says of it.
    #[must_use]
    pub fn spec_for(&self, curve: Curve, mode: LoopMode, track: &Track) -> CurveSpec {
        let spec = self.spec(curve, false);
        CurveSpec { looping: mode.loops(&spec, || opening(&track.rotations).is_none()), ..spec }
    }

    /// The batch of `tracks`, each on [`Self::spec_for`] its curve.
    ///
    /// # Errors
    /// As [`Batch::from_tracks_each`]'s.
    pub fn batch(&self, curve: Curve, mode: LoopMode, tracks: &[Track]) -> crate::error::Result<Batch> {
        Batch::from_tracks_each(tracks, |i| self.spec_for(curve, mode, &tracks[i]))
    }
}

/// Which curves loop (the option `loop`, of tracks and of clips alike; DESIGN section 5b).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LoopMode {
    /// Those whose rotations end on their first (within [`crate::batch::LOOP_TOLERANCE`]: each track's keys,
    /// every rotation channel of a clip) and whose curve can loop.
    #[default]
    Auto,
    /// Every one; one that does not close is an error naming it.
    On,
    /// None.
    Off,
}

names!(LoopMode, "loop mode", Auto => "auto", On => "on", Off => "off");

impl LoopMode {
    /// Whether a curve of `spec` loops under this mode, `closes` saying whether its rotations
    /// end on their first (asked only for [`LoopMode::Auto`]).
    #[must_use]
    pub fn loops(self, spec: &CurveSpec, closes: impl FnOnce() -> bool) -> bool {
        match self {
            LoopMode::On => true,
            LoopMode::Off => false,
            LoopMode::Auto => spec.can_loop() && closes(),
        }
    }
}

/// The angle (rad) between the last of `rotations` and the first, when it is more than
/// [`crate::batch::LOOP_TOLERANCE`] (or not a number); none for rotations that close ([`loop_gap`]).
#[must_use]
pub fn opening(rotations: &[[f64; 4]]) -> Option<f64> {
    let unit = |q: &[f64; 4]| QuatF64::from_array(*q).normalize();
    loop_gap(unit(rotations.first()?), unit(rotations.last()?))
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
    /// Which tracks loop: auto (those whose last key is their first rotation), on (every one;
    /// one that does not close is an error), off. A looping curve keeps its continuity across
    /// that seam and sample times wrap by the period.
    #[serde(rename = "loop")]
    #[cfg_attr(feature = "cli", arg(long = "loop", default_value_t = EvalOptions::DEFAULT.looping, value_parser = names::<LoopMode>(), help = loop_help()))]
    pub looping: LoopMode,
    /// Evaluation device: auto is a hardware GPU if any, else the fast CPU path (also over a
    /// software adapter such as lavapipe; gpu still takes one).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = EvalOptions::DEFAULT.device, value_parser = names::<DeviceChoice>()))]
    pub device: DeviceChoice,
    /// N samples per track from its domain's start to its end, both included.
    #[cfg_attr(feature = "cli", arg(long, conflicts_with = "rate"))]
    pub samples: Option<usize>,
    /// Samples per second from each track's domain start, unless samples is given.
    #[cfg_attr(feature = "cli", arg(long, value_name = "HZ", default_value_t = DEFAULT_RATE, allow_negative_numbers = true))]
    pub rate: f64,
    /// Also the body angular velocity and acceleration at each sample.
    #[cfg_attr(feature = "cli", arg(long))]
    pub derivatives: bool,
}

impl EvalOptions {
    /// Every option at its default.
    pub const DEFAULT: Self = Self {
        curve: DEFAULT_CURVE,
        curve_options: CurveOptions::DEFAULT,
        looping: LoopMode::Auto,
        device: DeviceChoice::Auto,
        samples: None,
        rate: DEFAULT_RATE,
        derivatives: false,
    };

    /// The curve these options ask for through `track`: looping as [`Self::looping`] says of it.
    #[must_use]
    pub fn spec_for(&self, track: &Track) -> CurveSpec {
        self.curve_options.spec_for(self.curve, self.looping, track)
    }

    /// The batch of `tracks`, each on [`Self::spec_for`] its curve.
    ///
    /// # Errors
    /// As [`Batch::from_tracks_each`]'s.
    pub fn batch(&self, tracks: &[Track]) -> crate::error::Result<Batch> {
        self.curve_options.batch(self.curve, self.looping, tracks)
    }

    /// Where each track is sampled when no sample times are given: `samples` per domain, or
    /// else `rate` Hz.
    ///
    /// # Errors
    /// [`OptionError::Value`] when both are given.
    pub fn sampling(&self) -> Result<Sampling, OptionError> {
        match self.samples {
            Some(_) if self.rate != DEFAULT_RATE => {
                Err(OptionError::Value { name: "samples".into(), reason: "give samples or rate, not both".into() })
            }
            Some(n) => Ok(Sampling::Count(n)),
            None => Ok(Sampling::Rate(self.rate)),
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
        "Which tracks loop: auto (those whose last key is their first rotation), on (every one; one that does not \
         close is an error), off. A looping curve keeps its continuity across that seam and sample times wrap by \
         the period ({})",
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

/// An option's spelling that is refused, with the option that means it now: each concept has
/// one name and one unit in every command and in Python's keywords.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Refused {
    /// The spelling refused (`max_error`).
    pub old: &'static str,
    /// The option that takes its place, where the options have it (`max_error_deg` in a bake's).
    pub new: &'static str,
    /// What changed beside the name (a unit), for the message.
    pub note: &'static str,
}

/// Every refused spelling. One spelling may stand for two options (`max_error`: a bake's
/// degrees, a fit's centimetres); each set of options takes the first listed that it has (a
/// bake has both, and its `max_error` was its degrees).
pub const REFUSED: [Refused; 7] = [
    Refused { old: "max_error", new: "max_error_deg", note: "degrees" },
    Refused { old: "max_error", new: "max_error_cm", note: "centimetres" },
    Refused { old: "max_error_mm", new: "max_error_cm", note: "centimetres: a tenth of the millimetres" },
    Refused { old: "unit_mm", new: "unit_cm", note: "centimetres per file unit: glTF's metre is 100" },
    Refused { old: "between_error", new: "between_error_cm", note: "centimetres" },
    Refused { old: "vertex_distance", new: "vertex_distance_cm", note: "centimetres" },
    Refused { old: "blend", new: "blend_function", note: "the Nam-Kim curve's blend function" },
];

/// The refused spelling `given` among options named `known`, if it is one: the option that
/// takes its place there.
#[must_use]
pub fn refused<'a>(given: &str, known: impl Fn(&str) -> bool) -> Option<&'a Refused> {
    REFUSED.iter().find(|r| r.old == given && known(r.new))
}

/// Why options given by name could not be read.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum OptionError {
    /// A spelling that names an option by another name now ([`REFUSED`]).
    #[error("'{old}' is now '{new}' ({note})", old = .0.old, new = .0.new, note = .0.note)]
    Refused(Refused),
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
        if let Some(r) = refused(name, |n| known.contains_key(n)) {
            return Err(OptionError::Refused(*r));
        }
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
        let given = serde_json::from_str(r#"{"curve": "squad", "loop": "on", "samples": 7, "device": "cpu"}"#).unwrap();
        let options: EvalOptions = from_named(&given).unwrap();
        let expected = EvalOptions {
            curve: Curve::Squad,
            looping: LoopMode::On,
            samples: Some(7),
            device: DeviceChoice::Cpu,
            ..EvalOptions::DEFAULT
        };
        assert_eq!(options, expected);
    }

    #[test]
    fn sampling_is_samples_or_rate_and_never_both() {
        let with = |samples, rate| EvalOptions { samples, rate, ..EvalOptions::DEFAULT }.sampling();
        assert_eq!(with(None, DEFAULT_RATE), Ok(Sampling::Rate(DEFAULT_RATE)));
        assert_eq!(with(Some(5), DEFAULT_RATE), Ok(Sampling::Count(5)));
        assert_eq!(with(None, 12.0), Ok(Sampling::Rate(12.0)));
        assert_eq!(with(Some(5), 12.0).unwrap_err().to_string(), "samples: give samples or rate, not both");
    }

    /// Auto loops the tracks that close on a curve that loops, each on its own.
    #[test]
    fn auto_loops_each_track_that_closes_on_a_curve_that_loops() {
        let turn = |degrees: f64| {
            let h = degrees.to_radians() / 2.0;
            [0.0, 0.0, h.sin(), h.cos()]
        };
        let closed = Track::from_rotations(vec![turn(0.0), turn(90.0), turn(180.0), turn(0.0)]);
        let open = Track::from_rotations(vec![turn(0.0), turn(90.0), turn(180.0)]);
        // The same rotation on the other side of the sphere closes too.
        let negated = Track::from_rotations(vec![turn(0.0), turn(90.0), turn(360.0)]);
        let looping = |mode, curve, track: &Track| {
            EvalOptions { looping: mode, curve, ..EvalOptions::DEFAULT }.spec_for(track).looping
        };
        let interp = Curve::BSplineInterp;
        assert!(looping(LoopMode::Auto, interp, &closed));
        assert!(looping(LoopMode::Auto, interp, &negated));
        assert!(!looping(LoopMode::Auto, interp, &open));
        assert!(!looping(LoopMode::Auto, Curve::Bezier, &closed), "bezier cannot loop");
        assert!(!looping(LoopMode::Off, interp, &closed));
        assert!(looping(LoopMode::On, interp, &open), "on asks; the batch refuses what does not close");
        let batch = EvalOptions { looping: LoopMode::On, ..EvalOptions::DEFAULT }.batch(&[closed, open]);
        assert!(batch.unwrap_err().to_string().contains("a looping track must end on its first rotation"));
    }
}
