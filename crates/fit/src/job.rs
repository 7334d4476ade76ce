//! A fit job: glTF/BVH inputs to one container each (`<stem>.qcf`), or every input's clips to
//! one container on their one skeleton (a clip library, `<library>.qcf`), with a report per
//! clip. Everything that can be found wrong before fitting is (a BVH without its unit, an
//! output directory that takes no file, two inputs with one stem, an output that would replace
//! its input, a library's inputs on other skeletons); a failed input is reported and the others
//! still finish (a library is then not written).

use super::clip::{fit_clip, Budget, ClipFit, FitClipError, Worst};
use quatcurve_anim::error::{InputError, OutputError};
use quatcurve_anim::Animation;
use quatcurve_eval::error::Number;
use quatcurve_eval::io::IoError;
use quatcurve_files::FileJobError;
use quatcurve_files::{expand, output_stems};
use quatcurve_files::{refuse_overwriting_input, OutputDir};
use quatcurve_formats::source::extension;
use quatcurve_formats::source::{ReadOptions, Source};
use quatcurve_formats::{fbx, usd};
use quatcurve_qcf::fitted::FittedClip;
use quatcurve_qcf::{BvhSkeleton, Container, EXTENSION};
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The extensions a fit reads (sources with keys; a container holds control points).
pub const FIT_EXTENSIONS: [&str; 8] = [
    "gltf",
    "glb",
    fbx::EXTENSION,
    usd::EXTENSIONS[0],
    usd::EXTENSIONS[1],
    usd::EXTENSIONS[2],
    usd::EXTENSIONS[3],
    "bvh",
];

/// What to fit, where to, and within what ([`FitOptions`]).
#[derive(Clone, Debug)]
pub struct FitJob {
    /// Files or directories of them ([`FIT_EXTENSIONS`]).
    pub inputs: Vec<PathBuf>,
    /// Where `<stem>.qcf` goes.
    pub output: PathBuf,
    /// The error budget and the file unit, lengths in centimetres.
    pub options: FitOptions,
}

/// The options of a fit, each defined once (as [`quatcurve_eval::options`] says), lengths in
/// centimetres.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(default)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct FitOptions {
    /// The largest distance, in cm, a virtual vertex may move at any source frame (ACL's
    /// metric: object space, so a parent's error counts in its children's).
    #[cfg_attr(feature = "cli", arg(long, value_name = "CM", default_value_t = FitOptions::DEFAULT.max_error_cm, allow_negative_numbers = true))]
    pub max_error_cm: f64,
    /// The largest between source frames, in cm, against the source's own interpolation;
    /// none: not checked (the curve may swing between frames; reported all the same).
    #[cfg_attr(feature = "cli", arg(long, value_name = "CM", default_value = default_between_error(), allow_negative_numbers = true))]
    pub between_error_cm: Option<f64>,
    /// The virtual vertices' distance from each joint, cm.
    #[cfg_attr(feature = "cli", arg(long, value_name = "CM", default_value_t = FitOptions::DEFAULT.vertex_distance_cm, allow_negative_numbers = true))]
    pub vertex_distance_cm: f64,
    /// The length of one file unit in cm (default: glTF's metre, 100). BVH files and fitted
    /// containers do not say theirs, so such an input needs it (CMU's BVH is 5.644).
    #[cfg_attr(feature = "cli", arg(long, value_name = "CM", allow_negative_numbers = true))]
    pub unit_cm: Option<f64>,
    /// One container, `<output>/<NAME>.qcf`, holding every input's clips on their one
    /// skeleton, stored once (a clip library; a clip name two inputs share is prefixed with
    /// its input's stem and a slash); none: one container per input.
    #[cfg_attr(feature = "cli", arg(long, value_name = "NAME"))]
    pub clip_library: Option<String>,
}

impl FitOptions {
    /// Every option's default: ACL's threshold and vertex distance.
    pub const DEFAULT: Self = Self {
        max_error_cm: 0.01,
        between_error_cm: Some(DEFAULT_BETWEEN_ERROR_CM),
        vertex_distance_cm: DEFAULT_VERTEX_DISTANCE_CM,
        unit_cm: None,
        clip_library: None,
    };
}

