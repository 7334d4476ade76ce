//! The offline builder: validates user tracks and packs them into the flat batch layout that
//! every evaluator (reference, fast CPU, GPU) consumes (DESIGN section 4).
//!
//! All per-track preparation happens here, once, in `f64`: normalization and hemisphere
//! alignment of the keys, tangent estimation, the log-coefficients `w_i`, squad's auxiliary
//! points, Hermite's three coefficients per segment, B-spline control points (with phantom
//! points) and full knot vectors. Evaluators then only locate a segment and multiply
//! exponentials; they never branch on knot modes or tangent sources.
//!
//! What the packed arrays hold per family (`coefs` entries are `[x, y, z, extra]`):
//!
//! | family  | points            | knots                   | coefs                                   |
//! |---------|-------------------|-------------------------|-----------------------------------------|
//! | slerp   | keys              | key times               | `w_i`, i = 1..=n                        |
//! | squad   | keys              | key times               | auxiliary quaternion `s_i` (xyzw), per key |
//! | bezier  | keys              | `[tau_0, tau_n]`        | `w_i`, i = 1..=n                        |
//! | hermite | keys              | key times               | `w1, w2, w3` per segment; `w2.extra` = start sign (+-1) |
//! | nam-kim | keys              | key times               | `a, b` per segment (half angle per unit segment parameter) |
//! | bspline | control points    | full knot vector (n+k+1) | `w_i`, i = 1..=m over control points  |
//!
//! `bspline-interp` is packed as a cubic `bspline` on explicit knots once [`crate::interp`] has
//! solved its control points. Looping tracks (`CurveSpec::looping`) are packed like open ones
//! with their seam neighbours built in (tangents, auxiliary and phantom points, periodic control
//! points) and [`PackedTrack::looping`] set, so that evaluators wrap sample times.

use crate::curve::{Curve, CurveSpec, KnotMode, Tangents, MAX_ORDER, MIN_ORDER};
use crate::error::{Error, Result, TrackId};
use crate::quat::relative_log;
use crate::quat::{DQuat, DVec3};
use crate::track::Track;
use std::f64::consts::PI;

/// Keys with a norm below this are errors (they carry no direction).
pub const MIN_KEY_NORM: f64 = 1e-6;
/// Relative tolerance on key spacing for knot modes that need uniform times.
pub const UNIFORM_TIME_TOLERANCE: f64 = 1e-3;
/// Below this length Hermite's middle coefficient has no axis for extra turns.
pub const MIN_TURN_AXIS: f64 = 1e-12;

/// One track's slice of the packed arrays and its parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct PackedTrack {
    /// The curve family.
    pub curve: Curve,
    /// B-spline order k; for Bezier the degree n; 0 otherwise.
    pub order: usize,
    /// Nam-Kim blend function.
    pub blend: crate::curve::Blend,
    /// First entry in [`Batch::points`].
    pub point_offset: usize,
    /// Number of entries in [`Batch::points`].
    pub point_count: usize,
    /// First entry in [`Batch::coefs`].
    pub coef_offset: usize,
    /// Number of entries in [`Batch::coefs`].
    pub coef_count: usize,
    /// First entry in [`Batch::knots`].
    pub knot_offset: usize,
    /// Number of entries in [`Batch::knots`].
    pub knot_count: usize,
    /// The domain `[start, end]`; sample times are clamped to it, or wrapped when looping.
    pub domain: [f64; 2],
    /// A periodic track: times outside the domain wrap by its length
    /// (DESIGN section 3; `segment::wrap` inside the crate).
    pub looping: bool,
    /// Equally spaced knots ([`knots_are_uniform`]), decided once here: the CPU and GPU
    /// paths then find spans by arithmetic and use the fixed polynomial span bases.
    pub uniform_knots: bool,
}

/// Relative spacing tolerance of [`knots_are_uniform`].
pub const UNIFORM_KNOT_TOLERANCE: f64 = 1e-9;

/// Whether a knot vector is equally spaced (to [`UNIFORM_KNOT_TOLERANCE`]).
#[must_use]
pub fn knots_are_uniform(knots: &[f64]) -> bool {
    let n = knots.len();
    if n < 2 || knots[n - 1] <= knots[0] {
        return false;
    }
    let dt = (knots[n - 1] - knots[0]) / (n - 1) as f64;
    knots.windows(2).all(|w| ((w[1] - w[0]) - dt).abs() <= UNIFORM_KNOT_TOLERANCE * dt)
}

