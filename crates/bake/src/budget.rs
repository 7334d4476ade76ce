//! Rates from an error budget (`bake --max-error-deg DEG`, `--max-error-cm CM`; DESIGN section 7):
//! per clip, the lowest rate at which a renderer interpolating the baked frames as
//! `shaders/bone_texture.wgsl` does (nlerp of rotations on the shorter arc, lerp of
//! translations and scales) stays within the budget of the continuous curve, measured at
//! [`SUBSTEPS`] points of every frame interval for every joint of every texture.
//!
//! [`interpolate`] is that shader's `bone_pose` on the host (one formula per path); the tests
//! run the shader itself on a GPU API over the chosen textures and hold the two together.

use super::texture::{self, Precision, TextureKind, LOCAL_CHANNELS};
use super::{clip_frame_grid, evaluate, grid_times, Baked, BakedClip, ClipRate};
use crate::error::{BakeError, Refusal};
use quatcurve_anim::curves::{CurveChoice, Curves};
use quatcurve_anim::error::{InputError, InternalError};
use quatcurve_anim::loops::{clip_loops, LoopMode};
use quatcurve_anim::{Animation, Clip, Skin, GLTF_UNIT_CM};
use quatcurve_device::Device;
use quatcurve_eval::batch::BatchBuilder;
use quatcurve_eval::error::Number;
use quatcurve_eval::sampling::TrackTimes;
use quatcurve_eval::skeleton::{self, Trs};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::HashSet;

/// Points of each frame interval where the error is measured (the interval's start included,
/// its end being the next interval's start).
pub const SUBSTEPS: usize = 16;

/// Points of each interval the search screens a rate at before it measures the one it picks
/// at [`SUBSTEPS`]: a quarter of them (every fourth, the middle included), so a rate the screen
/// refuses would be refused at every point too, and a search costs about a third as much.
pub const SCREEN_SUBSTEPS: usize = SUBSTEPS / 4;

/// The share of the budget a chosen rate may use on the host, so that the shader's own f32
/// arithmetic and a PNG16's quantization (at most 1/65535 of a channel's range, 0.002 degrees
/// of a quaternion) stay inside it.
pub const BUDGET_MARGIN: f64 = 0.01;

/// The highest rate (Hz) a budget may ask for by default (`--max-rate`): past it a clip is
/// refused, naming the error there.
pub const DEFAULT_MAX_RATE: f64 = 480.0;

/// What an interpolated texture may differ from the continuous curve by.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorBudget {
    /// Largest angle (degrees) between a texture's interpolated rotation and the curve's.
    pub degrees: Option<f64>,
    /// Largest distance (cm) between a joint's interpolated model-space position and
    /// the curve's (forward kinematics of a local texture: errors accumulated down the
    /// hierarchy).
    pub centimetres: Option<f64>,
    /// Centimetres per model unit: 100 for glTF (metres); what a BVH's offsets are in.
    pub unit_cm: f64,
    /// The highest rate tried (Hz).
    pub max_rate: f64,
}

pub use crate::error::Worst;

/// The error of one clip's frames against its continuous curve, between frames.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Measured {
    /// The clip's own rate (Hz) these frames are at.
    pub rate: f64,
    /// Frames.
    pub frames: usize,
    /// The largest rotation error (degrees).
    pub rotation: Worst,
    /// The largest model-space position error (centimetres).
    pub position: Worst,
}

/// The rate an error budget chose for one clip.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChosenRate {
    /// The clip's name.
    pub clip: String,
    /// The rate, frames and worst errors between frames.
    #[serde(flatten)]
    pub measured: Measured,
    /// The clip's texture bytes (frames times joints times channels times the element's).
    pub bytes: usize,
    /// The same at the job's fixed rate (`--rate`).
    pub fixed_rate_bytes: usize,
}

impl ErrorBudget {
    /// No budget: every clip at the job's rate.
    #[must_use]
    pub fn none() -> Self {
        Self { degrees: None, centimetres: None, unit_cm: GLTF_UNIT_CM, max_rate: DEFAULT_MAX_RATE }
    }

    /// Whether a budget is set (degrees, centimetres or both).
    #[must_use]
    pub fn is_set(&self) -> bool {
        self.degrees.is_some() || self.centimetres.is_some()
    }

    /// Whether `m` is within the budget, less [`BUDGET_MARGIN`].
    fn holds(&self, m: &Measured) -> bool {
        let within = |limit: Option<f64>, v: f64| limit.map_or(true, |l| v <= l * (1.0 - BUDGET_MARGIN));
        within(self.degrees, m.rotation.value) && within(self.centimetres, m.position.value)
    }

    /// The budget in words, for messages.
    pub(crate) fn describe(&self) -> String {
        let mut parts = Vec::new();
        if let Some(d) = self.degrees {
            parts.push(format!("{} degrees", Number(d)));
        }
        if let Some(cm) = self.centimetres {
            parts.push(format!("{} cm", Number(cm)));
        }
        parts.join(" and ")
    }
}

