//! The bake through its own API ([`BakeJob`]): what a job writes, and how one input's failure
//! is reported while the others are baked. The command line's own tests keep to its flags,
//! exit codes and file names.

use quatcurve_anim::error::{InputError, OutputError};
use quatcurve_bake::error::{BakeError, Refusal};
use quatcurve_bake::sidecar::Sidecar;
use quatcurve_bake::{BakeJob, BakeOptions};
use quatcurve_device::{Device, DeviceChoice};
use quatcurve_files::FileJobError;
use std::path::PathBuf;

fn cpu() -> Device {
    Device::open(DeviceChoice::Cpu).unwrap()
}

/// A job without inputs bakes a crowd of `characters`.
fn crowd_job(dir: &std::path::Path, characters: usize) -> BakeJob {
    let mut job = BakeJob::new(Vec::new(), dir);
    job.options = BakeOptions { characters, ..BakeOptions::DEFAULT };
    job
}

#[test]
fn a_job_without_inputs_bakes_the_built_in_crowd_into_a_texture_and_a_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    let report = crowd_job(dir.path(), 2).run(&cpu(), &()).unwrap();
    assert_eq!(report.inputs.len(), 1);
    let written = report.inputs[0].outcome.as_ref().unwrap();
    let names: Vec<String> = written.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert!(names.iter().any(|n| n.ends_with(".npy")), "{names:?}");
    assert!(names.iter().any(|n| n == "crowd.json"), "{names:?}");
    for path in written {
        assert!(path.is_file(), "{} was reported written", path.display());
    }
}

#[test]
fn the_sidecar_reads_back_with_the_rate_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let mut job = crowd_job(dir.path(), 1);
    job.options.rate = 24.0;
    job.run(&cpu(), &()).unwrap();
    let sidecar: Sidecar =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("crowd.json")).unwrap()).unwrap();
    assert_eq!(sidecar.requested_rate, 24.0);
}

#[test]
fn an_input_no_importer_takes_fails_alone_naming_every_format_read() {
    let dir = tempfile::tempdir().unwrap();
    let notes = dir.path().join("notes.txt");
    std::fs::write(&notes, "hello").unwrap();
    let job = BakeJob::new(vec![notes], dir.path().join("out"));
    let report = job.run(&cpu(), &()).unwrap();
    let failed: Vec<_> = report.failed().collect();
    assert_eq!(failed.len(), 1);
    match &failed[0].outcome {
        Err(BakeError::Input(InputError::UnknownFormat { expected })) => {
            assert_eq!(
                expected,
                ".gltf, .glb, .fbx, .usd, .usda, .usdc, .usdz, .bvh, .npz (SMPL-family poses) or .qcf (a fitted \
                 container)"
            );
        }
        other => panic!("expected an unknown format, got {other:?}"),
    }
    assert!(!failed[0].outcome.as_ref().unwrap_err().is_internal_failure());
}

#[test]
fn a_rate_that_is_not_positive_is_refused_before_any_input_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let mut job = BakeJob::new(vec![PathBuf::from("missing.glb")], dir.path().join("out"));
    job.options.rate = 0.0;
    let error = job.validate().unwrap_err();
    assert!(matches!(error, FileJobError::Option { option: "rate", .. }), "{error}");
    assert!(!dir.path().join("out").exists());
}

#[test]
fn a_pose_archive_baked_into_its_own_directory_is_refused_before_anything_is_read() {
    let dir = tempfile::tempdir().unwrap();
    // Never read: the name alone is refused.
    let input = dir.path().join("walk.npz");
    std::fs::write(&input, "not an archive").unwrap();
    let error = BakeJob::new(vec![input], dir.path()).run(&cpu(), &()).unwrap_err();
    match &error {
        FileJobError::Refused { error, job: "baked" } => {
            assert!(matches!(**error, InputError::Output(OutputError::OverwritesInput(_))), "{error:?}");
        }
        other => panic!("expected the job refused, got {other:?}"),
    }
    assert!(!dir.path().join("walk.json").exists());
}

#[test]
fn a_budget_no_rate_up_to_the_cap_meets_is_refused_naming_the_clip_the_rate_and_the_worst_joint() {
    let dir = tempfile::tempdir().unwrap();
    let mut job = crowd_job(dir.path(), 1);
    (job.options.max_error_deg, job.options.max_rate) = (Some(0.01), 10.0);
    let report = job.run(&cpu(), &()).unwrap();
    match &report.inputs[0].outcome {
        Err(BakeError::Refused(refusal)) => match &**refusal {
            Refusal::NoRateHolds { clip, max_rate, rotation, within, .. } => {
                assert!(!clip.is_empty() && !rotation.joint.is_empty(), "{refusal}");
                assert_eq!((*max_rate, within.as_str()), (10.0, "0.01 degrees"));
                assert!(rotation.value > 0.01, "{refusal}");
            }
            other => panic!("expected no rate to hold, got {other}"),
        },
        other => panic!("expected the budget refused, got {other:?}"),
    }
    let written: Vec<_> = std::fs::read_dir(dir.path()).unwrap().flatten().map(|e| e.file_name()).collect();
    assert!(written.iter().all(|f| !f.to_string_lossy().starts_with("crowd")), "wrote {written:?}");
}

#[test]
fn a_budget_tells_progress_of_every_rate_its_search_measures() {
    struct Rates(std::sync::Mutex<Vec<(String, f64)>>);
    impl quatcurve_bake::Progress for Rates {
        fn measuring(&self, source: &str, clip: &str, rate: f64) {
            assert!(source.starts_with("built-in crowd"), "{source}");
            self.0.lock().unwrap().push((clip.to_string(), rate));
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let mut job = crowd_job(dir.path(), 1);
    job.options.max_error_deg = Some(1.0);
    let rates = Rates(std::sync::Mutex::new(Vec::new()));
    let report = job.run(&cpu(), &rates).unwrap();
    let chosen = report.inputs[0].rates[0].measured.rate;
    let told = rates.0.into_inner().unwrap();
    assert!(told.len() >= 2, "a search measures more than one rate: {told:?}");
    assert!(told.iter().any(|(_, rate)| (rate - chosen).abs() < 1e-9), "the chosen {chosen} Hz among {told:?}");
}
