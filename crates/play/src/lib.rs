//! Crowds played straight from curves (DESIGN section 17): an animation's clips built once as
//! curves ([`quatcurve_anim::curves::Curves`], the bake's own), then, frame after frame, every
//! instance's joints evaluated at that instance's own time in up to two clips, the two poses
//! blended in local space, forward kinematics run and the skin's inverse binds multiplied:
//! the skin palette `[instances, joints, 3x4]` a vertex shader skins with. No texture per clip
//! and rate: any time, the curve's own smoothness, blends.
//!
//! On the GPU the clips are uploaded once ([`Playback::player`]) and a frame is one
//! submission: every joint's curves at each instance's times, the blend, forward kinematics
//! and palettes (`shaders/play_curves.wgsl`), only the instances sent. The CPU path and the
//! reference evaluate rotations as one job (SIMD f32, f64), translations and scales with the
//! Euclidean analogue in f64, then blend, run forward kinematics and build palettes an
//! instance at a time ([`Device::play_palettes`]).

pub mod error;
pub mod schedule;

use error::PlayError;
use quatcurve_anim::curves::{ChannelEval, CurveChoice, Curves};
use quatcurve_anim::error::{AnimationError, InputError};
use quatcurve_anim::loops::{clip_loops, LoopMode};
use quatcurve_anim::{Animation, Property, Skin};
use quatcurve_device::{Device, ResidentPlayback};
use quatcurve_eval::batch::BatchBuilder;
use quatcurve_eval::job::EvalJob;
use quatcurve_eval::output::{FloatOutput, LOCAL_CHANNELS, MATRIX_CHANNELS};
use quatcurve_eval::sampling::{PerTrack, SampleTimes};
use quatcurve_eval::skeleton::{self, PaletteSkin, PoseCurves, PoseSource, PoseTimes, POSE_PROPERTIES};
use rayon::prelude::*;

/// A pose of one clip: the clip's index and seconds from its first key. A loop plays on
/// past its end (rotations periodic, a travelling translation advancing by its per-cycle
/// offset each period); an open clip holds its first and last poses outside its span.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipTime {
    /// Index into the animation's clips.
    pub clip: usize,
    /// Seconds from the clip's start.
    pub time: f64,
}

/// What one instance plays this frame: `first`, or `first` blended towards `second` by
/// `weight` (0: `first` alone, 1: `second` alone).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// The first pose.
    pub first: ClipTime,
    /// The second pose and its weight, for a blend.
    pub second: Option<(ClipTime, f32)>,
}

impl Instance {
    /// One clip at one time, no blend.
    #[must_use]
    pub fn single(clip: usize, time: f64) -> Self {
        Self { first: ClipTime { clip, time }, second: None }
    }
}

/// An animation's clips ready to play: built once, evaluated for any instances at any times.
#[derive(Debug)]
pub struct Playback {
    animation: Animation,
    curves: Curves,
    parents: Vec<Option<usize>>,
    order: Vec<usize>,
    /// Per clip: its first key's time.
    starts: Vec<f64>,
    /// Per clip: its span in seconds.
    durations: Vec<f64>,
    /// Per clip: whether it plays as a loop.
    looping: Vec<bool>,
    /// Every joint's rest pose, one local row ([`Animation::rest_row`]).
    rest: Vec<f32>,
    /// The skin whose palette is played; `None`: every joint's model matrix (no skin).
    skin: Option<usize>,
}

impl Playback {
    /// Builds every clip's curves as `curve` says, loops chosen by `loops` as the bake chooses
    /// them ([`clip_loops`]), the palette that of skin `skin` (the first skin when `None`; a
    /// file without skins plays every joint's model matrix, as a `skin` texture does).
    ///
    /// # Errors
    /// The bake's, for keys or loops it refuses; [`InputError::Animation`] for a skin the
    /// animation does not have, or an animation without a clip.
    pub fn new(
        animation: Animation,
        curve: &CurveChoice,
        loops: LoopMode,
        skin: Option<usize>,
    ) -> Result<Self, InputError> {
        if animation.clips.is_empty() {
            return Err(AnimationError::NoClip.into());
        }
        let skin = match skin {
            Some(k) if k >= animation.skins.len() => {
                return Err(AnimationError::NoSuchSkin { skin: k, skins: animation.skins.len() }.into())
            }
            Some(k) => Some(k),
            None => (!animation.skins.is_empty()).then_some(0),
        };
        let looping =
            animation.clips.iter().map(|c| clip_loops(&animation, c, curve, loops)).collect::<Result<Vec<_>, _>>()?;
        let curves = Curves::build(&animation, curve, &looping, BatchBuilder::new())?;
        let spans: Vec<[f64; 2]> = animation.clips.iter().map(quatcurve_anim::Clip::span).collect();
        Ok(Self {
            parents: animation.parents(),
            order: animation.parents_first()?,
            starts: spans.iter().map(|s| s[0]).collect(),
            durations: spans.iter().map(|s| s[1] - s[0]).collect(),
            looping,
            rest: animation.rest_row(),
            skin,
            curves,
            animation,
        })
    }

