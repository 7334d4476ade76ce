//! Options as the library defines them, once each: a field's name is the option's name (the
//! Python keyword and the key in files; the command line's flag is `--` and the name with
//! dashes), its doc comment is the flag's help, and the type's `DEFAULT` holds its default.
//! The command line's flags are derived from these types (clap, with the `cli` feature) and
//! Python's keywords and the manifests are read and written through them (serde).

use quatcurve_core::curve::{Blend, Curve, CurveSpec, KnotMode, Tangents};
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