impl Default for FitOptions {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// [`DEFAULT_BETWEEN_ERROR_CM`] as the flag's default text (clap shows an optional value's
/// default as text).
#[cfg(feature = "cli")]
fn default_between_error() -> &'static str {
    static TEXT: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TEXT.get_or_init(|| DEFAULT_BETWEEN_ERROR_CM.to_string())
}

/// Between-frame error a fit defaults to, cm: the curve within 0.3 cm of the source's own
/// interpolation.
pub const DEFAULT_BETWEEN_ERROR_CM: f64 = 0.3;

/// Virtual-vertex distance a fit defaults to, cm (ACL's).
pub const DEFAULT_VERTEX_DISTANCE_CM: f64 = 3.0;

/// The worst error of a clip, where and when, in cm.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct WorstReport {
    /// The distance, cm.
    pub error_cm: f64,
    /// The joint's name.
    pub joint: String,
    /// Seconds from the clip's start.
    pub time: f64,
}

/// One clip's fit.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ClipReport {
    /// The clip's name.
    pub clip: String,
    /// Source frames (distinct key times).
    pub frames: usize,
    /// Joints of the skeleton.
    pub joints: usize,
    /// Bytes of the raw clip as ACL counts them (40 per joint per frame).
    pub raw_bytes: usize,
    /// The clip's bytes in the container.
    pub compressed_bytes: usize,
    /// `raw_bytes / compressed_bytes`.
    pub ratio: f64,
    /// The worst error at the source frames.
    pub at_frames: WorstReport,
    /// The worst error between source frames, against the source's interpolation.
    pub between_frames: WorstReport,
    /// Seconds the fit took.
    pub seconds: f64,
}

/// One input's fit: its container and clips, or why it failed.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct InputFit {
    /// The input file.
    pub input: String,
    /// The container written, when every clip fitted.
    pub output: Option<String>,
    /// The file's unit, cm.
    pub unit_cm: f64,
    /// Its bytes (0 in a library: [`FitReport::clip_library`]).
    pub container_bytes: usize,
    /// Its clips' raw bytes over the container's (skeleton and BVH hierarchy included; 0 in
    /// a library).
    pub whole_file_ratio: f64,
    /// Per clip.
    pub clips: Vec<ClipReport>,
    /// Why the input failed, when it did.
    pub error: Option<String>,
}

/// A job's report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FitReport {
    /// The budget, cm.
    pub max_error_cm: f64,
    /// See [`FitOptions::between_error_cm`].
    pub between_error_cm: Option<f64>,
    /// See [`FitOptions::vertex_distance_cm`].
    pub vertex_distance_cm: f64,
    /// Per input, in path order.
    pub inputs: Vec<InputFit>,
    /// The clip library, when one was asked for.
    pub clip_library: Option<LibraryFit>,
}

/// A clip library's container.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct LibraryFit {
    /// The container written, when every input fitted.
    pub output: Option<String>,
    /// Its clips.
    pub clips: usize,
    /// Their raw bytes as ACL counts them.
    pub raw_bytes: usize,
    /// Their bytes in the container.
    pub clip_bytes: usize,
    /// The container's bytes: the clips, the skeleton once and the checksum.
    pub container_bytes: usize,
    /// `raw_bytes / clip_bytes`.
    pub ratio: f64,
    /// `raw_bytes / container_bytes`.
    pub whole_file_ratio: f64,
}

impl FitReport {
    /// How many inputs failed.
    #[must_use]
    pub fn failed(&self) -> usize {
        self.inputs.iter().filter(|i| i.error.is_some()).count()
    }
}