    /// The animation played.
    #[must_use]
    pub fn animation(&self) -> &Animation {
        &self.animation
    }

    /// Clip `clip`'s span in seconds.
    ///
    /// # Panics
    /// When `clip` is not a clip of the animation.
    #[must_use]
    pub fn duration(&self, clip: usize) -> f64 {
        self.durations[clip]
    }

    /// Whether clip `clip` plays as a loop.
    ///
    /// # Panics
    /// When `clip` is not a clip of the animation.
    #[must_use]
    pub fn looping(&self, clip: usize) -> bool {
        self.looping[clip]
    }

    /// The skin played ([`Playback::new`]), `None` for model matrices of every joint.
    #[must_use]
    pub fn skin(&self) -> Option<&Skin> {
        self.skin.map(|k| &self.animation.skins[k])
    }

    /// Matrices per instance in a palette: the skin's joints (in its order), or every joint.
    #[must_use]
    pub fn palette_joints(&self) -> usize {
        self.skin().map_or(self.animation.joints.len(), |s| s.joints.len())
    }

    /// The seconds of the curves for a pose: the clip's start plus its time, an open clip's
    /// held inside its span (a loop's curves wrap themselves).
    fn curve_time(&self, pose: ClipTime) -> f64 {
        let time = if self.looping[pose.clip] { pose.time } else { pose.time.clamp(0.0, self.durations[pose.clip]) };
        self.starts[pose.clip] + time
    }

    /// Every instance's local pose: `[instances, joints, 10]` (rotation `x, y, z, w`,
    /// translation, scale per joint, in the animation's joint order), the two poses of a blend
    /// mixed in local space ([`skeleton::blend_poses`]: rotations by slerp on the shorter arc,
    /// translations and scales by lerp). What a clip does not animate keeps the joint's rest
    /// value. Rotations are evaluated in one job on `device`.
    ///
    /// # Errors
    /// [`PlayError::Animation`] for a clip that is not the animation's, a time that is not
    /// finite or a weight outside `[0, 1]`, naming the instance; the device's failures.
    pub fn local_poses(&self, device: &Device, instances: &[Instance]) -> Result<Vec<f32>, PlayError> {
        let (poses, weights) = self.pose_pairs(device, instances)?;
        Ok(skeleton::blend_poses(&poses, &weights, self.animation.joints.len()))
    }

    /// Every instance's skin palette: `[instances, palette joints, 12]`, each the 3x4
    /// row-major `model(joint) * inverseBind(joint)` in the skin's joint order (the rows of a
    /// `skin` texture), or every joint's model matrix for a file without skins
    /// ([`Playback::palette_joints`]). Everything runs on `device`; each call prepares it
    /// ([`Playback::player`]): a frame loop keeps one [`Player`] instead.
    ///
    /// # Errors
    /// As [`Playback::local_poses`], and [`Playback::player`]'s.
    pub fn palettes(&self, device: &Device, instances: &[Instance]) -> Result<Vec<f32>, PlayError> {
        self.player(device)?.palettes(instances)
    }

    /// These clips prepared on `device` for frame after frame: on the GPU the curves uploaded
    /// once ([`Device::resident_playback`]), so that a frame is one submission with only the
    /// instances sent; elsewhere, and for channels only the host evaluates
    /// ([`Playback::pose_curves`]), the host path of [`Playback::palettes`].
    ///
    /// # Errors
    /// The device's, for curves it cannot take (named).
    pub fn player<'a>(&'a self, device: &'a Device) -> Result<Player<'a>, PlayError> {
        let resident = match self.pose_curves() {
            Some(curves) => device.resident_playback(&curves)?,
            None => None,
        };
        Ok(Player { playback: self, device, resident })
    }

