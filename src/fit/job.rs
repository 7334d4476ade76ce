//! A fit job: glTF/BVH inputs to one container each (`<stem>.qcf`), with a report per clip.
//! Everything that can be found wrong before fitting is (a BVH without its unit, an output
//! directory that takes no file, two inputs with one stem, an output that would replace its
//! input); a failed input is reported and the others still finish.

use super::clip::{fit_clip, Budget, ClipFit, FitClipError, Worst};
use crate::anim::error::InputError;
use crate::anim::qcf::{BvhSkeleton, Container, EXTENSION};
use crate::anim::{Animation, GLTF_UNIT_CM};
use crate::bake::inputs::{expand, extension, output_stems};
use crate::bake::outputs::{refuse_overwriting_input, OutputDir};
use crate::bake::{bvh, gltf, BakeError};
use crate::error::Number;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The extensions a fit reads (sources with keys; a container holds control points).
pub const FIT_EXTENSIONS: [&str; 3] = ["gltf", "glb", "bvh"];

/// What to fit and within what, lengths in centimetres.
#[derive(Clone, Debug)]
pub struct FitJob {
    /// Files or directories of them ([`FIT_EXTENSIONS`]).
    pub inputs: Vec<PathBuf>,
    /// Where `<stem>.qcf` goes.
    pub output: PathBuf,
    /// The largest virtual-vertex error at any source frame, cm.
    pub max_error_cm: f64,
    /// The largest between source frames, cm, against the source's interpolation; `None`:
    /// not checked (the curve may swing between frames).
    pub between_error_cm: Option<f64>,
    /// The virtual vertices' distance from each joint, cm.
    pub vertex_distance_cm: f64,
    /// The length of one file unit in cm; `None`: glTF's metre, and an error for BVH, whose
    /// files do not say theirs.
    pub unit_cm: Option<f64>,
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
    /// Its bytes.
    pub container_bytes: usize,
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
    /// See [`FitJob::between_error_cm`].
    pub between_error_cm: Option<f64>,
    /// See [`FitJob::vertex_distance_cm`].
    pub vertex_distance_cm: f64,
    /// Per input, in path order.
    pub inputs: Vec<InputFit>,
}

impl FitReport {
    /// How many inputs failed.
    #[must_use]
    pub fn failed(&self) -> usize {
        self.inputs.iter().filter(|i| i.error.is_some()).count()
    }
}

impl FitJob {
    /// Fits every input, each clip on every core, writing each container atomically.
    ///
    /// # Errors
    /// What is wrong before any input is read: a length that is not positive, a BVH input
    /// without [`FitJob::unit_cm`], an input of another format, an output directory that
    /// takes no file, two inputs with one stem, a container that would replace its input.
    pub fn run(&self, progress: &dyn Fn(&str, &ClipReport)) -> Result<FitReport, BakeError> {
        for (option, value) in [
            ("max_error", Some(self.max_error_cm)),
            ("between_error", self.between_error_cm),
            ("vertex_distance", Some(self.vertex_distance_cm)),
            ("unit_cm", self.unit_cm),
        ] {
            if let Some(v) = value.filter(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(BakeError::option(option, format!("is {v}; it must be a positive length")));
            }
        }
        if self.inputs.is_empty() {
            return Err(BakeError::option("inputs", "names no file: give the glTF or BVH files to fit"));
        }
        let inputs = expand(&self.inputs, &FIT_EXTENSIONS)?;
        for input in &inputs {
            match extension(input).as_deref() {
                Some("bvh") if self.unit_cm.is_none() => {
                    return Err(BakeError::option(
                        "unit_cm",
                        format!(
                            "is needed for {}: a BVH file does not say its unit (CMU's is 5.644 cm); nothing was \
                             fitted",
                            input.display()
                        ),
                    ))
                }
                Some(e) if FIT_EXTENSIONS.contains(&e) => {}
                _ => {
                    return Err(BakeError::option(
                        "input",
                        format!("{}: not a file to fit: expected .gltf, .glb or .bvh", input.display()),
                    ))
                }
            }
        }
        let stems = output_stems(&inputs)?;
        let output = OutputDir::create(&self.output, "fitted")?;
        for (input, stem) in inputs.iter().zip(&stems) {
            let path = self.output.join(format!("{stem}.{EXTENSION}"));
            let refused = refuse_overwriting_input(&path, &input.display().to_string())
                .err()
                .or_else(|| path.is_dir().then(|| InputError::Output(format!("{}: is a directory", path.display()))));
            if let Some(e) = refused {
                output.remove_if_unused();
                return Err(BakeError::Job(format!("{e} (nothing was fitted)")));
            }
        }
        let inputs = inputs.iter().zip(&stems).map(|(input, stem)| self.fit_one(input, stem, progress)).collect();
        Ok(FitReport {
            max_error_cm: self.max_error_cm,
            between_error_cm: self.between_error_cm,
            vertex_distance_cm: self.vertex_distance_cm,
            inputs,
        })
    }