/// Why one input could not be fitted (its report keeps the words, [`InputFit::error`]); the
/// other inputs are fitted all the same.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FitInputError {
    /// The file could not be read into the model.
    #[error(transparent)]
    Input(#[from] InputError),
    /// The file has no clip to fit.
    #[error("no rotation, translation or scale animation to fit")]
    Empty,
    /// A clip that cannot be fitted at all.
    #[error("clip '{clip}': {error}")]
    Clip {
        /// The clip.
        clip: String,
        /// Why.
        error: FitClipError,
    },
    /// A clip no fit held within the budget: how close the closest came, and what loosens it.
    #[error("{}", over_budget(clip, *max_error_cm, *between_error_cm, at, between))]
    OverBudget {
        /// The clip.
        clip: String,
        /// The budget at frames, cm.
        max_error_cm: f64,
        /// The budget between frames, cm; none: unchecked.
        between_error_cm: Option<f64>,
        /// The closest fit's worst error at frames.
        at: Box<WorstReport>,
        /// Its worst between frames.
        between: Box<WorstReport>,
    },
    /// The container could not be written.
    #[error(transparent)]
    Write(#[from] IoError),
}

/// [`FitInputError::OverBudget`] in words.
fn over_budget(
    clip: &str,
    max_error: f64,
    between_error: Option<f64>,
    at: &WorstReport,
    between: &WorstReport,
) -> String {
    let between_budget = between_error.map_or_else(
        || "unchecked between them".into(),
        |cm| format!("{} cm between them (the between-frames error)", Number(cm)),
    );
    let loosen = "; a larger between-frames error, or none, loosens the check between frames";
    let hint = match between_error {
        Some(cm) if between.error_cm > cm => loosen,
        _ => "",
    };
    format!(
        "clip '{clip}': no fit within {} cm (the maximum error) at every frame and {between_budget}; the closest came to {} cm at frames ({} at {:.3} s) and {} cm between them ({} at {:.3} s){hint}",
        Number(max_error),
        Number(at.error_cm),
        at.joint,
        at.time,
        Number(between.error_cm),
        between.joint,
        between.time
    )
}

impl FitJob {
    /// Fits every input, the inputs side by side and each clip on every core (a clip's fit
    /// leaves cores idle between its passes, which the next input takes), writing each container
    /// atomically; the report lists the inputs in the order given, `progress` hears each clip as
    /// it finishes.
    ///
    /// # Errors
    /// What is wrong before any input is read: a length that is not positive, a BVH input
    /// without [`FitOptions::unit_cm`], an input of another format, an output directory that
    /// takes no file, two inputs with one stem, a container that would replace its input.
    pub fn run(&self, progress: &(dyn Fn(&str, &ClipReport) + Sync)) -> Result<FitReport, FileJobError> {
        for (option, value) in [
            ("max_error_cm", Some(self.options.max_error_cm)),
            ("between_error_cm", self.options.between_error_cm),
            ("vertex_distance_cm", Some(self.options.vertex_distance_cm)),
            ("unit_cm", self.options.unit_cm),
        ] {
            if let Some(v) = value.filter(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(FileJobError::option(option, format!("is {v}; it must be a positive length")));
            }
        }
        if self.inputs.is_empty() {
            return Err(FileJobError::option("inputs", "names no file: give the glTF, FBX, USD or BVH files to fit"));
        }
        let inputs = expand(&self.inputs, &FIT_EXTENSIONS)?;
        for input in &inputs {
            match extension(input).as_deref() {
                Some(e) if FIT_EXTENSIONS.contains(&e) => {}
                _ => {
                    return Err(FileJobError::option(
                        "input",
                        format!(
                            "{}: not a file to fit: expected {}",
                            input.display(),
                            quatcurve_eval::error::one_of(FIT_EXTENSIONS.iter().map(|e| format!(".{e}")))
                        ),
                    ))
                }
            }
        }
        let unit_cm = quatcurve_files::unit_cm(&inputs, self.options.unit_cm, "nothing was fitted")?;
        let stems = output_stems(&inputs)?;
        if let Some(name) = &self.options.clip_library {
            if name.is_empty() || name.contains(['/', '\\']) || name.starts_with('.') {
                let reason = format!("'{name}' is not a file name: the library is <output>/<NAME>.{EXTENSION}");
                return Err(FileJobError::option("clip_library", reason));
            }
        }
        let outputs: Vec<&str> = match &self.options.clip_library {
            Some(name) => vec![name],
            None => stems.iter().map(String::as_str).collect(),
        };
        let output = OutputDir::create(&self.output, "fitted")?;
        for (input, stem) in inputs.iter().flat_map(|input| outputs.iter().map(move |stem| (input, stem))) {
            let path = self.output.join(format!("{stem}.{EXTENSION}"));
            let refused = refuse_overwriting_input(&path, &input.display().to_string())
                .err()
                .or_else(|| path.is_dir().then(|| OutputError::IsDirectory(path.clone()).into()));
            if let Some(e) = refused {
                output.remove_if_unused();
                return Err(FileJobError::Refused { error: Box::new(e), job: "fitted" });
            }
        }
        let (inputs, clip_library) = match &self.options.clip_library {
            None => {
                let fits =
                    inputs.par_iter().zip(&stems).map(|(input, stem)| self.fit_one(input, stem, unit_cm, progress));
                (fits.collect(), None)
            }
            Some(name) => {
                let (inputs, library) =
                    self.fit_library(&inputs, &stems, name, unit_cm, progress).inspect_err(|_| {
                        output.remove_if_unused();
                    })?;
                (inputs, Some(library))
            }
        };
        Ok(FitReport {
            max_error_cm: self.options.max_error_cm,
            between_error_cm: self.options.between_error_cm,
            vertex_distance_cm: self.options.vertex_distance_cm,
            inputs,
            clip_library,
        })
    }

    /// Every input read, held to the first's skeleton, fitted side by side, then written as
    /// one container when every one fitted.
    fn fit_library(
        &self,
        inputs: &[PathBuf],
        stems: &[String],
        name: &str,
        unit_cm: f64,
        progress: &(dyn Fn(&str, &ClipReport) + Sync),
    ) -> Result<(Vec<InputFit>, LibraryFit), FileJobError> {
        let refused = |error: InputError| FileJobError::Refused { error: Box::new(error), job: "fitted" };
        let sources = inputs
            .par_iter()
            .map(|input| Source::read(input, ReadOptions::default()).map(|s| (s.animation().clone(), s.skeleton())))
            .collect::<Result<Vec<_>, InputError>>()
            .map_err(refused)?;
        let (first, first_skeleton) = &sources[0];
        for ((animation, skeleton), input) in sources.iter().zip(inputs).skip(1) {
            if let Some(difference) = skeleton_difference(first, first_skeleton.as_ref(), animation, skeleton.as_ref())
            {
                let reason = format!(
                    "holds clips of one skeleton: {}'s is not {}'s ({difference}); fit them into separate libraries",
                    input.display(),
                    inputs[0].display()
                );
                return Err(FileJobError::option("clip_library", reason));
            }
        }
        // A clip keeps its name unless another input has a clip of that name too.
        let mut names: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
        for (animation, _) in &sources {
            for clip in &animation.clips {
                *names.entry(&clip.name).or_default() += 1;
            }
        }
        let fits: Vec<(InputFit, Option<Vec<FittedClip>>)> = sources
            .par_iter()
            .zip(inputs)
            .zip(stems)
            .map(|(((animation, _), input), stem)| {
                let mut report = InputFit::new(input, unit_cm);
                let clips = match self.fit_clips(&report.input, animation, unit_cm, progress, &mut report.clips) {
                    Ok(clips) => Some(clips),
                    Err(e) => {
                        report.error = Some(e.to_string());
                        None
                    }
                };
                let renamed = clips.map(|clips| {
                    clips
                        .into_iter()
                        .map(|clip| match names[clip.name.as_str()] {
                            1 => clip,
                            _ => FittedClip { name: format!("{stem}/{}", clip.name), ..clip },
                        })
                        .collect()
                });
                (report, renamed)
            })
            .collect();
        let (mut reports, clips): (Vec<InputFit>, Vec<Option<Vec<FittedClip>>>) = fits.into_iter().unzip();
        for (report, clips) in reports.iter_mut().zip(&clips) {
            for (clip, fitted) in report.clips.iter_mut().zip(clips.iter().flatten()) {
                clip.clip.clone_from(&fitted.name);
            }
        }
        let raw_bytes: usize = reports.iter().flat_map(|r| &r.clips).map(|c| c.raw_bytes).sum();
        let clip_bytes: usize = reports.iter().flat_map(|r| &r.clips).map(|c| c.compressed_bytes).sum();
        let mut library = LibraryFit {
            output: None,
            clips: reports.iter().map(|r| r.clips.len()).sum(),
            raw_bytes,
            clip_bytes,
            container_bytes: 0,
            ratio: raw_bytes as f64 / clip_bytes.max(1) as f64,
            whole_file_ratio: 0.0,
        };
        let Some(clips) = clips.into_iter().collect::<Option<Vec<_>>>() else { return Ok((reports, library)) };
        let (first, skeleton) = sources.into_iter().next().expect("an input");
        let bytes =
            Container { joints: first.joints, bvh: skeleton, clips: clips.into_iter().flatten().collect() }.to_bytes();
        let path = self.output.join(format!("{name}.{EXTENSION}"));
        match quatcurve_eval::io::write_atomic(&path, |w| w.write_all(&bytes)) {
            Ok(()) => {
                let written = path.display().to_string();
                reports.iter_mut().for_each(|r| r.output = Some(written.clone()));
                library.output = Some(written);
                library.container_bytes = bytes.len();
                library.whole_file_ratio = raw_bytes as f64 / bytes.len() as f64;
            }
            Err(e) => {
                let error = FitInputError::from(e).to_string();
                reports.iter_mut().for_each(|r| r.error = Some(error.clone()));
            }
        }
        Ok((reports, library))
    }

    fn fit_one(
        &self,
        input: &Path,
        stem: &str,
        unit_cm: f64,
        progress: &(dyn Fn(&str, &ClipReport) + Sync),
    ) -> InputFit {
        let mut report = InputFit::new(input, unit_cm);
        let result = (|| -> Result<(String, usize), FitInputError> {
            let source = Source::read(input, ReadOptions::default())?;
            let clips = self.fit_clips(&report.input, source.animation(), unit_cm, progress, &mut report.clips)?;
            let joints = source.animation().joints.clone();
            let bytes = Container { joints, bvh: source.skeleton(), clips }.to_bytes();
            let path = self.output.join(format!("{stem}.{EXTENSION}"));
            quatcurve_eval::io::write_atomic(&path, |w| w.write_all(&bytes))?;
            Ok((path.display().to_string(), bytes.len()))
        })();
        match result {
            Ok((path, bytes)) => {
                report.output = Some(path);
                report.container_bytes = bytes;
                let raw: usize = report.clips.iter().map(|c| c.raw_bytes).sum();
                report.whole_file_ratio = raw as f64 / bytes as f64;
            }
            Err(e) => report.error = Some(e.to_string()),
        }
        report
    }

    /// Every clip of `animation` fitted within the budget, in order, each reported to
    /// `reports` and `progress` as it finishes.
    fn fit_clips(
        &self,
        name: &str,
        animation: &Animation,
        unit_cm: f64,
        progress: &(dyn Fn(&str, &ClipReport) + Sync),
        reports: &mut Vec<ClipReport>,
    ) -> Result<Vec<FittedClip>, FitInputError> {
        if animation.clips.is_empty() {
            return Err(FitInputError::Empty);
        }
        let budget = Budget {
            max_error: self.options.max_error_cm / unit_cm,
            between_error: self.options.between_error_cm.map_or(f64::INFINITY, |cm| cm / unit_cm),
            vertex_distance: self.options.vertex_distance_cm / unit_cm,
        };
        let mut clips = Vec::with_capacity(animation.clips.len());
        for c in 0..animation.clips.len() {
            let started = Instant::now();
            let fit = fit_clip(animation, c, &budget).map_err(|e| {
                let clip = animation.clips[c].name.clone();
                match e {
                    FitClipError::OverBudget { at_frames, between_frames } => FitInputError::OverBudget {
                        clip,
                        max_error_cm: self.options.max_error_cm,
                        between_error_cm: self.options.between_error_cm,
                        at: Box::new(worst_report(animation, &at_frames, unit_cm)),
                        between: Box::new(worst_report(animation, &between_frames, unit_cm)),
                    },
                    error => FitInputError::Clip { clip, error },
                }
            })?;
            let clip = clip_report(animation, &fit, unit_cm, started.elapsed().as_secs_f64());
            progress(name, &clip);
            reports.push(clip);
            clips.push(fit.clip);
        }
        Ok(clips)
    }
}

impl InputFit {
    /// An input's report before its fit.
    fn new(input: &Path, unit_cm: f64) -> Self {
        let input = input.display().to_string();
        Self { input, output: None, unit_cm, container_bytes: 0, whole_file_ratio: 0.0, clips: Vec::new(), error: None }
    }
}

/// How `other`'s skeleton differs from `first`'s, in words, or `None` for the same one: the
/// same joints (names, parents, rest poses within [`REST_TOLERANCE`]) and, for BVH sources,
/// the same hierarchy text.
fn skeleton_difference(
    first: &Animation,
    first_bvh: Option<&BvhSkeleton>,
    other: &Animation,
    other_bvh: Option<&BvhSkeleton>,
) -> Option<String> {
    if first.joints.len() != other.joints.len() {
        return Some(format!("{} joints, not {}", other.joints.len(), first.joints.len()));
    }
    for (j, (a, b)) in first.joints.iter().zip(&other.joints).enumerate() {
        let pose = |j: &quatcurve_anim::Joint| -> Vec<f64> {
            j.rotation.iter().chain(&j.translation).chain(&j.scale).copied().collect()
        };
        let near = pose(a).iter().zip(pose(b)).all(|(x, y)| (x - y).abs() <= REST_TOLERANCE * x.abs().max(1.0));
        if a.name != b.name || a.parent != b.parent || !near {
            return Some(format!("joint {j}: '{}' is not '{}' as it hangs and rests", b.name, a.name));
        }
    }
    match (first_bvh, other_bvh) {
        (None, None) => None,
        (Some(a), Some(b)) if a.hierarchy == b.hierarchy => None,
        (Some(_), Some(_)) => Some("another BVH hierarchy".into()),
        _ => Some("one is BVH, the other not".into()),
    }
}

/// How far two library inputs' rest poses may differ (relative to values over 1): a skeleton
/// written twice by one tool.
const REST_TOLERANCE: f64 = 1e-6;

fn worst_report(animation: &Animation, w: &Worst, unit_cm: f64) -> WorstReport {
    WorstReport { error_cm: w.error * unit_cm, joint: animation.joints[w.joint].name.clone(), time: w.time }
}

fn clip_report(animation: &Animation, fit: &ClipFit, unit_cm: f64, seconds: f64) -> ClipReport {
    let worst = |w: &Worst| worst_report(animation, w, unit_cm);
    ClipReport {
        clip: fit.clip.name.clone(),
        frames: fit.frames,
        joints: animation.joints.len(),
        raw_bytes: fit.raw_bytes,
        compressed_bytes: fit.fitted_bytes,
        ratio: fit.raw_bytes as f64 / fit.fitted_bytes as f64,
        at_frames: worst(&fit.at_frames),
        between_frames: worst(&fit.between_frames),
        seconds,
    }
}

#[cfg(all(test, feature = "cli"))]
mod tests {
    use super::*;

    /// Every fit option is a flag of the command line, spelled from its name, and reads back
    /// by name as Python gives it.
    #[test]
    fn every_option_is_a_flag_named_after_it_and_reads_by_name() {
        use clap::Args;
        let command = FitOptions::augment_args(clap::Command::new("fit"));
        let mut flags: Vec<String> = command.get_arguments().filter_map(|a| a.get_long().map(str::to_string)).collect();
        let serde_json::Value::Object(names) = serde_json::to_value(FitOptions::DEFAULT).unwrap() else { panic!() };
        let mut names: Vec<String> = names.keys().map(|n| n.replace('_', "-")).collect();
        names.sort();
        flags.sort();
        assert_eq!(flags, names);
        let given = serde_json::from_str(r#"{"between_error_cm": null, "unit_cm": 5.644}"#).unwrap();
        let options: FitOptions = quatcurve_eval::options::from_named(&given).unwrap();
        assert_eq!(options, FitOptions { between_error_cm: None, unit_cm: Some(5.644), ..FitOptions::DEFAULT });
    }
}
