//! What a bake reports: to its caller as it runs ([`Progress`]), per input when it is done
//! ([`InputReport`], [`BakeReport`]), and to the manifest ([`input_record`]).
use super::budget::ChosenRate;
use super::manifest::{FileRecord, InputRecord};
use super::texture_file::Written;
use super::Baked;
use crate::error::BakeError;
use quatcurve_anim::Animation;
use quatcurve_files::shard::Shard;
use std::path::{Path, PathBuf};

/// What a running job tells its caller (a progress bar, a log); every method has a default
/// that does nothing, and `()` is the silent observer. Called from the job's worker threads.
pub trait Progress: Sync {
    /// The job starts `inputs` inputs (this shard's).
    fn start(&self, inputs: usize) {
        let _ = inputs;
    }
    /// An input is being read (or verified, when resuming).
    fn begin(&self, source: &str) {
        let _ = source;
    }
    /// An input is done, baked, resumed or failed.
    fn finish(&self, input: &InputReport) {
        let _ = input;
    }
    /// An error budget measures clip `clip` of input `source` baked at `rate` Hz: the search
    /// tries several rates a clip, which on a long clip take seconds.
    fn measuring(&self, source: &str, clip: &str, rate: f64) {
        let _ = (source, clip, rate);
    }
}

impl Progress for () {}

/// What a job did: its device and shard, and one report per input of this shard, in job order.
#[derive(Debug)]
pub struct BakeReport {
    /// The device's name (with its adapter or instruction set).
    pub device: String,
    /// The share of the job that ran.
    pub shard: Shard,
    /// Inputs in the whole job (every shard's).
    pub job_inputs: usize,
    /// This shard's inputs.
    pub inputs: Vec<InputReport>,
    /// Temporary files a killed run of this shard left in the output directory, removed.
    pub stale_removed: usize,
}

impl BakeReport {
    /// The inputs that failed.
    pub fn failed(&self) -> impl Iterator<Item = &InputReport> {
        self.inputs.iter().filter(|r| r.outcome.is_err())
    }
}

/// What one input became.
#[derive(Debug)]
pub struct InputReport {
    /// The input's path as given or found, or the built-in crowd's description.
    pub source: String,
    /// Clips, keyed channels and keys read.
    pub clips: usize,
    /// Keyed channels over every clip.
    pub channels: usize,
    /// Keys over every channel.
    pub keys: usize,
    /// Samples baked (frames times channels).
    pub samples: usize,
    /// Wall time of reading, baking and writing.
    pub seconds: f64,
    /// The largest angle between a rotation key and the baked curve at its time, where the
    /// curve is meant to pass through keys.
    pub max_key_error: Option<f64>,
    /// The files written (or kept, when resumed), or why the input failed: `Input` for the
    /// file's own faults, `Device` for the machine's.
    pub outcome: Result<Vec<PathBuf>, BakeError>,
    /// Skipped by `resume`: the earlier run's outputs were verified and kept.
    pub resumed: bool,
    /// What the bake did that a user should know but that did not fail it: source keys that
    /// are probably broken ([`super::source_step_warnings`]), clip ends an exact rate did not
    /// bake. Each names the clip and channel.
    pub warnings: Vec<String>,
    /// Vertex textures: vertex-frames skinned and the seconds skinning took on the bake's
    /// device (without forward kinematics or writing).
    pub skinning: Option<(u64, f64)>,
    /// With an error budget ([`super::BakeOptions::max_error_deg`]): per clip, the rate chosen and what
    /// it measured.
    pub rates: Vec<ChosenRate>,
    /// The box of the joints at rest (model space, the file's units: glTF's and FBX's metres),
    /// `x, y, z`: a rig read at the wrong scale shows at a glance. `None` for a source without
    /// joint offsets (SMPL poses).
    pub rig: Option<[f64; 3]>,
    /// Meshes the textures do not draw (rigid parts, `node 'N', mesh 'M'`, under a texture of
    /// skinned meshes), also in the warnings and the sidecar.
    pub not_drawn: Vec<String>,
}

impl InputReport {
    /// A report with nothing done yet.
    pub(super) fn new(source: &str) -> Self {
        Self {
            source: source.to_string(),
            clips: 0,
            channels: 0,
            keys: 0,
            samples: 0,
            seconds: 0.0,
            max_key_error: None,
            outcome: Ok(Vec::new()),
            resumed: false,
            warnings: Vec::new(),
            skinning: None,
            rates: Vec::new(),
            rig: None,
            not_drawn: Vec::new(),
        }
    }
}

/// A warning per clip whose end an exact rate left unbaked ([`super::BakedClip::unbaked_end`]).
pub(super) fn unbaked_ends(animation: &Animation, baked: &Baked) -> Vec<String> {
    let number = quatcurve_eval::error::Number;
    animation
        .clips
        .iter()
        .zip(&baked.clips)
        .filter(|(_, b)| b.unbaked_end() * b.rate > super::UNBAKED_FRAMES)
        .map(|(clip, b)| {
            let last = b.times[b.times.len() - 1];
            let looping = if b.looping {
                "; a loop, its frames on its looping curve, but its last frame is not its seam, so players hold \
                 its end (the sidecar's loop is false)"
            } else {
                ""
            };
            format!(
                "clip '{}': at exactly {} Hz the last frame is at {} s, so the last {} s before its last key at {} \
                    s are not baked (fit the rate to keep them){looping}",
                clip.name,
                number(b.rate),
                number(last),
                number(b.unbaked_end()),
                number(b.end)
            )
        })
        .collect()
}

/// An input `resume` skips: the earlier run's record, its outputs verified intact.
pub(super) fn resumed(name: &str, record: &InputRecord, dir: &Path) -> InputReport {
    let files = record.outputs.iter().map(|o| dir.join(&o.file)).collect();
    let warnings = record.warnings.clone();
    InputReport { outcome: Ok(files), resumed: true, warnings, ..InputReport::new(name) }
}

/// The manifest entry of a finished input.
pub(super) fn input_record(
    report: &InputReport,
    written: &[Written],
    (size, sha256): (u64, String),
    kept: Option<&InputRecord>,
) -> InputRecord {
    let (status, error, outputs) = match (&report.outcome, kept) {
        (Ok(_), Some(kept)) => ("resumed", None, kept.outputs.clone()),
        (Ok(_), None) => {
            let record = |w: &Written| {
                let file = w.path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
                match &w.hash {
                    Some((size, sha256)) => Ok(FileRecord { file, size: *size, sha256: sha256.clone() }),
                    None => FileRecord::of(&w.path, file),
                }
            };
            match written.iter().map(record).collect::<std::io::Result<Vec<_>>>() {
                Ok(outputs) => ("ok", None, outputs),
                Err(e) => ("failed", Some(format!("cannot hash an output: {e}")), Vec::new()),
            }
        }
        (Err(e), _) => ("failed", Some(e.to_string()), Vec::new()),
    };
    InputRecord {
        path: report.source.clone(),
        size,
        sha256,
        status: status.into(),
        error,
        warnings: report.warnings.clone(),
        seconds: report.seconds,
        outputs,
    }
}
