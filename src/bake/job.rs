//! The bake as a job over files (DESIGN sections 5b and 7): read each input (glTF/GLB, BVH,
//! or the built-in crowd), bake every clip, write its outputs atomically, and keep the shard's
//! manifest current. The command line (`quatcurve bake`) and the Python package
//! (`quatcurve.bake`) both fill a [`BakeJob`] and run it; neither holds a second copy.
//!
//! One input failing is reported in its [`InputReport`] and the others still finish; only a
//! job that cannot start (a bad option, an output directory that cannot be made) is an `Err`.

use super::error::{BakeError, InputError};
use super::manifest::{hash_bytes, hash_file, FileRecord, InputRecord, Manifest, ShardRecord};
use super::shard::Shard;
use super::texture::{self, Precision, TextureKind};
use super::{bvh, crowd, gltf, Animation, Baked, ClipRate, LoopMode};
use crate::curve::CurveSpec;
use crate::device::{Device, DeviceChoice};
use crate::io::{npy_header, write_atomic, AtomicFile, NpyElement};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// Everything a bake reads: the inputs, where the outputs go, and how they are made. Fill it
/// with [`BakeJob::new`] and field updates, then [`BakeJob::run`] (which validates first).
#[derive(Clone, Debug)]
pub struct BakeJob {
    /// `.gltf`, `.glb` and `.bvh` files, or directories of them; none: the built-in crowd.
    pub inputs: Vec<PathBuf>,
    /// Output directory (created if missing, removed again if the job wrote nothing).
    pub output: PathBuf,
    /// Output frame rate in Hz, fitted per clip so that its first and last frames are its
    /// first and last keys (DESIGN section 5b) unless [`BakeJob::exact_rate`].
    pub rate: f64,
    /// Bake open clips at exactly [`BakeJob::rate`]: frames `start + i / rate` while not past
    /// the last key, so the end of a clip off the grid is not baked (each input's report
    /// warns how much). Loops always fit.
    pub exact_rate: bool,
    /// Curve and its options (`looping` is ignored: [`BakeJob::looping`] decides per clip).
    pub spec: CurveSpec,
    /// Which clips loop.
    pub looping: LoopMode,
    /// The device the job is recorded as using (the one [`BakeJob::run`] is given was opened
    /// from it); part of the options that `resume` compares.
    pub device: DeviceChoice,
    /// Read glTF buffers from anywhere their URIs point, not only data URIs and files beside
    /// the input.
    pub allow_external_uris: bool,
    /// Texture per clip: local, model or skin (DESIGN 5b).
    pub texture: TextureKind,
    /// Texture element type.
    pub precision: Precision,
    /// One texture per input with every clip stacked along frames.
    pub atlas: bool,
    /// Also draw each clip's skeleton to `<stem>.<clip>.png` (cargo feature `plot`).
    pub preview: bool,
    /// Characters in the built-in crowd.
    pub characters: usize,
    /// This process's share of the inputs; `None`: the share a scheduler's environment names
    /// (Slurm, Kubernetes, AWS Batch, Google Batch), else the whole job.
    pub shard: Option<Shard>,
    /// Skip inputs whose outputs this shard's manifest records as intact, from the same bytes
    /// and options.
    pub resume: bool,
    /// Inputs read, baked and written at once (each bake also uses every core).
    pub jobs: usize,
}

impl BakeJob {
    /// The defaults of `quatcurve bake`: [`crate::sampling::DEFAULT_RATE`],
    /// [`crate::curve::DEFAULT_CURVE`], loops detected, local f32 textures, one job.
    #[must_use]
    pub fn new(inputs: Vec<PathBuf>, output: impl Into<PathBuf>) -> Self {
        Self {
            inputs,
            output: output.into(),
            rate: crate::sampling::DEFAULT_RATE,
            exact_rate: false,
            spec: CurveSpec::new(crate::curve::DEFAULT_CURVE),
            looping: LoopMode::Auto,
            device: DeviceChoice::Auto,
            allow_external_uris: false,
            texture: TextureKind::Local,
            precision: Precision::F32,
            atlas: false,
            preview: false,
            characters: crowd::CHARACTERS,
            shard: None,
            resume: false,
            jobs: 1,
        }
    }

