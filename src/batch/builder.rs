//! [`BatchBuilder`]: the only way to make a [`Batch`]. Tracks are validated and prepared
//! (`families`) on every core, a slice at a time, and appended to the packed arrays, sharing
//! a knot vector between consecutive tracks keyed at the same times.

use super::families::{prepare_all, PackedData};
use super::knots::knots_are_uniform;
use super::{Batch, PackedTrack};
use crate::curve::CurveSpec;
use crate::error::{Error, Result, TrackId};
use crate::track::Track;

/// Tracks [`BatchBuilder::extend`] prepares at once.
pub(super) const EXTEND_CHUNK: usize = 1 << 14;

/// Tracks one core prepares together (a multiple of the solve's four lanes).
const LANE_GROUP: usize = 64;

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

    /// Validates `track` for `spec` and appends it; returns its index in the batch.
    ///
    /// # Errors
    /// The first rule broken, naming the track and key; the builder is unchanged then.
    pub fn add(&mut self, track: &Track, spec: &CurveSpec) -> Result<usize> {
        let index = self.batch.tracks.len();
        let id = TrackId { index, name: track.name.clone() };
        let packed = prepare_all(&[(id, track, *spec)]).pop().expect("one track in, one out")?;
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
    fn append(&mut self, track: &Track, spec: &CurveSpec, packed: PackedData) -> usize {
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
            bezier_degree: packed.bezier_degree,
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
