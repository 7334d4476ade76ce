//! `quatcurve play`: a crowd played from a file's curves (DESIGN section 17), every frame's
//! skin palettes written as `[frames, instances, joints, 12]` in one `.npy`.

use super::{names, open_device, CurveOptions, Failure};
use clap::Args;
use quatcurve::anim::curves::CurveChoice;
use quatcurve::anim::loops::LoopMode;
use quatcurve::bake::usd::CrowdInstance;
use quatcurve::curve::Curve;
use quatcurve::formats::gltf::GltfFile;
use quatcurve::formats::mesh::skinned_primitives;
use quatcurve::formats::source::{importer, Source};
use quatcurve::io::{npy_header, AtomicFile, NpyElement};
use quatcurve::output::LOCAL_CHANNELS;
use quatcurve::play::error::PlayError;
use quatcurve::play::schedule::Schedule;
use quatcurve::play::{skin_by_name, Playback, PALETTE_CHANNELS};
use quatcurve::DeviceChoice;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

/// Most floats one palette file may hold (4 GiB): the frames, instances and joints asked for
/// are counted before anything is evaluated.
pub const MAX_PALETTE_FLOATS: u64 = 1 << 30;

/// How far below a whole number of frames `--seconds` times `--rate` may fall and still count
/// it.
const FRAME_ROUNDING: f64 = 1e-9;

#[derive(Args, Debug)]
pub struct PlayArgs {
    /// The file whose clips are played (.gltf, .glb, .fbx, .usd/.usda/.usdc/.usdz, .bvh, .npz, .qcf).
    #[arg(long)]
    input: PathBuf,
    /// Instances per frame; instance i plays clip i mod clips from phase frac(i * 0.618...) of
    /// its span (instance 0: clip 0 from its start).
    #[arg(long, default_value_t = 1)]
    instances: usize,
    /// Frames per second.
    #[arg(long, value_name = "HZ", default_value_t = quatcurve::DEFAULT_RATE, allow_negative_numbers = true)]
    rate: f64,
    /// Seconds played: frames 0 .. floor(seconds * rate), both ends included.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    seconds: f64,
    /// Blend every instance towards a second pose with this weight in [0, 1]: the blend clip
    /// at the same phase of its span as the instance's own clip (the viewer's rule).
    #[arg(long, value_name = "WEIGHT", allow_negative_numbers = true)]
    blend_weight: Option<f32>,
    /// The clip blended towards, by name or index (default: each instance's next clip, the
    /// same clip for a file of one).
    #[arg(long, value_name = "CLIP", requires = "blend_weight")]
    blend_clip: Option<String>,
    /// The palettes, `[frames, instances, joints, 12]` float32 (each 3x4 row-major, joints in
    /// the skin's order).
    #[arg(long, default_value = "palettes.npy")]
    output: PathBuf,
    /// Which skin's palette, by default the first (a file without skins plays every joint's
    /// model matrix).
    #[arg(long)]
    skin: Option<usize>,
    /// Take the skin from this file (.gltf, .glb, .fbx), its joints matched by name: a fitted
    /// container keeps a glTF's joints and clips, not its skins.
    #[arg(long, value_name = "FILE")]
    skin_from: Option<PathBuf>,
    /// Curve family for every channel; by default each channel as its source plays it, as
    /// bake's.
    #[arg(long, value_parser = names::<Curve>())]
    curve: Option<Curve>,
    #[command(flatten)]
    curve_options: CurveOptions,
    /// Which clips loop: auto, on, off (as bake's).
    #[arg(long = "loop", default_value_t = LoopMode::Auto, value_parser = names::<LoopMode>())]
    looping: LoopMode,
    /// Evaluation device (as bake's).
    #[arg(long, default_value_t = DeviceChoice::Auto, value_parser = names::<DeviceChoice>())]
    device: DeviceChoice,
    /// Also write the crowd as one OpenUSD stage, the output's name with `.usda`: the
    /// character once, each instance an instanced reference to it playing its own
    /// `SkelAnimation` of its poses at every frame.
    #[arg(long)]
    usd: bool,
    /// The length of one file unit in cm, for --usd (as bake's: BVH files and fitted
    /// containers do not say theirs).
    #[arg(long, value_name = "CM", allow_negative_numbers = true)]
    unit_cm: Option<f64>,
}