    /// Checks the options that do not need the inputs.
    ///
    /// # Errors
    /// [`BakeError::Option`] naming the option.
    pub fn validate(&self) -> Result<(), BakeError> {
        if !(self.rate.is_finite() && self.rate > 0.0) {
            return Err(BakeError::option("rate", format!("must be a positive number of Hz, not {}", self.rate)));
        }
        if self.jobs == 0 {
            return Err(BakeError::option("jobs", "must be at least 1"));
        }
        if self.inputs.is_empty() && self.characters == 0 {
            return Err(BakeError::option("characters", "must be at least 1 for the built-in crowd"));
        }
        if self.preview && !cfg!(feature = "plot") {
            return Err(BakeError::option(
                "preview",
                "needs the `plot` cargo feature, which this build of quatcurve leaves out",
            ));
        }
        Ok(())
    }

    /// The options that decide the outputs (the manifest's `options`; `resume` redoes every
    /// input when they differ).
    fn record(&self) -> serde_json::Value {
        let s = &self.spec;
        serde_json::json!({
            "curve": s.curve.name(), "order": s.order, "knots": s.knots.name(), "tangents": s.tangents.name(),
            "blend": s.blend.name(), "loop": self.looping.name(), "rate": self.rate, "exact_rate": self.exact_rate, "device": self.device.name(),
            "allow_external_uris": self.allow_external_uris, "characters": self.characters,
            "texture": self.texture.name(), "precision": self.precision.name(), "atlas": self.atlas, "preview": self.preview,
        })
    }

    /// Bakes this shard's inputs on `device` (opened from [`BakeJob::device`]; a caller baking
    /// repeatedly keeps one open), telling `progress` as inputs start and finish.
    ///
    /// # Errors
    /// A job that cannot start or cannot write its manifest. Inputs that fail are not errors
    /// here: see [`BakeReport::failed`].
    pub fn run(&self, device: &Device, progress: &dyn Progress) -> Result<BakeReport, BakeError> {
        self.validate()?;
        let shard = match &self.shard {
            Some(shard) => shard.clone(),
            None => Shard::from_env(&|name| std::env::var(name).ok())?,
        };
        let inputs = expand(&self.inputs)?;
        // Over the whole job, so every shard refuses the same clashes.
        let stems = output_stems(&inputs)?;
        let output = OutputDir::create(&self.output)?;
        if let Err(e) = self.check_output_names(&inputs, &stems) {
            output.remove_if_unused();
            return Err(e);
        }
        let device_name = device.name();
        let options = self.record();
        let manifest_path = shard.manifest_path(&self.output);
        let previous = if self.resume { Manifest::load(&manifest_path) } else { None };
        let mut manifest = Manifest {
            tool: format!("quatcurve {}", env!("CARGO_PKG_VERSION")),
            shard: ShardRecord { index: shard.index, count: shard.count, source: shard.source.clone() },
            options: options.clone(),
            host: super::manifest::host(),
            started: super::manifest::now(),
            updated: 0,
            inputs: Vec::new(),
        };
        // This shard's inputs: (name, stem, path); the built-in crowd is input 0 of its job.
        let crowd_name =
            format!("built-in crowd: {} x {} joints, {} s", self.characters, crowd::JOINTS, crowd::SECONDS);
        let all: Vec<(String, &str, Option<&Path>)> = if self.inputs.is_empty() {
            vec![(crowd_name, "crowd", None)]
        } else {
            inputs.iter().zip(&stems).map(|(p, s)| (p.display().to_string(), s.as_str(), Some(p.as_path()))).collect()
        };
        let job_inputs = all.len();
        let mine: Vec<_> =
            all.into_iter().enumerate().filter(|(k, _)| shard.owns(*k)).map(|(_, input)| input).collect();
        progress.start(mine.len());
        // One input: verify and keep (resume), or read, bake and write.
        let process = |(name, stem, path): &(String, &str, Option<&Path>)| -> (InputReport, InputRecord) {
            progress.begin(name);
            let fingerprint = match path {
                Some(path) => hash_file(path).unwrap_or((0, String::new())),
                None => (0, hash_bytes(options.to_string().as_bytes())),
            };
            let kept = previous
                .as_ref()
                .and_then(|m| m.resumable(&options, name, fingerprint.0, &fingerprint.1, &self.output));
            let (report, written) = match (kept, path) {
                (Some(record), _) => (resumed(name, record, &self.output), Vec::new()),
                (None, Some(path)) => self.bake_one(name, stem, || self.read(path), device),
                (None, None) => self.bake_one(name, stem, || Ok(Source::Crowd(crowd::crowd(self.characters))), device),
            };
            let record = input_record(&report, &written, fingerprint, kept);
            progress.finish(&report);
            (report, record)
        };
        // Kept current while the job runs, so a killed task resumes from where it was.
        let (last_write, write_error) = (Mutex::new(Instant::now()), Mutex::new(None));
        let results = in_order(&mine, self.jobs, process, |done| {
            let mut last = last_write.lock().unwrap_or_else(|e| e.into_inner());
            if last.elapsed().as_secs_f64() > 2.0 {
                let mut partial =
                    Manifest { inputs: done.iter().flatten().map(|(_, r)| r.clone()).collect(), ..manifest.clone() };
                if let Err(e) = write_manifest(&mut partial, &manifest_path) {
                    *write_error.lock().unwrap_or_else(|e| e.into_inner()) = Some(e);
                }
                *last = Instant::now();
            }
        });
        if let Some(e) = write_error.into_inner().unwrap_or_else(|e| e.into_inner()) {
            return Err(e);
        }
        let (inputs, records): (Vec<InputReport>, Vec<InputRecord>) = results.into_iter().unzip();
        manifest.inputs = records;
        // A record of what was done, unless nothing was (a failed job leaves nothing behind).
        if inputs.iter().any(|r| r.outcome.is_ok()) {
            write_manifest(&mut manifest, &manifest_path)?;
        }
        output.remove_if_unused();
        Ok(BakeReport { device: device_name, shard, job_inputs, inputs })
    }

