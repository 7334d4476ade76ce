//! Baking: resample keyed animation (glTF, BVH, SMPL-family poses, a synthetic crowd) at a fixed rate with any
//! curve, rotations through an evaluation [`Device`] and translations/scales through their
//! Euclidean analogue ([`quatcurve_eval::euclidean`]).
//!
//! Every source is read into one model, [`Animation`] (`quatcurve_anim`): joints with rest
//! poses, and clips of keyed [`Channel`]s. [`bake`] resamples the clips; the formats write the
//! results back ([`Baked::frames`]) and [`texture`] lays them out as animation textures
//! (local, model-space by forward kinematics, skin matrices).

pub mod babylon;
pub mod budget;
pub mod error;
pub mod image;
pub mod job;
pub mod manifest;
pub mod options;
pub(crate) mod outputs;
pub mod player;
pub mod poses;
mod report;
pub mod root_motion;
pub mod sidecar;
pub mod texture;
mod texture_file;
pub mod uniforms;
pub mod usd;
pub mod vertex_encoding;
mod vertex_glb;
mod vertex_texture;
mod workers;

use crate::error::BakeError;
pub use job::BakeJob;
pub use options::BakeOptions;
use quatcurve_anim::curves::{ChannelEval, CurveChoice, Curves};
use quatcurve_anim::error::{AnimationError, InputError};
use quatcurve_anim::loops::{clip_loops, LoopMode};
use quatcurve_anim::{Animation, Channel, Clip, ClipFrames, Property};
pub use quatcurve_files::shard::Shard;
pub use report::{BakeReport, InputReport, Progress};

use quatcurve_core::quat::QuatF64;
use quatcurve_device::Device;
use quatcurve_eval::batch::BatchBuilder;
use quatcurve_eval::job::EvalJob;
use quatcurve_eval::output::FloatOutput;
use quatcurve_eval::sampling::{PerTrack, SampleTimes, Sampling, TrackTimes};
use quatcurve_eval::track::Track;
use rayon::prelude::*;

/// The curve a sidecar names for a fitted input: its own B-splines, whatever `--curve` says.
pub const FITTED_CURVE: &str = "fitted-bspline";

/// Consecutive rotation keys more than this many degrees apart (at the source's own rate) are
/// flagged as probably broken source data: a joint of a motion capture that turns more than a
/// quarter turn between two frames is a tracking flip far more often than motion.
pub const SOURCE_STEP_WARNING_DEGREES: f64 = 90.0;

/// The steps between consecutive keys of a rotation channel that turn more than
/// [`SOURCE_STEP_WARNING_DEGREES`]: each as the index of its first key and its angle (rad).
/// None for a fitted channel, whose control points are not keys.
#[must_use]
pub fn broken_steps(channel: &Channel) -> Vec<(usize, f64)> {
    let limit = SOURCE_STEP_WARNING_DEGREES.to_radians();
    // Steps whose |dot| is clearly above cos(limit / 2) are under the limit: only the others
    // take the exact angle (a quarter of a crowd bake's serial time when every step did).
    let clearly_under = (limit / 2.0).cos() + 1e-9;
    let Some((_, values)) = channel.keyed().filter(|_| channel.property == Property::Rotation) else {
        return Vec::new();
    };
    values
        .windows(2)
        .enumerate()
        .filter_map(|(i, w)| {
            let (a, b) = (QuatF64::from_array(w[0]).normalize(), QuatF64::from_array(w[1]).normalize());
            if a.dot(b).abs() > clearly_under {
                return None;
            }
            let angle = a.angle_to(b);
            (angle > limit).then_some((i, angle))
        })
        .collect()
}