/// The tracks' names, in one string with where each ends: a million named tracks are one
/// allocation, not a million small ones beside the packed arrays. An empty name reads as none.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TrackNames {
    text: String,
    ends: Vec<usize>,
}

impl TrackNames {
    /// Track `index`'s name, if it has one.
    ///
    /// # Panics
    /// When `index` is past the end, like slice indexing.
    #[must_use]
    pub fn get(&self, index: usize) -> Option<&str> {
        let start = index.checked_sub(1).map_or(0, |i| self.ends[i]);
        Some(&self.text[start..self.ends[index]]).filter(|name| !name.is_empty())
    }

    /// Number of tracks.
    #[must_use]
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// Whether there is no track.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    fn push(&mut self, name: Option<&str>) {
        self.text.push_str(name.unwrap_or(""));
        self.ends.push(self.text.len());
    }

    fn truncate(&mut self, tracks: usize) {
        self.ends.truncate(tracks);
        self.text.truncate(self.ends.last().copied().unwrap_or(0));
    }
}

/// Many tracks packed flat (CSR style). Build one with [`BatchBuilder`] or [`Batch::from_tracks`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Batch {
    /// Per-track parameters and offsets.
    pub tracks: Vec<PackedTrack>,
    /// Per-track names, for messages ([`Batch::id`]).
    pub names: TrackNames,
    /// The index messages give the first track: 0, or where a [`Batch::subset`] starts in the
    /// batch it was taken from.
    pub first_index: usize,
    /// Unit quaternions: keys or control points, sign-continuous within each track.
    pub points: Vec<DQuat>,
    /// Derived coefficients, `[x, y, z, extra]` (see the module table).
    pub coefs: Vec<[f64; 4]>,
    /// Segment boundaries or B-spline knot vectors; consecutive tracks with equal knots share
    /// one entry (a track's are `knots[knot_offset..knot_offset + knot_count]`).
    pub knots: Vec<f64>,
}

impl Batch {
    /// Builds a batch of `tracks`, all with the same curve `spec`.
    ///
    /// # Errors
    /// The first rule broken, naming the track and key ([`Error`]).
    pub fn from_tracks(tracks: &[Track], spec: &CurveSpec) -> Result<Self> {
        Self::from_tracks_each(tracks, |_| *spec)
    }

    /// Builds a batch of `tracks`, track `i` with curve `spec(i)` (a bake mixes looping and
    /// open clips).
    ///
    /// # Errors
    /// The first rule broken, naming the track and key ([`Error`]).
    pub fn from_tracks_each(tracks: &[Track], spec: impl Fn(usize) -> CurveSpec + Sync) -> Result<Self> {
        let mut builder = BatchBuilder::new();
        builder.extend(tracks, spec)?;
        builder.build()
    }

    /// Number of tracks.
    #[must_use]
    pub fn len(&self) -> usize {
        self.tracks.len()
    }

    /// Whether the batch has no track.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.tracks.is_empty()
    }

    /// A batch of the tracks in `range` alone (their packed data copied, offsets rebased), so
    /// that a large job can run in pieces of bounded memory. Track ids keep their index in
    /// `self`, so messages still name the track the user gave.
    ///
    /// # Panics
    /// When `range` reaches past the end, like slice indexing.
    #[must_use]
    pub fn subset(&self, range: std::ops::Range<usize>) -> Batch {
        let mut out = Batch { first_index: self.first_index + range.start, ..Batch::default() };
        for index in range {
            out.names.push(self.names.get(index));
            let view = self.view(index);
            out.tracks.push(PackedTrack {
                point_offset: out.points.len(),
                coef_offset: out.coefs.len(),
                knot_offset: out.knots.len(),
                ..view.track.clone()
            });
            out.points.extend_from_slice(view.points);
            out.coefs.extend_from_slice(view.coefs);
            out.knots.extend_from_slice(view.knots);
        }
        out
    }

    /// Track `index` as messages name it: its index (in the batch a subset was taken from) and
    /// its name.
    #[must_use]
    pub fn id(&self, index: usize) -> TrackId {
        TrackId { index: self.first_index + index, name: self.names.get(index).map(str::to_owned) }
    }

    /// The slices of the packed arrays that belong to track `index`, or `None` past the end.
    #[must_use]
    pub fn get(&self, index: usize) -> Option<TrackView<'_>> {
        (index < self.tracks.len()).then(|| self.view(index))
    }

    /// The slices of the packed arrays that belong to track `index`.
    ///
    /// # Panics
    /// When `index >= self.len()`, like slice indexing; [`Batch::get`] returns an `Option`.
    #[must_use]
    pub fn view(&self, index: usize) -> TrackView<'_> {
        let t = &self.tracks[index];
        TrackView {
            track: t,
            points: &self.points[t.point_offset..t.point_offset + t.point_count],
            coefs: &self.coefs[t.coef_offset..t.coef_offset + t.coef_count],
            knots: &self.knots[t.knot_offset..t.knot_offset + t.knot_count],
        }
    }
}

