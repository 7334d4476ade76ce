//! One vocabulary across the subcommands: a concept has one flag, one unit and one default
//! wherever it appears (the test below holds it), and a spelling the library refuses
//! ([`quatcurve::options::REFUSED`]) is refused on the command line too, naming the flag that
//! takes its place.

use super::flag;
use clap::{Arg, ArgAction, ArgMatches, Command};
use quatcurve::options::{refused, REFUSED};

/// The id of the hidden argument that catches a refused spelling.
fn id(old: &str) -> String {
    format!("refused {old}")
}

/// `command` with every subcommand catching the refused spellings of its options (hidden from
/// `--help`), so that [`refused_given`] can name the flag that takes their place.
#[must_use]
pub fn with_refused(mut command: Command) -> Command {
    let names: Vec<String> = command.get_subcommands().map(|s| s.get_name().to_string()).collect();
    for name in names {
        command = command.mut_subcommand(name, |sub| {
            let longs: Vec<String> = sub.get_arguments().filter_map(|a| a.get_long().map(str::to_string)).collect();
            let has = |option: &str| longs.iter().any(|l| *l == flag(option)[2..]);
            let mut sub = sub;
            let mut added = Vec::new();
            for r in &REFUSED {
                if has(r.new) && !has(r.old) && !added.contains(&r.old) {
                    added.push(r.old);
                    let arg = Arg::new(id(r.old))
                        .long(flag(r.old)[2..].to_string())
                        .hide(true)
                        .num_args(0..=1)
                        .allow_negative_numbers(true)
                        .action(ArgAction::Append);
                    sub = sub.arg(arg);
                }
            }
            sub
        });
    }
    command
}

