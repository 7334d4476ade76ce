//! The bake as a job over files (DESIGN sections 6 and 13): read each input (glTF/GLB, BVH,
//! or the built-in crowd), bake every clip, write its outputs atomically, and keep the shard's
//! manifest current. The command line (`quatcurve bake`) and the Python package
//! (`quatcurve.bake`) both fill a [`BakeJob`] and run it; neither holds a second copy.
//!
//! One input failing is reported in its [`InputReport`] and the others still finish; only a
//! job that cannot start (a bad option, an output directory that cannot be made) is an `Err`.

use super::babylon;
use super::budget::{self, ChosenRate};
use super::image::Format;
use super::manifest::{hash_bytes, hash_file, InputRecord, Manifest, ShardRecord};
use super::options::BakeOptions;
use super::outputs::clip_file_names;
use super::outputs::Outputs;
use super::report::{input_record, resumed, unbaked_ends, BakeReport, InputReport, Progress};
use super::root_motion::{self, RootMotion};
use super::sidecar::{ArrayRecord, ConversionRecord, Sidecar, SidecarClip, SidecarOptions};
use super::texture::{self, Precision, TextureKind};
use super::texture_file::{self, SheetSpec, TextureFile, TextureOptions, Written};
use super::vertex_texture::VertexSheets;
use super::workers::in_order;
use super::{vertex_glb, Baked, ClipRate};
use crate::error::{BakeError, Refusal};
use quatcurve_anim::curves::CurveChoice;
use quatcurve_anim::error::{AnimationError, InputError, OutputError};
use quatcurve_anim::Animation;
use quatcurve_device::Device;
use quatcurve_eval::io::write_atomic;
use quatcurve_files::shard::Shard;
use quatcurve_files::FileJobError;
use quatcurve_files::{expand, output_stems};
use quatcurve_files::{refuse_overwriting_input, OutputDir};
use quatcurve_formats::mesh::DeclaredPrimitive;
use quatcurve_formats::source::{ReadOptions, Source};
use quatcurve_formats::{crowd, gltf, mesh};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

/// Everything a bake reads: the inputs, where the outputs go, which share of them this process
/// takes, and how they are made ([`BakeOptions`]). Fill it with [`BakeJob::new`] and field
/// updates, then [`BakeJob::run`] (which validates first).
#[derive(Clone, Debug)]
pub struct BakeJob {
    /// `.gltf`, `.glb` and `.bvh` files, or directories of them; none: the built-in crowd.
    pub inputs: Vec<PathBuf>,
    /// Output directory (created if missing, removed again if the job wrote nothing).
    pub output: PathBuf,
    /// How the outputs are made: what the manifest records and `resume` compares.
    pub options: BakeOptions,
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
    /// A job over `inputs` into `output` with every option at its default
    /// ([`BakeOptions::DEFAULT`]), the whole job in this process, one input at a time.
    #[must_use]
    pub fn new(inputs: Vec<PathBuf>, output: impl Into<PathBuf>) -> Self {
        Self { inputs, output: output.into(), options: BakeOptions::DEFAULT, shard: None, resume: false, jobs: 1 }
    }

    /// Checks the options that do not need the inputs, as [`BakeOptions::for_player`] resolves
    /// them.
    ///
    /// # Errors
    /// [`FileJobError::Option`] naming the option.
    pub fn validate(&self) -> Result<(), FileJobError> {
        Self { options: self.options.for_player()?, ..self.clone() }.validate_resolved()
    }