    /// The output faults that can be found before any input is baked: a baked file that would
    /// replace its input, a directory where an input's baked file or sidecar goes.
    fn check_output_names(&self, inputs: &[PathBuf], stems: &[String]) -> Result<(), BakeError> {
        let stems: Vec<&str> =
            if inputs.is_empty() { vec!["crowd"] } else { stems.iter().map(String::as_str).collect() };
        for (k, stem) in stems.iter().enumerate() {
            let mut names = vec![format!("{stem}.json")];
            if let Some(input) = inputs.get(k) {
                let baked = match input.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
                    Some("gltf" | "glb") => Some(format!("{stem}.glb")),
                    Some("bvh") => Some(format!("{stem}.bvh")),
                    _ => None,
                };
                if let Some(baked) = baked {
                    refuse_overwriting_input(&self.output.join(&baked), &input.display().to_string())
                        .map_err(|e| BakeError::Job(format!("{e} (nothing was baked)")))?;
                    names.push(baked);
                }
            }
            if let Some(dir) = names.iter().map(|n| self.output.join(n)).find(|p| p.is_dir()) {
                return Err(BakeError::option(
                    "output",
                    format!(
                        "{}: a directory is where a baked file goes; move it away (nothing was baked)",
                        dir.display()
                    ),
                ));
            }
        }
        Ok(())
    }

    fn read(&self, path: &Path) -> Result<Source, InputError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("gltf" | "glb") => Ok(Source::Gltf(Box::new(gltf::read(
                path,
                gltf::UriPolicy { allow_external: self.allow_external_uris },
            )?))),
            Some("bvh") => {
                let file = bvh::read(path)?;
                let name = path.file_stem().map_or_else(|| "motion".into(), |s| s.to_string_lossy().into_owned());
                let animation = file.animation(&name);
                Ok(Source::Bvh(file, animation))
            }
            _ => Err(InputError::UnknownFormat),
        }
    }

    /// Reads, bakes and writes one input; the files it wrote come back with the report.
    fn bake_one(
        &self,
        source: &str,
        stem: &str,
        read: impl FnOnce() -> Result<Source, InputError>,
        device: &Device,
    ) -> (InputReport, Vec<Written>) {
        let start = Instant::now();
        let mut report = InputReport::new(source);
        let result = read().and_then(|src| {
            let animation = src.animation();
            report.clips = animation.clips.len();
            report.channels = animation.clips.iter().map(|c| c.channels.len()).sum();
            report.keys = animation.key_count();
            if animation.clips.is_empty() {
                return Err(InputError::Animation("no rotation, translation or scale animation to bake".into()));
            }
            report.warnings = super::source_step_warnings(animation);
            let rate = if self.exact_rate { ClipRate::Exact(self.rate) } else { ClipRate::Fit(self.rate) };
            let baked = super::bake(animation, &self.spec, rate, self.looping, device)?;
            report.warnings.extend(unbaked_ends(animation, &baked));
            report.samples = baked.sample_count();
            report.max_key_error = baked.max_key_error;
            // The device that ran this input (auto: the CPU path for a batch the GPU cannot take).
            let used = baked.device.clone().unwrap_or_else(|| device.name());
            self.write_outputs(&src, &baked, source, stem, &used, device)
        });
        report.seconds = start.elapsed().as_secs_f64();
        let written = match result {
            Ok(written) => {
                report.outcome = Ok(written.iter().map(|w| w.path.clone()).collect());
                written
            }
            Err(e) => {
                report.outcome = Err(e);
                Vec::new()
            }
        };
        (report, written)
    }

    /// Writes the baked file (GLB or BVH), the textures and the sidecar; if any write fails,
    /// removes the ones already written so the job leaves nothing partial. Forward kinematics
    /// (model and skin textures, previews) runs on `fk_device`, the bake's.
    fn write_outputs(
        &self,
        src: &Source,
        baked: &Baked,
        source: &str,
        stem: &str,
        device: &str,
        fk_device: &Device,
    ) -> Result<Vec<Written>, InputError> {
        let mut out = Outputs { dir: &self.output, stem, source, written: Vec::new(), atlas: Vec::new(), rows: 0 };
        match self.write_all(&mut out, src, baked, device, fk_device) {
            Ok(()) => Ok(out.written),
            Err(e) => {
                for file in &out.written {
                    let _ = std::fs::remove_file(&file.path);
                }
                Err(e)
            }
        }
    }

    /// [`BakeJob::write_outputs`]'s files, recorded in `out` as they are written.
    fn write_all(
        &self,
        out: &mut Outputs<'_>,
        src: &Source,
        baked: &Baked,
        device: &str,
        fk_device: &Device,
    ) -> Result<(), InputError> {
        let (animation, dir, stem) = (src.animation(), out.dir, out.stem);
        // Checked before anything is written.
        let order = animation.parents_first()?;
        if self.texture == TextureKind::Skin && matches!(src, Source::Gltf(_)) && animation.skins.is_empty() {
            return Err(InputError::Animation(
                "the file has no skin to bake a skin texture for; bake a model texture instead".into(),
            ));
        }
        let baked_file = match src {
            Source::Gltf(file) => Some((format!("{stem}.glb"), file.to_glb(baked)?)),
            Source::Bvh(file, animation) => {
                Some((format!("{stem}.bvh"), file.to_text(&animation.clips[0], baked).into_bytes()))
            }
            Source::Crowd(_) => None,
        };
        if let Some((name, bytes)) = &baked_file {
            let path = dir.join(name);
            refuse_overwriting_input(&path, out.source)?;
            write_atomic(&path, |w| w.write_all(bytes)).map_err(|e| InputError::Output(e.to_string()))?;
            out.written.push(path.into());
        }
        // An atlas stacks every clip's frames in one file per sheet, opened with its whole shape.
        if self.atlas {
            let rows = baked.clips.iter().map(|c| c.times.len()).sum();
            out.atlas = self.open_textures(animation, rows, |suffix| dir.join(format!("{stem}{suffix}.npy")))?;
        }
        let clips = (0..animation.clips.len())
            .map(|index| self.write_clip(out, animation, baked, &order, index, fk_device))
            .collect::<Result<Vec<_>, _>>()?;
        for texture in std::mem::take(&mut out.atlas) {
            out.written.push(texture.finish()?);
        }
        let sidecar = self.sidecar(animation, baked, out.source, device, baked_file.map(|(name, _)| name), clips);
        let path = dir.join(format!("{stem}.json"));
        write_atomic(&path, |w| serde_json::to_writer_pretty(&mut *w, &sidecar).map_err(std::io::Error::from))
            .map_err(|e| InputError::Output(e.to_string()))?;
        out.written.push(path.into());
        Ok(())
    }

    /// Clip `index`'s textures (or its rows of the atlas) and preview; its sidecar entry.
    fn write_clip(
        &self,
        out: &mut Outputs<'_>,
        animation: &Animation,
        baked: &Baked,
        order: &[usize],
        index: usize,
        fk_device: &Device,
    ) -> Result<SidecarClip, InputError> {
        let (clip, result, dir, stem) = (&animation.clips[index], &baked.clips[index], out.dir, out.stem);
        let frames = result.times.len();
        let preview = if self.preview {
            // Forward kinematics of the drawn frames alone.
            let picks = texture::preview_frames(frames);
            let model = texture::sheet_rows(animation, order, baked, index, TextureKind::Model, fk_device, &picks)?
                .swap_remove(0)
                .data;
            let name = format!("{stem}.{index}.png");
            draw_preview(
                &dir.join(&name),
                &format!("{}: clip '{}'", out.source, clip.name),
                &model,
                &picks,
                animation,
            )?;
            out.written.push(dir.join(&name).into());
            Some(name)
        } else {
            None
        };
        let (files, first_row) = if self.atlas {
            self.stream_clip(animation, baked, order, index, fk_device, &mut out.atlas)?;
            out.rows += frames;
            (out.atlas.iter().map(TextureFile::name).collect::<Vec<_>>(), out.rows - frames)
        } else {
            let mut textures =
                self.open_textures(animation, frames, |suffix| dir.join(format!("{stem}.{index}{suffix}.npy")))?;
            self.stream_clip(animation, baked, order, index, fk_device, &mut textures)?;
            let names = textures.iter().map(TextureFile::name).collect();
            for texture in textures {
                out.written.push(texture.finish()?);
            }
            (names, 0)
        };
        Ok(SidecarClip {
            name: clip.name.clone(),
            file: files[0].clone(),
            files,
            first_row,
            frames,
            start: result.times[0],
            end: result.times[frames - 1],
            rate: result.rate,
            looping: result.looping,
            preview,
        })
    }

    /// One [`TextureFile`] per sheet of this job's texture kind ([`texture::layout`]), each
    /// `[rows, width, channels]`, at `path(suffix)`.
    fn open_textures(
        &self,
        animation: &Animation,
        rows: usize,
        path: impl Fn(&str) -> PathBuf,
    ) -> Result<Vec<TextureFile>, InputError> {
        let channels = self.texture.channels();
        texture::layout(animation, self.texture)
            .into_iter()
            .map(|(suffix, width)| {
                TextureFile::create(path(&suffix), self.precision, &[rows as u64, width as u64, channels as u64])
            })
            .collect()
    }

    /// Computes clip `index`'s sheets a block of frames at a time (frames on every core) and
    /// appends each block to `textures` on another thread as the next block is computed: the
    /// texture is never whole in memory, and the disk writes overlap the arithmetic.
    fn stream_clip(
        &self,
        animation: &Animation,
        baked: &Baked,
        order: &[usize],
        index: usize,
        fk_device: &Device,
        textures: &mut [TextureFile],
    ) -> Result<(), InputError> {
        let frames = baked.clips[index].times.len();
        let row_bytes = textures.iter().map(|t| t.row_bytes).max().unwrap_or(1).max(1);
        let block = (TEXTURE_BLOCK_BYTES / row_bytes).max(1);
        std::thread::scope(|s| {
            // One block in flight beside the one being computed.
            let (send, receive) = std::sync::mpsc::sync_channel::<Vec<texture::Sheet>>(1);
            let writer = s.spawn(move || -> Result<(), InputError> {
                for sheets in receive {
                    for (texture, sheet) in textures.iter_mut().zip(&sheets) {
                        texture.append(&sheet.data)?;
                    }
                }
                Ok(())
            });
            let mut computed = Ok(());
            for start in (0..frames).step_by(block) {
                let picks: Vec<usize> = (start..frames.min(start + block)).collect();
                match texture::sheet_rows(animation, order, baked, index, self.texture, fk_device, &picks) {
                    Ok(sheets) => {
                        // A closed channel: the writer failed, and says why below.
                        if send.send(sheets).is_err() {
                            break;
                        }
                    }
                    Err(e) => {
                        computed = Err(e);
                        break;
                    }
                }
            }
            drop(send);
            let written =
                writer.join().unwrap_or_else(|_| Err(InputError::Internal("the texture writer panicked".into())));
            computed.and(written)
        })
    }

    fn sidecar<'a>(
        &'a self,
        animation: &'a Animation,
        baked: &Baked,
        source: &'a str,
        device: &'a str,
        baked_file: Option<String>,
        clips: Vec<SidecarClip>,
    ) -> Sidecar<'a> {
        let channels = self.texture.channels();
        let names = self.texture.channel_names().join(",");
        let layout = match (self.atlas, self.texture) {
            (false, TextureKind::Skin) if !animation.skins.is_empty() => {
                format!("per clip and skin: [frames, skin joints, {channels}] {}: {names}", self.precision)
            }
            (false, _) => format!("per clip: [frames, joints, {channels}] {}: {names}", self.precision),
            (true, _) => format!(
                "one atlas: [frames of every clip, joints, {channels}] {}: {names}; clip rows from first_row",
                self.precision
            ),
        };
        Sidecar {
            source,
            curve: self.spec.curve.name(),
            rate: self.rate,
            device,
            texture: self.texture.name(),
            channels: self.texture.channel_names(),
            precision: self.precision.name(),
            layout,
            max_key_error_rad: baked.max_key_error,
            baked_file,
            joints: animation.joints.iter().map(|j| j.name.as_str()).collect(),
            parents: animation.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i64)).collect(),
            rest: animation
                .joints
                .iter()
                .map(|j| Rest { translation: j.translation, rotation: j.rotation, scale: j.scale })
                .collect(),
            skins: animation.skins.iter().map(|s| SidecarSkin { name: &s.name, joints: &s.joints }).collect(),
            clips,
        }
    }
}

