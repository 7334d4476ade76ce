//! The packed batch every evaluator (reference, fast CPU, GPU) consumes (DESIGN section 4),
//! and its offline builder, the only way to make one: [`BatchBuilder`] (in `builder`) validates
//! user tracks and packs them; the per-family preparation is `families` (shared with the
//! Euclidean analogue), key and time rules `keys`, knot vectors `knots`.
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
//! | normalized-bspline | control points | as bspline     | none                                    |
//!
//! `bspline-interp` is packed as a cubic `bspline` on explicit knots once [`quatcurve_core::interp`] has
//! solved its control points. Looping tracks (`CurveSpec::looping`) are packed like open ones
//! with their seam neighbours built in (tangents, auxiliary and phantom points, periodic control
//! points) and [`PackedTrack::looping`] set, so that evaluators wrap sample times.

mod builder;
mod families;
mod keys;
mod knots;

pub use builder::{BatchBuilder, Spline};
pub use families::MIN_TURN_AXIS;
pub(crate) use families::{catmull_rom_velocities, squad_points};
pub use keys::key_times;
pub use keys::normalized_key;
pub use keys::{loop_gap, LOOP_TOLERANCE, MIN_KEY_NORM};
pub(crate) use knots::bspline_knots;
pub use knots::{knots_are_uniform, UNIFORM_KNOT_TOLERANCE, UNIFORM_TIME_TOLERANCE};

use crate::error::{Result, TrackId};
use crate::track::Track;
use quatcurve_core::curve::{Blend, Curve, CurveSpec};
use quatcurve_core::quat::QuatF64;

/// One track's slice of the packed arrays and its parameters, as [`BatchBuilder`] made it
/// (read-only: the offsets and counts always lie inside the batch's arrays).
#[derive(Clone, Debug, PartialEq)]
pub struct PackedTrack {
    curve: Curve,
    order: usize,
    bezier_degree: usize,
    blend: Blend,
    point_offset: usize,
    point_count: usize,
    coef_offset: usize,
    coef_count: usize,
    knot_offset: usize,
    knot_count: usize,
    domain: [f64; 2],
    looping: bool,
    uniform_knots: bool,
}

impl PackedTrack {
    /// The family evaluators run (`bspline` for a `bspline-interp` track, once solved).
    #[must_use]
    pub fn curve(&self) -> Curve {
        self.curve
    }

    /// B-spline order k (degree k - 1); 0 for the other families.
    #[must_use]
    pub fn order(&self) -> usize {
        self.order
    }

    /// A Bezier curve's degree n (its keys are its n + 1 control points); 0 for the others.
    #[must_use]
    pub fn bezier_degree(&self) -> usize {
        self.bezier_degree
    }

    /// Nam-Kim's blend function.
    #[must_use]
    pub fn blend(&self) -> Blend {
        self.blend
    }

    /// First entry in [`Batch::points`].
    #[must_use]
    pub fn point_offset(&self) -> usize {
        self.point_offset
    }

    /// Entries in [`Batch::points`].
    #[must_use]
    pub fn point_count(&self) -> usize {
        self.point_count
    }

    /// First entry in [`Batch::coefs`].
    #[must_use]
    pub fn coef_offset(&self) -> usize {
        self.coef_offset
    }

    /// Entries in [`Batch::coefs`].
    #[must_use]
    pub fn coef_count(&self) -> usize {
        self.coef_count
    }

    /// First entry in [`Batch::knots`] (consecutive tracks with equal knots share them).
    #[must_use]
    pub fn knot_offset(&self) -> usize {
        self.knot_offset
    }

    /// Entries in [`Batch::knots`].
    #[must_use]
    pub fn knot_count(&self) -> usize {
        self.knot_count
    }

    /// The domain `[start, end]`; sample times are clamped to it, or wrapped when looping.
    #[must_use]
    pub fn domain(&self) -> [f64; 2] {
        self.domain
    }

    /// A periodic track: times outside the domain wrap by its length (DESIGN section 3).
    #[must_use]
    pub fn looping(&self) -> bool {
        self.looping
    }