/// One warning per rotation channel with steps between consecutive keys over
/// [`SOURCE_STEP_WARNING_DEGREES`] ([`broken_steps`]), naming the channel, the first such
/// step and how many there are. The bake goes on, through the step as the curve takes it; an
/// error budget leaves the step out of what it measures (`budget::measure`).
#[must_use]
pub fn source_step_warnings(animation: &Animation) -> Vec<String> {
    let channels: Vec<(&Clip, &Channel)> = animation
        .clips
        .iter()
        .flat_map(|clip| clip.channels.iter().filter(|c| c.property == Property::Rotation).map(move |c| (clip, c)))
        .collect();
    let warning = |&(clip, channel): &(&Clip, &Channel)| -> Option<String> {
        let times = channel.keyed()?.0;
        let steps = broken_steps(channel);
        let &(first, angle) = steps.first()?;
        Some(format!(
            "{}: {} step{} between consecutive keys turn{} more than {SOURCE_STEP_WARNING_DEGREES} degrees \
                    (probably broken source data); the first is key {first} to key {} at {} \
                    s, {} degrees",
            animation.label(clip, channel),
            steps.len(),
            if steps.len() == 1 { "" } else { "s" },
            if steps.len() == 1 { "s" } else { "" },
            first + 1,
            quatcurve_eval::error::Number(times[first + 1]),
            quatcurve_eval::error::Number(angle.to_degrees()),
        ))
    };
    channels.par_iter().with_min_len(64).filter_map(warning).collect()
}

/// A resampled clip: frame times, and where each channel's frames lie in [`Baked`].
#[derive(Clone, Debug, PartialEq)]
pub struct BakedClip {
    /// Uniform from the clip's first key to its last, both included ([`fitted_frame_grid`]);
    /// at an exact rate, open clips end at the last frame not past their last key
    /// ([`frame_grid`]).
    pub times: Vec<f64>,
    /// Frames per second of `times`: the requested rate fitted to the clip's span, or the
    /// requested rate itself ([`ClipRate::Exact`], open clips).
    pub rate: f64,
    /// The clip's last key time: past the last frame when an exact rate left the end unbaked.
    pub end: f64,
    /// Whether the clip was baked as a loop (periodic curves, seam continuity).
    pub looping: bool,
    /// Per channel, in the clip's order: where its frames are ([`Baked::values`]).
    frames: Vec<Frames>,
}

impl BakedClip {
    /// Seconds of the clip after its last frame: 0 unless an exact rate ([`ClipRate::Exact`])
    /// left the end of the clip off the grid (a last frame up to [`END_TOLERANCE_FRAMES`] past
    /// the end counts as ending on it).
    #[must_use]
    pub fn unbaked_end(&self) -> f64 {
        self.times.last().map_or(0.0, |&last| (self.end - last).max(0.0))
    }

    /// Whether it is a loop whose last frame is its seam (its first pose), so that a player
    /// wraps it by `frames - 1`: a loop not baked at an exact rate its period is not whole
    /// frames of ([`clip_frame_grid`]).
    #[must_use]
    pub fn closes(&self) -> bool {
        self.looping && self.unbaked_end() * self.rate <= UNBAKED_FRAMES
    }
}

/// Where one channel's frames are kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Frames {
    /// Rows `start..end` of the device's output ([`Baked`]'s `rotations`), as it wrote them.
    Device(usize, usize),
    /// Entry `i` of the values computed on the host (vectors, one-key channels).
    Host(usize),
}

/// The result of [`bake`].
#[derive(Clone, Debug, PartialEq)]
pub struct Baked {
    /// One per clip, in order.
    pub clips: Vec<BakedClip>,
    /// For curves that interpolate their keys: the largest angle (rad) between a rotation
    /// key and the curve evaluated at that key's time on the same device.
    pub max_key_error: Option<f64>,
    /// The device that evaluated the rotations ([`Device::evaluate_into`]); `None` when
    /// there was no rotation channel to evaluate.
    pub device: Option<String>,
    /// The device's output, kept as it came (rows `x, y, z, w`, track after track): the
    /// textures and files read their rows from it, with no copy per channel.
    rotations: Vec<f32>,
    /// Channels evaluated on the host, one value per frame.
    host: Vec<Vec<[f32; 4]>>,
    /// Per clip, with `--root-motion extract`: the scene roots' local rows with the root track
    /// taken out ([`root_motion::extract`]), which the textures take in place of their values.
    in_place: Vec<Option<root_motion::InPlace>>,
}