#[cfg(feature = "plot")]
fn draw_preview(
    path: &Path,
    title: &str,
    model: &[f32],
    picks: &[usize],
    animation: &Animation,
) -> Result<(), InputError> {
    crate::plot::skeleton(path, title, model, picks, animation).map_err(InputError::Output)
}

#[cfg(not(feature = "plot"))]
fn draw_preview(_: &Path, _: &str, _: &[f32], _: &[usize], _: &Animation) -> Result<(), InputError> {
    // validate() refuses previews without the feature.
    Err(InputError::Output("previews need the `plot` cargo feature".into()))
}

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
    pub outcome: Result<Vec<PathBuf>, InputError>,
    /// Skipped by `resume`: the earlier run's outputs were verified and kept.
    pub resumed: bool,
    /// What the bake did that a user should know but that did not fail it: source keys that
    /// are probably broken ([`super::source_step_warnings`]), clip ends an exact rate did not
    /// bake. Each names the clip and channel.
    pub warnings: Vec<String>,
}

impl InputReport {
    /// A report with nothing done yet.
    fn new(source: &str) -> Self {
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
        }
    }
}

/// A warning per clip whose end an exact rate left unbaked ([`super::BakedClip::unbaked_end`]).
fn unbaked_ends(animation: &Animation, baked: &Baked) -> Vec<String> {
    let number = crate::error::Number;
    animation
        .clips
        .iter()
        .zip(&baked.clips)
        .filter(|(_, b)| b.unbaked_end() * b.rate > 1e-6)
        .map(|(clip, b)| {
            let last = b.times[b.times.len() - 1];
            format!(
                "clip '{}': at exactly {} Hz the last frame is at {} s, so the last {} s before its last key at {} s are not baked (fit the rate to keep them)",
                clip.name,
                number(b.rate),
                number(last),
                number(b.unbaked_end()),
                number(b.end)
            )
        })
        .collect()
}

