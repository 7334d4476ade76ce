//! `quatcurve bake`: resample glTF/GLB and BVH files (or the built-in crowd) at a new rate.
//!
//! Per input file: read, bake every clip, then write all of that file's outputs atomically;
//! a failure in one file is reported and the others still finish (exit non-zero at the end).

use super::manifest::{hash_bytes, hash_file, hash_parts, FileRecord, InputRecord, Manifest, ShardRecord};
use super::shard::Shard;
use super::{names, print_stdout, CurveArgs, DeviceArgs, Failure};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use quatcurve::bake::texture::{self, Precision, TextureKind};
use quatcurve::bake::{self, bvh, crowd, gltf, Animation, Baked, LoopMode};
use quatcurve::io::{write_atomic, Npy};
use quatcurve::{Curve, CurveSpec, Device, KnotMode};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct BakeArgs {
    /// Input files (.gltf, .glb, .bvh) or directories of them; without it, the built-in
    /// synthetic crowd.
    #[arg(long, num_args = 1..)]
    input: Vec<PathBuf>,
    /// Output rate in Hz.
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    rate: f64,
    /// Curve family; the default, bspline-interp, is C2 and passes through every key.
    #[arg(long, default_value = "bspline-interp", value_parser = names::<Curve>())]
    curve: Curve,
    /// Which clips loop: auto (those whose rotation channels end on their first rotation),
    /// on (every clip; one that does not close is an error), off.
    #[arg(long = "loop", default_value = "auto", value_parser = names::<LoopMode>())]
    looping: LoopMode,
    #[command(flatten)]
    options: CurveArgs,
    #[command(flatten)]
    device: DeviceArgs,
    /// Read glTF buffers from anywhere the URI points (absolute paths, `..` out of the file's
    /// directory, `file:` URIs). Off by default: only data URIs and files beside the input.
    #[arg(long)]
    allow_external_uris: bool,
    /// Texture per clip: local (rotation, translation, scale of each joint relative to its
    /// parent), model (3x4 matrices relative to the scene root, by forward kinematics) or skin
    /// (model times inverse bind matrix, one texture per glTF skin; BVH and the crowd: model).
    #[arg(long, default_value = "local", value_parser = names::<TextureKind>())]
    texture: TextureKind,
    /// Texture element type: f32, or f16 (half the bytes, about 3 significant digits).
    #[arg(long, default_value = "f32", value_parser = names::<Precision>())]
    precision: Precision,
    /// One texture per input with every clip stacked along frames (`<stem>.npy`; each clip's
    /// rows from `first_row` in the sidecar), instead of one per clip.
    #[arg(long)]
    atlas: bool,
    /// Also draw each clip's skeleton at evenly spaced frames, front and side views, to
    /// `<stem>.<clip>.png`.
    #[arg(long)]
    preview: bool,
    /// Output directory (created if missing).
    #[arg(long, default_value = "baked")]
    output: PathBuf,
    /// Characters in the built-in crowd.
    #[arg(long, default_value_t = crowd::CHARACTERS)]
    characters: usize,
    /// Bake only this share of the inputs, I/N (0-based): inputs sorted by path, file k
    /// belongs to shard k mod N. Without it, the array index Slurm, Kubernetes, AWS Batch or
    /// Google Batch sets (README "Large jobs"); else the whole job.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Skip inputs that this shard's manifest records as baked with the same options from
    /// the same bytes, whose outputs are still intact (size and SHA-256).
    #[arg(long)]
    resume: bool,
    /// Inputs read, baked and written at once (each bake also uses every core).
    #[arg(long, default_value_t = 1, value_name = "N")]
    jobs: usize,
}

/// What one input became.
struct Row {
    source: String,
    clips: usize,
    channels: usize,
    keys: usize,
    samples: usize,
    seconds: f64,
    max_key_error: Option<f64>,
    outcome: Result<Vec<Written>, Failure>,
    /// Skipped by `--resume`: the earlier run's outputs were verified and kept.
    resumed: bool,
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
    /// First row (frame) of the clip in `file`: 0, or its place in the `--atlas` texture.
    first_row: usize,
    frames: usize,
    start: f64,
    end: f64,
    /// Frames per second: `--rate`, or for a loop the nearest rate that fits a whole number
    /// of frames in its period.
    rate: f64,
    /// Baked as a loop: periodic curves, continuous across the seam.
    #[serde(rename = "loop")]
    looping: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    preview: Option<String>,
}