/// Borrowed view of one packed track.
#[derive(Clone, Copy, Debug)]
pub struct TrackView<'a> {
    /// Parameters.
    pub track: &'a PackedTrack,
    /// Keys or control points.
    pub points: &'a [DQuat],
    /// Derived coefficients.
    pub coefs: &'a [[f64; 4]],
    /// Segment boundaries or knot vector.
    pub knots: &'a [f64],
}

/// Tracks [`BatchBuilder::extend`] prepares at once.
const EXTEND_CHUNK: usize = 1 << 14;

/// Builds a [`Batch`] track by track or slice by slice; tracks may use different curve specs.
#[derive(Debug, Default)]
pub struct BatchBuilder {
    batch: Batch,
}

impl BatchBuilder {
    /// An empty builder.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Validates `track` for `spec` and appends it; returns its index in the batch.
    ///
    /// # Errors
    /// The first rule broken, naming the track and key; the builder is unchanged then.
    pub fn add(&mut self, track: &Track, spec: &CurveSpec) -> Result<usize> {
        let index = self.batch.tracks.len();
        let id = TrackId { index, name: track.name.clone() };
        let packed = prepare(&id, track, spec)?;
        Ok(self.append(track, spec, packed))
    }

    /// Validates and appends `tracks`, track `i` of the slice with curve `spec(i)`, preparing
    /// them on every core; returns their indices in the batch. A caller with more tracks than
    /// it wants in memory at once passes them in slices and drops each after.
    ///
    /// # Errors
    /// The first rule broken (the first track's in slice order), naming the track (by its
    /// index in the batch) and key; the builder is unchanged then.
    pub fn extend(
        &mut self,
        tracks: &[Track],
        spec: impl Fn(usize) -> CurveSpec + Sync,
    ) -> Result<std::ops::Range<usize>> {
        use rayon::prelude::*;
        let b = &self.batch;
        let (first, lengths) = (b.tracks.len(), [b.points.len(), b.coefs.len(), b.knots.len()]);
        // Prepared a chunk at a time (bspline-interp solves a Newton system per track), so the
        // per-track vectors of only one chunk are alive beside the packed arrays.
        for (c, chunk) in tracks.chunks(EXTEND_CHUNK).enumerate() {
            let offset = c * EXTEND_CHUNK;
            let prepared: Result<Vec<Prepared>> = chunk
                .par_iter()
                .enumerate()
                .with_min_len(64)
                .map(|(i, track)| {
                    prepare(&TrackId { index: first + offset + i, name: track.name.clone() }, track, &spec(offset + i))
                })
                .collect();
            let prepared = match prepared {
                Ok(prepared) => prepared,
                Err(e) => {
                    self.truncate(first, lengths);
                    return Err(e);
                }
            };
            // Room for every track at the first chunk's sizes (exact for a batch of alike
            // tracks): arrays of hundreds of MB grown by doubling cost copies and fresh pages.
            let scale = |n: usize| if c == 0 { n * tracks.len() / chunk.len() } else { n };
            let b = &mut self.batch;
            b.tracks.reserve(scale(prepared.len()));
            b.names.ends.reserve(scale(prepared.len()));
            b.points.reserve(scale(prepared.iter().map(|p| p.points.len()).sum()));
            b.coefs.reserve(scale(prepared.iter().map(|p| p.coefs.len()).sum()));
            b.knots.reserve(scale(prepared.iter().map(|p| p.knots.len()).sum()));
            for (i, (track, packed)) in chunk.iter().zip(prepared).enumerate() {
                self.append(track, &spec(offset + i), packed);
            }
        }
        Ok(first..self.batch.tracks.len())
    }

    /// Drops every track from index `tracks` on, the packed arrays back to `lengths`.
    fn truncate(&mut self, tracks: usize, [points, coefs, knots]: [usize; 3]) {
        let b = &mut self.batch;
        b.tracks.truncate(tracks);
        b.names.truncate(tracks);
        b.points.truncate(points);
        b.coefs.truncate(coefs);
        b.knots.truncate(knots);
    }