/// A file an input wrote, with its size and SHA-256 when they were taken as it was written
/// (the textures: hashed from memory while the bytes go to disk, not read back).
struct Written {
    path: PathBuf,
    hash: Option<(u64, String)>,
}

impl From<PathBuf> for Written {
    fn from(path: PathBuf) -> Self {
        Self { path, hash: None }
    }
}

/// A source read into the common model, with what it needs to write itself back.
enum Source {
    Gltf(Box<gltf::GltfFile>),
    Bvh(bvh::BvhFile, Animation),
    Crowd(Animation),
}

impl Source {
    fn animation(&self) -> &Animation {
        match self {
            Source::Gltf(f) => &f.animation,
            Source::Bvh(_, a) | Source::Crowd(a) => a,
        }
    }
}

/// The sidecar JSON next to the animation textures (DESIGN section 5b).
#[derive(Serialize)]
struct Sidecar<'a> {
    source: &'a str,
    curve: &'a str,
    rate: f64,
    device: &'a str,
    texture: &'a str,
    channels: &'static [&'static str],
    precision: &'a str,
    layout: String,
    max_key_error_rad: Option<f64>,
    baked_file: Option<String>,
    joints: Vec<&'a str>,
    /// Parent joint index, -1 for a root.
    parents: Vec<i64>,
    rest: Vec<Rest>,
    skins: Vec<SidecarSkin<'a>>,
    clips: Vec<SidecarClip>,
}

