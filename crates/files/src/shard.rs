//! Which share of a job this process runs (DESIGN section 13): `I/N` given, or the array index
//! and count an existing scheduler sets in the environment. quatcurve schedules nothing
//! itself; it is a well-behaved array task.
use crate::FileJobError;
use std::path::PathBuf;

/// Why a scheduler's environment names no share of the job.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ShardError {
    /// An index variable set without its count.
    #[error("{scheduler}: {index} is set but {count} is not; set it to the number of array tasks (or give the shard as I/N)")]
    NoCount {
        /// The scheduler.
        scheduler: &'static str,
        /// Its index variable.
        index: &'static str,
        /// Its count variable.
        count: &'static str,
    },
    /// A variable that is not a whole number.
    #[error("{variable}: {text:?} is not a whole number")]
    NotWhole {
        /// The variable.
        variable: &'static str,
        /// Its value.
        text: String,
    },
    /// An index below the scheduler's first.
    #[error("{variable} {index} is below {min_variable} {min}")]
    BelowMin {
        /// The index variable.
        variable: &'static str,
        /// Its value.
        index: usize,
        /// The first index's variable.
        min_variable: &'static str,
        /// Its value.
        min: usize,
    },
    /// A share that does not exist.
    #[error("{from}: shard {index} of {count} does not exist (need 0 <= index < count)")]
    NoSuchShard {
        /// Where the numbers came from.
        from: String,
        /// The index.
        index: usize,
        /// The count.
        count: usize,
    },
}

/// This process's share: inputs `k` with `k mod count == index`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Shard {
    /// 0-based.
    pub index: usize,
    /// At least 1.
    pub count: usize,
    /// Where the numbers came from, for the summary and the manifest.
    pub source: String,
}

impl Shard {
    /// The whole job.
    pub fn whole() -> Self {
        Self { index: 0, count: 1, source: "default (one shard)".into() }
    }

    /// Whether input `k` of the sorted list belongs to this shard.
    pub fn owns(&self, k: usize) -> bool {
        k % self.count == self.index
    }

    /// `I/N`, as `--shard` and Python's `shard=` give it.
    ///
    /// # Errors
    /// [`FileJobError::Option`] (`shard`): not two whole numbers, or no such shard.
    pub fn parse(text: &str) -> Result<Self, FileJobError> {
        let bad = |reason: String| FileJobError::option("shard", format!("{text}: {reason}"));
        let (index, count) = text.split_once('/').ok_or_else(|| bad("expected I/N, e.g. 0/4".into()))?;
        let number =
            |what: &str, n: &str| n.trim().parse().map_err(|_| bad(format!("the {what} {n:?} is not a whole number")));
        let (index, count) = (number("index", index)?, number("count", count)?);
        if count == 0 || index >= count {
            return Err(bad(format!("shard {index} of {count} does not exist (need 0 <= index < count)")));
        }
        Ok(Self { index, count, source: format!("shard {text}") })
    }

    /// The first scheduler whose index variable `env` has, else the whole job.
    ///
    /// # Errors
    /// [`ShardError`]: an index without its count, a value that is not a whole number, or a
    /// shard that does not exist.
    pub fn from_env(env: &dyn Fn(&str) -> Option<String>) -> Result<Self, ShardError> {
        // (scheduler, index variable, minimum variable to subtract, count variable)
        let schedulers: [(&str, &str, Option<&str>, &str); 4] = [
            ("Slurm", "SLURM_ARRAY_TASK_ID", Some("SLURM_ARRAY_TASK_MIN"), "SLURM_ARRAY_TASK_COUNT"),
            ("Kubernetes", "JOB_COMPLETION_INDEX", None, "QUATCURVE_SHARD_COUNT"),
            ("AWS Batch", "AWS_BATCH_JOB_ARRAY_INDEX", None, "QUATCURVE_SHARD_COUNT"),
            ("Google Batch", "BATCH_TASK_INDEX", None, "BATCH_TASK_COUNT"),
        ];
        for (scheduler, index_var, min_var, count_var) in schedulers {
            let Some(index) = env(index_var) else { continue };
            let count = env(count_var).ok_or(ShardError::NoCount { scheduler, index: index_var, count: count_var })?;
            let mut index = number(index_var, &index)?;
            let mut source = format!("{scheduler}: {index_var}");
            if let Some(min_var) = min_var {
                let min = env(min_var).map(|m| number(min_var, &m)).transpose()?.unwrap_or(0);
                index = index.checked_sub(min).ok_or(ShardError::BelowMin {
                    variable: index_var,
                    index,
                    min_variable: min_var,
                    min,
                })?;
                source = format!("{source} - {min_var}");
            }
            return Self::new(index, number(count_var, &count)?, format!("{source} of {count_var}"));
        }
        Ok(Self::whole())
    }