    /// Appends a prepared track; returns its index.
    fn append(&mut self, track: &Track, spec: &CurveSpec, packed: Prepared) -> usize {
        let index = self.batch.tracks.len();
        let b = &mut self.batch;
        // Tracks keyed at the same times (the channels of a clip, a synthetic batch) share one
        // knot vector: views only slice the array, and a million 32-key tracks save 0.3 GB.
        let shared = b
            .tracks
            .last()
            .filter(|last| b.knots[last.knot_offset..last.knot_offset + last.knot_count] == packed.knots[..]);
        let (knot_offset, uniform_knots) = match shared {
            Some(last) => (last.knot_offset, last.uniform_knots),
            None => (b.knots.len(), knots_are_uniform(&packed.knots)),
        };
        let share = shared.is_some();
        b.tracks.push(PackedTrack {
            curve: packed.curve,
            order: packed.order,
            blend: spec.blend,
            point_offset: b.points.len(),
            point_count: packed.points.len(),
            coef_offset: b.coefs.len(),
            coef_count: packed.coefs.len(),
            knot_offset,
            knot_count: packed.knots.len(),
            domain: packed.domain,
            looping: spec.looping,
            uniform_knots,
        });
        b.points.extend(packed.points);
        b.coefs.extend(packed.coefs);
        if !share {
            b.knots.extend(packed.knots);
        }
        b.names.push(track.name.as_deref());
        index
    }

    /// Finishes the batch.
    ///
    /// # Errors
    /// [`Error::EmptyBatch`] when no track was added.
    pub fn build(self) -> Result<Batch> {
        if self.batch.is_empty() {
            return Err(Error::EmptyBatch);
        }
        Ok(self.batch)
    }
}

/// One track's packed data before it is appended.
struct Prepared {
    /// The family evaluators run (`bspline` for `bspline-interp`).
    curve: Curve,
    order: usize,
    points: Vec<DQuat>,
    coefs: Vec<[f64; 4]>,
    knots: Vec<f64>,
    domain: [f64; 2],
}

fn prepare(id: &TrackId, track: &Track, spec: &CurveSpec) -> Result<Prepared> {
    let keys = aligned_keys(id, &track.rotations, spec)?;
    let times = key_times(id, track.times.as_deref(), keys.len())?;
    let n = keys.len() - 1;
    if spec.looping {
        check_loop(id, spec, &keys)?;
    }
    let (t0, tn) = (times[0], times[n]);
    let vec_coef = |v: DVec3| [v.x, v.y, v.z, 0.0];
    let steps = || (1..=n).map(|i| vec_coef(relative_log(keys[i - 1], keys[i])));
    let piecewise = |coefs: Vec<[f64; 4]>, points: Vec<DQuat>| Prepared {
        curve: spec.curve,
        order: 0,
        coefs,
        points,
        knots: times.clone(),
        domain: [t0, tn],
    };
    Ok(match spec.curve {
        Curve::Slerp => piecewise(steps().collect(), keys),
        Curve::Bezier => Prepared {
            curve: spec.curve,
            order: n,
            coefs: steps().collect(),
            points: keys,
            knots: vec![t0, tn],
            domain: [t0, tn],
        },
        Curve::Squad => piecewise(squad_points(&keys, spec.looping).into_iter().map(DQuat::to_array).collect(), keys),
        Curve::Hermite => {
            let omega = key_velocities(id, track, spec, &keys, &times)?;
            let coefs = hermite_coefs(id, track, &keys, &times, &omega)?;
            piecewise(coefs, keys)
        }
        Curve::NamKim => {
            let omega = key_velocities(id, track, spec, &keys, &times)?;
            let coefs = (0..n)
                .flat_map(|i| {
                    let half_t = 0.5 * (times[i + 1] - times[i]);
                    [vec_coef(omega[i].scale(half_t)), vec_coef(omega[i + 1].scale(half_t))]
                })
                .collect();
            piecewise(coefs, keys)
        }
        Curve::BSpline => bspline(id, track, spec, keys, &times)?,
        Curve::BSplineInterp => {
            let solved =
                crate::interp::solve_rotations(&keys, &times, spec.looping).map_err(|e| Error::NoConvergence {
                    track: id.clone(),
                    key: e.worst_key,
                    error: e.error,
                    iterations: e.iterations,
                    tolerance: crate::interp::KEY_TOLERANCE,
                })?;
            let coefs = solved.coefs.into_iter().map(vec_coef).collect();
            Prepared {
                curve: Curve::BSpline,
                order: 4,
                points: solved.points,
                coefs,
                knots: solved.knots,
                domain: [t0, tn],
            }
        }
    })
}