/// `bone_pose`'s blend of two frames' rigid rows (`x, y, z, w`, translation, scale): the
/// second rotation turned to the first's side, normalized lerp; lerp of the rest.
#[must_use]
pub fn interpolate(a: &[f32], b: &[f32], blend: f64) -> [f32; LOCAL_CHANNELS] {
    let dot: f64 = (0..4).map(|i| f64::from(a[i]) * f64::from(b[i])).sum();
    let side = if dot < 0.0 { -1.0 } else { 1.0 };
    let mut out = [0.0f64; LOCAL_CHANNELS];
    for (i, o) in out.iter_mut().enumerate() {
        let b = if i < 4 { side * f64::from(b[i]) } else { f64::from(b[i]) };
        *o = f64::from(a[i]) + (b - f64::from(a[i])) * blend;
    }
    let n = (out[..4].iter().map(|v| v * v).sum::<f64>()).sqrt();
    out[..4].iter_mut().for_each(|v| *v /= n);
    out.map(|v| v as f32)
}

/// Angle (degrees) between two rotations given as quaternions.
#[cfg(test)]
fn angle_degrees(a: &[f32], b: &[f32]) -> f64 {
    degrees_of_turn(turn(a, b))
}

/// What [`angle_degrees`] grows with, cheaply: `|a - b|^2 / |a + b|^2` of the unit quaternions
/// on one side. A measure compares millions of these and takes the angle of the largest.
fn turn(a: &[f32], b: &[f32]) -> f64 {
    let norm = |q: &[f32]| q[..4].iter().map(|&v| f64::from(v) * f64::from(v)).sum::<f64>().sqrt();
    let dot: f64 = (0..4).map(|i| f64::from(a[i]) * f64::from(b[i])).sum();
    let (ka, kb) = (1.0 / norm(a), if dot < 0.0 { -1.0 } else { 1.0 } / norm(b));
    let (mut minus, mut plus) = (0.0, 0.0);
    for i in 0..4 {
        let (x, y) = (f64::from(a[i]) * ka, f64::from(b[i]) * kb);
        minus += (x - y) * (x - y);
        plus += (x + y) * (x + y);
    }
    minus / plus
}

/// The angle (degrees) of a [`turn`]. A rotation turns twice its quaternion's angle:
/// 4 atan(|a - b| / |a + b|), exact near zero, where 2 acos(|dot|) loses half its digits.
fn degrees_of_turn(turn: f64) -> f64 {
    (4.0 * turn.sqrt().atan()).to_degrees()
}

/// Joint `j`'s rigid row in frame `frame` of rows `width` joints wide.
fn row(data: &[f32], width: usize, frame: usize, j: usize) -> &[f32] {
    let at = (frame * width + j) * LOCAL_CHANNELS;
    &data[at..at + LOCAL_CHANNELS]
}

/// One clip of `animation` alone, so its frames can be baked at rates of their own, with its
/// skins as one: each joint and inverse bind matrix once, in the skins' order. Skins of one
/// character share most of their joints and binds (a Mixamo body and its joints mesh: 64 and
/// 65 of 65), and a column repeated gives the same rows and errors.
fn only(animation: &Animation, clip: usize) -> Animation {
    let mut skins: Vec<Skin> = animation.skins.iter().take(1).cloned().collect();
    if let Some(merged) = skins.first_mut() {
        let mut seen: HashSet<(usize, [u64; 12])> = HashSet::new();
        merged.joints.clear();
        merged.inverse_bind.clear();
        for skin in &animation.skins {
            for (&joint, ibm) in skin.joints.iter().zip(&skin.inverse_bind) {
                if seen.insert((joint, ibm.map(f64::to_bits))) {
                    merged.joints.push(joint);
                    merged.inverse_bind.push(*ibm);
                }
            }
        }
    }
    Animation { joints: animation.joints.clone(), clips: vec![animation.clips[clip].clone()], skins }
}

/// What a bake writes and the options that decide it.
pub struct Setting<'a> {
    /// What the keys are interpolated with.
    pub curve: &'a CurveChoice,
    /// Which clips loop.
    pub looping: LoopMode,
    /// The texture kind (local, model-trs or skin-trs).
    pub kind: TextureKind,
    /// The element type the renderer reads (half rounds the frames before they are blended).
    pub precision: Precision,
    /// The device the frames are evaluated on.
    pub device: &'a Device,
    /// Told of each rate the search measures (Hz), with its clip's name.
    pub measuring: &'a dyn Fn(&str, f64),
}

/// The error of clip `clip` baked at `rate` (fitted to its span) against its curve at
/// [`SUBSTEPS`] points of every interval; positions in cm at `unit_cm` per model unit.
///
/// # Errors
/// The bake's ([`super::bake`], [`texture::sheets`]).
pub fn measure(
    animation: &Animation,
    clip: usize,
    rate: f64,
    setting: &Setting<'_>,
    unit_cm: f64,
) -> Result<Measured, BakeError> {
    Measure::new(animation, clip, setting, unit_cm)?.at(rate, SUBSTEPS, true)
}

/// Dense frames of the truth computed at a time: its buffers stay a few megabytes, reused
/// window after window, where a whole clip's truth at 16 points an interval took gigabytes
/// and a quarter of a budget's time in page faults.
pub const WINDOW_FRAMES: usize = 512;