impl Baked {
    /// Clip `clip`'s root track and in-place scene roots, when its root motion was extracted.
    #[must_use]
    pub fn in_place(&self, clip: usize) -> Option<&root_motion::InPlace> {
        self.in_place.get(clip).and_then(Option::as_ref)
    }

    /// Every clip's frames, in order: what the format writers write back
    /// ([`quatcurve_formats::gltf::GltfFile::to_glb`], [`quatcurve_formats::bvh::BvhFile::to_text`]).
    #[must_use]
    pub fn frames(&self) -> Vec<ClipFrames<'_>> {
        (0..self.clips.len())
            .map(|c| ClipFrames { times: &self.clips[c].times, rate: self.clips[c].rate, values: self.values(c) })
            .collect()
    }

    /// Clip `clip`'s channels (in the clip's order), one value per frame: rotations
    /// `x, y, z, w`; vectors `x, y, z, 0`.
    ///
    /// # Panics
    /// When `clip` is not a clip of this bake.
    #[must_use]
    pub fn values(&self, clip: usize) -> Vec<&[[f32; 4]]> {
        let rows: &[[f32; 4]] = bytemuck::cast_slice(&self.rotations);
        self.clips[clip]
            .frames
            .iter()
            .map(|&f| match f {
                Frames::Device(start, end) => &rows[start..end],
                Frames::Host(i) => self.host[i].as_slice(),
            })
            .collect()
    }

    /// Samples written, over every channel.
    #[must_use]
    pub fn sample_count(&self) -> usize {
        (0..self.clips.len()).flat_map(|c| self.values(c)).map(<[_]>::len).sum()
    }
}

/// Most samples (frames times channels plus frames times joints for the texture, over all
/// clips) one input may bake: 2 GiB as f32 rotations. Key times come from the file, so a
/// crafted clip could otherwise ask for any amount of memory (two keys a year apart at 30 Hz are a billion frames per channel).
pub const MAX_BAKE_SAMPLES: usize = 1 << 27;

/// Frames of a clip's end left unbaked below which it counts as baked whole (a rounding of
/// the grid, not a part of the clip).
pub const UNBAKED_FRAMES: f64 = 1e-6;

/// How far past the clip's end (in frames) a last frame is still kept at an exact rate
/// ([`ClipRate::Exact`]): glTF stores times as f32, so a clip meant to end on the grid can end
/// a rounding error before it.
pub const END_TOLERANCE_FRAMES: f64 = 0.01;

/// How a clip's frames are laid on its span `[first key, last key]` (DESIGN section 6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ClipRate {
    /// The rate nearest this one (Hz) that puts a whole number of frames in the clip's span:
    /// its first and last frames are its first and last keys. The default, and the only
    /// choice for loops (whose last frame is the seam).
    Fit(f64),
    /// This rate exactly: frames `start + i / rate` while not past the last key, so the end of
    /// a clip that does not land on the grid is not baked ([`BakedClip::unbaked_end`]); a
    /// loop's frames are on its looping curve ([`clip_frame_grid`]).
    Exact(f64),
}

impl ClipRate {
    /// The requested rate in Hz.
    #[must_use]
    pub fn hz(self) -> f64 {
        match self {
            ClipRate::Fit(hz) | ClipRate::Exact(hz) => hz,
        }
    }
}

/// The frame grid of an open clip at an exact rate: `start + i / rate` while not past `end`
/// (DESIGN section 5), except that a frame at most [`END_TOLERANCE_FRAMES`] past the end is
/// kept (and evaluates to the end pose).
///
/// # Errors
/// [`InputError::Keys`] for a rate that is not finite and positive, or a grid too long.
pub fn frame_grid(start: f64, end: f64, rate: f64) -> Result<TrackTimes, InputError> {
    Ok(Sampling::Rate(rate).over(start, end + END_TOLERANCE_FRAMES / rate)?)
}

