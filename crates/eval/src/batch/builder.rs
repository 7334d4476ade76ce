//! [`BatchBuilder`]: the only way to make a [`Batch`]. Tracks are validated and prepared
//! (`families`) on every core, a slice at a time, and appended to the packed arrays, sharing
//! a knot vector between consecutive tracks keyed at the same times.

use super::families::{check_half_turn, prepare_all, PackedData};
use super::keys::{aligned, check_key_count};
use super::knots::{check_explicit_knots, check_order, knots_are_uniform};
use super::{Batch, PackedTrack};
use crate::error::{Error, Result, TrackId};
use crate::track::Track;
use quatcurve_core::curve::{Curve, CurveSpec, MAX_ORDER};
use quatcurve_core::quat::{relative_log, QuatF64};

/// Tracks [`BatchBuilder::extend`] prepares at once.
pub(super) const EXTEND_CHUNK: usize = 1 << 14;

/// Tracks one core prepares together (a multiple of the solve's four lanes).
const LANE_GROUP: usize = 64;

/// An open B-spline as evaluators read it ([`BatchBuilder::extend_splines`]): its name, its
/// control points and its knot vector.
#[derive(Clone, Copy, Debug)]
pub struct Spline<'a> {
    /// For messages, as a track's name.
    pub name: Option<&'a str>,
    /// Control points `x, y, z, w` (normalized and made sign-continuous as keys are).
    pub points: &'a [[f64; 4]],
    /// The knot vector: `points.len() + k` knots for order `k`.
    pub knots: &'a [f64],
    /// Its form: [`Curve::BSpline`] (KKS's cumulative form) or [`Curve::NormalizedBSpline`].
    pub curve: Curve,
}

impl Spline<'_> {
    /// The coefficients it packs: one per step between control points for the cumulative
    /// form, none for the normalized one.
    fn coef_count(&self) -> usize {
        if self.curve == Curve::NormalizedBSpline {
            0
        } else {
            self.points.len().saturating_sub(1)
        }
    }
}

/// Builds a [`Batch`] track by track or slice by slice; tracks may use different curve specs.
#[derive(Debug)]
pub struct BatchBuilder {
    batch: Batch,
}

impl Default for BatchBuilder {
    fn default() -> Self {
        Self { batch: Batch::empty() }
    }
}

impl BatchBuilder {
    /// An empty builder.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty builder on `batch`'s arrays, its tracks dropped: one that builds batch after
    /// batch (a decoder baking clip after clip) writes into pages it already touched.
    #[must_use]
    pub fn reusing(mut batch: Batch) -> Self {
        batch.first_index = 0;
        let mut builder = Self { batch };
        builder.truncate(0, [0; 3]);
        builder
    }

    /// Validates `track` for `spec` and appends it; returns its index in the batch.
    ///
    /// # Errors
    /// The first rule broken, naming the track and key; the builder is unchanged then.
    pub fn add(&mut self, track: &Track, spec: &CurveSpec) -> Result<usize> {
        let index = self.batch.tracks.len();
        let id = TrackId { index, name: track.name.clone() };
        let packed = prepare_all(&[(id, track, *spec)]).pop().expect("one track in, one out")?;
        self.append_all(std::slice::from_ref(track), |_| *spec, &[packed]);
        Ok(index)
    }

    /// Validates and appends an open B-spline given as evaluators read it: control points
    /// `points` on the knot vector `knots` ([`BatchBuilder::extend_splines`] of one).
    ///
    /// # Errors
    /// As [`BatchBuilder::add`] for that track; the builder is unchanged then.
    pub fn add_spline(
        &mut self,
        name: Option<&str>,
        points: &[[f64; 4]],
        knots: &[f64],
        curve: Curve,
    ) -> Result<usize> {
        self.extend_splines(&[Spline { name, points, knots, curve }]).map(|range| range.start)
    }