/// The message for a refused spelling given in `matches` of `command` ([`with_refused`]'s), if
/// one was: the option of that subcommand that takes its place.
#[must_use]
pub fn refused_given(command: &Command, matches: &ArgMatches) -> Option<String> {
    let (name, sub) = matches.subcommand()?;
    let given = |option: &str| sub.try_contains_id(&id(option)).unwrap_or(false);
    let options = command.find_subcommand(name)?;
    let known = |option: &str| options.get_arguments().any(|a| a.get_id().as_str() == option);
    REFUSED.iter().find(|r| given(r.old)).map(|r| {
        let now = refused(r.old, known).unwrap_or(r);
        format!("{} is now {} ({})", flag(now.old), flag(now.new), now.note)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Cli;
    use clap::CommandFactory;
    use std::collections::BTreeMap;

    /// Flags whose default is each command's own, and why.
    const OWN_DEFAULTS: [(&str, &str); 7] = [
        ("output", "each command writes its own product"),
        ("curve", "a file's own interpolation (bake, play); the C2 curve through bare keys (eval, bench)"),
        ("device", "an analysis's numbers are the f64 reference's unless another device is asked for"),
        ("samples", "bench's workload size; eval samples at the rate unless asked"),
        ("keys", "each workload's own size (bench's tracks, analyze's --paper sequences)"),
        ("instances", "play's crowd; bench's crowd sizes"),
        ("max-error-cm", "a fit always has a budget (ACL's 0.01 cm); a bake only when asked"),
    ];

    /// What a flag is, wherever it appears: its values' name (the unit), type and choices,
    /// and its default.
    #[derive(Debug, PartialEq)]
    struct Meaning {
        value_names: Vec<String>,
        type_id: String,
        choices: Vec<String>,
        default: Vec<String>,
    }

    fn meaning(arg: &Arg) -> Meaning {
        let strings = |v: Option<&[clap::builder::Str]>| v.unwrap_or_default().iter().map(|s| s.to_string()).collect();
        Meaning {
            value_names: strings(arg.get_value_names()),
            type_id: format!("{:?}", arg.get_value_parser().type_id()),
            choices: arg.get_possible_values().iter().map(|p| p.get_name().to_string()).collect(),
            default: arg.get_default_values().iter().map(|v| v.to_string_lossy().into_owned()).collect(),
        }
    }

    fn commands() -> Command {
        with_refused(Cli::command())
    }

    /// Every flag that appears in more than one subcommand means the same there: the same
    /// unit, type and choices, and the same default unless it is one of [`OWN_DEFAULTS`].
    #[test]
    fn a_flag_means_the_same_in_every_subcommand_that_has_it() {
        let mut seen: BTreeMap<String, Vec<(String, Meaning)>> = BTreeMap::new();
        for sub in commands().get_subcommands() {
            for arg in sub.get_arguments().filter(|a| !a.is_hide_set()) {
                if let Some(long) = arg.get_long() {
                    seen.entry(long.to_string()).or_default().push((sub.get_name().to_string(), meaning(arg)));
                }
            }
        }
        let shared: Vec<&String> = seen.iter().filter(|(_, m)| m.len() > 1).map(|(f, _)| f).collect();
        assert!(shared.len() >= 12, "flags in several subcommands: {shared:?}");
        let mut differ = Vec::new();
        for (long, meanings) in &seen {
            let (first_command, first) = &meanings[0];
            let own_default = OWN_DEFAULTS.iter().any(|(f, _)| f == long);
            for (command, m) in &meanings[1..] {
                let compared = |m: &Meaning| Meaning {
                    default: if own_default { Vec::new() } else { m.default.clone() },
                    value_names: m.value_names.clone(),
                    type_id: m.type_id.clone(),
                    choices: m.choices.clone(),
                };
                if compared(m) != compared(first) {
                    differ.push(format!("--{long}: {command} {m:?} against {first_command} {first:?}"));
                }
            }
        }
        assert!(differ.is_empty(), "{}", differ.join("\n"));
        for (long, _) in OWN_DEFAULTS {
            assert!(seen.get(long).is_some_and(|m| m.len() > 1), "--{long} is listed but in one command at most");
        }
    }

    /// A length is in centimetres and an angle in degrees wherever it is asked, and a flag
    /// taking one says so in its name.
    #[test]
    fn lengths_are_centimetres_and_angles_degrees_each_named_with_its_unit() {
        for sub in commands().get_subcommands() {
            for arg in sub.get_arguments().filter(|a| !a.is_hide_set()) {
                let (Some(long), Some(names)) = (arg.get_long(), arg.get_value_names()) else { continue };
                for name in names.iter().map(ToString::to_string) {
                    let here = format!("{} --{long} <{name}>", sub.get_name());
                    assert!(
                        !["MM", "M", "METRES", "RAD"].contains(&name.as_str()),
                        "{here}: lengths in CM, angles in DEG"
                    );
                    if let Some(unit) = ["CM", "DEG"].iter().find(|u| **u == name) {
                        assert!(long.ends_with(&format!("-{}", unit.to_lowercase())), "{here}: the unit in the name");
                    }
                }
            }
        }
    }

    /// Each refused spelling is no flag of any subcommand, and a subcommand whose options have
    /// the option that takes its place refuses it, naming that flag; `--help` does not show it.
    #[test]
    fn an_old_spelling_is_refused_naming_the_flag_that_takes_its_place() {
        let command = commands();
        let mut refusals = 0;
        for sub in command.get_subcommands() {
            let live: Vec<&str> =
                sub.get_arguments().filter(|a| !a.is_hide_set()).filter_map(|a| a.get_long()).collect();
            let mut olds: Vec<&str> = REFUSED.iter().map(|r| r.old).collect();
            olds.dedup();
            for old in olds {
                assert!(!live.contains(&&flag(old)[2..]), "{} still has {}", sub.get_name(), flag(old));
                // The first option of that spelling that this subcommand has takes its place.
                let Some(r) = REFUSED.iter().find(|r| r.old == old && live.contains(&&flag(r.new)[2..])) else {
                    continue;
                };
                let required = sub.get_arguments().filter(|a| a.is_required_set()).filter_map(|a| a.get_long());
                let mut given = vec!["quatcurve".to_string(), sub.get_name().to_string(), flag(old), "1".into()];
                given.extend(required.flat_map(|l| [format!("--{l}"), "x".into()]));
                let matches = commands().try_get_matches_from(&given).expect("the spelling parses, to be refused");
                let message = refused_given(&commands(), &matches).expect("refused");
                assert_eq!(message, format!("{} is now {} ({})", flag(old), flag(r.new), r.note), "{given:?}");
                refusals += 1;
            }
        }
        // bake: max-error, max-error-mm, unit-mm, blend; fit: those but blend, and between-error,
        // vertex-distance; play: blend, unit-mm; eval, bench, analyze: blend.
        assert_eq!(refusals, 14);
        let matches = commands().try_get_matches_from(["quatcurve", "bake", "--max-error-deg", "1"]).unwrap();
        assert_eq!(refused_given(&commands(), &matches), None);
    }
}
