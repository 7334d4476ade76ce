//! Where a bake writes: the output directory (proven writable before the work, removed again
//! if the job left it empty), one input's files so far (taken away if it fails), and the rule
//! that a baked file never replaces its input.
use super::budget::ChosenRate;
use super::error::BakeError;
use super::texture_file::{TextureFile, Written};
use quatcurve_anim::error::InputError;
use quatcurve_eval::io::AtomicFile;
use std::path::{Path, PathBuf};

/// The output directory, created for the job; if this job created it (and any missing
/// parents) and wrote nothing into it, [`Self::remove_if_unused`] takes them away again, so a
/// failed job leaves nothing behind.
pub(crate) struct OutputDir {
    /// Directories this job created, deepest first.
    created: Vec<PathBuf>,
}

impl OutputDir {
    /// Creates `dir` and proves it takes a new file (as every output is first written), so an
    /// output directory that cannot be written is refused before any input is read; `done`
    /// says what the job would have done to them (`baked`).
    pub(crate) fn create(dir: &Path, done: &str) -> Result<Self, BakeError> {
        let created: Vec<PathBuf> =
            dir.ancestors().take_while(|a| !a.as_os_str().is_empty() && !a.exists()).map(Path::to_path_buf).collect();
        let refuse = |what: &str, e: std::io::Error| {
            BakeError::option("output", format!("{}: {what}: {e} (nothing was {done})", dir.display()))
        };
        std::fs::create_dir_all(dir).map_err(|e| refuse("cannot create the directory", e))?;
        let this = Self { created };
        if let Err(e) = AtomicFile::create(&dir.join("probe")) {
            this.remove_if_unused();
            let e = match e {
                quatcurve_eval::io::IoError::Write { source, .. } => source,
                other => std::io::Error::other(other.to_string()),
            };
            return Err(refuse("cannot write into the directory", e));
        }
        Ok(this)
    }

    pub(crate) fn remove_if_unused(&self) {
        // remove_dir only removes empty directories.
        for dir in &self.created {
            if std::fs::remove_dir(dir).is_err() {
                break;
            }
        }
    }
}

/// Where one input's outputs go and what is written so far (taken away again if the input
/// fails), with the atlas being gathered and its row count.
pub(super) struct Outputs<'a> {
    pub(super) dir: &'a Path,
    pub(super) stem: &'a str,
    pub(super) source: &'a str,
    /// With an error budget: each clip's chosen rate and its errors, for the sidecar.
    pub(super) rates: &'a [ChosenRate],
    pub(super) written: Vec<Written>,
    /// `--atlas`: the open files every clip appends to, and their rows so far.
    pub(super) atlas: Vec<TextureFile>,
    pub(super) rows: usize,
    /// Each clip's name in its files' names ([`clip_file_names`]).
    pub(super) clip_names: Vec<String>,
}

/// Baking into the input's own directory must not replace the input.
pub(crate) fn refuse_overwriting_input(output: &Path, source: &str) -> Result<(), InputError> {
    let same = match (std::fs::canonicalize(output), std::fs::canonicalize(source)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same {
        return Err(InputError::Output(format!(
            "{} would overwrite the input; choose another output directory",
            output.display()
        )));
    }
    Ok(())
}

/// Each clip's name as it appears in its files' names (`Fox.Walk.npy`): letters, digits, `-`
/// and `_` kept, any other character `_`; an empty name is `clip<index>`, and a name that
/// two clips would share (ignoring case, as some file systems do) gets `-<index>`.
pub(super) fn clip_file_names(animation: &quatcurve_anim::Animation) -> Vec<String> {
    let safe: Vec<String> = animation
        .clips
        .iter()
        .enumerate()
        .map(|(index, clip)| {
            let name: String = clip
                .name
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' })
                .collect();
            if name.is_empty() {
                format!("clip{index}")
            } else {
                name
            }
        })
        .collect();
    let lower: Vec<String> = safe.iter().map(|n| n.to_ascii_lowercase()).collect();
    safe.iter()
        .enumerate()
        .map(|(index, name)| {
            if lower.iter().filter(|n| **n == lower[index]).count() > 1 {
                format!("{name}-{index}")
            } else {
                name.clone()
            }
        })
        .collect()
}