/// A joint's rest pose, parent-relative.
#[derive(Serialize)]
struct Rest {
    translation: [f64; 3],
    rotation: [f64; 4],
    scale: [f64; 3],
}

#[derive(Serialize)]
struct SidecarSkin<'a> {
    name: &'a str,
    /// Joint indices in the skin's order (the rows of its skin texture).
    joints: &'a [usize],
}

#[derive(Serialize)]
struct SidecarClip {
    name: String,
    /// The texture (for `skin`, skin 0's).
    file: String,
    /// Every texture of the clip: one, or for `skin` one per glTF skin.
    files: Vec<String>,
    /// First row (frame) of the clip in `file`: 0, or its place in the atlas texture.
    first_row: usize,
    frames: usize,
    start: f64,
    end: f64,
    /// Frames per second: the job's rate fitted to the clip's span (its first and last frames
    /// are its first and last keys), or with an exact rate the job's rate (open clips).
    rate: f64,
    /// Baked as a loop: periodic curves, continuous across the seam.
    #[serde(rename = "loop")]
    looping: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    preview: Option<String>,
}

/// `work` over `items` on `jobs` threads, taking items in order; the results come back in item
/// order whatever finishes first, so nothing written depends on timing. `progress` sees every
/// slot (finished or not) after each item; it should be cheap unless it acts (the manifest
/// writer checks the time first).
fn in_order<I: Sync, R: Send>(
    items: &[I],
    jobs: usize,
    work: impl Fn(&I) -> R + Sync,
    progress: impl Fn(&[Option<R>]) + Sync,
) -> Vec<R> {
    let done: Mutex<Vec<Option<R>>> = Mutex::new(items.iter().map(|_| None).collect());
    let next = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..jobs.clamp(1, items.len().max(1)) {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(k) else { break };
                let result = work(item);
                let mut done = done.lock().unwrap_or_else(|e| e.into_inner());
                done[k] = Some(result);
                progress(&done);
            });
        }
    });
    done.into_inner().unwrap_or_else(|e| e.into_inner()).into_iter().flatten().collect()
}

