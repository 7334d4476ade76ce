//! Sharded bakes (DESIGN section 13): shards reproduce one unsharded run byte for byte,
//! manifests record SHA-256s, `--resume` redoes exactly what is missing or damaged, and the
//! scheduler examples in `examples/` run as their schedulers would run them.

use super::{json, library, stderr};
use assert_cmd::Command;
use std::collections::BTreeMap;
use std::path::Path;

fn quatcurve() -> Command {
    Command::cargo_bin("quatcurve").unwrap()
}

/// Every file in `dir` except manifests, by name, with its bytes.
fn outputs(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .map(|e| (e.file_name().to_string_lossy().into_owned(), e.path()))
        .filter(|(name, _)| !name.starts_with("manifest."))
        .map(|(name, path)| (name, std::fs::read(path).unwrap()))
        .collect()
}

pub(super) fn sha256(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// Statuses by input path in a manifest.
fn statuses(manifest: &serde_json::Value) -> BTreeMap<String, String> {
    manifest["inputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| (i["path"].as_str().unwrap().to_string(), i["status"].as_str().unwrap().to_string()))
        .collect()
}

#[test]
fn three_shards_equal_one_run_and_resume_redoes_only_damage() {
    let Some(data) = library() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (whole, sharded) = (dir.path().join("whole"), dir.path().join("sharded"));
    let base = ["bake", "--input", data.to_str().unwrap(), "--rate", "24", "--device", "cpu"];
    let run = |out: &Path, extra: &[&str], env: &[(&str, &str)]| {
        let mut command = quatcurve();
        command.args(base).args(["--output", out.to_str().unwrap()]).args(extra);
        for (k, v) in env {
            command.env(k, v);
        }
        let result = command.output().unwrap();
        assert!(result.status.success(), "{extra:?} {env:?}: {}", stderr(&result));
        String::from_utf8_lossy(&result.stdout).into_owned()
    };
    run(&whole, &[], &[]);
    // Two shards by flag, one from Slurm's variables (task IDs 10..12: index = ID - MIN).
    run(&sharded, &["--shard", "0/3"], &[]);
    let summary = run(
        &sharded,
        &[],
        &[("SLURM_ARRAY_TASK_ID", "11"), ("SLURM_ARRAY_TASK_MIN", "10"), ("SLURM_ARRAY_TASK_COUNT", "3")],
    );
    assert!(
        summary.contains("shard 1 of 3 (Slurm: SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN of SLURM_ARRAY_TASK_COUNT)"),
        "{summary}"
    );
    // --jobs bakes several inputs at once; nothing it writes may depend on that.
    run(&sharded, &["--shard", "2/3", "--jobs", "3"], &[]);
    let expected = outputs(&whole);
    assert_eq!(outputs(&sharded), expected, "the union of 3 shards differs from one run");
    // Each manifest lists its inputs and every output with size and SHA-256.
    let mut recorded = BTreeMap::new();
    for i in 0..3 {
        let manifest = json(&sharded.join(format!("manifest.{i}-of-3.json")));
        assert_eq!(manifest["shard"]["count"], 3);
        for input in manifest["inputs"].as_array().unwrap() {
            let bytes = std::fs::read(input["path"].as_str().unwrap()).unwrap();
            assert_eq!(input["sha256"].as_str().unwrap(), sha256(&bytes));
            for output in input["outputs"].as_array().unwrap() {
                recorded.insert(
                    output["file"].as_str().unwrap().to_string(),
                    (output["size"].as_u64().unwrap(), output["sha256"].as_str().unwrap().to_string()),
                );
            }
        }
    }
    let actual: BTreeMap<String, (u64, String)> =
        expected.iter().map(|(n, b)| (n.clone(), (b.len() as u64, sha256(b)))).collect();
    assert_eq!(recorded, actual, "manifests do not list every output with its hash");
    // Resume after success: nothing redone.
    let before = json(&sharded.join("manifest.0-of-3.json"));
    run(&sharded, &["--shard", "0/3", "--resume"], &[]);
    let after = json(&sharded.join("manifest.0-of-3.json"));
    assert!(statuses(&after).values().all(|s| s == "resumed"), "{after}");
    // Damage one output of shard 0 (truncate) and delete one: exactly those inputs are redone.
    let shard0: Vec<(String, Vec<String>)> = before["inputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| {
            (
                i["path"].as_str().unwrap().to_string(),
                i["outputs"].as_array().unwrap().iter().map(|o| o["file"].as_str().unwrap().to_string()).collect(),
            )
        })
        .collect();
    assert!(shard0.len() >= 2, "{before}");
    let truncated = sharded.join(&shard0[0].1[0]);
    let bytes = std::fs::read(&truncated).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    std::fs::remove_file(sharded.join(&shard0[1].1[1])).unwrap();
    run(&sharded, &["--shard", "0/3", "--resume"], &[]);
    let redone = statuses(&json(&sharded.join("manifest.0-of-3.json")));
    for (k, (path, _)) in shard0.iter().enumerate() {
        assert_eq!(redone[path], if k < 2 { "ok" } else { "resumed" }, "{path}: {redone:?}");
    }
    assert_eq!(outputs(&sharded), expected, "resume did not restore the outputs");
    // Other options: everything redone.
    run(&sharded, &["--shard", "0/3", "--resume", "--curve", "hermite"], &[]);
    assert!(statuses(&json(&sharded.join("manifest.0-of-3.json"))).values().all(|s| s == "ok"));
}

#[test]
fn a_scheduler_index_without_a_count_is_exit_2() {
    let result = quatcurve()
        .args(["bake", "--characters", "1"])
        .env("JOB_COMPLETION_INDEX", "1")
        .env_remove("QUATCURVE_SHARD_COUNT")
        .output()
        .unwrap();
    assert_eq!(result.status.code(), Some(2), "{}", stderr(&result));
    assert!(
        stderr(&result).contains("JOB_COMPLETION_INDEX is set but QUATCURVE_SHARD_COUNT is not"),
        "{}",
        stderr(&result)
    );
}

/// The repository root's `examples/` file `name`.
fn example(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples").join(name)
}

/// `examples/slurm-array.sh` as `sbatch --array=0-2` would run it, and
/// `examples/k8s-indexed-job.yaml`'s container command as its three pods would: each with the
/// variables its scheduler sets. Both together reproduce one unsharded run.
#[test]
fn the_scheduler_examples_run_as_their_schedulers_run_them() {
    let Some(data) = library() else { return };
    let dir = tempfile::tempdir().unwrap();
    let bin = assert_cmd::cargo::cargo_bin("quatcurve");
    let whole = dir.path().join("whole");
    let result = quatcurve()
        .args([
            "bake",
            "--input",
            data.to_str().unwrap(),
            "--output",
            whole.to_str().unwrap(),
            "--rate",
            "30",
            "--device",
            "cpu",
        ])
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", stderr(&result));
    let expected = outputs(&whole);

    let slurm = dir.path().join("slurm");
    for task in 0..3 {
        let result = std::process::Command::new("bash")
            .arg(example("slurm-array.sh"))
            .args([data.to_str().unwrap(), slurm.to_str().unwrap()])
            .env("QUATCURVE", &bin)
            .env("SLURM_ARRAY_TASK_ID", task.to_string())
            .env("SLURM_ARRAY_TASK_MIN", "0")
            .env("SLURM_ARRAY_TASK_MAX", "2")
            .env("SLURM_ARRAY_TASK_COUNT", "3")
            .output()
            .unwrap();
        assert!(result.status.success(), "slurm task {task}: {}", stderr(&result));
    }
    assert_eq!(outputs(&slurm), expected, "Slurm array");
    assert!((0..3).all(|i| slurm.join(format!("manifest.{i}-of-3.json")).exists()));

    // The Job's command line, its completions and QUATCURVE_SHARD_COUNT, from the YAML.
    let yaml = std::fs::read_to_string(example("k8s-indexed-job.yaml")).unwrap();
    let field = |key: &str| {
        yaml.lines().find_map(|l| l.trim().strip_prefix(key).map(str::trim)).unwrap_or_else(|| panic!("{key} missing"))
    };
    let completions: usize = field("completions:").parse().unwrap();
    let count = yaml
        .lines()
        .skip_while(|l| l.trim() != "- name: QUATCURVE_SHARD_COUNT")
        .nth(1)
        .and_then(|l| l.trim().strip_prefix("value:"))
        .unwrap()
        .trim()
        .trim_matches('"');
    assert_eq!(count, completions.to_string(), "QUATCURVE_SHARD_COUNT must equal completions");
    assert_eq!(field("command:"), "[\"quatcurve\"]");
    let args: Vec<String> = serde_json::from_str(field("args:")).unwrap();
    let k8s = dir.path().join("k8s");
    let args: Vec<String> = args
        .iter()
        .map(|a| a.replace("/data", data.to_str().unwrap()).replace("/baked", k8s.to_str().unwrap()))
        .collect();
    for index in 0..completions {
        let result = quatcurve()
            .args(&args)
            .env("JOB_COMPLETION_INDEX", index.to_string())
            .env("QUATCURVE_SHARD_COUNT", count)
            .output()
            .unwrap();
        assert!(result.status.success(), "pod {index}: {}", stderr(&result));
    }
    assert_eq!(outputs(&k8s), expected, "Kubernetes Indexed Job");
}

/// A shard killed while it writes (SIGKILL, as a scheduler preempts a task) at 20% and at 80%
/// of its inputs leaves temporary files; run again with `--resume`, it removes its own (their
/// names say which file each was to become) and never another shard's, and its outputs are
/// those of a run never killed.
#[test]
fn a_killed_shard_resumed_leaves_no_temporary_file_of_its_own() {
    let Some(data) = super::data_dir() else { return };
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("inputs");
    std::fs::create_dir_all(&inputs).unwrap();
    let count = 40;
    for k in 0..count {
        std::os::unix::fs::symlink(data.join("CesiumMan.glb"), inputs.join(format!("man{k:02}.glb"))).unwrap();
    }
    let args = |out: &Path| {
        let mut command = std::process::Command::new(assert_cmd::cargo::cargo_bin("quatcurve"));
        command.args(["bake", "--input", inputs.to_str().unwrap(), "--output", out.to_str().unwrap()]);
        command.args(["--texture", "model", "--rate", "1000", "--shard", "0/2", "--resume"]);
        command
    };
    let (clean, killed) = (dir.path().join("clean"), dir.path().join("killed"));
    let result = args(&clean).output().unwrap();
    assert!(result.status.success(), "{}", stderr(&result));
    let temporaries = |out: &Path| -> Vec<String> {
        std::fs::read_dir(out)
            .map(|d| {
                d.flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .filter(|n| n.ends_with(".tmp"))
                    .collect()
            })
            .unwrap_or_default()
    };
    // Shard 1's input man01, being written by a shard still running: left alone.
    let others = ".quatcurve-man01.json.abcdef.tmp";
    for fraction in [0.2, 0.8] {
        let sidecars = |out: &Path| {
            std::fs::read_dir(out)
                .map(|d| d.flatten().filter(|e| e.file_name().to_string_lossy().ends_with(".json")).count())
                .unwrap_or(0)
        };
        // Killed once this shard (20 inputs) has written the fraction and a file is half
        // written; again (resuming) if the file was renamed whole between the look and the kill.
        let mut left = Vec::new();
        for _ in 0..20 {
            let mut child =
                args(&killed).stdout(std::process::Stdio::null()).stderr(std::process::Stdio::null()).spawn().unwrap();
            while child.try_wait().unwrap().is_none() {
                if sidecars(&killed) as f64 >= fraction * (count / 2) as f64 && !temporaries(&killed).is_empty() {
                    child.kill().unwrap();
                    break;
                }
            }
            child.wait().unwrap();
            left = temporaries(&killed);
            if !left.is_empty() {
                break;
            }
        }
        eprintln!("killed at {fraction}: {left:?} left");
        assert!(!left.is_empty(), "no run at {fraction} was killed while writing");
        std::fs::write(killed.join(others), b"another shard's").unwrap();
        let result = args(&killed).output().unwrap();
        assert!(result.status.success(), "{}", stderr(&result));
        let summary = String::from_utf8_lossy(&result.stdout);
        assert!(summary.contains("temporary files a killed run of this shard left"), "{summary}");
        assert_eq!(temporaries(&killed), [others], "after --resume");
        std::fs::remove_file(killed.join(others)).unwrap();
        assert_eq!(outputs(&killed), outputs(&clean), "killed at {fraction}, the resumed outputs differ");
        std::fs::remove_dir_all(&killed).unwrap();
    }
}