/// One clip's measure, its curves built once for every rate the search tries.
struct Measure<'a> {
    /// The clip alone, its skins one ([`only`]): one sheet, its columns `joints`.
    one: Animation,
    order: Vec<usize>,
    /// The sheet's columns' joints.
    joints: Vec<usize>,
    /// Whether the clip is baked as a loop.
    looping: bool,
    curves: Curves,
    /// Per joint, the broken source steps left out ([`broken_spans`]).
    broken: Vec<Vec<[f64; 2]>>,
    /// For a rigid kind whose binds are rigid: each column's bind (none for model-trs), so
    /// that the truth composes in quaternions ([`Measure::truth`]).
    binds: Option<Vec<Option<Trs>>>,
    /// For skin-trs: each column's joint in bind space ([`bind_position`]).
    bind_positions: Vec<[f64; 3]>,
    device: &'a Device,
    kind: TextureKind,
    precision: Precision,
    unit_cm: f64,
}

/// The worst rotation and position of some frames, each as its value, column and time.
#[derive(Clone, Copy, Default)]
struct Worsts {
    rotation: Option<(f64, usize, f64)>,
    position: Option<(f64, usize, f64)>,
}

impl Worsts {
    /// Takes the worst of later frames where it is larger: the first of equals kept, as one
    /// scan in order keeps it.
    fn then(mut self, later: Worsts) -> Self {
        let larger = |kept: &mut Option<(f64, usize, f64)>, found: Option<(f64, usize, f64)>| {
            if let Some(found) = found.filter(|f| kept.map_or(true, |k| f.0 > k.0)) {
                *kept = Some(found);
            }
        };
        larger(&mut self.rotation, later.rotation);
        larger(&mut self.position, later.position);
        self
    }
}

impl<'a> Measure<'a> {
    fn new(animation: &'a Animation, clip: usize, setting: &Setting<'a>, unit_cm: f64) -> Result<Self, BakeError> {
        let one = only(animation, clip);
        let order = one.parents_first()?;
        let looping = clip_loops(&one, &one.clips[0], setting.curve, setting.looping)?;
        let curves = Curves::build(&one, setting.curve, &[looping], BatchBuilder::new())?;
        let broken = broken_spans(animation, clip);
        let (device, kind, precision) = (setting.device, setting.kind, setting.precision);
        let skin = one.skins.first().filter(|_| kind.is_skin());
        let joints = skin.map_or_else(|| (0..one.joints.len()).collect(), |s| s.joints.clone());
        let binds = match skin {
            _ if !kind.is_rigid() => None,
            Some(skin) => {
                skin.inverse_bind.iter().map(|ibm| Trs::from_affine(ibm, texture::SHEAR_TOLERANCE).map(Some)).collect()
            }
            None => Some(vec![None; joints.len()]),
        };
        let bind_positions = match skin {
            Some(skin) if kind == TextureKind::SkinTrs => skin.inverse_bind.iter().map(bind_position).collect(),
            _ => Vec::new(),
        };
        Ok(Self {
            one,
            order,
            joints,
            looping,
            curves,
            broken,
            binds,
            bind_positions,
            device,
            kind,
            precision,
            unit_cm,
        })
    }

    /// The curves on `grid` (a rate's frames, or a window of them).
    fn evaluate(&self, grid: TrackTimes, rate: f64) -> Result<Baked, BakeError> {
        let clip = &self.one.clips[0];
        let clips = vec![BakedClip {
            times: grid_times(grid),
            rate,
            end: clip.span()[1],
            looping: self.looping,
            frames: Vec::new(),
        }];
        evaluate(&self.curves, clips, &[grid], self.device, Vec::new())
    }

    /// The clip's rows on `grid` as the bake lays them out (its one sheet's data).
    fn rows(&self, grid: TrackTimes, rate: f64) -> Result<Vec<f32>, BakeError> {
        let baked = self.evaluate(grid, rate)?;
        let frames: Vec<usize> = (0..baked.clips[0].times.len()).collect();
        let sheets = texture::sheet_rows(&self.one, &self.order, &baked, 0, self.kind, self.device, &frames)?;
        Ok(sheets.into_iter().next().map(|s| s.data).unwrap_or_default())
    }

    /// The rows [`Self::rows`] gives on `grid`, for the rigid kinds composed in quaternions
    /// ([`skeleton::trs_pose`]): the same rows to f32 rounding at a fraction of the cost of
    /// matrices built and taken apart, which were most of a budget's time. A pose with a
    /// parent's scales that differ by axis takes the matrices.
    fn truth(&self, grid: TrackTimes, rate: f64) -> Result<Vec<f32>, BakeError> {
        let Some(binds) = &self.binds else { return self.rows(grid, rate) };
        let baked = self.evaluate(grid, rate)?;
        let frames: Vec<usize> = (0..baked.clips[0].times.len()).collect();
        let local = texture::local_rows(&self.one, &baked, 0, &frames);
        let (parents, joints) = (self.one.parents(), self.one.joints.len());
        let width = self.joints.len() * LOCAL_CHANNELS;
        let mut data = vec![0.0f32; frames.len() * width];
        let composed =
            data.par_chunks_mut(width.max(1)).zip(local.par_chunks(joints * LOCAL_CHANNELS)).try_for_each_init(
                || vec![Trs::identity(); joints],
                |object, (out, rows)| {
                    skeleton::trs_pose(&parents, &self.order, rows, object)?;
                    for ((out, &j), bind) in out.chunks_exact_mut(LOCAL_CHANNELS).zip(&self.joints).zip(binds) {
                        let row = match bind {
                            Some(bind) => object[j].then(bind)?.row(),
                            None => object[j].row(),
                        };
                        out.iter_mut().zip(row).for_each(|(o, v)| *o = v as f32);
                    }
                    Some(())
                },
            );
        match composed {
            Some(()) => Ok(data),
            None => self.rows(grid, rate),
        }
    }