fn write_manifest(manifest: &mut Manifest, path: &Path) -> Result<(), BakeError> {
    manifest.updated = super::manifest::now();
    write_atomic(path, |w| serde_json::to_writer_pretty(&mut *w, manifest).map_err(std::io::Error::from))
        .map_err(BakeError::Manifest)
}

/// An input `resume` skips: the earlier run's record, its outputs verified intact.
fn resumed(name: &str, record: &InputRecord, dir: &Path) -> InputReport {
    let files = record.outputs.iter().map(|o| dir.join(&o.file)).collect();
    let warnings = record.warnings.clone();
    InputReport { outcome: Ok(files), resumed: true, warnings, ..InputReport::new(name) }
}

/// The manifest entry of a finished input.
fn input_record(
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

/// The output directory, created for the job; if this job created it (and any missing
/// parents) and wrote nothing into it, [`Self::remove_if_unused`] takes them away again, so a
/// failed job leaves nothing behind.
struct OutputDir {
    /// Directories this job created, deepest first.
    created: Vec<PathBuf>,
}

impl OutputDir {
    /// Creates `dir` and proves it takes a new file (as every output is first written), so an
    /// output directory that cannot be written is refused before any input is baked.
    fn create(dir: &Path) -> Result<Self, BakeError> {
        let created: Vec<PathBuf> =
            dir.ancestors().take_while(|a| !a.as_os_str().is_empty() && !a.exists()).map(Path::to_path_buf).collect();
        let refuse = |what: &str, e: std::io::Error| {
            BakeError::option("output", format!("{}: {what}: {e} (nothing was baked)", dir.display()))
        };
        std::fs::create_dir_all(dir).map_err(|e| refuse("cannot create the directory", e))?;
        let this = Self { created };
        if let Err(e) = AtomicFile::create(&dir.join("probe")) {
            this.remove_if_unused();
            let e = match e {
                crate::io::IoError::Write { source, .. } => source,
                other => std::io::Error::other(other.to_string()),
            };
            return Err(refuse("cannot write into the directory", e));
        }
        Ok(this)
    }

    fn remove_if_unused(&self) {
        // remove_dir only removes empty directories.
        for dir in &self.created {
            if std::fs::remove_dir(dir).is_err() {
                break;
            }
        }
    }
}

/// Files given, with directories replaced by their .gltf/.glb/.bvh files, sorted by path. A
/// directory without one is an error: baking the built-in crowd instead would be a surprise.
fn expand(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, BakeError> {
    let known = |p: &Path| {
        matches!(
            p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref(),
            Some("gltf" | "glb" | "bvh")
        )
    };
    let mut files = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let entries = std::fs::read_dir(input)
                .map_err(|e| BakeError::option("input", format!("{}: cannot list: {e}", input.display())))?;
            let found: Vec<PathBuf> =
                entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file() && known(p)).collect();
            if found.is_empty() {
                return Err(BakeError::option(
                    "input",
                    format!("{}: the directory holds no .gltf, .glb or .bvh file", input.display()),
                ));
            }
            files.extend(found);
        } else {
            files.push(input.clone());
        }
    }
    // One order for every shard (DESIGN section 7): by path, bytewise.
    files.sort_by(|a, b| a.as_os_str().as_encoded_bytes().cmp(b.as_os_str().as_encoded_bytes()));
    Ok(files)
}