    /// Equally spaced knots ([`knots_are_uniform`]), decided once by the builder: the CPU and
    /// GPU paths then find spans by arithmetic and use the fixed polynomial span bases.
    #[must_use]
    pub fn uniform_knots(&self) -> bool {
        self.uniform_knots
    }
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

/// Many tracks packed flat (CSR style). Made only by [`BatchBuilder`] (or
/// [`Batch::from_tracks`]), so its offsets always lie inside its arrays; read through its
/// accessors and [`Batch::view`].
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    tracks: Vec<PackedTrack>,
    names: TrackNames,
    /// The index messages give the first track: 0, or where a [`Batch::subset`] starts in the
    /// batch it was taken from.
    first_index: usize,
    points: Vec<QuatF64>,
    coefs: Vec<[f64; 4]>,
    knots: Vec<f64>,
}

impl Batch {
    /// Builds a batch of `tracks`, all with the same curve `spec`.
    ///
    /// # Errors
    /// The first rule broken, naming the track and key ([`crate::error::Error`]).
    pub fn from_tracks(tracks: &[Track], spec: &CurveSpec) -> Result<Self> {
        Self::from_tracks_each(tracks, |_| *spec)
    }

    /// Builds a batch of `tracks`, track `i` with curve `spec(i)` (a bake mixes looping and
    /// open clips).
    ///
    /// # Errors
    /// The first rule broken, naming the track and key ([`crate::error::Error`]).
    pub fn from_tracks_each(tracks: &[Track], spec: impl Fn(usize) -> CurveSpec + Sync) -> Result<Self> {
        let mut builder = BatchBuilder::new();
        builder.extend(tracks, spec)?;
        builder.build()
    }

    /// Per-track parameters and offsets.
    #[must_use]
    pub fn tracks(&self) -> &[PackedTrack] {
        &self.tracks
    }

    /// Unit quaternions: keys or control points, sign-continuous within each track.
    #[must_use]
    pub fn points(&self) -> &[QuatF64] {
        &self.points
    }

    /// Derived coefficients, `[x, y, z, extra]` (see the module table).
    #[must_use]
    pub fn coefs(&self) -> &[[f64; 4]] {
        &self.coefs
    }

    /// Segment boundaries or B-spline knot vectors; consecutive tracks with equal knots share
    /// one entry (a track's are `knots[knot_offset..knot_offset + knot_count]`).
    #[must_use]
    pub fn knots(&self) -> &[f64] {
        &self.knots
    }