    /// [`Self::validate`] of options already resolved for their player.
    fn validate_resolved(&self) -> Result<(), FileJobError> {
        if !(self.options.rate.is_finite() && self.options.rate > 0.0) {
            return Err(FileJobError::option(
                "rate",
                format!("must be a positive number of Hz, not {}", self.options.rate),
            ));
        }
        if self.jobs == 0 {
            return Err(FileJobError::option("jobs", "must be at least 1"));
        }
        if self.inputs.is_empty() && self.options.characters == 0 {
            return Err(FileJobError::option("characters", "must be at least 1 for the built-in crowd"));
        }
        if self.inputs.is_empty() && self.options.texture == TextureKind::Vertex {
            return Err(FileJobError::option(
                "texture",
                "vertex skins a glTF's meshes, and the built-in crowd has none; name glTF inputs, or bake a bone texture",
            ));
        }
        if self.options.format == Format::Png16 && self.options.precision == Precision::F16 {
            return Err(FileJobError::option("precision", "f16 does not apply to png16, which stores 16-bit integers"));
        }
        if self.options.format == Format::Babylon && self.options.texture != TextureKind::Skin {
            return Err(FileJobError::option(
                "format",
                format!(
                    "babylon holds a skin's bone matrices as Babylon.js's VertexAnimationBaker does; bake a skin texture, \
                     not a {} one",
                    self.options.texture
                ),
            ));
        }
        if self.options.format == Format::Babylon && self.options.precision == Precision::F16 {
            return Err(FileJobError::option(
                "precision",
                "f16 does not apply to babylon, whose JSON Babylon.js reads as 32-bit floats",
            ));
        }
        if self.options.format == Format::Png16 && !cfg!(feature = "plot") {
            return Err(FileJobError::option(
                "format",
                "png16 needs the `plot` cargo feature, which this build leaves out",
            ));
        }
        let budget = self.options.budget();
        for (option, value) in [("max_error_deg", budget.degrees), ("max_error_cm", budget.centimetres)] {
            if value.is_some_and(|v| !(v.is_finite() && v > 0.0)) {
                return Err(FileJobError::option(
                    option,
                    format!("must be a positive number, not {}", value.unwrap_or(0.0)),
                ));
            }
        }
        if budget.is_set() {
            if !(budget.max_rate.is_finite() && budget.max_rate > 0.0) {
                return Err(FileJobError::option(
                    "max_rate",
                    format!("must be a positive number of Hz, not {}", budget.max_rate),
                ));
            }
            if !(budget.unit_cm.is_finite() && budget.unit_cm > 0.0) {
                return Err(FileJobError::option(
                    "unit_cm",
                    format!("must be a positive number, not {}", budget.unit_cm),
                ));
            }
            // The budget given, by its option.
            let asked = if budget.degrees.is_some() { "max_error_deg" } else { "max_error_cm" };
            if self.options.texture == TextureKind::Vertex {
                return Err(FileJobError::option(
                    asked,
                    "measures joints blended between frames, not a vertex texture's positions; bake vertex textures at a \
                     fixed rate",
                ));
            }
            if !matches!(self.options.texture, TextureKind::Local | TextureKind::ModelTrs | TextureKind::SkinTrs) {
                return Err(FileJobError::option(
                    asked,
                    format!(
                        "measures what a shader interpolates between frames, which a {} texture's matrices do not \
                         hold without shearing; bake a local, model-trs or skin-trs texture",
                        self.options.texture
                    ),
                ));
            }
            if self.options.exact_rate {
                return Err(FileJobError::option(
                    "exact_rate",
                    "cannot be set with an error budget, which chooses each clip's rate",
                ));
            }
        }
        if self.options.max_texture_size == 0 {
            return Err(FileJobError::option("max_texture_size", "must be at least 1 texel"));
        }
        if self.options.preview && !cfg!(feature = "plot") {
            return Err(FileJobError::option(
                "preview",
                "needs the `plot` cargo feature, which this build of quatcurve leaves out",
            ));
        }
        Ok(())
    }

    /// How this job writes its textures.
    fn texture_options(&self) -> TextureOptions {
        TextureOptions {
            format: self.options.format,
            precision: self.options.precision,
            max_size: self.options.max_texture_size,
        }
    }

    /// The files of each clip's (or the atlas's) texture; for `--format babylon`, each skin's
    /// in the space of the node Babylon's loader hangs its mesh from (`skinned`: the nodes
    /// drawing skinned meshes).
    fn sheets(
        &self,
        animation: &Animation,
        vertex: Option<&VertexSheets>,
        skinned: &[DeclaredPrimitive],
    ) -> Result<Vec<SheetSpec>, BakeError> {
        if let Some(vertex) = vertex {
            return Ok(vertex.layout());
        }
        let spaces = match self.options.format {
            Format::Babylon => babylon::mesh_parents(animation, skinned)
                .into_iter()
                .zip(&animation.skins)
                .map(|(parent, skin)| {
                    babylon::from_world(animation, parent)
                        .map_err(|error| BakeError::from(Refusal::Singular { skin: skin.name.clone(), error }))
                })
                .collect::<Result<Vec<_>, _>>()?,
            _ => Vec::new(),
        };
        Ok(texture_file::bone_sheets(animation, self.options.texture, &spaces))
    }