pub fn run(args: &BakeArgs) -> Result<(), Failure> {
    if !(args.rate.is_finite() && args.rate > 0.0) {
        return Err(Failure::Input(format!("--rate must be a positive number of Hz, not {}", args.rate)));
    }
    let spec = args.options.spec(args.curve, KnotMode::Phantom, false);
    let shard = Shard::resolve(args.shard.as_deref(), &|name| std::env::var(name).ok())?;
    let inputs = expand(&args.input)?;
    // Over the whole job, so every shard refuses the same clashes.
    let stems = output_stems(&inputs, &args.output)?;
    let output = OutputDir::create(&args.output)?;
    let device = Device::open(args.device.device)?;
    let device_name = device.name();
    let options = options_record(args);
    let manifest_path = shard.manifest_path(&args.output);
    let previous = if args.resume { Manifest::load(&manifest_path) } else { None };
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
    let crowd_name = format!("built-in crowd: {} x {} joints, {} s", args.characters, crowd::JOINTS, crowd::SECONDS);
    let jobs: Vec<(String, &str, Option<&Path>)> = if args.input.is_empty() {
        vec![(crowd_name, "crowd", None)]
    } else {
        inputs.iter().zip(&stems).map(|(p, s)| (p.display().to_string(), s.as_str(), Some(p.as_path()))).collect()
    };
    let mine: Vec<_> = jobs.into_iter().enumerate().filter(|(k, _)| shard.owns(*k)).map(|(_, job)| job).collect();
    let bar = ProgressBar::new(mine.len() as u64);
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} files, {per_sec} {elapsed} (eta {eta}) {msg}").expect("valid template"));
    let started = Instant::now();
    let samples = AtomicUsize::new(0);
    // One input: verify and keep (--resume), or read, bake and write.
    let process = |(name, stem, path): &(String, &str, Option<&Path>)| -> (Row, InputRecord) {
        bar.set_message(format!("{:.1} M samples/s {name}", samples.load(Ordering::Relaxed) as f64 / started.elapsed().as_secs_f64().max(1e-9) / 1e6));
        let fingerprint = match path {
            Some(path) => hash_file(path).unwrap_or((0, String::new())),
            None => (0, hash_bytes(options.to_string().as_bytes())),
        };
        let kept = previous.as_ref().and_then(|m| m.resumable(&options, name, fingerprint.0, &fingerprint.1, &args.output));
        let row = match (kept, path) {
            (Some(record), _) => resumed_row(name, record, &args.output),
            (None, Some(path)) => bake_one(name, stem, || read(path, args), args, &spec, &device),
            (None, None) => bake_one(name, stem, || Ok(Source::Crowd(crowd::crowd(args.characters))), args, &spec, &device),
        };
        samples.fetch_add(row.samples, Ordering::Relaxed);
        let record = input_record(&row, fingerprint, kept);
        bar.inc(1);
        (row, record)
    };
    // Kept current while the job runs, so a killed task resumes from where it was.
    let (last_write, write_error) = (Mutex::new(Instant::now()), Mutex::new(None));
    let results = in_order(&mine, args.jobs, process, |done| {
        let mut last = last_write.lock().unwrap_or_else(|e| e.into_inner());
        if last.elapsed().as_secs_f64() > 2.0 {
            let mut partial = Manifest { inputs: done.iter().flatten().map(|(_, r)| r.clone()).collect(), ..manifest.clone() };
            if let Err(e) = write_manifest(&mut partial, &manifest_path) {
                *write_error.lock().unwrap_or_else(|e| e.into_inner()) = Some(e);
            }
            *last = Instant::now();
        }
    });
    bar.finish_and_clear();
    if let Some(e) = write_error.into_inner().unwrap_or_else(|e| e.into_inner()) {
        return Err(e);
    }
    let (rows, records): (Vec<Row>, Vec<InputRecord>) = results.into_iter().unzip();
    manifest.inputs = records;
    // A record of what was done, unless nothing was (a failed job leaves nothing behind).
    if rows.iter().any(|r| r.outcome.is_ok()) {
        write_manifest(&mut manifest, &manifest_path)?;
    }
    output.remove_if_unused();
    print_stdout(|w| summary(w, &rows, &device_name, args, &shard, inputs.len().max(1)))?;
    let failed: Vec<&Row> = rows.iter().filter(|r| r.outcome.is_err()).collect();
    if failed.is_empty() {
        return Ok(());
    }
    for row in &failed {
        if let Err(Failure::Input(msg) | Failure::Internal(msg)) = &row.outcome {
            eprintln!("error: {}: {msg}", row.source);
        }
    }
    let summary = format!("{} of {} inputs failed (the others were baked)", failed.len(), rows.len());
    Err(if failed.iter().any(|r| matches!(r.outcome, Err(Failure::Internal(_)))) { Failure::Internal(summary) } else { Failure::Input(summary) })
}