/// Largest angle (rad) between a looping track's last key and its first (DESIGN section 3).
pub const LOOP_TOLERANCE: f64 = 1e-3;

/// A looping spec must be a family that loops, and the keys must close.
fn check_loop(id: &TrackId, spec: &CurveSpec, keys: &[DQuat]) -> Result<()> {
    if !spec.can_loop() {
        return Err(Error::LoopUnsupported {
            track: id.clone(),
            curve: curve_label(spec),
            looping: CurveSpec::looping_curves(),
        });
    }
    let angle = keys[0].angle_to(keys[keys.len() - 1]);
    if angle.is_nan() || angle > LOOP_TOLERANCE {
        return Err(Error::LoopNotClosed { track: id.clone(), last: keys.len() - 1, angle, tolerance: LOOP_TOLERANCE });
    }
    Ok(())
}

/// The curve as messages name it: B-splines with their order and knot mode.
fn curve_label(spec: &CurveSpec) -> String {
    match spec.curve {
        Curve::BSpline => format!("bspline order {} with {} knots", spec.order, spec.knots),
        other => other.to_string(),
    }
}

/// Normalizes keys and makes them sign-continuous (DESIGN section 1).
fn aligned_keys(id: &TrackId, rotations: &[[f64; 4]], spec: &CurveSpec) -> Result<Vec<DQuat>> {
    let min = spec.min_keys();
    if rotations.len() < min {
        return Err(Error::TooFewKeys { track: id.clone(), curve: curve_label(spec), min, found: rotations.len() });
    }
    let mut keys: Vec<DQuat> = Vec::with_capacity(rotations.len());
    for (key, &value) in rotations.iter().enumerate() {
        let q = normalized_key(id, key, value)?;
        keys.push(match keys.last() {
            Some(&prev) => q.aligned_with(prev),
            None => q,
        });
    }
    Ok(keys)
}

/// Key `key` of track `id` as a unit quaternion: finite and not (near) zero. The one check of
/// a rotation key, also for the keys bake holds constant.
pub(crate) fn normalized_key(id: &TrackId, key: usize, value: [f64; 4]) -> Result<DQuat> {
    let q = DQuat::from_array(value);
    if !q.is_finite() {
        return Err(Error::NonFiniteKey { track: id.clone(), key, value });
    }
    let norm = q.length();
    if norm < MIN_KEY_NORM {
        return Err(Error::ZeroKey { track: id.clone(), key, norm, min: MIN_KEY_NORM });
    }
    Ok(q.mul_scalar(1.0 / norm))
}

/// The key times, defaulting to `0, 1, ..., n`; finite and strictly increasing.
pub(crate) fn key_times(id: &TrackId, times: Option<&[f64]>, count: usize) -> Result<Vec<f64>> {
    let Some(times) = times else {
        return Ok((0..count).map(|i| i as f64).collect());
    };
    if times.len() != count {
        return Err(Error::TimesCount { track: id.clone(), expected: count, found: times.len() });
    }
    for (key, &value) in times.iter().enumerate() {
        if !value.is_finite() {
            return Err(Error::NonFiniteTime { track: id.clone(), key, value });
        }
        if key > 0 && value <= times[key - 1] {
            return Err(Error::TimesNotIncreasing { track: id.clone(), key, value, previous: times[key - 1] });
        }
    }
    Ok(times.to_vec())
}

/// Squad's auxiliary points `s_i = q_i exp(-(log(q_i^-1 q_{i+1}) + log(q_i^-1 q_{i-1})) / 4)`
/// (P eq. 19), with `s_0 = q_0` and `s_n = q_n`; looping, `s_0` uses `q_{n-1}` before it and
/// `s_n` is `q_n` times the same body offset, so both sides of the seam agree.
fn squad_points(keys: &[DQuat], looping: bool) -> Vec<DQuat> {
    let n = keys.len() - 1;
    let offset =
        |i: usize, prev: DQuat, next: DQuat| (relative_log(keys[i], next) + relative_log(keys[i], prev)).scale(-0.25);
    let seam = looping.then(|| offset(0, keys[n - 1], keys[1]));
    (0..=n)
        .map(|i| {
            if i == 0 || i == n {
                return seam.map_or(keys[i], |v| keys[i] * DQuat::exp(v));
            }
            keys[i] * DQuat::exp(offset(i, keys[i - 1], keys[i + 1]))
        })
        .collect()
}

