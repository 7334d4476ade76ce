//! What every job over files (the bake, the fit) shares: inputs found and given their output
//! stems, the output directory proven writable before the work, the rule that an output never
//! replaces its input, and the job's own errors ([`FileJobError`]); one input's failure is the
//! job's to report (the bake's `BakeError`, the fit's `FitInputError`), and the job goes on
//! with the others.

use quatcurve_anim::error::{InputError, OutputError};
use quatcurve_eval::io::{AtomicFile, IoError};
use quatcurve_formats::source::extension;
use std::path::{Path, PathBuf};

pub mod shard;

/// Why a job over files could not start, or could not keep its manifest.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FileJobError {
    /// An option outside its rules; `option` is its library name (`rate`, `max_texture_size`,
    /// `inputs`, ...), which is also its Python keyword; the command line shows its flag.
    #[error("{option} {reason}")]
    Option {
        /// The option's name.
        option: &'static str,
        /// What is wrong with it, said after the name.
        reason: String,
    },
    /// Two inputs that would write the same outputs.
    #[error("{} and {} would both write {stem}.*; bake them into separate output directories", first.display(), second.display())]
    SameStem {
        /// The first input.
        first: PathBuf,
        /// The second.
        second: PathBuf,
        /// The stem both would write.
        stem: String,
    },
    /// An output refused before the work (one that would overwrite its input), so nothing ran.
    #[error("{error} (nothing was {job})")]
    Refused {
        /// Why.
        error: Box<InputError>,
        /// What the job does, past tense (`baked`).
        job: &'static str,
    },
    /// A scheduler's environment that names no share of the job.
    #[error(transparent)]
    Shard(#[from] shard::ShardError),
    /// The manifest could not be written.
    #[error(transparent)]
    Manifest(#[from] IoError),
}

impl FileJobError {
    /// An option outside its rules ([`Self::Option`]).
    pub fn option(option: &'static str, reason: impl Into<String>) -> Self {
        Self::Option { option, reason: reason.into() }
    }
}

/// Files given, with directories replaced by their files of the `known` extensions (lower
/// case), sorted by path. A directory without one is an error: baking the built-in crowd
/// instead would be a surprise.
pub fn expand(inputs: &[PathBuf], known: &[&str]) -> Result<Vec<PathBuf>, FileJobError> {
    let listed = known.iter().map(|e| format!(".{e}")).collect::<Vec<_>>().join(", ");
    let known = |p: &Path| extension(p).is_some_and(|e| known.contains(&e.as_str()));
    let mut files = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let entries = std::fs::read_dir(input)
                .map_err(|e| FileJobError::option("inputs", format!("{}: cannot list: {e}", input.display())))?;
            let found: Vec<PathBuf> =
                entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file() && known(p)).collect();
            if found.is_empty() {
                return Err(FileJobError::option(
                    "inputs",
                    format!("{}: the directory holds no file of {listed}", input.display()),
                ));
            }
            files.extend(found);
        } else {
            files.push(input.clone());
        }
    }
    // One order for every shard (DESIGN section 13): by path, bytewise.
    files.sort_by(|a, b| a.as_os_str().as_encoded_bytes().cmp(b.as_os_str().as_encoded_bytes()));
    Ok(files)
}

/// The length of one file unit in cm for every input: `given`, or glTF's metre (every format
/// that says its unit is read into metres). An input whose format does not say its unit (BVH,
/// a fitted container) needs it given: an error naming it.
///
/// # Errors
/// [`FileJobError::Option`] (`unit_cm`) naming the first such input, and what was not done
/// (`nothing was fitted`).
pub fn unit_cm(inputs: &[PathBuf], given: Option<f64>, not_done: &str) -> Result<f64, FileJobError> {
    if let Some(unit) = given {
        return Ok(unit);
    }
    let unsaid = inputs.iter().find(|p| quatcurve_formats::source::importer(p).is_some_and(|i| !i.says_unit));
    match unsaid {
        Some(input) => Err(FileJobError::option(
            "unit_cm",
            format!(
                "is needed for {}: a {} file does not say its unit (CMU's BVH is 5.644 cm); {not_done}",
                input.display(),
                extension(input).unwrap_or_default().to_uppercase()
            ),
        )),
        None => Ok(quatcurve_anim::GLTF_UNIT_CM),
    }
}

/// Each input's output stem (its file name without extension). Two inputs with one stem
/// (`walk/idle.glb`, `run/idle.bvh`) would write the same outputs, the second silently
/// replacing the first: refused before anything is baked.
pub fn output_stems(inputs: &[PathBuf]) -> Result<Vec<String>, FileJobError> {
    let stems: Vec<String> = inputs
        .iter()
        .map(|p| p.file_stem().map_or_else(|| "out".into(), |s| s.to_string_lossy().into_owned()))
        .collect();
    let mut seen: std::collections::HashMap<&str, &Path> = std::collections::HashMap::new();
    for (stem, path) in stems.iter().zip(inputs) {
        if let Some(first) = seen.insert(stem, path) {
            return Err(FileJobError::SameStem {
                first: first.to_path_buf(),
                second: path.to_path_buf(),
                stem: stem.to_string(),
            });
        }
    }
    Ok(stems)
}

/// The output directory, created for the job; if this job created it (and any missing
/// parents) and wrote nothing into it, [`Self::remove_if_unused`] takes them away again, so a
/// failed job leaves nothing behind.
pub struct OutputDir {
    /// Directories this job created, deepest first.
    created: Vec<PathBuf>,
}

impl OutputDir {
    /// Creates `dir` and proves it takes a new file (as every output is first written), so an
    /// output directory that cannot be written is refused before any input is read; `done`
    /// says what the job would have done to them (`baked`).
    pub fn create(dir: &Path, done: &str) -> Result<Self, FileJobError> {
        let created: Vec<PathBuf> =
            dir.ancestors().take_while(|a| !a.as_os_str().is_empty() && !a.exists()).map(Path::to_path_buf).collect();
        let refuse = |what: &str, e: std::io::Error| {
            FileJobError::option("output", format!("{}: {what}: {e} (nothing was {done})", dir.display()))
        };
        std::fs::create_dir_all(dir).map_err(|e| refuse("cannot create the directory", e))?;
        let this = Self { created };
        if let Err(e) = AtomicFile::create(&dir.join("probe")) {
            this.remove_if_unused();
            let e = match e {
                IoError::Write { source, .. } => source,
                other => std::io::Error::other(other.to_string()),
            };
            return Err(refuse("cannot write into the directory", e));
        }
        Ok(this)
    }

    /// Takes away the directories this job created, if it wrote nothing into them.
    pub fn remove_if_unused(&self) {
        // remove_dir only removes empty directories.
        for dir in &self.created {
            if std::fs::remove_dir(dir).is_err() {
                break;
            }
        }
    }
}

/// An output written into its input's own directory must not replace the input.
///
/// # Errors
/// [`InputError::Output`] when `output` is `source`.
pub fn refuse_overwriting_input(output: &Path, source: &str) -> Result<(), InputError> {
    let same = match (std::fs::canonicalize(output), std::fs::canonicalize(source)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same {
        return Err(OutputError::OverwritesInput(output.to_path_buf()).into());
    }
    Ok(())
}