    /// What a skin texture's matrices draw of `file`, and what they do not: skinned meshes and
    /// rigid parts, except that Babylon's baked vertex animation moves skinned meshes alone.
    fn skin_primitives(&self, file: &gltf::GltfFile) -> Result<mesh::Drawn<DeclaredPrimitive>, BakeError> {
        let mut drawn = mesh::declared_skinned_primitives(file)?;
        if self.options.format == Format::Babylon {
            let (rigid, skinned): (Vec<_>, Vec<_>) = drawn.primitives.into_iter().partition(|p| p.rigid.is_some());
            drawn.primitives = skinned;
            // One entry a mesh, as the other reasons are named.
            drawn.not_drawn.extend(rigid.iter().filter(|p| p.primitive == 0).map(|p| {
                let mesh = p.name.strip_suffix(", primitive 0").unwrap_or(&p.name);
                format!("{mesh}: a rigid part, and Babylon's baked vertex animation moves skinned meshes alone")
            }));
        }
        Ok(drawn)
    }

    /// The options that decide the outputs (the manifest's `options`; `resume` redoes every
    /// input when they differ).
    fn record(&self) -> serde_json::Value {
        serde_json::to_value(&self.options).unwrap_or_else(|e| unreachable!("options serialize: {e}"))
    }

    /// Bakes this shard's inputs on `device` (opened from [`BakeOptions::device`]; a caller baking
    /// repeatedly keeps one open), telling `progress` as inputs start and finish.
    ///
    /// # Errors
    /// A job that cannot start or cannot write its manifest. Inputs that fail are not errors
    /// here: see [`BakeReport::failed`].
    pub fn run(&self, device: &Device, progress: &dyn Progress) -> Result<BakeReport, FileJobError> {
        let resolved = Self { options: self.options.for_player()?, ..self.clone() };
        resolved.run_resolved(device, progress)
    }

    /// [`Self::run`] of options already resolved for their player.
    fn run_resolved(&self, device: &Device, progress: &dyn Progress) -> Result<BakeReport, FileJobError> {
        self.validate_resolved()?;
        let shard = match &self.shard {
            Some(shard) => shard.clone(),
            None => Shard::from_env(&|name| std::env::var(name).ok())?,
        };
        let inputs = expand(&self.inputs, &quatcurve_formats::source::input_extensions().collect::<Vec<_>>())?;
        // Over the whole job, so every shard refuses the same clashes.
        let stems = output_stems(&inputs)?;
        // A stage says its unit (`metersPerUnit`), as a position budget counts in cm.
        if self.options.max_error_cm.is_some() || self.options.usd {
            quatcurve_files::unit_cm(&inputs, self.options.unit_cm, "nothing was baked")?;
        }
        let output = OutputDir::create(&self.output, "baked")?;
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
            format!("built-in crowd: {} x {} joints, {} s", self.options.characters, crowd::JOINTS, crowd::SECONDS);
        let all: Vec<(String, &str, Option<&Path>)> = if self.inputs.is_empty() {
            vec![(crowd_name, "crowd", None)]
        } else {
            inputs.iter().zip(&stems).map(|(p, s)| (p.display().to_string(), s.as_str(), Some(p.as_path()))).collect()
        };
        let job_inputs = all.len();
        let all_stems: Vec<&str> = all.iter().map(|(_, stem, _)| *stem).collect();
        let stale_removed = remove_stale_temporaries(&self.output, &all_stems, &shard, &manifest_path);
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
                (None, Some(path)) => {
                    let uris = gltf::UriPolicy { allow_external: self.options.allow_external_uris };
                    self.bake_one(name, stem, || Source::read(path, ReadOptions { uris }), device, progress)
                }
                (None, None) => {
                    self.bake_one(name, stem, || Ok(Source::crowd(self.options.characters)), device, progress)
                }
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
        Ok(BakeReport { device: device_name, shard, job_inputs, inputs, stale_removed })
    }