/// The non-uniform Catmull-Rom body angular velocity at `key` from its neighbours `prev`
/// (`d0` before) and `next` (`d1` after), DESIGN section 3.
fn catmull_rom(key: DQuat, prev: DQuat, next: DQuat, d0: f64, d1: f64) -> DVec3 {
    let back = -relative_log(key, prev).scale(1.0 / d0);
    let ahead = relative_log(key, next).scale(1.0 / d1);
    (back.scale(d1 / (d0 + d1)) + ahead.scale(d0 / (d0 + d1))).scale(2.0)
}

/// Body angular velocity (rad/s) at each key, from the chosen source (DESIGN section 3).
fn key_velocities(id: &TrackId, track: &Track, spec: &CurveSpec, keys: &[DQuat], times: &[f64]) -> Result<Vec<DVec3>> {
    let n = keys.len() - 1;
    match spec.tangents {
        Tangents::Zero => Ok(vec![DVec3::zero(); n + 1]),
        Tangents::Given => {
            let given = track.angular_velocities.as_deref().unwrap_or(&[]);
            if given.len() != n + 1 {
                return Err(Error::VelocityCount { track: id.clone(), expected: n + 1, found: given.len() });
            }
            given
                .iter()
                .enumerate()
                .map(|(key, &value)| {
                    if value.iter().all(|c| c.is_finite()) {
                        Ok(DVec3::from_array(value))
                    } else {
                        Err(Error::NonFiniteVelocity { track: id.clone(), key, value })
                    }
                })
                .collect()
        }
        Tangents::CatmullRom => {
            // Across a loop's seam key 0 sees key n-1 before it (d_{-1} = d_{n-1}); key n
            // takes the same body velocity, so both sides of the seam agree.
            let seam = spec
                .looping
                .then(|| catmull_rom(keys[0], keys[n - 1], keys[1], times[n] - times[n - 1], times[1] - times[0]));
            Ok((0..=n)
                .map(|i| match seam {
                    Some(v) if i == 0 || i == n => v,
                    _ if i == 0 => relative_log(keys[0], keys[1]).scale(2.0 / (times[1] - times[0])),
                    _ if i == n => relative_log(keys[n - 1], keys[n]).scale(2.0 / (times[n] - times[n - 1])),
                    _ => {
                        catmull_rom(keys[i], keys[i - 1], keys[i + 1], times[i] - times[i - 1], times[i + 1] - times[i])
                    }
                })
                .collect())
        }
    }
}

/// KKS section 5.2 per segment: `w1 = w_a/3`, `w3 = w_b/3` used as given (never folded), and
/// `w2 = log(q_1^-1 q_2)` with `q_1 = q_a exp(w1)`, `q_2 = q_b exp(-w3)` folded to the short
/// way, plus `pi * m` along its axis for `m` extra turns.
///
/// When the fold negates `q_2`, the segment's product runs from `q_a` to `-q_b`. To keep the
/// output sign-continuous, segment `i` starts from `sigma_i q_i` where `sigma_i` is the product
/// of the fold signs of segments `0..i`, stored in `w2`'s fourth slot. Rotations are unchanged.
fn hermite_coefs(id: &TrackId, track: &Track, keys: &[DQuat], times: &[f64], omega: &[DVec3]) -> Result<Vec<[f64; 4]>> {
    let n = keys.len() - 1;
    let turns = match &track.extra_turns {
        Some(turns) if turns.len() != n => {
            return Err(Error::ExtraTurnsCount { track: id.clone(), expected: n, found: turns.len() })
        }
        Some(turns) => turns.clone(),
        None => vec![0; n],
    };
    let mut coefs = Vec::with_capacity(3 * n);
    let mut start_sign = 1.0;
    for i in 0..n {
        let half_t = 0.5 * (times[i + 1] - times[i]);
        let w1 = omega[i].scale(half_t / 3.0);
        let w3 = omega[i + 1].scale(half_t / 3.0);
        let q1 = keys[i] * DQuat::exp(w1);
        let q2 = keys[i + 1] * DQuat::exp(-w3);
        let sign = if q1.dot(q2) < 0.0 { -1.0 } else { 1.0 };
        let mut w2 = (q1.conjugate() * q2.mul_scalar(sign)).log();
        if turns[i] != 0 {
            let len = w2.length();
            if len < MIN_TURN_AXIS {
                return Err(Error::ExtraTurnOnZeroArc { track: id.clone(), segment: i, turns: turns[i] });
            }
            w2 = w2 + w2.scale(PI * turns[i] as f64 / len);
        }
        coefs.push([w1.x, w1.y, w1.z, 0.0]);
        coefs.push([w2.x, w2.y, w2.z, start_sign]);
        coefs.push([w3.x, w3.y, w3.z, 0.0]);
        start_sign *= sign;
    }
    Ok(coefs)
}