/// Most local-pose floats a crowd stage may hold (about 0.7 GB of text): counted before
/// anything is evaluated.
pub const MAX_STAGE_FLOATS: u64 = 1 << 26;

pub fn run(args: &PlayArgs) -> Result<(), Failure> {
    if !(args.rate.is_finite() && args.rate > 0.0) {
        return Err(Failure::Input(format!("--rate {} must be a positive number of frames per second", args.rate)));
    }
    if !(args.seconds.is_finite() && args.seconds >= 0.0) {
        return Err(Failure::Input(format!("--seconds {} must be a number of seconds, 0 or more", args.seconds)));
    }
    if let Some(w) = args.blend_weight.filter(|w| !(0.0..=1.0).contains(w)) {
        return Err(Failure::Input(format!("--blend-weight {w} must be a weight in [0, 1]")));
    }
    if args.instances == 0 {
        return Err(Failure::Input("--instances must be 1 or more".into()));
    }
    let input = args.input.display().to_string();
    if let Some(unit) = args.unit_cm.filter(|u| !(u.is_finite() && *u > 0.0)) {
        return Err(Failure::Input(format!("--unit-cm {unit} must be a positive length")));
    }
    let says_unit = importer(&args.input).is_some_and(|i| i.says_unit);
    if args.usd && !says_unit && args.unit_cm.is_none() {
        return Err(Failure::Input(format!(
            "--unit-cm is needed for --usd: {input} does not say its length unit (CMU's BVH is 5.644)"
        )));
    }
    let usd_path = args.output.with_extension("usda");
    if args.usd && usd_path == args.output {
        return Err(Failure::Input(format!("--output {} is where --usd writes its stage", args.output.display())));
    }
    let source = Source::read(&args.input, Default::default()).map_err(|e| Failure::Input(format!("{input}: {e}")))?;
    // Palettes are matrices of positions.
    source
        .require_offsets("the palettes' positions", "bake local textures of it instead")
        .map_err(|e| Failure::Input(format!("{input}: {e}")))?;
    let curve = CurveChoice::new(args.curve.or(source.default_curve()), &args.curve_options);
    let mut animation = source.animation().clone();
    if let Some(path) = &args.skin_from {
        let from = path.display().to_string();
        let other = Source::read(path, Default::default()).map_err(|e| Failure::Input(format!("{from}: {e}")))?;
        let skin = skin_by_name(&animation, other.animation(), args.skin.unwrap_or(0))
            .map_err(|e| Failure::Input(format!("--skin-from {from}: {e}")))?;
        animation.skins = vec![skin];
    }
    let skin = if args.skin_from.is_some() { Some(0) } else { args.skin };
    let playback =
        Playback::new(animation, &curve, args.looping, skin).map_err(|e| Failure::Input(format!("{input}: {e}")))?;
    let blend_clip = match &args.blend_clip {
        Some(given) => Some(
            quatcurve::play::schedule::clip_named(playback.animation(), given)
                .map_err(|e| Failure::Input(format!("--blend-clip: {input}: {e}")))?,
        ),
        None => None,
    };
    // A product meant to be whole (0.7 s at 30 Hz) can round just below it.
    let frames = (args.seconds * args.rate + FRAME_ROUNDING).floor() as u64 + 1;
    let joints = playback.palette_joints();
    let shape = [frames, args.instances as u64, joints as u64, PALETTE_CHANNELS as u64];
    if shape.iter().try_fold(1u64, |a, &d| a.checked_mul(d)).map_or(true, |n| n > MAX_PALETTE_FLOATS) {
        return Err(Failure::Input(format!(
            "{frames} frames of {} instances of {joints} joints are more than {MAX_PALETTE_FLOATS} floats of \
             palettes; play fewer seconds, instances or a lower rate",
            args.instances
        )));
    }
    let pose_floats = shape[0] * shape[1] * (playback.animation().joints.len() * LOCAL_CHANNELS) as u64;
    if args.usd && pose_floats > MAX_STAGE_FLOATS {
        return Err(Failure::Input(format!(
            "{frames} frames of {} instances of {} joints are more than {MAX_STAGE_FLOATS} floats of poses for --usd's \
             text stage; play fewer seconds, instances or a lower rate",
            args.instances,
            playback.animation().joints.len()
        )));
    }
    let device = open_device(args.device, "--device")?;
    // An output that cannot be created is the request's fault (exit 2); one that fails while
    // written, the machine's (exit 1).
    let mut file = AtomicFile::create(&args.output).map_err(|e| Failure::Input(e.to_string()))?;
    let usd_file =
        if args.usd { Some(AtomicFile::create(&usd_path).map_err(|e| Failure::Input(e.to_string()))?) } else { None };
    let io = |e: quatcurve::io::IoError| Failure::Internal(e.to_string());
    file.write_all(&npy_header("<f4", &shape)).map_err(|e| io(file.error(e)))?;
    let schedule = Schedule { instances: args.instances, rate: args.rate, blend: args.blend_weight, blend_clip };
    let failure = |e: PlayError| match e {
        PlayError::Device(d) if d.is_device_failure() => Failure::Internal(format!("{input}: {d}")),
        other => Failure::Input(format!("{input}: {other}")),
    };
    let player = playback.player(&device).map_err(failure)?;
    let started = Instant::now();
    let mut poses = Vec::new();
    for frame in 0..frames as usize {
        let instances = schedule.frame(&playback, frame);
        let palettes = player.palettes(&instances).map_err(failure)?;
        file.write_all(&NpyElement::F32.bytes(&palettes)).map_err(|e| io(file.error(e)))?;
        if usd_file.is_some() {
            poses.extend(playback.local_poses(&device, &instances).map_err(failure)?);
        }
    }
    let seconds = started.elapsed().as_secs_f64();
    if let Some(mut stage_file) = usd_file {
        let stem = args.input.file_stem().map_or_else(|| "character".into(), |s| s.to_string_lossy());
        // A skin taken from another file binds none of this file's meshes.
        let meshes = if args.skin_from.is_none() { source.gltf() } else { None };
        let stage = crowd_stage(meshes, &stem, &playback, &schedule, &poses, args.unit_cm)
            .map_err(|e| Failure::Input(format!("{input}: {e}")))?;
        stage_file.write_all(stage.as_bytes()).map_err(|e| io(stage_file.error(e)))?;
        stage_file.commit().map_err(io)?;
    }
    file.commit().map_err(io)?;
    let per_frame = seconds / frames as f64;
    eprintln!(
        "{input}: {frames} frames of {} instances x {joints} joints on {} in {seconds:.3} s ({:.3} ms a frame, {:.3e} \
         instance-joints/s) -> {}",
        args.instances,
        device.name(),
        per_frame * 1e3,
        (args.instances * joints) as f64 / per_frame,
        args.output.display()
    );
    if args.usd {
        eprintln!("{input}: the crowd as a USD stage -> {}", usd_path.display());
    }
    Ok(())
}