/// The fitted frame grid of a clip spanning `[start, end]`: `N = round((end - start) rate)`
/// intervals (at least one), at the rate `N / (end - start)` it returns with it, so the first
/// frame is `start` and the last is `end` exactly (for a loop: the seam, equal to the first).
/// A clip of one instant (only one-key channels) is one frame at `rate`.
///
/// # Errors
/// As [`frame_grid`].
pub fn fitted_frame_grid(start: f64, end: f64, rate: f64) -> Result<(TrackTimes, f64), InputError> {
    let span = end - start;
    if span <= 0.0 {
        return Ok((frame_grid(start, start, rate)?, rate));
    }
    let intervals = (span * rate).round().max(1.0);
    // Counted as Sampling::Rate counts, so a hostile span meets the same limits.
    frame_grid(start, start + intervals / rate, rate)?;
    let grid = TrackTimes::Uniform { start, step: span / intervals, count: intervals as usize + 1, last: Some(end) };
    // A span that is a whole number of frames keeps the rate as given, not a rounding of it
    // (a 120 Hz take baked at 120 Hz writes 1/120 s per frame).
    let fitted = intervals / span;
    Ok((grid, if ((fitted - rate) / rate).abs() < 1e-9 { rate } else { fitted }))
}

/// A clip's frame grid and its rate: fitted ([`fitted_frame_grid`]) unless `rate` asks for an
/// exact rate. At an exact rate an open clip's grid is [`frame_grid`]'s, and so is a loop's
/// whose period is not a whole number of frames (within [`END_TOLERANCE_FRAMES`]): its rows
/// `start + i / rate` on its looping curve, the loop closed by the curve rather than by a last
/// row equal to the first ([`BakedClip::closes`] is false); a loop of whole frames ends on its
/// seam.
///
/// # Errors
/// As [`frame_grid`].
pub fn clip_frame_grid(start: f64, end: f64, rate: ClipRate, looping: bool) -> Result<(TrackTimes, f64), InputError> {
    match rate {
        ClipRate::Exact(hz) => {
            let frames = (end - start) * hz;
            let whole = frames.round();
            if !looping || whole < 1.0 || (frames - whole).abs() > END_TOLERANCE_FRAMES {
                return Ok((frame_grid(start, end, hz)?, hz));
            }
            // Counted as Sampling::Rate counts, so a hostile span meets the same limits.
            frame_grid(start, start + whole / hz, hz)?;
            Ok((TrackTimes::Uniform { start, step: 1.0 / hz, count: whole as usize + 1, last: Some(end) }, hz))
        }
        ClipRate::Fit(hz) => fitted_frame_grid(start, end, hz),
    }
}

/// The times of a uniform grid, as [`SampleTimes::time`] computes them.
pub fn grid_times(grid: TrackTimes) -> Vec<f64> {
    (0..grid.count()).filter_map(|j| grid.grid_time(j)).collect()
}

/// Resamples every clip at `rate` as `choice` says: rotation channels on `device` (one batch
/// for the whole animation), vector channels with the Euclidean analogue in f64, keys a
/// source declares STEP or CUBICSPLINE as glTF defines them in f64. Channels with a single
/// key are held constant. Samples outside a channel's keys hold its end value
/// (glTF's clamping). Clips that loop (`loops`, [`clip_loops`]) use the periodic curves of
/// DESIGN section 3, translations keeping their per-cycle offset.
///
/// # Errors
/// [`InputError::Keys`] naming the clip, joint, property and key for bad keys;
/// [`InputError::Animation`] for a clip that cannot bake as asked; [`BakeError::Device`]
/// when the device refuses or fails.
pub fn bake(
    animation: &Animation,
    choice: &CurveChoice,
    rate: ClipRate,
    loops: LoopMode,
    device: &Device,
) -> Result<Baked, BakeError> {
    bake_each(animation, choice, &vec![rate; animation.clips.len()], loops, device)
}

/// [`bake`] with a rate of each clip's own (`rates[c]` for clip `c`): what an error budget
/// chose ([`budget::choose_rates`]).
///
/// # Errors
/// As [`bake`].
///
/// # Panics
/// When `rates` has not one rate per clip.
pub fn bake_each(
    animation: &Animation,
    choice: &CurveChoice,
    rates: &[ClipRate],
    loops: LoopMode,
    device: &Device,
) -> Result<Baked, BakeError> {
    bake_reusing(animation, choice, rates, loops, device, &mut Reuse::default())
}