/// Each input's output stem (its file name without extension). Two inputs with one stem
/// (`walk/idle.glb`, `run/idle.bvh`) would write the same outputs, the second silently
/// replacing the first: refused before anything is baked.
fn output_stems(inputs: &[PathBuf]) -> Result<Vec<String>, BakeError> {
    let stems: Vec<String> = inputs
        .iter()
        .map(|p| p.file_stem().map_or_else(|| "out".into(), |s| s.to_string_lossy().into_owned()))
        .collect();
    let mut seen: std::collections::HashMap<&str, &Path> = std::collections::HashMap::new();
    for (stem, path) in stems.iter().zip(inputs) {
        if let Some(first) = seen.insert(stem, path) {
            return Err(BakeError::Job(format!(
                "{} and {} would both write {stem}.*; bake them into separate output directories",
                first.display(),
                path.display(),
            )));
        }
    }
    Ok(stems)
}

/// Where one input's outputs go and what is written so far (taken away again if the input
/// fails), with the atlas being gathered and its row count.
struct Outputs<'a> {
    dir: &'a Path,
    stem: &'a str,
    source: &'a str,
    written: Vec<Written>,
    /// `--atlas`: the open files every clip appends to, and their rows so far.
    atlas: Vec<TextureFile>,
    rows: usize,
}

/// Bytes of texture rows computed and written at a time ([`BakeJob::stream_clip`]): large
/// enough that a block is many frames of a small skeleton and a few of a crowd.
const TEXTURE_BLOCK_BYTES: usize = 32 << 20;

/// A `.npy` texture being written atomically a block of rows at a time, hashed on the way (the
/// manifest's SHA-256 without reading the file back).
struct TextureFile {
    file: AtomicFile,
    element: NpyElement,
    hasher: Sha256,
    /// Values still to come, and bytes written so far.
    left: u64,
    size: u64,
    /// Bytes of one row (a frame of the sheet), as stored.
    row_bytes: usize,
}

impl TextureFile {
    /// The file at `path` with its header for `shape` written.
    fn create(path: PathBuf, precision: Precision, shape: &[u64; 3]) -> Result<Self, InputError> {
        let element = precision.element();
        let file = AtomicFile::create(&path).map_err(|e| InputError::Output(e.to_string()))?;
        let row_bytes = (shape[1] * shape[2]) as usize * element.size();
        let mut texture =
            Self { file, element, hasher: Sha256::new(), left: shape.iter().product(), size: 0, row_bytes };
        texture.write(&npy_header(element.descr(), shape))?;
        Ok(texture)
    }

    /// The file's name (as the sidecar lists it).
    fn name(&self) -> String {
        self.file.path().file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned())
    }

    /// Appends `values` (whole rows), hashed on another core while written.
    fn append(&mut self, values: &[f32]) -> Result<(), InputError> {
        self.left = self.left.checked_sub(values.len() as u64).ok_or_else(|| {
            InputError::Internal(format!("{}: more values than its shape holds", self.file.path().display()))
        })?;
        let bytes = self.element.bytes(values);
        self.write(&bytes)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), InputError> {
        let Self { file, hasher, .. } = self;
        let written = std::thread::scope(|s| {
            s.spawn(|| hasher.update(bytes));
            file.write_all(bytes)
        });
        written.map_err(|e| InputError::Output(self.file.error(e).to_string()))?;
        self.size += bytes.len() as u64;
        Ok(())
    }

    /// Commits the file once its shape is filled; what the manifest records of it.
    fn finish(self) -> Result<Written, InputError> {
        let path = self.file.path().to_path_buf();
        if self.left != 0 {
            return Err(InputError::Internal(format!("{}: {} values short of its shape", path.display(), self.left)));
        }
        self.file.commit().map_err(|e| InputError::Output(e.to_string()))?;
        Ok(Written { path, hash: Some((self.size, super::manifest::hex(&self.hasher.finalize()))) })
    }
}

/// Baking into the input's own directory must not replace the input.
fn refuse_overwriting_input(output: &Path, source: &str) -> Result<(), InputError> {
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