    /// [`measure`] at `points` points of each interval ([`SUBSTEPS`], or [`SCREEN_SUBSTEPS`]
    /// to screen a rate), positions only where `positions` asks (a screen of a budget in
    /// degrees alone does not): the rate's frames against the truth a window of dense frames
    /// at a time, windows on every core.
    fn at(&self, rate: f64, points: usize, positions: bool) -> Result<Measured, BakeError> {
        let [start, end] = self.one.clips[0].span();
        let (grid, fitted) = clip_frame_grid(start, end, ClipRate::Fit(rate), self.looping)?;
        let mut coarse = self.rows(grid, fitted)?;
        if self.precision == Precision::F16 {
            coarse.iter_mut().for_each(|v| *v = half::f16::from_f32(*v).to_f32());
        }
        let intervals = grid.count() - 1;
        let mut measured = Measured { rate: fitted, frames: grid.count(), ..Measured::default() };
        if intervals == 0 {
            return Ok(measured);
        }
        let (dense, dense_rate) = clip_frame_grid(start, end, ClipRate::Fit(fitted * points as f64), self.looping)?;
        let substeps = (dense.count() - 1) / intervals;
        if substeps * intervals != dense.count() - 1 {
            let (clip, frames) = (self.one.clips[0].name.clone(), dense.count());
            return Err(InputError::from(InternalError::Grid { clip, frames, substeps: points, intervals }).into());
        }
        let TrackTimes::Uniform { step, .. } = dense else { unreachable!("a fitted grid is uniform") };
        let window = WINDOW_FRAMES.max(substeps);
        let windows: Vec<Worsts> = (0..dense.count())
            .step_by(window)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|first| {
                let count = window.min(dense.count() - first);
                let last = if first + count == dense.count() { dense.grid_time(first + count - 1) } else { None };
                let Some(at) = dense.grid_time(first) else { unreachable!("a fitted grid is uniform") };
                let truth = self.truth(TrackTimes::Uniform { start: at, step, count, last }, dense_rate)?;
                let times: Vec<f64> = (first..first + count).filter_map(|k| dense.grid_time(k)).collect();
                Ok(self.compare(&coarse, &truth, [first, substeps, intervals], &times, positions))
            })
            .collect::<Result<_, BakeError>>()?;
        let worst = windows.into_iter().fold(Worsts::default(), Worsts::then);
        let named = |(value, column, time): (f64, usize, f64)| Worst {
            value,
            joint: self.one.joints[self.joints[column]].name.clone(),
            time: time - start,
        };
        if let Some(w) = worst.rotation {
            measured.rotation = named(w);
        }
        if let Some(w) = worst.position {
            measured.position = named(w);
        }
        Ok(measured)
    }

    /// The truth's rows at the dense frames `first..` (times `times`) against the renderer's
    /// blend of the rate's rows `coarse`, `substeps` dense frames an interval of `intervals`,
    /// a frame at a time on every core: the largest errors, with their column and time.
    fn compare(
        &self,
        coarse: &[f32],
        truth: &[f32],
        [first, substeps, intervals]: [usize; 3],
        times: &[f64],
        with_positions: bool,
    ) -> Worsts {
        let width = self.joints.len();
        let frame = width * LOCAL_CHANNELS;
        let per_frame = truth.par_chunks(frame.max(1)).enumerate().map_init(
            || vec![0.0f32; frame],
            |blended, (k, truth)| {
                // The last dense frame is the end of the last interval.
                let i = ((first + k) / substeps).min(intervals - 1);
                let u = (first + k - i * substeps) as f64 / substeps as f64;
                for (j, out) in blended.chunks_exact_mut(LOCAL_CHANNELS).enumerate() {
                    out.copy_from_slice(&interpolate(row(coarse, width, i, j), row(coarse, width, i + 1, j), u));
                }
                // A point inside a step of broken source data, the joint's or an ancestor's, is
                // left out.
                let t = times[k];
                let counted = |j: usize| !self.broken[self.joints[j]].iter().any(|&[a, b]| t > a && t < b);
                let largest = |values: &mut dyn Iterator<Item = f64>| {
                    values.enumerate().filter(|&(j, v)| v > 0.0 && counted(j)).fold(None, |kept, (j, v)| match kept {
                        Some((_, w)) if w >= v => kept,
                        _ => Some((j, v)),
                    })
                };
                let pairs = || blended.chunks_exact(LOCAL_CHANNELS).zip(truth.chunks_exact(LOCAL_CHANNELS));
                let rotation = largest(&mut pairs().map(|(b, t)| turn(b, t)))
                    .map(|(j, turn)| (degrees_of_turn(turn), j, times[k]));
                let position = with_positions
                    .then(|| {
                        let (p, q) = (self.positions(blended), self.positions(truth));
                        let distance = |(p, q): (&[f64; 3], &[f64; 3])| {
                            (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>().sqrt() * self.unit_cm
                        };
                        largest(&mut p.iter().zip(&q).map(distance)).map(|(j, d)| (d, j, times[k]))
                    })
                    .flatten();
                Worsts { rotation, position }
            },
        );
        // In order, so that the first of equals is kept.
        per_frame.collect::<Vec<_>>().into_iter().fold(Worsts::default(), Worsts::then)
    }

    /// Each column's joint position in model space (model units) in one frame's rows:
    /// forward kinematics of a local texture, a model-trs row's translation, a skin-trs row
    /// applied to the joint's bind position.
    fn positions(&self, rows: &[f32]) -> Vec<[f64; 3]> {
        match self.kind {
            TextureKind::Local => skeleton::forward_kinematics(&self.one.parents(), &self.order, rows)
                .chunks_exact(texture::MATRIX_CHANNELS)
                .map(|m| [3, 7, 11].map(|c| f64::from(m[c])))
                .collect(),
            TextureKind::SkinTrs if !self.bind_positions.is_empty() => rows
                .chunks_exact(LOCAL_CHANNELS)
                .zip(&self.bind_positions)
                .map(|(row, &bind)| skeleton::transform_point(&skeleton::trs_row(row), bind))
                .collect(),
            _ => rows.chunks_exact(LOCAL_CHANNELS).map(|r| [4, 5, 6].map(|c| f64::from(r[c]))).collect(),
        }
    }
}