/// The large buffers of one bake, kept for the next ([`bake_reusing`]): the packed batch's
/// arrays and the device's output. Fresh ones are allocated and faulted in page by page at
/// every bake; decompressing clip after clip, that was a fifth of the time.
#[derive(Debug, Default)]
pub struct Reuse {
    batch: Option<quatcurve_eval::batch::Batch>,
    rotations: Vec<f32>,
}

impl Reuse {
    /// Keeps `baked`'s output for the next bake.
    pub fn keep(&mut self, baked: Baked) {
        self.rotations = baked.rotations;
    }
}

/// [`bake_each`] into the buffers `reuse` kept ([`Reuse::keep`] gives a result's back).
///
/// # Errors
/// As [`bake`].
///
/// # Panics
/// When `rates` has not one rate per clip.
pub fn bake_reusing(
    animation: &Animation,
    choice: &CurveChoice,
    rates: &[ClipRate],
    loops: LoopMode,
    device: &Device,
    reuse: &mut Reuse,
) -> Result<Baked, BakeError> {
    assert_eq!(rates.len(), animation.clips.len(), "one rate per clip");
    let (clips, grids) = plan_clips(animation, choice, rates, loops)?;
    let looping: Vec<bool> = clips.iter().map(|c| c.looping).collect();
    let builder = reuse.batch.take().map_or_else(BatchBuilder::new, BatchBuilder::reusing);
    let curves = Curves::build(animation, choice, &looping, builder)?;
    let mut baked = evaluate(&curves, clips, &grids, device, std::mem::take(&mut reuse.rotations))?;
    if let Some(batch) = &curves.batch {
        // A fitted clip's control points are not keys the curve passes through.
        if choice.interpolates() && !animation.is_fitted() {
            baked.max_key_error = Some(key_error(&curves.tracks, batch, device)?);
        }
    }
    reuse.batch = curves.batch;
    Ok(baked)
}

/// The frames of `clips` on their `grids` (one each) from curves already built: host
/// channels on every core, rotation tracks on `device` into `rotations` (a kept buffer).
fn evaluate(
    curves: &Curves,
    mut clips: Vec<BakedClip>,
    grids: &[TrackTimes],
    device: &Device,
    rotations: Vec<f32>,
) -> Result<Baked, BakeError> {
    // The host's channels at their clip's frames, on every core.
    let host_channels: Vec<(usize, &ChannelEval)> = curves
        .channels
        .iter()
        .enumerate()
        .flat_map(|(c, channels)| channels.iter().filter(|k| !matches!(k, ChannelEval::Device(_))).map(move |k| (c, k)))
        .collect();
    let host: Vec<Vec<[f32; 4]>> = host_channels
        .par_iter()
        .map(|&(c, curve)| clips[c].times.iter().filter_map(|&t| curve.host_value(t)).collect())
        .collect();
    let mut next_host = 0;
    for (clip, channels) in clips.iter_mut().zip(&curves.channels) {
        clip.frames = channels
            .iter()
            .map(|k| match k {
                ChannelEval::Device(_) => Frames::Device(0, 0),
                _ => {
                    next_host += 1;
                    Frames::Host(next_host - 1)
                }
            })
            .collect();
    }
    let mut baked =
        Baked { clips, max_key_error: None, device: None, rotations: Vec::new(), host, in_place: Vec::new() };
    let Some(batch) = &curves.batch else {
        return Ok(baked);
    };
    let track_clips = &curves.track_clips;
    // Each channel on its clip's frame grid (three numbers, not a list per channel); a
    // looping channel whose keys span less than its clip gets the list, which wraps.
    let clips = &baked.clips;
    let times = SampleTimes::per_track(batch, |i, [first, last]| {
        let c = track_clips[i];
        let frames = &clips[c].times;
        let inside = first <= frames[0] && frames[frames.len() - 1] <= last;
        Ok(if clips[c].looping && !inside { PerTrack::List(frames) } else { PerTrack::Grid(grids[c]) })
    })?;
    let mut rotations = FloatOutput { channels: 4, data: rotations };
    let name = device.evaluate_into(&EvalJob::new(batch, &times), &mut rotations)?;
    let mut next = 0;
    for clip in &mut baked.clips {
        for frames in clip.frames.iter_mut().filter(|f| matches!(f, Frames::Device(..))) {
            *frames = Frames::Device(times.offsets()[next], times.offsets()[next + 1]);
            next += 1;
        }
    }
    baked.rotations = rotations.data;
    baked.device = Some(name);
    Ok(baked)
}