/// `work` over `items` on `jobs` threads (`--jobs`), taking items in order; the results come
/// back in item order whatever finishes first, so nothing written depends on timing.
/// `progress` sees every slot (finished or not) after each item; it should be cheap unless
/// it acts (the manifest writer checks the time first).
fn in_order<I: Sync, R: Send>(items: &[I], jobs: usize, work: impl Fn(&I) -> R + Sync, progress: impl Fn(&[Option<R>]) + Sync) -> Vec<R> {
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

/// The options that decide a bake's outputs (the manifest's `options`; `--resume` redoes
/// everything when they differ).
fn options_record(args: &BakeArgs) -> serde_json::Value {
    let o = &args.options;
    serde_json::json!({
        "curve": args.curve.name(), "order": o.order, "knots": o.knots.map(|k| k.name()), "tangents": o.tangents.name(),
        "blend": o.blend.name(), "loop": args.looping.name(), "rate": args.rate, "device": args.device.device.name(),
        "allow_external_uris": args.allow_external_uris, "characters": args.characters,
        "texture": args.texture.name(), "precision": args.precision.name(), "atlas": args.atlas, "preview": args.preview,
    })
}

fn write_manifest(manifest: &mut Manifest, path: &Path) -> Result<(), Failure> {
    manifest.updated = super::manifest::now();
    write_atomic(path, |w| serde_json::to_writer_pretty(&mut *w, manifest).map_err(std::io::Error::from)).map_err(|e| Failure::Input(e.to_string()))
}

/// An input `--resume` skips: the earlier run's record, its outputs verified intact.
fn resumed_row(name: &str, record: &InputRecord, dir: &Path) -> Row {
    let files = record.outputs.iter().map(|o| Written::from(dir.join(&o.file))).collect();
    Row { source: name.to_string(), clips: 0, channels: 0, keys: 0, samples: 0, seconds: 0.0, max_key_error: None, outcome: Ok(files), resumed: true }
}

/// The manifest entry of a finished row.
fn input_record(row: &Row, (size, sha256): (u64, String), kept: Option<&InputRecord>) -> InputRecord {
    let (status, error, outputs) = match (&row.outcome, kept) {
        (Ok(_), Some(kept)) => ("resumed", None, kept.outputs.clone()),
        (Ok(files), None) => {
            let record = |w: &Written| {
                let file = w.path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
                match &w.hash {
                    Some((size, sha256)) => Ok(FileRecord { file, size: *size, sha256: sha256.clone() }),
                    None => FileRecord::of(&w.path, file),
                }
            };
            match files.iter().map(record).collect::<std::io::Result<Vec<_>>>() {
                Ok(outputs) => ("ok", None, outputs),
                Err(e) => ("failed", Some(format!("cannot hash an output: {e}")), Vec::new()),
            }
        }
        (Err(Failure::Input(msg) | Failure::Internal(msg)), _) => ("failed", Some(msg.clone()), Vec::new()),
    };
    InputRecord { path: row.source.clone(), size, sha256, status: status.into(), error, seconds: row.seconds, outputs }
}

/// The output directory, created for the job; if this job created it (and any missing
/// parents) and wrote nothing into it, [`Self::remove_if_unused`] takes them away again, so a
/// failed job leaves nothing behind.
struct OutputDir {
    /// Directories this job created, deepest first.
    created: Vec<PathBuf>,
}

impl OutputDir {
    fn create(dir: &Path) -> Result<Self, Failure> {
        let created: Vec<PathBuf> = dir.ancestors().take_while(|a| !a.as_os_str().is_empty() && !a.exists()).map(Path::to_path_buf).collect();
        std::fs::create_dir_all(dir).map_err(|e| Failure::Input(format!("--output {}: cannot create the directory: {e}", dir.display())))?;
        Ok(Self { created })
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
fn expand(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, Failure> {
    let known = |p: &Path| matches!(p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref(), Some("gltf" | "glb" | "bvh"));
    let mut files = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let entries = std::fs::read_dir(input).map_err(|e| Failure::Input(format!("{}: cannot list: {e}", input.display())))?;
            let found: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file() && known(p)).collect();
            if found.is_empty() {
                return Err(Failure::Input(format!("{}: the directory holds no .gltf, .glb or .bvh file", input.display())));
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
fn output_stems(inputs: &[PathBuf], output: &Path) -> Result<Vec<String>, Failure> {
    let stems: Vec<String> = inputs.iter().map(|p| p.file_stem().map_or_else(|| "out".into(), |s| s.to_string_lossy().into_owned())).collect();
    let mut seen: std::collections::HashMap<&str, &Path> = std::collections::HashMap::new();
    for (stem, path) in stems.iter().zip(inputs) {
        if let Some(first) = seen.insert(stem, path) {
            return Err(Failure::Input(format!(
                "{} and {} would both write {}; bake them into separate --output directories",
                first.display(),
                path.display(),
                output.join(format!("{stem}.*")).display()
            )));
        }
    }
    Ok(stems)
}

fn read(path: &Path, args: &BakeArgs) -> Result<Source, Failure> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("gltf" | "glb") => Ok(Source::Gltf(Box::new(gltf::read(path, gltf::UriPolicy { allow_external: args.allow_external_uris })?))),
        Some("bvh") => {
            let file = bvh::read(path)?;
            let name = path.file_stem().map_or_else(|| "motion".into(), |s| s.to_string_lossy().into_owned());
            let animation = file.animation(&name);
            Ok(Source::Bvh(file, animation))
        }
        _ => Err(Failure::Input("unknown format: expected .gltf, .glb or .bvh".into())),
    }
}

fn bake_one(
    source: &str,
    stem: &str,
    read: impl FnOnce() -> Result<Source, Failure>,
    args: &BakeArgs,
    spec: &CurveSpec,
    device: &Device,
) -> Row {
    let start = Instant::now();
    let mut row = Row { source: source.to_string(), clips: 0, channels: 0, keys: 0, samples: 0, seconds: 0.0, max_key_error: None, outcome: Ok(Vec::new()), resumed: false };
    let result = read().and_then(|src| {
        let animation = src.animation();
        row.clips = animation.clips.len();
        row.channels = animation.clips.iter().map(|c| c.channels.len()).sum();
        row.keys = animation.key_count();
        if animation.clips.is_empty() {
            return Err(Failure::Input("no rotation, translation or scale animation to bake".into()));
        }
        let baked = bake::bake(animation, spec, args.rate, args.looping, device)?;
        row.samples = baked.sample_count();
        row.max_key_error = baked.max_key_error;
        // The device that ran this input (auto: the CPU path for a batch the GPU cannot take).
        let used = baked.device.clone().unwrap_or_else(|| device.name());
        write_outputs(&src, &baked, source, stem, args, &used, device)
    });
    row.seconds = start.elapsed().as_secs_f64();
    row.outcome = result;
    row
}

/// Writes the baked file (GLB or BVH), one `.npy` texture per clip and the sidecar; if any
/// write fails, removes the ones already written so the job leaves nothing partial.
/// Forward kinematics (model and skin textures, previews) runs on `fk_device`, the bake's.
fn write_outputs(src: &Source, baked: &Baked, source: &str, stem: &str, args: &BakeArgs, device: &str, fk_device: &Device) -> Result<Vec<Written>, Failure> {
    let animation = src.animation();
    let dir = &args.output;
    let mut written: Vec<Written> = Vec::new();
    let result = (|| {
        // Checked before anything is written.
        let order = animation.parents_first()?;
        if args.texture == TextureKind::Skin && matches!(src, Source::Gltf(_)) && animation.skins.is_empty() {
            return Err(Failure::Input("--texture skin: the file has no skin; use --texture model".into()));
        }
        let baked_file = match src {
            Source::Gltf(file) => Some((format!("{stem}.glb"), file.to_glb(baked)?)),
            Source::Bvh(file, animation) => Some((format!("{stem}.bvh"), file.to_text(&animation.clips[0], baked).into_bytes())),
            Source::Crowd(_) => None,
        };
        if let Some((name, bytes)) = &baked_file {
            let path = dir.join(name);
            refuse_overwriting_input(&path, source)?;
            write_atomic(&path, |w| w.write_all(bytes)).map_err(|e| Failure::Input(e.to_string()))?;
            written.push(path.into());
        }
        let channels = args.texture.channels();
        let write_sheet = |name: &str, frames: usize, width: usize, data: &[f32]| -> Result<Written, Failure> {
            let path = dir.join(name);
            let shape = [frames as u64, width as u64, channels as u64];
            let failed = |e: std::io::Error| Failure::Input(format!("{}: cannot write: {e}", path.display()));
            let npy = match args.precision {
                Precision::F32 => Npy::f32(&shape, data),
                Precision::F16 => Npy::f16(&shape, data),
            }
            .map_err(failed)?;
            // The manifest's SHA-256 on another core while the bytes go to disk.
            let (sha256, result) = std::thread::scope(|s| {
                let sha256 = s.spawn(|| hash_parts(&[&npy.header, &npy.body]));
                (sha256.join(), write_atomic(&path, |w| npy.write(w)))
            });
            result.map_err(|e| Failure::Input(e.to_string()))?;
            // Written but not recorded: taken away again, as every output of a failed input is.
            let sha256 = sha256.map_err(|_| {
                let _ = std::fs::remove_file(&path);
                Failure::Internal(format!("{}: hashing failed", path.display()))
            })?;
            Ok(Written { path, hash: Some((npy.len() as u64, sha256)) })
        };
        let mut clips = Vec::new();
        // --atlas: per sheet, every clip's rows.
        let mut atlas: Vec<texture::Sheet> = Vec::new();
        let mut first_row = 0;
        for (index, (clip, result)) in animation.clips.iter().zip(&baked.clips).enumerate() {
            let frames = result.times.len();
            // Forward kinematics once per clip, for the textures and the preview alike.
            let local = texture::local(animation, baked, index);
            let model = if args.texture != TextureKind::Local || args.preview { Some(texture::model_on(fk_device, animation, &order, &local)?) } else { None };
            let preview = match &model {
                Some(model) if args.preview => {
                    let name = format!("{stem}.{index}.png");
                    super::plot::skeleton(&dir.join(&name), &format!("{source}: clip '{}'", clip.name), model, animation, frames).map_err(Failure::Input)?;
                    written.push(dir.join(&name).into());
                    Some(name)
                }
                _ => None,
            };
            let clip_sheets = texture::arrange(animation, &order, args.texture, local, model);
            let mut files = Vec::new();
            for (k, sheet) in clip_sheets.iter().enumerate() {
                let suffix = &sheet.suffix;
                if args.atlas {
                    files.push(format!("{stem}{suffix}.npy"));
                    match atlas.get_mut(k) {
                        Some(rows) => rows.data.extend_from_slice(&sheet.data),
                        None => atlas.push(sheet.clone()),
                    }
                } else {
                    let name = format!("{stem}.{index}{suffix}.npy");
                    written.push(write_sheet(&name, frames, sheet.width, &sheet.data)?);
                    files.push(name);
                }
            }
            let (start, end) = (result.times[0], result.times[frames - 1]);
            clips.push(SidecarClip {
                name: clip.name.clone(),
                file: files[0].clone(),
                files,
                first_row: if args.atlas { first_row } else { 0 },
                frames,
                start,
                end,
                rate: result.rate,
                looping: result.looping,
                preview,
            });
            first_row += frames;
        }
        for sheet in &atlas {
            written.push(write_sheet(&format!("{stem}{}.npy", sheet.suffix), first_row, sheet.width, &sheet.data)?);
        }
        let names = args.texture.channel_names().join(",");
        let layout = match (args.atlas, args.texture) {
            (false, TextureKind::Skin) if !animation.skins.is_empty() => format!("per clip and skin: [frames, skin joints, {channels}] {}: {names}", args.precision),
            (false, _) => format!("per clip: [frames, joints, {channels}] {}: {names}", args.precision),
            (true, _) => format!("one atlas: [frames of every clip, joints, {channels}] {}: {names}; clip rows from first_row", args.precision),
        };
        let sidecar = Sidecar {
            source,
            curve: args.curve.name(),
            rate: args.rate,
            device,
            texture: args.texture.name(),
            channels: args.texture.channel_names(),
            precision: args.precision.name(),
            layout,
            max_key_error_rad: baked.max_key_error,
            baked_file: baked_file.map(|(name, _)| name),
            joints: animation.joints.iter().map(|j| j.name.as_str()).collect(),
            parents: animation.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i64)).collect(),
            rest: animation.joints.iter().map(|j| Rest { translation: j.translation, rotation: j.rotation, scale: j.scale }).collect(),
            skins: animation.skins.iter().map(|s| SidecarSkin { name: &s.name, joints: &s.joints }).collect(),
            clips,
        };
        let path = dir.join(format!("{stem}.json"));
        write_atomic(&path, |w| serde_json::to_writer_pretty(&mut *w, &sidecar).map_err(std::io::Error::from))
            .map_err(|e| Failure::Input(e.to_string()))?;
        written.push(path.into());
        Ok(())
    })();
    match result {
        Ok(()) => Ok(written),
        Err(e) => {
            for file in &written {
                let _ = std::fs::remove_file(&file.path);
            }
            Err(e)
        }
    }
}

/// Baking into the input's own directory must not replace the input.
fn refuse_overwriting_input(output: &Path, source: &str) -> Result<(), Failure> {
    let same = match (std::fs::canonicalize(output), std::fs::canonicalize(source)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same {
        return Err(Failure::Input(format!("{} would overwrite the input; choose another --output directory", output.display())));
    }
    Ok(())
}

fn summary(w: &mut dyn std::io::Write, rows: &[Row], device: &str, args: &BakeArgs, shard: &Shard, inputs: usize) -> std::io::Result<()> {
    writeln!(w, "baked at {} Hz with {} on {device} -> {}", args.rate, args.curve, args.output.display())?;
    if shard.count > 1 {
        writeln!(w, "shard {} of {} ({}): {} of {inputs} inputs", shard.index, shard.count, shard.source, rows.len())?;
    }
    writeln!(w, "{:<44} {:>5} {:>8} {:>9} {:>11} {:>8} {:>14}  status", "input", "clips", "channels", "keys in", "samples out", "seconds", "key error rad")?;
    for r in rows {
        let error = r.max_key_error.map_or_else(|| "-".to_string(), |e| format!("{e:.2e}"));
        let status = match &r.outcome {
            Ok(files) if r.resumed => format!("ok (resumed: {} files intact)", files.len()),
            Ok(files) => format!("ok ({} files)", files.len()),
            Err(Failure::Input(_)) => "FAILED (input)".to_string(),
            Err(Failure::Internal(_)) => "FAILED (device)".to_string(),
        };
        let chars = r.source.chars().count();
        let name = if chars > 44 { format!("...{}", r.source.chars().skip(chars - 41).collect::<String>()) } else { r.source.clone() };
        writeln!(w, "{name:<44} {:>5} {:>8} {:>9} {:>11} {:>8.2} {:>14}  {status}", r.clips, r.channels, r.keys, r.samples, r.seconds, error)?;
    }
    Ok(())
}