/// Per joint, the key intervals (s) of clip `clip` in which it or an ancestor turns more than
/// [`super::SOURCE_STEP_WARNING_DEGREES`] between keys ([`super::broken_steps`]): broken
/// source data the bake warns of, which a budget leaves out rather than chase with a rate no
/// frame could follow.
fn broken_spans(animation: &Animation, clip: usize) -> Vec<Vec<[f64; 2]>> {
    let mut own = vec![Vec::new(); animation.joints.len()];
    for channel in &animation.clips[clip].channels {
        let Some((times, _)) = channel.keyed() else { continue };
        own[channel.joint].extend(super::broken_steps(channel).into_iter().map(|(i, _)| [times[i], times[i + 1]]));
    }
    (0..animation.joints.len())
        .map(|joint| {
            let (mut spans, mut at) = (Vec::new(), Some(joint));
            while let Some(j) = at {
                spans.extend_from_slice(&own[j]);
                at = animation.joints[j].parent;
            }
            spans
        })
        .collect()
}

/// Where a joint is in bind space: the point its inverse bind matrix takes to the origin.
fn bind_position(ibm: &[f64; 12]) -> [f64; 3] {
    skeleton::inverse(ibm).map_or([0.0; 3], |m| [m[3], m[7], m[11]])
}

/// How far past [`ErrorBudget::max_rate`] a refused clip's search goes to say what rate would
/// hold.
pub const REFUSAL_SEARCH: f64 = 8.0;

/// Per clip, the lowest rate whose frames keep within `budget` ([`measure`]), with what it
/// measured: a search over whole numbers of steps in the clip's span, doubling and then
/// bisecting (the error falls as the rate rises). A step is a second, or, where the curve
/// turns corners at keys (slerp: the source's own linear keys) and every key of the clip lies
/// on one uniform grid, an interval of that grid, so that rows fall on every key.
///
/// # Errors
/// [`Refusal::NoRateHolds`] naming the clip, the budget, the error at
/// [`ErrorBudget::max_rate`] and the rate that would hold (or that none up to
/// [`REFUSAL_SEARCH`] times it does) when no rate up to it holds; the bake's.
pub fn choose_rates(
    animation: &Animation,
    budget: &ErrorBudget,
    setting: &Setting<'_>,
) -> Result<Vec<Measured>, BakeError> {
    if let Some(clip) = animation.clips.iter().find(|c| c.channels.iter().any(quatcurve_anim::Channel::is_spline)) {
        return Err(Refusal::FittedBudget(clip.name.clone()).into());
    }
    let mut chosen = Vec::with_capacity(animation.clips.len());
    for (c, clip) in animation.clips.iter().enumerate() {
        let [start, end] = clip.span();
        let span = end - start;
        let rate = |intervals: f64| {
            let rate = if span > 0.0 { intervals / span } else { 1.0 };
            (setting.measuring)(&clip.name, rate);
            rate
        };
        let measure = Measure::new(animation, c, setting, budget.unit_cm)?;
        let screen = |intervals: f64| measure.at(rate(intervals), SCREEN_SUBSTEPS, budget.centimetres.is_some());
        let full = |intervals: f64| measure.at(rate(intervals), SUBSTEPS, true);
        // Intervals per step of the search, and the first step tried.
        let grid =
            key_grid(clip).filter(|&keys| setting.curve.corners_at_keys() && keys as f64 <= span * budget.max_rate);
        let (step, first) = match grid {
            Some(keys) => (keys as f64, 1.0),
            None => (1.0, span.ceil().max(1.0)),
        };
        let steps = |rate: f64| (span * rate / step).floor().max(1.0);
        let most = steps(budget.max_rate);
        let best = match screened(&screen, &full, budget, [0.0, first.min(most), most], step)? {
            Ok(best) => best,
            Err(worst) => {
                let further = [
                    most,
                    (most * 2.0).min(steps(budget.max_rate * REFUSAL_SEARCH)),
                    steps(budget.max_rate * REFUSAL_SEARCH),
                ];
                let higher = match screened(&screen, &full, budget, further, step)? {
                    Ok(m) => Ok(m.rate),
                    Err(m) => Err(m.rate),
                };
                return Err(Refusal::NoRateHolds {
                    clip: clip.name.clone(),
                    within: budget.describe(),
                    max_rate: budget.max_rate,
                    rate: worst.rate,
                    rotation: worst.rotation,
                    position: worst.position,
                    higher,
                }
                .into());
            }
        };
        chosen.push(best);
    }
    Ok(chosen)
}