    /// The output faults that can be found before any input is baked: a baked file that would
    /// replace its input, a directory where an input's baked file or sidecar goes.
    fn check_output_names(&self, inputs: &[PathBuf], stems: &[String]) -> Result<(), FileJobError> {
        let stems: Vec<&str> =
            if inputs.is_empty() { vec!["crowd"] } else { stems.iter().map(String::as_str).collect() };
        for (k, stem) in stems.iter().enumerate() {
            let mut names = vec![format!("{stem}.json")];
            if let Some(input) = inputs.get(k) {
                let importer = quatcurve_formats::source::importer(input);
                if let Some(extension) = importer.and_then(|i| i.writes_back) {
                    names.push(format!("{stem}.{extension}"));
                }
                if importer.is_some_and(|i| i.meshes) && self.options.texture == TextureKind::Vertex {
                    names.push(format!("{stem}{MESH_GLB_SUFFIX}"));
                }
                for baked in &names[1..] {
                    refuse_overwriting_input(&self.output.join(baked), &input.display().to_string())
                        .map_err(|e| FileJobError::Refused { error: Box::new(e), job: "baked" })?;
                }
            }
            if let Some(dir) = names.iter().map(|n| self.output.join(n)).find(|p| p.is_dir()) {
                return Err(FileJobError::option(
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

    /// Per clip, what the budget chose and measured, and the texture bytes against
    /// [`BakeOptions::rate`]'s (frames times joints times channels times the element's bytes).
    fn chosen_rates(
        &self,
        animation: &Animation,
        baked: &Baked,
        measured: Vec<budget::Measured>,
    ) -> Result<Vec<ChosenRate>, BakeError> {
        let joints: usize = texture::layout(animation, self.options.texture).iter().map(|(_, width)| width).sum();
        let element = if self.options.format == Format::Png16 { 2 } else { self.options.precision.element().size() };
        let frame_bytes = joints * self.options.texture.channels() * element;
        let mut chosen = Vec::with_capacity(measured.len());
        for ((clip, result), measured) in animation.clips.iter().zip(&baked.clips).zip(measured) {
            let [start, end] = clip.span();
            let (grid, _) = super::clip_frame_grid(start, end, ClipRate::Fit(self.options.rate), result.looping)?;
            chosen.push(ChosenRate {
                clip: clip.name.clone(),
                bytes: result.times.len() * frame_bytes,
                fixed_rate_bytes: grid.count() * frame_bytes,
                measured,
            });
        }
        Ok(chosen)
    }

    /// Reads, bakes and writes one input; the files it wrote come back with the report.
    fn bake_one(
        &self,
        source: &str,
        stem: &str,
        read: impl FnOnce() -> Result<Source, InputError>,
        device: &Device,
        progress: &dyn Progress,
    ) -> (InputReport, Vec<Written>) {
        let start = Instant::now();
        let mut report = InputReport::new(source);
        let result = read().map_err(BakeError::from).and_then(|src| {
            let animation = src.animation();
            report.clips = animation.clips.len();
            report.channels = animation.clips.iter().map(|c| c.channels.len()).sum();
            report.keys = animation.key_count();
            if animation.clips.is_empty() {
                return Err(InputError::from(AnimationError::NothingAnimated).into());
            }
            report.warnings = super::source_step_warnings(animation);
            if src.has_offsets() {
                report.rig = Some(super::texture::rig_extent(animation)?);
            }
            // Checked before the curves are baked; what a skin texture draws, for the sidecar.
            let mut skinned = Vec::new();
            let vertex = match (src.gltf(), self.options.texture) {
                (Some(file), TextureKind::Vertex) => {
                    let drawn = mesh::skinned_primitives(file)?;
                    report.not_drawn = drawn.not_drawn;
                    Some(VertexSheets::new(drawn.primitives, self.options.format != Format::Npy))
                }
                (None, TextureKind::Vertex) => return Err(Refusal::VertexNeedsGltf(src.kind()).into()),
                (Some(file), kind) if kind.is_skin() => {
                    let drawn = self.skin_primitives(file)?;
                    (report.not_drawn, skinned) = (drawn.not_drawn, drawn.primitives);
                    None
                }
                _ => None,
            };
            if !report.not_drawn.is_empty() {
                report.warnings.push(format!(
                    "{} mesh{} not drawn by a {} texture: {} (the baked glTF plays {}; a model texture holds the \
                     nodes' transforms)",
                    report.not_drawn.len(),
                    if report.not_drawn.len() == 1 { " is" } else { "es are" },
                    self.options.texture,
                    report.not_drawn.join("; "),
                    if report.not_drawn.len() == 1 { "it" } else { "them" },
                ));
            }
            let needs_space = self.options.texture != TextureKind::Local
                || self.options.max_error_cm.is_some()
                || self.options.preview
                || self.options.root_motion == RootMotion::Extract;
            if needs_space {
                src.require_offsets(
                    "positions and headings",
                    "bake local textures, without a millimetre budget, previews or root motion extracted",
                )?;
            }
            let rate = self.options.clip_rate();
            let (choice, budget) = (self.options.choice(&src), self.options.budget());
            let mut baked = if budget.is_set() {
                let setting = budget::Setting {
                    curve: &choice,
                    looping: self.options.looping,
                    kind: self.options.texture,
                    precision: self.options.precision,
                    device,
                    measuring: &|clip, rate| progress.measuring(source, clip, rate),
                };
                let measured = budget::choose_rates(animation, &budget, &setting)?;
                let rates: Vec<ClipRate> = measured.iter().map(|m| ClipRate::Fit(m.rate)).collect();
                let baked = super::bake_each(animation, &choice, &rates, self.options.looping, device)?;
                report.rates = self.chosen_rates(animation, &baked, measured)?;
                baked
            } else {
                super::bake(animation, &choice, rate, self.options.looping, device)?
            };
            if self.options.root_motion == RootMotion::Extract {
                root_motion::extract(animation, &mut baked)?;
            }
            report.warnings.extend(unbaked_ends(animation, &baked));
            report.samples = baked.sample_count();
            report.max_key_error = baked.max_key_error;
            // The device that ran this input (auto: the CPU path for a batch the GPU cannot take).
            let used = baked.device.clone().unwrap_or_else(|| device.name());
            let written = self.write_outputs(&src, &baked, &report, &skinned, stem, &used, device, vertex.as_ref());
            report.skinning = vertex.map(|v| v.work());
            written
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

    /// Writes the baked file (GLB or BVH), the textures and the sidecar (with the rates a
    /// budget chose, from `report`); if any write fails, removes the ones already written so
    /// the job leaves nothing partial. Forward kinematics (model and skin textures, previews)
    /// and skinning (`vertex`, for vertex textures) run on `fk_device`, the bake's.
    #[allow(clippy::too_many_arguments)]
    fn write_outputs(
        &self,
        src: &Source,
        baked: &Baked,
        report: &InputReport,
        skinned: &[DeclaredPrimitive],
        stem: &str,
        device: &str,
        fk_device: &Device,
        vertex: Option<&VertexSheets>,
    ) -> Result<Vec<Written>, BakeError> {
        let mut out = Outputs {
            dir: &self.output,
            stem,
            source: &report.source,
            rates: &report.rates,
            not_drawn: &report.not_drawn,
            skinned,
            written: Vec::new(),
            atlas: Vec::new(),
            rows: 0,
            clip_names: Vec::new(),
            sheets: Vec::new(),
        };
        match self.write_all(&mut out, src, baked, device, fk_device, vertex) {
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
        vertex: Option<&VertexSheets>,
    ) -> Result<(), BakeError> {
        let (animation, dir, stem) = (src.animation(), out.dir, out.stem);
        // Checked before anything is written.
        let order = animation.parents_first()?;
        if self.options.texture.is_skin() && src.gltf().is_some() && animation.skins.is_empty() {
            return Err(Refusal::NoSkin.into());
        }
        if self.options.format == Format::Babylon && (src.gltf().is_none() || animation.skins.is_empty()) {
            return Err(Refusal::BabylonNeedsSkin(src.kind()).into());
        }
        let skinned = out.skinned;
        out.sheets = self.sheets(animation, vertex, skinned)?;
        let slerped = self.options.choice(src) == CurveChoice::Source;
        let baked_file =
            src.write_back(&baked.frames(), slerped)?.map(|file| (format!("{stem}.{}", file.extension), file.bytes));
        let usd_file = if self.options.usd {
            // The meshes a skin draws, as a vertex texture reads them (none without a skin).
            let read = match (vertex, src.gltf()) {
                (None, Some(file)) if !animation.skins.is_empty() => mesh::skinned_primitives(file)?.primitives,
                _ => Vec::new(),
            };
            let meshes = vertex.map_or(&read[..], |v| &v.primitives[..]);
            let metres = self.options.unit_cm.unwrap_or(quatcurve_anim::GLTF_UNIT_CM) / 100.0;
            let stage = super::usd::stage(animation, &order, meshes, baked, stem, metres, self.options.rate);
            Some((format!("{stem}.usda"), stage.into_bytes()))
        } else {
            None
        };
        let mesh_file = match vertex {
            Some(vertex) => Some((
                format!("{stem}{MESH_GLB_SUFFIX}"),
                vertex_glb::write(&vertex.primitives, self.options.max_texture_size)?,
            )),
            None => None,
        };
        for (name, bytes) in baked_file.iter().chain(&mesh_file).chain(&usd_file) {
            let path = dir.join(name);
            refuse_overwriting_input(&path, out.source)?;
            write_atomic(&path, |w| w.write_all(bytes)).map_err(OutputError::from)?;
            out.written.push(path.into());
        }
        // An atlas stacks every clip's frames in one file per sheet, opened with its whole shape.
        let extension = self.options.format.extension();
        if self.options.atlas {
            let rows = baked.clips.iter().map(|c| c.times.len()).sum();
            out.atlas =
                texture_file::open(&out.sheets, &self.texture_options(), rows, "the atlas of every clip", |suffix| {
                    dir.join(format!("{stem}{suffix}.{extension}"))
                })?;
        }
        out.clip_names = clip_file_names(animation);
        let clips = (0..animation.clips.len())
            .map(|index| self.write_clip(out, animation, baked, &order, index, fk_device, vertex))
            .collect::<Result<Vec<_>, _>>()?;
        texture_file::finish_all(std::mem::take(&mut out.atlas), &mut out.written)?;
        let budget = self.options.budget();
        let options = SidecarOptions {
            device,
            curve: if animation.is_fitted() { super::FITTED_CURVE } else { self.options.choice(src).name() },
            rate: self.options.rate,
            texture: self.options.texture,
            precision: self.options.precision,
            format: self.options.format,
            atlas: self.options.atlas,
            max_error: budget.is_set().then_some(&budget),
        };
        let baked_file = baked_file.map(|(name, _)| name);
        let vertex = vertex.zip(mesh_file.map(|(name, _)| name));
        let mut sidecar =
            Sidecar::new(&options, animation, baked, out.source, baked_file, clips, &out.written, vertex, skinned)?;
        sidecar.conversion = src.conversion().map(ConversionRecord::from);
        let record = |(name, written): (String, &str)| ArrayRecord { name, written: written.to_string() };
        sidecar.arrays = src.arrays().into_iter().map(record).collect();
        sidecar.not_drawn = out.not_drawn.to_vec();
        let path = dir.join(format!("{stem}.json"));
        write_atomic(&path, |w| serde_json::to_writer_pretty(&mut *w, &sidecar).map_err(std::io::Error::from))
            .map_err(OutputError::from)?;
        out.written.push(path.into());
        Ok(())
    }

    /// Clip `index`'s textures (or its rows of the atlas) and preview; its sidecar entry.
    #[allow(clippy::too_many_arguments)]
    fn write_clip(
        &self,
        out: &mut Outputs<'_>,
        animation: &Animation,
        baked: &Baked,
        order: &[usize],
        index: usize,
        fk_device: &Device,
        vertex: Option<&VertexSheets>,
    ) -> Result<SidecarClip, BakeError> {
        let (clip, result, dir, stem) = (&animation.clips[index], &baked.clips[index], out.dir, out.stem);
        let file_name = out.clip_names[index].clone();
        let frames = result.times.len();
        let preview = if self.options.preview {
            // Forward kinematics of the drawn frames alone.
            let picks = texture::preview_frames(frames);
            let model = texture::sheet_rows(animation, order, baked, index, TextureKind::Model, fk_device, &picks)?
                .swap_remove(0)
                .data;
            let name = format!("{stem}.{file_name}.preview.png");
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
        // The clip's sheets for a block of its frames, and the shear they dropped.
        let (mut signs, mut shear) = (texture::Signs::default(), 0.0f64);
        let rows = |frames: &[usize]| match vertex {
            Some(vertex) => vertex.rows(animation, order, baked, index, fk_device, frames),
            None => {
                let mut sheets =
                    texture::sheet_rows(animation, order, baked, index, self.options.texture, fk_device, frames)?;
                signs.follow(self.options.texture, &mut sheets);
                shear = sheets.iter().map(|s| s.shear).fold(shear, f64::max);
                Ok(sheets)
            }
        };
        let (files, first_row) = if self.options.atlas {
            texture_file::stream(frames, rows, &mut out.atlas)?;
            out.rows += frames;
            (out.atlas.iter().map(TextureFile::name).collect::<Vec<_>>(), out.rows - frames)
        } else {
            let what = format!("clip '{}'", clip.name);
            let extension = self.options.format.extension();
            let mut textures = texture_file::open(&out.sheets, &self.texture_options(), frames, &what, |suffix| {
                dir.join(format!("{stem}.{file_name}{suffix}.{extension}"))
            })?;
            texture_file::stream(frames, rows, &mut textures)?;
            let names = textures.iter().map(TextureFile::name).collect();
            texture_file::finish_all(textures, &mut out.written)?;
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
            looping: result.closes(),
            preview,
            between_frames: out.rates.get(index).cloned(),
            root_motion: baked.in_place(index).map(|p| p.track.clone()),
            dropped_shear: self.options.texture.is_rigid().then_some(shear),
        })
    }
}

#[cfg(feature = "plot")]
fn draw_preview(
    path: &Path,
    title: &str,
    model: &[f32],
    picks: &[usize],
    animation: &Animation,
) -> Result<(), BakeError> {
    Ok(quatcurve_plot::skeleton(path, title, model, picks, animation)?)
}

#[cfg(not(feature = "plot"))]
fn draw_preview(_: &Path, _: &str, _: &[f32], _: &[usize], _: &Animation) -> Result<(), BakeError> {
    // validate() refuses previews without the feature.
    Err(InputError::from(OutputError::NotBuilt { what: "previews", feature: "plot" }).into())
}

/// The file name after an input's stem of the mesh a vertex texture plays
/// (skinned primitives as plain meshes, DESIGN section 8).
pub const MESH_GLB_SUFFIX: &str = ".mesh.glb";

/// Removes the temporary files a killed run of this shard left in `dir`
/// ([`quatcurve_eval::io::temporary_target`] names the file each was to become): its manifest's,
/// and those of an output of one of its inputs (the input whose stem, of the job's `stems`, is
/// the longest that begins the file's name followed by a dot). Another shard's, which may be
/// running, are left alone. Returns how many were removed.
fn remove_stale_temporaries(dir: &Path, stems: &[&str], shard: &Shard, manifest: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else { return 0 };
    let manifest = manifest.file_name().map(|n| n.to_string_lossy().into_owned());
    let owner = |target: &str| {
        (0..stems.len())
            .filter(|&k| target.strip_prefix(stems[k]).is_some_and(|rest| rest.starts_with('.')))
            .max_by_key(|&k| stems[k].len())
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(target) = quatcurve_eval::io::temporary_target(&name) else { continue };
        let mine = manifest.as_deref() == Some(target) || owner(target).is_some_and(|k| shard.owns(k));
        if mine && std::fs::remove_file(entry.path()).is_ok() {
            removed += 1;
        }
    }
    removed
}

fn write_manifest(manifest: &mut Manifest, path: &Path) -> Result<(), FileJobError> {
    manifest.updated = super::manifest::now();
    write_atomic(path, |w| serde_json::to_writer_pretty(&mut *w, manifest).map_err(std::io::Error::from))
        .map_err(FileJobError::Manifest)
}