/// Checks `|tau_i - tau_0 - i dt| <= 1e-3 dt` (DESIGN section 3).
fn check_uniform(id: &TrackId, times: &[f64], mode: KnotMode) -> Result<()> {
    let n = times.len() - 1;
    let dt = (times[n] - times[0]) / n as f64;
    for (key, &value) in times.iter().enumerate() {
        let expected = times[0] + key as f64 * dt;
        if (value - expected).abs() > UNIFORM_TIME_TOLERANCE * dt {
            return Err(Error::NonUniformTimes {
                track: id.clone(),
                key,
                value,
                expected,
                mode: mode.to_string(),
                tolerance: UNIFORM_TIME_TOLERANCE,
            });
        }
    }
    Ok(())
}

/// `a + (b - a) s` written so that `s = 0` gives `a` and `s = 1` gives `b` exactly.
fn lerp(a: f64, b: f64, s: f64) -> f64 {
    a * (1.0 - s) + b * s
}

/// Control points, knot vector and coefficients of a B-spline track (DESIGN section 3).
fn bspline(id: &TrackId, track: &Track, spec: &CurveSpec, keys: Vec<DQuat>, times: &[f64]) -> Result<Prepared> {
    let k = spec.order;
    let knots = bspline_knots(id, track.knots.as_deref(), spec, times)?;
    let points = if spec.knots == KnotMode::Phantom {
        // q_-1 = q_0 q_1^-1 q_0 and q_{n+1} = q_n q_{n-1}^-1 q_n: the key steps mirrored; or,
        // looping, the neighbours across the seam carried over it: q_-1 = q_0 q_n^-1 q_{n-1}
        // and q_{n+1} = q_n q_0^-1 q_1 (key n-1 and key 1 when the keys close exactly).
        let n = keys.len() - 1;
        let (first, last) = if spec.looping {
            (keys[0] * keys[n].conjugate() * keys[n - 1], keys[n] * keys[0].conjugate() * keys[1])
        } else {
            (keys[0] * keys[1].conjugate() * keys[0], keys[n] * keys[n - 1].conjugate() * keys[n])
        };
        let mut points = Vec::with_capacity(n + 3);
        points.push(first);
        points.extend_from_slice(&keys);
        points.push(last);
        points
    } else {
        keys
    };
    let m = points.len() - 1;
    let mut coefs: Vec<[f64; 4]> = (1..=m)
        .map(|i| {
            let w = relative_log(points[i - 1], points[i]);
            [w.x, w.y, w.z, 0.0]
        })
        .collect();
    if spec.knots == KnotMode::Phantom && !spec.looping {
        // q_-1^-1 q_0 = q_0^-1 q_1 exactly (and likewise at the end): reuse the key's
        // coefficient so the curve passes through q_0 and q_n to rounding.
        coefs[0] = coefs[1];
        coefs[m - 1] = coefs[m - 2];
    }
    let domain = [knots[k - 1], knots[m + 1]];
    Ok(Prepared { curve: Curve::BSpline, order: k, points, coefs, knots, domain })
}

/// The full knot vector of a B-spline through `times.len()` keys (DESIGN section 3): phantom
/// knots cover the two phantom control points too (`n + 7` knots), the other modes `n + k + 1`.
/// Shared with the Euclidean analogue ([`crate::euclidean`]), so both use the same basis.
pub(crate) fn bspline_knots(
    id: &TrackId,
    explicit: Option<&[f64]>,
    spec: &CurveSpec,
    times: &[f64],
) -> Result<Vec<f64>> {
    let k = spec.order;
    if !(MIN_ORDER..=MAX_ORDER).contains(&k) {
        return Err(Error::BadOrder {
            track: id.clone(),
            reason: format!("bspline order {k} is outside {MIN_ORDER}..={MAX_ORDER}"),
        });
    }
    let n = times.len() - 1;
    let (t0, tn) = (times[0], times[n]);
    Ok(match spec.knots {
        KnotMode::Phantom => {
            if k != 4 {
                return Err(Error::BadOrder {
                    track: id.clone(),
                    reason: format!(
                        "phantom knots are defined for order 4 only, not {k}; use uniform, clamped or explicit"
                    ),
                });
            }
            check_uniform(id, times, spec.knots)?;
            // Control points c_0..c_{n+2}; knots t_j = tau_0 + (j - 3) dt, j = 0..=n+6.
            (0..n + 7).map(|j| lerp(t0, tn, (j as f64 - 3.0) / n as f64)).collect()
        }
        KnotMode::Uniform => {
            check_uniform(id, times, spec.knots)?;
            (0..=n + k).map(|j| lerp(t0, tn, (j as f64 - (k as f64 - 1.0)) / n as f64)).collect()
        }
        KnotMode::Clamped => {
            let inner = n + 2 - k;
            let mut knots = vec![t0; k];
            knots.extend((1..inner).map(|j| lerp(t0, tn, j as f64 / inner as f64)));
            knots.extend(std::iter::repeat(tn).take(k));
            knots
        }
        KnotMode::Explicit => explicit_knots(id, explicit, k, n)?,
    })
}