    /// A clip no fit held within the budget: how close the closest came, and what loosens it.
    fn over_budget(&self, clip: &str, at: &WorstReport, between: &WorstReport) -> String {
        let between_budget = self.between_error_cm.map_or_else(
            || "unchecked between them".into(),
            |cm| format!("{} cm between them (the between-frames error)", Number(cm)),
        );
        let loosen = "; a larger between-frames error, or none, loosens the check between frames";
        let hint = match self.between_error_cm {
            Some(cm) if between.error_cm > cm => loosen,
            _ => "",
        };
        format!(
            "clip '{clip}': no fit within {} cm (the maximum error) at every frame and {between_budget}; the closest came to {} cm at frames ({} at {:.3} s) and {} cm between them ({} at {:.3} s){hint}",
            Number(self.max_error_cm),
            Number(at.error_cm),
            at.joint,
            at.time,
            Number(between.error_cm),
            between.joint,
            between.time
        )
    }

    fn fit_one(&self, input: &Path, stem: &str, progress: &dyn Fn(&str, &ClipReport)) -> InputFit {
        let name = input.display().to_string();
        let bvh = extension(input).as_deref() == Some("bvh");
        let unit_cm = self.unit_cm.unwrap_or(GLTF_UNIT_CM);
        let mut report =
            InputFit { input: name.clone(), output: None, unit_cm, container_bytes: 0, clips: Vec::new(), error: None };
        let result = (|| -> Result<(String, usize), String> {
            let (animation, skeleton): (Animation, Option<BvhSkeleton>) = if bvh {
                let file = bvh::read(input).map_err(|e| e.to_string())?;
                let skeleton = BvhSkeleton { hierarchy: file.hierarchy().to_string(), frame_time: file.frame_time };
                (file.animation(stem), Some(skeleton))
            } else {
                let file = gltf::read(input, gltf::UriPolicy::default()).map_err(|e| e.to_string())?;
                (file.animation, None)
            };
            if animation.clips.is_empty() {
                return Err("no rotation, translation or scale animation to fit".into());
            }
            let budget = Budget {
                max_error: self.max_error_cm / unit_cm,
                between_error: self.between_error_cm.map_or(f64::INFINITY, |cm| cm / unit_cm),
                vertex_distance: self.vertex_distance_cm / unit_cm,
            };
            let mut clips = Vec::with_capacity(animation.clips.len());
            for c in 0..animation.clips.len() {
                let started = Instant::now();
                let fit = fit_clip(&animation, c, &budget).map_err(|e| {
                    let clip = &animation.clips[c].name;
                    match e {
                        FitClipError::OverBudget { at_frames, between_frames } => self.over_budget(
                            clip,
                            &worst_report(&animation, &at_frames, unit_cm),
                            &worst_report(&animation, &between_frames, unit_cm),
                        ),
                        FitClipError::Input(e) => format!("clip '{clip}': {e}"),
                    }
                })?;
                let clip = clip_report(&animation, &fit, unit_cm, started.elapsed().as_secs_f64());
                progress(&name, &clip);
                report.clips.push(clip);
                clips.push(fit.clip);
            }
            let bytes = Container { joints: animation.joints, bvh: skeleton, clips }.to_bytes();
            let path = self.output.join(format!("{stem}.{EXTENSION}"));
            crate::io::write_atomic(&path, |w| w.write_all(&bytes)).map_err(|e| e.to_string())?;
            Ok((path.display().to_string(), bytes.len()))
        })();
        match result {
            Ok((path, bytes)) => {
                report.output = Some(path);
                report.container_bytes = bytes;
            }
            Err(e) => report.error = Some(e),
        }
        report
    }
}

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