/// [`lowest`] over the `screen`'s measures, then the steps it picks measured in `full`: the
/// answer when they hold, else the search goes on above them in `full` measures. The screen's
/// points are the full measure's, so a step it refuses the full measure refuses too, and
/// the rate found is the one a search of full measures alone finds. Refused: the full
/// measure at `most`.
fn screened(
    screen: &impl Fn(f64) -> Result<Measured, BakeError>,
    full: &impl Fn(f64) -> Result<Measured, BakeError>,
    budget: &ErrorBudget,
    [low, first, most]: [f64; 3],
    step: f64,
) -> Result<Result<Measured, Measured>, BakeError> {
    match lowest(screen, budget, [low, first, most], step)? {
        Ok((steps, _)) => {
            let m = full(steps * step)?;
            if budget.holds(&m) {
                return Ok(Ok(m));
            }
            if steps >= most {
                return Ok(Err(m));
            }
            Ok(lowest(full, budget, [steps, (steps + 1.0).min(most), most], step)?.map(|(_, m)| m))
        }
        Err(_) => Ok(Err(full(most * step)?)),
    }
}

/// The fewest steps above `low` (known to fail; 0: none tried), trying `first` and doubling up
/// to `most` (each step `step` intervals of the clip), whose frames keep within `budget`, and
/// what they measured (`Err`: what `most` steps measured, when they do not hold).
fn lowest(
    at: &impl Fn(f64) -> Result<Measured, BakeError>,
    budget: &ErrorBudget,
    [mut low, first, most]: [f64; 3],
    step: f64,
) -> Result<Result<(f64, Measured), Measured>, BakeError> {
    let mut high = first;
    let mut best = loop {
        let m = at(high * step)?;
        if budget.holds(&m) {
            break m;
        }
        if high >= most {
            return Ok(Err(m));
        }
        low = high;
        high = (high * 2.0).min(most);
    };
    while high - low > 1.0 {
        let mid = ((low + high) / 2.0).floor();
        let m = at(mid * step)?;
        if budget.holds(&m) {
            high = mid;
            best = m;
        } else {
            low = mid;
        }
    }
    Ok(Ok((high, best)))
}

/// How far (a fraction of its step) a key may be from a uniform grid and lie on it: exporters
/// round key times (BrainStem's 37.5 Hz keys are up to 0.14% of a step off theirs).
pub const KEY_GRID_TOLERANCE: f64 = 0.005;

/// The finest key grid a budget looks for, as a fraction of a channel's shortest (or mean)
/// step between keys.
pub const KEY_GRID_DIVISORS: usize = 8;