/// Per clip: whether it loops and its frame grid, within the sample budget, which is counted
/// before anything is allocated for the clip (frames rounded up; the channel samples and the
/// texture's joint rows).
fn plan_clips(
    animation: &Animation,
    choice: &CurveChoice,
    rates: &[ClipRate],
    loops: LoopMode,
) -> Result<(Vec<BakedClip>, Vec<TrackTimes>), InputError> {
    let mut clips: Vec<BakedClip> = Vec::with_capacity(animation.clips.len());
    let mut grids = Vec::with_capacity(animation.clips.len());
    let mut total_samples = 0usize;
    for (clip, &rate) in animation.clips.iter().zip(rates) {
        let [start, end] = clip.span();
        let looping = clip_loops(animation, clip, choice, loops)?;
        let hz = rate.hz();
        let frames = ((end - start) * hz).max(0.0).floor() + 2.0;
        let samples = frames * (clip.channels.len() + animation.joints.len()) as f64;
        if total_samples as f64 + samples > MAX_BAKE_SAMPLES as f64 {
            return Err(AnimationError::TooManySamples {
                clip: clip.name.clone(),
                span: end - start,
                frames: frames - 1.0,
                rate: hz,
                channels: clip.channels.len(),
                joints: animation.joints.len(),
                limit: MAX_BAKE_SAMPLES,
            }
            .into());
        }
        total_samples += samples as usize;
        let (grid, clip_rate) = clip_frame_grid(start, end, rate, looping)?;
        clips.push(BakedClip { times: grid_times(grid), rate: clip_rate, end, looping, frames: Vec::new() });
        grids.push(grid);
    }
    Ok((clips, grids))
}

/// The largest angle (rad) between a rotation key and the curve evaluated at that key's time
/// on `device`. The largest chord `|key - q|` (hemispheres aligned) is found first, on every
/// core: the angle grows with it, so one `angle_to` at the end gives the same answer as one
/// per key.
fn key_error(tracks: &[Track], batch: &quatcurve_eval::batch::Batch, device: &Device) -> Result<f64, BakeError> {
    let overrides: Vec<Option<&[f64]>> = tracks.iter().map(|t| t.times.as_deref()).collect();
    let times = SampleTimes::new(batch, &overrides, Sampling::Count(1))?;
    let mut out = FloatOutput::default();
    device.evaluate_into(&EvalJob::new(batch, &times), &mut out)?;
    let rows: &[[f32; 4]] = bytemuck::cast_slice(&out.data);
    let chord = |key: QuatF64, q: QuatF64| {
        let s = if key.dot(q) < 0.0 { -1.0 } else { 1.0 };
        (key - q.mul_scalar(s)).length()
    };
    let worst = tracks
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, track)| {
            let got = &rows[times.offsets()[i]..times.offsets()[i + 1]];
            track.rotations.iter().zip(got).map(|(&key, q)| {
                let (key, q) = (QuatF64::from_array(key).normalize(), QuatF64::from_array(q.map(f64::from)));
                (chord(key, q.normalize()), key, q)
            })
        })
        // A NaN (a non-finite sample) wins: it must not pass for a small error.
        .reduce(
            || (0.0, QuatF64::identity(), QuatF64::identity()),
            |a, b| if b.0 > a.0 || b.0.is_nan() { b } else { a },
        );
    Ok(if worst.0.is_nan() { f64::NAN } else { worst.1.angle_to(worst.2) })
}
