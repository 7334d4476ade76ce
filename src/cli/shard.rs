//! Which share of a job this process runs (DESIGN section 7): `--shard I/N`, or the array
//! index and count an existing scheduler sets in the environment. quatcurve schedules
//! nothing itself; it is a well-behaved array task.

use super::Failure;
use std::path::PathBuf;

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

    /// `--shard` when given, else the first scheduler whose index variable is set.
    pub fn resolve(flag: Option<&str>, env: &dyn Fn(&str) -> Option<String>) -> Result<Self, Failure> {
        if let Some(flag) = flag {
            let (index, count) = flag.split_once('/').ok_or_else(|| bad(format!("--shard {flag}: expected I/N, e.g. 0/4")))?;
            return Self::new(number("--shard index", index)?, number("--shard count", count)?, format!("--shard {flag}"));
        }
        // (scheduler, index variable, minimum variable to subtract, count variable)
        let schedulers: [(&str, &str, Option<&str>, &str); 4] = [
            ("Slurm", "SLURM_ARRAY_TASK_ID", Some("SLURM_ARRAY_TASK_MIN"), "SLURM_ARRAY_TASK_COUNT"),
            ("Kubernetes", "JOB_COMPLETION_INDEX", None, "QUATCURVE_SHARD_COUNT"),
            ("AWS Batch", "AWS_BATCH_JOB_ARRAY_INDEX", None, "QUATCURVE_SHARD_COUNT"),
            ("Google Batch", "BATCH_TASK_INDEX", None, "BATCH_TASK_COUNT"),
        ];
        for (scheduler, index_var, min_var, count_var) in schedulers {
            let Some(index) = env(index_var) else { continue };
            let count = env(count_var).ok_or_else(|| {
                bad(format!("{scheduler}: {index_var} is set but {count_var} is not; set it to the number of array tasks (or pass --shard I/N)"))
            })?;
            let mut index = number(index_var, &index)?;
            let mut source = format!("{scheduler}: {index_var}");
            if let Some(min_var) = min_var {
                let min = env(min_var).map(|m| number(min_var, &m)).transpose()?.unwrap_or(0);
                index = index.checked_sub(min).ok_or_else(|| bad(format!("{index_var} {index} is below {min_var} {min}")))?;
                source = format!("{source} - {min_var}");
            }
            return Self::new(index, number(count_var, &count)?, format!("{source} of {count_var}"));
        }
        Ok(Self::whole())
    }

    fn new(index: usize, count: usize, source: String) -> Result<Self, Failure> {
        if count == 0 || index >= count {
            return Err(bad(format!("{source}: shard {index} of {count} does not exist (need 0 <= index < count)")));
        }
        Ok(Self { index, count, source })
    }

    /// `manifest.<I>-of-<N>.json` in `dir`.
    pub fn manifest_path(&self, dir: &std::path::Path) -> PathBuf {
        dir.join(format!("manifest.{}-of-{}.json", self.index, self.count))
    }
}

fn bad(msg: String) -> Failure {
    Failure::Input(msg)
}

fn number(what: &str, text: &str) -> Result<usize, Failure> {
    text.trim().parse().map_err(|_| bad(format!("{what}: {text:?} is not a whole number")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(pairs: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| pairs.iter().find(|(n, _)| *n == k).map(|(_, v)| (*v).to_string())
    }

    #[test]
    fn flag_wins_then_schedulers_in_order() {
        let slurm = [("SLURM_ARRAY_TASK_ID", "7"), ("SLURM_ARRAY_TASK_MIN", "5"), ("SLURM_ARRAY_TASK_COUNT", "3")];
        assert_eq!(Shard::resolve(Some("1/4"), &env(&slurm)).ok().map(|s| (s.index, s.count)), Some((1, 4)));
        let s = Shard::resolve(None, &env(&slurm)).ok().unwrap();
        assert_eq!((s.index, s.count), (2, 3));
        assert!(s.source.contains("SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN of SLURM_ARRAY_TASK_COUNT"));
        let k8s = [("JOB_COMPLETION_INDEX", "0"), ("QUATCURVE_SHARD_COUNT", "2")];
        assert_eq!(Shard::resolve(None, &env(&k8s)).ok().map(|s| (s.index, s.count)), Some((0, 2)));
        let aws = [("AWS_BATCH_JOB_ARRAY_INDEX", "1"), ("QUATCURVE_SHARD_COUNT", "2")];
        assert_eq!(Shard::resolve(None, &env(&aws)).ok().map(|s| (s.index, s.count)), Some((1, 2)));
        let google = [("BATCH_TASK_INDEX", "3"), ("BATCH_TASK_COUNT", "4")];
        assert_eq!(Shard::resolve(None, &env(&google)).ok().map(|s| (s.index, s.count)), Some((3, 4)));
        assert_eq!(Shard::resolve(None, &env(&[])).ok(), Some(Shard::whole()));
    }

    #[test]
    fn an_index_without_a_count_and_out_of_range_shards_are_errors() {
        for (flag, pairs) in [
            (None, vec![("JOB_COMPLETION_INDEX", "0")]),
            (None, vec![("BATCH_TASK_INDEX", "0")]),
            (Some("4/4"), vec![]),
            (Some("0/0"), vec![]),
            (Some("1"), vec![]),
            (Some("a/2"), vec![]),
        ] {
            assert!(matches!(Shard::resolve(flag, &env(&pairs)), Err(Failure::Input(_))), "{flag:?} {pairs:?}");
        }
    }
}