    /// The clips as a device keeps them: per clip, joint and property, the track, vector curve
    /// or constant it plays (a property the clip leaves alone: its rest value). `None` where a
    /// channel is evaluated on the host alone (keys a source declares STEP or CUBICSPLINE).
    #[must_use]
    pub fn pose_curves(&self) -> Option<PoseCurves<'_>> {
        let joints = self.animation.joints.len();
        let mut vectors = Vec::new();
        let mut sources = Vec::with_capacity(self.animation.clips.len() * joints * POSE_PROPERTIES);
        for (clip, evals) in self.animation.clips.iter().zip(&self.curves.channels) {
            let first = sources.len();
            for rest in self.rest.chunks(LOCAL_CHANNELS) {
                sources.extend([
                    PoseSource::Value([rest[0], rest[1], rest[2], rest[3]]),
                    PoseSource::Value([rest[4], rest[5], rest[6], 0.0]),
                    PoseSource::Value([rest[7], rest[8], rest[9], 0.0]),
                ]);
            }
            for (channel, eval) in clip.channels.iter().zip(evals) {
                let property = match channel.property {
                    Property::Rotation => 0,
                    Property::Translation => 1,
                    Property::Scale => 2,
                };
                sources[first + POSE_PROPERTIES * channel.joint + property] = match eval {
                    ChannelEval::Device(track) => PoseSource::Rotation(*track),
                    ChannelEval::Vector(curve) => {
                        vectors.push(curve);
                        PoseSource::Vector(vectors.len() - 1)
                    }
                    ChannelEval::Constant(value) => PoseSource::Value(*value),
                    ChannelEval::Declared(_) => return None,
                };
            }
        }
        Some(PoseCurves {
            batch: self.curves.batch.as_ref(),
            vectors,
            sources,
            parents: &self.parents,
            order: &self.order,
            skin: self.palette_skin(),
        })
    }

    /// The played skin's joints and inverse binds.
    fn palette_skin(&self) -> Option<PaletteSkin<'_>> {
        self.skin().map(|s| PaletteSkin { joints: &s.joints, inverse_binds: &s.inverse_bind })
    }

    /// An instance's two poses on the curves' times (without a blend: the first twice).
    fn pose_times(&self, instance: &Instance) -> PoseTimes {
        let (second, weight) = instance.second.unwrap_or((instance.first, 0.0));
        PoseTimes {
            clips: [instance.first.clip, second.clip],
            times: [self.curve_time(instance.first), self.curve_time(second)],
            weight,
        }
    }

    /// [`Playback::palettes`] on the host path: rotations by one evaluator job, vectors in f64,
    /// then [`Device::play_palettes`].
    fn host_palettes(&self, device: &Device, instances: &[Instance]) -> Result<Vec<f32>, PlayError> {
        let (poses, weights) = self.pose_pairs(device, instances)?;
        Ok(device.play_palettes(&self.parents, &self.order, &poses, &weights, self.palette_skin())?)
    }

    /// Each instance's two local poses, `[instances, 2, joints, 10]` (an instance without a
    /// blend: its pose twice), and the second's weight (0 without a blend).
    fn pose_pairs(&self, device: &Device, instances: &[Instance]) -> Result<(Vec<f32>, Vec<f32>), PlayError> {
        self.check(instances)?;
        // Every pose asked for, grouped by clip: (instance, slot) -> (clip, k-th time of it).
        let clips = self.animation.clips.len();
        let mut times: Vec<Vec<f64>> = vec![Vec::new(); clips];
        let mut at = |pose: ClipTime| {
            times[pose.clip].push(self.curve_time(pose));
            (pose.clip, times[pose.clip].len() - 1)
        };
        let poses: Vec<[Option<(usize, usize)>; 2]> =
            instances.iter().map(|i| [Some(at(i.first)), i.second.map(|(p, _)| at(p))]).collect();
        let rotations = match &self.curves.batch {
            Some(batch) => {
                let track_clips = &self.curves.track_clips;
                let sample_times = SampleTimes::per_track(batch, |i, _| Ok(PerTrack::List(&times[track_clips[i]])))?;
                let mut out = FloatOutput::default();
                device.evaluate_into(&EvalJob::new(batch, &sample_times), &mut out)?;
                Some((out.data, sample_times))
            }
            None => None,
        };
        let rest = &self.rest;
        let row = rest.len();
        // One pose's local row: rest values, then every channel of its clip.
        let pose_row = |(clip, k): (usize, usize), out: &mut [f32]| {
            out.copy_from_slice(rest);
            let t = times[clip][k];
            for (channel, eval) in self.animation.clips[clip].channels.iter().zip(&self.curves.channels[clip]) {
                let value = match eval {
                    ChannelEval::Device(track) => {
                        let (data, sample_times) = rotations.as_ref().expect("a device channel has a batch");
                        let s = sample_times.offsets()[*track] + k;
                        [data[4 * s], data[4 * s + 1], data[4 * s + 2], data[4 * s + 3]]
                    }
                    host => host.host_value(t).expect("a host channel has a value"),
                };
                let j = channel.joint * LOCAL_CHANNELS;
                match channel.property {
                    Property::Rotation => out[j..j + 4].copy_from_slice(&value),
                    Property::Translation => out[j + 4..j + 7].copy_from_slice(&value[..3]),
                    Property::Scale => out[j + 7..j + 10].copy_from_slice(&value[..3]),
                }
            }
        };
        let mut pairs = vec![0.0f32; instances.len() * 2 * row];
        pairs.par_chunks_mut((2 * row).max(1)).zip(&poses).for_each(|(out, pose)| {
            let (first, second) = out.split_at_mut(row);
            pose_row(pose[0].expect("every instance has a first pose"), first);
            match pose[1] {
                Some(p) => pose_row(p, second),
                None => second.copy_from_slice(first),
            }
        });
        let weights = instances.iter().map(|i| i.second.map_or(0.0, |(_, w)| w)).collect();
        Ok((pairs, weights))
    }

    /// Refuses a pose of a clip the animation lacks, a time that is not finite or a weight
    /// outside `[0, 1]`.
    fn check(&self, instances: &[Instance]) -> Result<(), InputError> {
        let clips = self.animation.clips.len();
        for (i, instance) in instances.iter().enumerate() {
            let weight = instance.second.map(|(_, w)| w);
            for pose in std::iter::once(instance.first).chain(instance.second.map(|(p, _)| p)) {
                if pose.clip >= clips {
                    return Err(AnimationError::InstanceClip { instance: i, clip: pose.clip, clips }.into());
                }
                if !pose.time.is_finite() {
                    return Err(AnimationError::InstanceTime { instance: i, time: pose.time }.into());
                }
            }
            if let Some(w) = weight.filter(|w| !(0.0..=1.0).contains(w)) {
                return Err(AnimationError::InstanceWeight { instance: i, weight: w }.into());
            }
        }
        Ok(())
    }
}