/// Where every key of `clip` (every channel's, two keys or more) lies on one uniform grid
/// from its first key to its last: that grid's intervals (each key within
/// [`KEY_GRID_TOLERANCE`] of a step from a grid time; the coarsest such grid found).
fn key_grid(clip: &Clip) -> Option<usize> {
    let [start, end] = clip.span();
    let keys = || clip.channels.iter().filter_map(|c| c.keyed().map(|(t, _)| t)).filter(|t| t.len() > 1);
    // The step: the shortest between a channel's own keys (a channel with gaps on the grid),
    // else the densest channel's mean (keys rounded off their grid: the shortest step is
    // short of it), or a whole fraction of either (Fox's Run: 24 Hz frames and keys a fifth of
    // one off them).
    let mean = keys().map(|t| (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64).fold(f64::INFINITY, f64::min);
    let shortest = keys().flat_map(|t| t.windows(2).map(|w| w[1] - w[0])).fold(f64::INFINITY, f64::min);
    let steps = [shortest, mean].into_iter().flat_map(|s| (1..=KEY_GRID_DIVISORS).map(move |k| s / k as f64));
    steps.filter(|&step| step.is_finite() && step > 0.0).find_map(|step| {
        let intervals = ((end - start) / step).round().max(1.0);
        let step = (end - start) / intervals;
        let on_grid = |t: &f64| {
            let i = ((t - start) / step).round();
            (t - start - i * step).abs() <= KEY_GRID_TOLERANCE * step
        };
        keys().flatten().all(on_grid).then_some(intervals as usize)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A measure whose rotation error at `steps` is `error(steps)` (its rate the steps).
    fn measured(error: impl Fn(f64) -> f64) -> impl Fn(f64) -> Result<Measured, BakeError> {
        move |steps| {
            let rotation = Worst { value: error(steps), ..Worst::default() };
            Ok(Measured { rate: steps, rotation, ..Measured::default() })
        }
    }

    #[test]
    fn a_screened_search_picks_what_a_search_of_full_measures_picks() {
        let budget = ErrorBudget { degrees: Some(1.0), centimetres: None, unit_cm: 1.0, max_rate: 480.0 };
        let full = |steps: f64| 100.0 / steps;
        // The screen sees the worst point, or misses it and sees half the error.
        for seen in [1.0, 0.5] {
            let screen = measured(move |s| seen * full(s));
            let name = format!("the screen sees {seen} of the error");
            let alone = lowest(&measured(full), &budget, [0.0, 3.0, 400.0], 1.0).unwrap().unwrap();
            let picked = screened(&screen, &measured(full), &budget, [0.0, 3.0, 400.0], 1.0).unwrap().unwrap();
            assert_eq!(picked.rate, alone.1.rate, "{name}");
            assert_eq!(picked.rate, 102.0, "{name}: 100 / 102 is within 0.99 degrees");
        }
        // Refused: the full measure at the most steps.
        let refused = screened(&measured(full), &measured(full), &budget, [0.0, 3.0, 50.0], 1.0).unwrap().unwrap_err();
        assert_eq!(refused.rate, 50.0);
    }

    fn about_z(degrees: f64) -> [f32; 4] {
        let h = degrees.to_radians() / 2.0;
        [0.0, 0.0, h.sin() as f32, h.cos() as f32]
    }

    /// A chain of two joints, the child turning about z through 60 keys at 30 Hz on a smooth
    /// path; with `flip`, one key turned half a turn about x (a tracking flip).
    fn arm(flip: bool) -> Animation {
        use quatcurve_anim::{Channel, Joint, Property};
        let joints = vec![Joint::at("root".into(), None, [0.0; 3]), Joint::at("arm".into(), Some(0), [0.0, 1.0, 0.0])];
        let times: Vec<f64> = (0..60).map(|k| f64::from(k) / 30.0).collect();
        let mut values: Vec<[f64; 4]> = times
            .iter()
            .map(|t| {
                let h = (0.8 * (3.0 * t).sin()) / 2.0;
                [0.0, 0.0, h.sin(), h.cos()]
            })
            .collect();
        if flip {
            values[30] = [1.0, 0.0, 0.0, 0.0];
        }
        let turn = Channel::keys(1, Property::Rotation, times, values);
        Animation { joints, clips: vec![Clip { name: "wave".into(), channels: vec![turn] }], skins: Vec::new() }
    }

    /// The source's curves, no loop, f32, on `device`, for a texture of `kind`.
    fn setting(kind: TextureKind, device: &Device) -> Setting<'_> {
        Setting {
            curve: &CurveChoice::Source,
            looping: LoopMode::Off,
            kind,
            precision: Precision::F32,
            device,
            measuring: &|_, _| {},
        }
    }

    #[test]
    fn a_flipped_key_is_left_out_of_a_budget_not_chased_with_a_higher_rate() {
        let device = Device::open(quatcurve_device::DeviceChoice::Cpu).unwrap();
        let setting = setting(TextureKind::Local, &device);
        let budget = ErrorBudget { degrees: Some(0.5), centimetres: None, unit_cm: 1000.0, max_rate: 480.0 };
        let [clean, flipped] =
            [false, true].map(|flip| choose_rates(&arm(flip), &budget, &setting).unwrap()[0].clone());
        assert_eq!(super::super::broken_steps(&arm(true).clips[0].channels[0]).len(), 2, "into the flip and out");
        assert_eq!(flipped.rate, clean.rate, "the flip chased: {flipped:?}");
        assert!(flipped.rotation.value <= 0.5, "{flipped:?}");
    }

    /// [`arm`] with three skins: a body over both joints, its joints mesh (the same), and a
    /// hand bound to the arm twice as far out.
    fn skinned_arm() -> Animation {
        let mut animation = arm(false);
        let bind = |y: f64| [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -y, 0.0, 0.0, 1.0, 0.0];
        let skin = |name: &str, joints: Vec<usize>, at: &[f64]| Skin {
            name: name.into(),
            joints,
            inverse_bind: at.iter().map(|&y| bind(y)).collect(),
            skeleton: None,
        };
        animation.skins = vec![
            skin("body", vec![0, 1], &[0.0, 1.0]),
            skin("joints", vec![0, 1], &[0.0, 1.0]),
            skin("hand", vec![1], &[2.0]),
        ];
        animation
    }

    #[test]
    fn the_truth_composed_in_quaternions_is_the_bake_s_rows_and_skins_are_measured_as_one() {
        let device = Device::open(quatcurve_device::DeviceChoice::Cpu).unwrap();
        let setting = setting(TextureKind::SkinTrs, &device);
        let animation = skinned_arm();
        let measure = Measure::new(&animation, 0, &setting, 100.0).unwrap();
        assert_eq!(measure.joints, [0, 1, 1], "each joint and bind once");
        assert!(measure.binds.is_some(), "rigid binds compose in quaternions");
        let grid = TrackTimes::Uniform { start: 0.0, step: 1.0 / 97.0, count: 190, last: None };
        let (truth, rows) = (measure.truth(grid, 97.0).unwrap(), measure.rows(grid, 97.0).unwrap());
        assert_eq!(truth.len(), rows.len());
        for (k, (t, r)) in truth.chunks(LOCAL_CHANNELS).zip(rows.chunks(LOCAL_CHANNELS)).enumerate() {
            assert!(angle_degrees(t, r) < 1e-4, "row {k}: {t:?} against {r:?}");
            assert!(t[4..].iter().zip(&r[4..]).all(|(a, b)| (a - b).abs() < 1e-6), "row {k}: {t:?} against {r:?}");
        }
        // The skins as one measure each skin's worst: here the hand's, the farthest out.
        let alone = |k: usize| {
            let mut alone = animation.clone();
            alone.skins = vec![animation.skins[k].clone()];
            measure_of(&alone, 45.0, &setting)
        };
        let (all, body, hand) = (measure.at(45.0, SUBSTEPS, true).unwrap(), alone(0), alone(2));
        assert_eq!(all.rotation.value, body.rotation.value.max(hand.rotation.value));
        assert_eq!(all.position, hand.position);
        assert!(hand.position.value > body.position.value * 1.5, "{hand:?} against {body:?}");
    }

    fn measure_of(animation: &Animation, rate: f64, setting: &Setting<'_>) -> Measured {
        measure(animation, 0, rate, setting, 100.0).unwrap()
    }

    #[test]
    fn the_angle_is_the_rotation_s_not_the_quaternions() {
        for degrees in [0.01, 0.5, 30.0, 179.0] {
            let e = angle_degrees(&about_z(0.0), &about_z(degrees));
            assert!((e - degrees).abs() < 1e-4 * degrees.max(1.0), "{degrees}: {e}");
            // q and -q are one rotation.
            let minus = about_z(degrees).map(|v| -v);
            assert!((angle_degrees(&about_z(0.0), &minus) - degrees).abs() < 1e-4 * degrees.max(1.0));
        }
    }

    #[test]
    fn interpolation_blends_on_the_shorter_arc_and_lerps_the_rest() {
        let mut a = [0.0f32; LOCAL_CHANNELS];
        let mut b = [0.0f32; LOCAL_CHANNELS];
        a[..4].copy_from_slice(&about_z(0.0));
        // The second frame's quaternion on the far side: still a 40 degree turn.
        b[..4].copy_from_slice(&about_z(40.0).map(|v| -v));
        a[4..].copy_from_slice(&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        b[4..].copy_from_slice(&[2.0, 4.0, 6.0, 3.0, 1.0, 1.0]);
        let mid = interpolate(&a, &b, 0.5);
        // nlerp of a symmetric pair lands on the half-way rotation.
        assert!((angle_degrees(&mid, &about_z(20.0)) - 0.0).abs() < 1e-3);
        assert_eq!(&mid[4..], &[1.0, 2.0, 3.0, 2.0, 1.0, 1.0]);
    }

    fn clip(channels: &[&[f64]]) -> Clip {
        let channel = |times: &[f64]| {
            let values = vec![[0.0, 0.0, 0.0, 1.0]; times.len()];
            quatcurve_anim::Channel::keys(0, quatcurve_anim::Property::Rotation, times.to_vec(), values)
        };
        Clip { name: "c".into(), channels: channels.iter().map(|t| channel(t)).collect() }
    }

    #[test]
    fn keys_on_one_uniform_grid_give_its_intervals_and_keys_off_it_none() {
        let grid = |n: usize, step: f64| (0..=n).map(|i| i as f64 * step).collect::<Vec<_>>();
        // Every channel on 24 Hz, one with gaps; a one-key channel does not count.
        let gaps = [0.0, 1.0 / 24.0, 5.0 / 24.0, 1.0];
        assert_eq!(key_grid(&clip(&[&grid(24, 1.0 / 24.0), &gaps, &[0.3]])), Some(24));
        // Keys rounded off their grid by 0.4% of a step, a channel's times apart.
        let jittered: Vec<f64> =
            grid(300, 1.0 / 37.5).iter().enumerate().map(|(i, t)| t + if i % 7 == 3 { 1e-4 } else { 0.0 }).collect();
        assert_eq!(key_grid(&clip(&[&jittered, &grid(300, 1.0 / 37.5)])), Some(300));
        // Fox's Run: 24 Hz frames, then keys a fifth of a frame off them: a 120 Hz grid.
        let run = [0.0, 1.0 / 24.0, 2.0 / 24.0, 20.8 / 24.0, 21.8 / 24.0];
        assert_eq!(key_grid(&clip(&[&run])), Some(109));
        // Keys at no fraction of a step up to the eighth: none.
        let off = [0.0, 0.1, 0.2, 0.2 + 0.1 * std::f64::consts::FRAC_1_SQRT_2];
        assert_eq!(key_grid(&clip(&[&off])), None);
        // Two channels on grids of their own (30 and 24 Hz) share one of 120 Hz.
        assert_eq!(key_grid(&clip(&[&grid(30, 1.0 / 30.0), &grid(24, 1.0 / 24.0)])), Some(120));
    }

    #[test]
    fn bind_positions_undo_the_inverse_bind_matrix() {
        // Inverse bind: a quarter turn about z, scale 2, then translation; the joint sits where
        // the matrix takes to the origin.
        let ibm = [0.0, -2.0, 0.0, 1.0, 2.0, 0.0, 0.0, 2.0, 0.0, 0.0, 2.0, 3.0];
        let p = bind_position(&ibm);
        let back: Vec<f64> = (0..3)
            .map(|r| ibm[4 * r] * p[0] + ibm[4 * r + 1] * p[1] + ibm[4 * r + 2] * p[2] + ibm[4 * r + 3])
            .collect();
        assert!(back.iter().all(|v| v.abs() < 1e-12), "{back:?}");
    }
}