    /// Per-track names, for messages ([`Batch::id`]).
    #[must_use]
    pub fn names(&self) -> &TrackNames {
        &self.names
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
        let mut out = Batch::empty();
        out.first_index = self.first_index + range.start;
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

    /// No track yet (the builder's start).
    fn empty() -> Self {
        Batch {
            tracks: Vec::new(),
            names: TrackNames::default(),
            first_index: 0,
            points: Vec::new(),
            coefs: Vec::new(),
            knots: Vec::new(),
        }
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
    pub points: &'a [QuatF64],
    /// Derived coefficients.
    pub coefs: &'a [[f64; 4]],
    /// Segment boundaries or knot vector.
    pub knots: &'a [f64],
}

#[cfg(test)]
mod tests {
    use super::{BatchBuilder, Spline, TrackId};
    use crate::track::Track;
    use quatcurve_core::curve::{Curve, CurveSpec};

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
        let mut many: Vec<Track> =
            (0..=super::builder::EXTEND_CHUNK).map(|i| named(Some(&format!("n{i}")), 1.0)).collect();
        many[super::builder::EXTEND_CHUNK] = named(Some("bad"), 0.0);
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

    /// A spline added as control points and knots packs as the same track with explicit knots
    /// does: unnormalized and sign-flipped points, orders 2 and 4, knots shared with the track
    /// before when equal, a reused builder; and every broken rule is the same error, naming
    /// the same track and key, with the builder left as it was.
    #[test]
    fn a_spline_packs_and_fails_as_its_track_does() {
        use quatcurve_core::curve::{Curve, CurveSpec};
        // Either form: the cumulative one's coefficients, the normalized one's rule.
        for curve in [Curve::BSpline, Curve::NormalizedBSpline] {
            let spec_of = |order: usize| CurveSpec::open_spline(curve, order);
            let point = |i: usize| {
                let a = 0.3 * i as f64;
                let sign = if i % 3 == 1 { -2.0 } else { 0.5 };
                [sign * a.sin() * 0.3, sign * a.cos() * 0.2, sign * 0.1, sign * (1.0 + 0.1 * a)]
            };
            let points: Vec<[f64; 4]> = (0..7).map(point).collect();
            let cubic = vec![0.0, 0.0, 0.0, 0.0, 0.5, 0.5, 1.5, 2.0, 2.0, 2.0, 2.0];
            let keys = vec![0.0, 0.0, 0.25, 0.5, 1.0, 1.5, 1.75, 2.0, 2.0];
            let inputs = [(Some("a"), &cubic), (Some("b"), &cubic), (None, &keys)];
            let track = |(name, knots): (Option<&str>, &Vec<f64>)| Track {
                name: name.map(str::to_owned),
                knots: Some(knots.clone()),
                rotations: points.clone(),
                ..Track::default()
            };
            let tracks: Vec<Track> = inputs.iter().map(|&(n, k)| track((n, k))).collect();
            let want = super::Batch::from_tracks_each(&tracks, |i| {
                spec_of(tracks[i].knots.as_ref().unwrap().len() - points.len())
            })
            .unwrap();
            let mut builder = BatchBuilder::reusing(want.clone());
            for &(name, knots) in &inputs {
                builder.add_spline(name, &points, knots, curve).unwrap();
            }
            let got = builder.build().unwrap();
            assert_eq!(got, want, "{curve:?}");
            assert_eq!(got.knots().len(), cubic.len() + keys.len(), "the second cubic shares the first's knots");
            let splines: Vec<Spline<'_>> =
                inputs.iter().map(|&(name, knots)| Spline { name, points: &points, knots, curve }).collect();
            let mut builder = BatchBuilder::new();
            assert_eq!(builder.extend_splines(&splines).unwrap(), 0..3);
            assert_eq!(builder.build().unwrap(), want, "{curve:?}: all at once");

            let mut bad_point = points.clone();
            bad_point[4] = [0.0; 4];
            let mut decreasing = cubic.clone();
            decreasing[5] = 0.25;
            let mut repeated = keys.clone();
            repeated[3] = 0.25;
            // Points 4 and 5 half a turn apart: the normalized form's packers name the same
            // pair; the cumulative one takes them.
            let mut apart = points.clone();
            apart[4] = [0.0, 0.0, 1.0, 0.0];
            apart[5] = [0.0, 0.0, 0.0, 1.0];
            for (points, knots) in [
                (&bad_point, &cubic),
                (&points, &decreasing),
                (&points, &repeated),
                (&points, &cubic[..10].to_vec()),
                (&points[..2].to_vec(), &vec![0.0, 1.0, 2.0]),
                (&points[..3].to_vec(), &vec![0.0; 12]),
                (&apart, &cubic),
            ] {
                let spec = spec_of(knots.len().saturating_sub(points.len()));
                let track = Track {
                    name: Some("t".into()),
                    knots: Some(knots.clone()),
                    rotations: points.clone(),
                    ..Track::default()
                };
                let mut builder = BatchBuilder::new();
                builder.add(&tracks[0], &spec_of(4)).unwrap();
                let Err(want) = builder.add(&track, &spec) else {
                    assert_eq!(curve, Curve::BSpline, "only the cumulative form takes points apart");
                    continue;
                };
                assert_eq!(builder.add_spline(Some("t"), points, knots, curve).unwrap_err(), want);
                // Among good ones it is the error it is as the third track, and none is kept.
                let good = Spline { name: Some("a"), points: &tracks[0].rotations, knots: &cubic, curve };
                let among = [good, Spline { name: Some("t"), points, knots, curve }, good];
                let mut third = BatchBuilder::new();
                third.extend(&tracks[..2], |_| spec_of(4)).unwrap();
                assert_eq!(builder.extend_splines(&among).unwrap_err(), third.add(&track, &spec).unwrap_err());
                assert_eq!(
                    builder.build().unwrap(),
                    super::Batch::from_tracks_each(&tracks[..1], |_| spec_of(4)).unwrap()
                );
            }
        }
    }
}