/// A [`Playback`] prepared on one device ([`Playback::player`]): what a frame loop holds.
#[derive(Debug)]
pub struct Player<'a> {
    playback: &'a Playback,
    device: &'a Device,
    /// The curves on the device, where it keeps them.
    resident: Option<ResidentPlayback>,
}

impl Player<'_> {
    /// The curves on the device, where it keeps them (the GPU): a renderer takes a frame's
    /// palettes there, left on the device ([`ResidentPlayback::gpu`]).
    #[must_use]
    pub fn resident(&self) -> Option<&ResidentPlayback> {
        self.resident.as_ref()
    }

    /// What the device plays for `instances`: each one's two clips on the curves' times.
    ///
    /// # Errors
    /// As [`Playback::local_poses`], for instances it refuses.
    pub fn pose_times(&self, instances: &[Instance]) -> Result<Vec<PoseTimes>, InputError> {
        self.playback.check(instances)?;
        Ok(instances.iter().map(|i| self.playback.pose_times(i)).collect())
    }

    /// [`Playback::palettes`] of `instances`: on the GPU one submission from the resident
    /// curves.
    ///
    /// # Errors
    /// As [`Playback::local_poses`].
    pub fn palettes(&self, instances: &[Instance]) -> Result<Vec<f32>, PlayError> {
        if instances.is_empty() {
            return Ok(Vec::new());
        }
        let playback = self.playback;
        match &self.resident {
            Some(resident) => Ok(resident.palettes(&self.pose_times(instances)?)?),
            None => playback.host_palettes(self.device, instances),
        }
    }
}

/// Skin `skin` of `source` bound to `target`'s joints by name: how a fitted container (which
/// keeps the joints and clips of a glTF, not its skins) plays the character's palette.
///
/// # Errors
/// [`InputError::Animation`] for a skin `source` lacks, or a joint of it `target` does not
/// have, named.
pub fn skin_by_name(target: &Animation, source: &Animation, skin: usize) -> Result<Skin, InputError> {
    let from = source.skins.get(skin).ok_or(AnimationError::NoSuchSkin { skin, skins: source.skins.len() })?;
    let joints = from
        .joints
        .iter()
        .map(|&j| {
            let name = &source.joints[j].name;
            target
                .joints
                .iter()
                .position(|t| &t.name == name)
                .ok_or_else(|| AnimationError::SkinJoint { skin: from.name.clone(), joint: name.clone() })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Skin { name: from.name.clone(), joints, inverse_bind: from.inverse_bind.clone(), skeleton: None })
}

/// Floats per palette matrix: 3x4 row-major.
pub const PALETTE_CHANNELS: usize = MATRIX_CHANNELS;