/// Validates a user knot vector: length n + k + 1, finite, non-decreasing, multiplicity at most
/// k - 1 strictly inside the domain and at most k elsewhere, non-empty domain.
fn explicit_knots(id: &TrackId, knots: Option<&[f64]>, k: usize, n: usize) -> Result<Vec<f64>> {
    let expected = n + k + 1;
    let knots = knots.unwrap_or(&[]);
    if knots.len() != expected {
        return Err(Error::KnotCount { track: id.clone(), order: k, keys: n + 1, expected, found: knots.len() });
    }
    for (knot, &value) in knots.iter().enumerate() {
        if !value.is_finite() {
            return Err(Error::NonFiniteKnot { track: id.clone(), knot, value });
        }
        if knot > 0 && value < knots[knot - 1] {
            return Err(Error::KnotsDecreasing { track: id.clone(), knot, value, previous: knots[knot - 1] });
        }
    }
    let (start, end) = (knots[k - 1], knots[n + 1]);
    if start >= end {
        return Err(Error::EmptyDomain { track: id.clone(), first: k - 1, last: n + 1, start, end });
    }
    let mut run_start = 0;
    for knot in 1..=knots.len() {
        if knot < knots.len() && knots[knot] == knots[run_start] {
            continue;
        }
        let multiplicity = knot - run_start;
        let value = knots[run_start];
        let inside = value > start && value < end;
        let (max, place) = if inside { (k - 1, "inside the domain") } else { (k, "at or outside the domain ends") };
        if multiplicity > max {
            return Err(Error::KnotMultiplicity {
                track: id.clone(),
                knot: run_start,
                value,
                multiplicity,
                max,
                order: k,
                place,
            });
        }
        run_start = knot;
    }
    Ok(knots.to_vec())
}

#[cfg(test)]
mod tests {
    use super::{BatchBuilder, TrackId};
    use crate::curve::{Curve, CurveSpec};
    use crate::track::Track;

    fn named(name: Option<&str>, key_norm: f64) -> Track {
        Track {
            name: name.map(str::to_owned),
            times: Some(vec![0.0, 1.0, 2.0]),
            ..Track::from_rotations(vec![[0.0, 0.0, 0.0, key_norm]; 3])
        }
    }

    /// Names read back per track (empty as none), a failed `extend` leaves no name behind (also
    /// when it fails after appending a slice), and a subset's messages keep the indices and
    /// names of the batch it came from.
    #[test]
    fn track_names_survive_failed_extends_and_subsets() {
        let spec = CurveSpec::new(Curve::Slerp);
        let mut builder = BatchBuilder::new();
        builder.extend(&[named(Some("a"), 1.0), named(None, 1.0)], |_| spec).unwrap();
        assert!(builder.extend(&[named(Some("dropped"), 1.0), named(Some("bad"), 0.0)], |_| spec).is_err());
        // A failure in a later slice: the first slice was appended and must be taken back.
        let mut many: Vec<Track> = (0..=super::EXTEND_CHUNK).map(|i| named(Some(&format!("n{i}")), 1.0)).collect();
        many[super::EXTEND_CHUNK] = named(Some("bad"), 0.0);
        assert!(builder.extend(&many, |_| spec).is_err());
        builder.extend(&[named(Some(""), 1.0), named(Some("dé"), 1.0)], |_| spec).unwrap();
        let batch = builder.build().unwrap();
        let id = |index: usize, name: Option<&str>| TrackId { index, name: name.map(str::to_owned) };
        assert_eq!(
            (0..4).map(|i| batch.id(i)).collect::<Vec<_>>(),
            [id(0, Some("a")), id(1, None), id(2, None), id(3, Some("dé"))]
        );
        let subset = batch.subset(1..4).subset(1..3);
        assert_eq!(subset.names.len(), 2);
        assert_eq!([subset.id(0), subset.id(1)], [id(2, None), id(3, Some("dé"))]);
    }
}