    fn new(index: usize, count: usize, source: String) -> Result<Self, ShardError> {
        if count == 0 || index >= count {
            return Err(ShardError::NoSuchShard { from: source, index, count });
        }
        Ok(Self { index, count, source })
    }

    /// `manifest.<I>-of-<N>.json` in `dir`.
    pub fn manifest_path(&self, dir: &std::path::Path) -> PathBuf {
        dir.join(format!("manifest.{}-of-{}.json", self.index, self.count))
    }
}

fn number(variable: &'static str, text: &str) -> Result<usize, ShardError> {
    text.trim().parse().map_err(|_| ShardError::NotWhole { variable, text: text.into() })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(pairs: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| pairs.iter().find(|(n, _)| *n == k).map(|(_, v)| (*v).to_string())
    }

    #[test]
    fn a_given_shard_parses_and_schedulers_go_in_order() {
        let slurm = [("SLURM_ARRAY_TASK_ID", "7"), ("SLURM_ARRAY_TASK_MIN", "5"), ("SLURM_ARRAY_TASK_COUNT", "3")];
        assert_eq!(Shard::parse("1/4").ok().map(|s| (s.index, s.count)), Some((1, 4)));
        let s = Shard::from_env(&env(&slurm)).ok().unwrap();
        assert_eq!((s.index, s.count), (2, 3));
        assert!(s.source.contains("SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN of SLURM_ARRAY_TASK_COUNT"));
        let k8s = [("JOB_COMPLETION_INDEX", "0"), ("QUATCURVE_SHARD_COUNT", "2")];
        assert_eq!(Shard::from_env(&env(&k8s)).ok().map(|s| (s.index, s.count)), Some((0, 2)));
        let aws = [("AWS_BATCH_JOB_ARRAY_INDEX", "1"), ("QUATCURVE_SHARD_COUNT", "2")];
        assert_eq!(Shard::from_env(&env(&aws)).ok().map(|s| (s.index, s.count)), Some((1, 2)));
        let google = [("BATCH_TASK_INDEX", "3"), ("BATCH_TASK_COUNT", "4")];
        assert_eq!(Shard::from_env(&env(&google)).ok().map(|s| (s.index, s.count)), Some((3, 4)));
        assert_eq!(Shard::from_env(&env(&[])).ok(), Some(Shard::whole()));
    }

    #[test]
    fn an_index_without_a_count_is_refused_naming_both_variables() {
        for (index, count) in
            [("JOB_COMPLETION_INDEX", "QUATCURVE_SHARD_COUNT"), ("BATCH_TASK_INDEX", "BATCH_TASK_COUNT")]
        {
            match Shard::from_env(&env(&[(index, "0")])) {
                Err(ShardError::NoCount { index: i, count: c, .. }) => assert_eq!((i, c), (index, count)),
                other => panic!("{index}: expected its count missing, got {other:?}"),
            }
        }
    }

    #[test]
    fn a_scheduler_s_shard_out_of_range_or_not_a_number_is_refused() {
        let past = [("BATCH_TASK_INDEX", "2"), ("BATCH_TASK_COUNT", "2")];
        assert!(matches!(Shard::from_env(&env(&past)), Err(ShardError::NoSuchShard { index: 2, count: 2, .. })));
        let below = [("SLURM_ARRAY_TASK_ID", "1"), ("SLURM_ARRAY_TASK_MIN", "5"), ("SLURM_ARRAY_TASK_COUNT", "3")];
        assert!(matches!(Shard::from_env(&env(&below)), Err(ShardError::BelowMin { index: 1, min: 5, .. })));
        let word = [("BATCH_TASK_INDEX", "x"), ("BATCH_TASK_COUNT", "2")];
        assert!(matches!(Shard::from_env(&env(&word)), Err(ShardError::NotWhole { variable: "BATCH_TASK_INDEX", .. })));
    }

    #[test]
    fn a_given_shard_that_is_not_one_of_its_count_is_an_option_error() {
        for text in ["4/4", "0/0", "1", "a/2"] {
            assert!(matches!(Shard::parse(text), Err(FileJobError::Option { option: "shard", .. })), "{text}");
        }
    }
}