    /// Validates and appends open B-splines given as evaluators read them, each of its form
    /// and the order its counts make ([`CurveSpec::open_spline`] of `knots.len() -
    /// points.len()`; a normalized one packs no coefficients), checked
    /// as a [`Track`] with explicit knots is and packed as it would be, on every core. Straight
    /// into the packed arrays, with no track and no copy per step: a fitted container's
    /// channels built through tracks cost more than evaluating them. Returns their indices.
    ///
    /// # Errors
    /// As [`BatchBuilder::extend`] for those tracks (the first rule broken, in slice order);
    /// the builder is unchanged then.
    pub fn extend_splines(&mut self, splines: &[Spline<'_>]) -> Result<std::ops::Range<usize>> {
        use rayon::prelude::*;
        let b = &mut self.batch;
        let first = b.tracks.len();
        // Where each goes, and which knots it shares with the track before it (as `append_all`
        // shares them): decided in order, before any work.
        let mut last_knots: Option<&[f64]> = b.tracks.last().map(|t| &b.knots[t.knot_offset..][..t.knot_count]);
        let mut own = Vec::with_capacity(splines.len());
        for spline in splines {
            own.push(last_knots != Some(spline.knots));
            last_knots = Some(spline.knots);
        }
        let lengths = |s: &Spline<'_>, own: bool| [s.points.len(), s.coef_count(), if own { s.knots.len() } else { 0 }];
        let totals = splines.iter().zip(&own).fold([0; 3], |sum, (s, &own)| {
            let [p, c, k] = lengths(s, own);
            [sum[0] + p, sum[1] + c, sum[2] + k]
        });
        b.points.reserve(totals[0]);
        b.coefs.reserve(totals[1]);
        b.knots.reserve(totals[2]);
        let (mut points, mut coefs, mut knots) = (
            &mut b.points.spare_capacity_mut()[..totals[0]],
            &mut b.coefs.spare_capacity_mut()[..totals[1]],
            &mut b.knots.spare_capacity_mut()[..totals[2]],
        );
        let mut slots = Vec::with_capacity(splines.len());
        for (s, &own) in splines.iter().zip(&own) {
            let [p, c, k] = lengths(s, own);
            let (these, rest) = std::mem::take(&mut points).split_at_mut(p);
            points = rest;
            let (their_coefs, rest) = std::mem::take(&mut coefs).split_at_mut(c);
            coefs = rest;
            let (their_knots, rest) = std::mem::take(&mut knots).split_at_mut(k);
            knots = rest;
            slots.push((these, their_coefs, their_knots));
        }
        let checked: Vec<Result<()>> = splines
            .par_iter()
            .zip(slots)
            .enumerate()
            .with_min_len(8)
            .map(|(i, (spline, (points, coefs, knots)))| {
                let id = TrackId { index: first + i, name: spline.name.map(str::to_owned) };
                let order = spline.knots.len().saturating_sub(spline.points.len());
                let spec = CurveSpec::open_spline(spline.curve, order);
                check_key_count(&id, &spec, spline.points.len())?;
                check_order(&id, order)?;
                let normalized = spline.curve == Curve::NormalizedBSpline;
                // A normalized spline's last `order - 1` points, for its rule: each new point
                // against them.
                let mut recent = [QuatF64::identity(); MAX_ORDER];
                let mut prev = None;
                for (j, q) in aligned(&id, spline.points).enumerate() {
                    let q = q?;
                    points[j].write(q);
                    if normalized {
                        for i in j.saturating_sub(order - 1)..j {
                            check_half_turn(&id, &spec, (i, recent[i % MAX_ORDER]), (j, q))?;
                        }
                        recent[j % MAX_ORDER] = q;
                    } else if let Some(prev) = prev {
                        let v = relative_log(prev, q);
                        coefs[j - 1].write([v.x, v.y, v.z, 0.0]);
                    }
                    prev = Some(q);
                }
                check_explicit_knots(&id, spline.knots, order, spline.points.len() - 1)?;
                for (slot, &knot) in knots.iter_mut().zip(spline.knots) {
                    slot.write(knot);
                }
                Ok(())
            })
            .collect();
        checked.into_iter().collect::<Result<()>>()?;
        // SAFETY: the slots split the first `totals` spare elements of each array into the
        // splines' lengths, and every spline that checked (all of them, here) wrote every
        // element of its slots: each point, a step between each two, its own knots.
        unsafe {
            b.points.set_len(b.points.len() + totals[0]);
            b.coefs.set_len(b.coefs.len() + totals[1]);
            b.knots.set_len(b.knots.len() + totals[2]);
        }
        let (mut point_offset, mut coef_offset) = (b.points.len() - totals[0], b.coefs.len() - totals[1]);
        let mut knot_at = b.knots.len() - totals[2];
        for (spline, &own) in splines.iter().zip(&own) {
            let (knot_offset, uniform_knots) = match b.tracks.last() {
                Some(last) if !own => (last.knot_offset, last.uniform_knots),
                _ => {
                    knot_at += spline.knots.len();
                    (knot_at - spline.knots.len(), knots_are_uniform(spline.knots))
                }
            };
            let (order, last) = (spline.knots.len() - spline.points.len(), spline.points.len() - 1);
            let coef_count = spline.coef_count();
            b.tracks.push(PackedTrack {
                curve: spline.curve,
                order,
                bezier_degree: 0,
                blend: CurveSpec::open_spline(spline.curve, order).blend,
                point_offset,
                point_count: spline.points.len(),
                coef_offset,
                coef_count,
                knot_offset,
                knot_count: spline.knots.len(),
                domain: [spline.knots[order - 1], spline.knots[last + 1]],
                looping: false,
                uniform_knots,
            });
            b.names.push(spline.name);
            point_offset += spline.points.len();
            coef_offset += coef_count;
        }
        Ok(first..b.tracks.len())
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
        // PackedData a chunk at a time (bspline-interp solves a Newton system per track), so the
        // per-track vectors of only one chunk are alive beside the packed arrays.
        for (c, chunk) in tracks.chunks(EXTEND_CHUNK).enumerate() {
            let offset = c * EXTEND_CHUNK;
            // Slices of LANE_GROUP tracks, so that a clip's channels meet in one slice and
            // share the solve's SIMD lanes.
            let prepared: Result<Vec<PackedData>> = chunk
                .par_chunks(LANE_GROUP)
                .enumerate()
                .map(|(s, slice)| {
                    let items: Vec<(TrackId, &Track, CurveSpec)> = slice
                        .iter()
                        .enumerate()
                        .map(|(i, track)| {
                            let i = offset + s * LANE_GROUP + i;
                            (TrackId { index: first + i, name: track.name.clone() }, track, spec(i))
                        })
                        .collect();
                    prepare_all(&items)
                })
                .flatten_iter()
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
            self.append_all(chunk, |i| spec(offset + i), &prepared);
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

    /// Appends prepared tracks, track `i` with curve `spec(i)`. Offsets and knot sharing are
    /// decided in order; the arrays are then copied on every core (the copy into fresh pages,
    /// one track at a time on one core, was a quarter of a `bspline-interp` build).
    fn append_all(&mut self, tracks: &[Track], spec: impl Fn(usize) -> CurveSpec, prepared: &[PackedData]) {
        let b = &mut self.batch;
        // Tracks keyed at the same times (the channels of a clip, a synthetic batch) share one
        // knot vector: views only slice the array, and a million 32-key tracks save 0.3 GB.
        let mut shared_with_last = b
            .tracks
            .last()
            .filter(|last| {
                prepared.first().is_some_and(|p| b.knots[last.knot_offset..][..last.knot_count] == p.knots[..])
            })
            .map(|last| (last.knot_offset, last.uniform_knots));
        let (mut point_at, mut coef_at, mut knot_at) = (b.points.len(), b.coefs.len(), b.knots.len());
        let mut own_knots = Vec::with_capacity(prepared.len());
        for (i, (track, packed)) in tracks.iter().zip(prepared).enumerate() {
            let (knot_offset, uniform_knots) =
                shared_with_last.unwrap_or_else(|| (knot_at, knots_are_uniform(&packed.knots)));
            let spec = spec(i);
            b.tracks.push(PackedTrack {
                curve: packed.curve,
                order: packed.order,
                bezier_degree: packed.bezier_degree,
                blend: spec.blend,
                point_offset: point_at,
                point_count: packed.points.len(),
                coef_offset: coef_at,
                coef_count: packed.coefs.len(),
                knot_offset,
                knot_count: packed.knots.len(),
                domain: packed.domain,
                looping: spec.looping,
                uniform_knots,
            });
            b.names.push(track.name.as_deref());
            if shared_with_last.is_none() {
                own_knots.push(&packed.knots[..]);
                knot_at += packed.knots.len();
            }
            point_at += packed.points.len();
            coef_at += packed.coefs.len();
            shared_with_last =
                prepared.get(i + 1).filter(|next| next.knots == packed.knots).map(|_| (knot_offset, uniform_knots));
        }
        extend_on_every_core(&mut b.points, &prepared.iter().map(|p| &p.points[..]).collect::<Vec<_>>());
        extend_on_every_core(&mut b.coefs, &prepared.iter().map(|p| &p.coefs[..]).collect::<Vec<_>>());
        extend_on_every_core(&mut b.knots, &own_knots);
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

/// Appends `parts`, in order, to `v`, each part copied by whichever core takes it.
fn extend_on_every_core<T: Copy + Send + Sync>(v: &mut Vec<T>, parts: &[&[T]]) {
    use rayon::prelude::*;
    let total: usize = parts.iter().map(|p| p.len()).sum();
    v.reserve(total);
    let mut spare = &mut v.spare_capacity_mut()[..total];
    let mut slots = Vec::with_capacity(parts.len());
    for part in parts {
        let (slot, rest) = std::mem::take(&mut spare).split_at_mut(part.len());
        slots.push(slot);
        spare = rest;
    }
    slots.into_par_iter().zip(parts).with_min_len(64).for_each(|(slot, part)| {
        for (to, &from) in slot.iter_mut().zip(part.iter()) {
            to.write(from);
        }
    });
    // SAFETY: the slots split the first `total` spare elements into the parts' lengths, and
    // every element of every slot was written above.
    unsafe { v.set_len(v.len() + total) };
}