/// The crowd of `schedule` as one USD stage ([`quatcurve::bake::usd::crowd_stage`]): the
/// character `stem` of `playback` (its skeleton, and the skinned meshes of `file`), each
/// instance's clip, phase and blend as at frame 0, and its local `poses` at every frame;
/// lengths in `unit_cm` (else the file's, metres).
fn crowd_stage(
    file: Option<&GltfFile>,
    stem: &str,
    playback: &Playback,
    schedule: &Schedule,
    poses: &[f32],
    unit_cm: Option<f64>,
) -> Result<String, quatcurve::anim::error::InputError> {
    let animation = playback.animation();
    let meshes = match file {
        Some(file) if !animation.skins.is_empty() => skinned_primitives(file)?.primitives,
        _ => Vec::new(),
    };
    let name = |clip: usize| animation.clips[clip].name.clone();
    let instances: Vec<CrowdInstance> = schedule
        .frame(playback, 0)
        .iter()
        .map(|i| CrowdInstance {
            clip: name(i.first.clip),
            phase: i.first.time,
            blend: i.second.map(|(pose, weight)| (name(pose.clip), weight)),
        })
        .collect();
    let metres = unit_cm.unwrap_or(quatcurve::anim::GLTF_UNIT_CM) / 100.0;
    quatcurve::bake::usd::crowd_stage(animation, &meshes, stem, &instances, poses, schedule.rate, metres)
}
