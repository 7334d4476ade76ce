//! An animation's channels as curves, built once and evaluated at any times: rotations as the
//! tracks of one batch (evaluated on a [`quatcurve_device::Device`]), vectors as their
//! Euclidean analogue and one-key channels as constants (on the host, f64). The bake
//! evaluates them on frame grids; the playback runtime at each instance's own time.

use quatcurve_anim::error::InputError;
use quatcurve_anim::{Animation, ChannelCurve as Stored, Property};
use quatcurve_core::curve::CurveSpec;
use quatcurve_eval::batch::{Batch, BatchBuilder, Spline};
use quatcurve_eval::error::TrackId;
use quatcurve_eval::euclidean::VectorCurve;
use quatcurve_eval::track::Track;
use rayon::prelude::*;

/// How one channel is evaluated.
#[derive(Clone, Debug, PartialEq)]
pub enum ChannelEval {
    /// Track `i` of [`Curves::batch`] (a rotation with two keys or more, or a fitted rotation).
    Device(usize),
    /// A translation or scale of two keys or more, or fitted.
    Vector(VectorCurve),
    /// A channel of one key, held: `x, y, z, w` (a vector's `w` is 0).
    Constant([f32; 4]),
}

impl ChannelEval {
    /// A host channel's value at `t` (`x, y, z, 0` for vectors); `None` for a device track.
    #[must_use]
    pub fn host_value(&self, t: f64) -> Option<[f32; 4]> {
        match self {
            ChannelEval::Device(_) => None,
            ChannelEval::Vector(curve) => {
                let [x, y, z] = curve.evaluate(t).to_array().map(|v| v as f32);
                Some([x, y, z, 0.0])
            }
            ChannelEval::Constant(value) => Some(*value),
        }
    }
}

/// Every channel of an animation ready to evaluate.
#[derive(Debug)]
pub struct Curves {
    /// The rotation tracks of every clip, in channel order; `None` when no channel needs the
    /// device.
    pub batch: Option<Batch>,
    /// Per clip, per channel in the clip's order.
    pub channels: Vec<Vec<ChannelEval>>,
    /// Per track of the batch: its clip.
    pub track_clips: Vec<usize>,
    /// The keyed rotation tracks last put in the batch (all of them unless the animation is
    /// fitted): what the bake's key error evaluates at the keys.
    pub tracks: Vec<Track>,
}

impl Curves {
    /// Builds the curves of every clip with `spec`, clip `c` looping where `looping[c]`
    /// (DESIGN section 3's periodic curves; translations keep their per-cycle offset), into
    /// `builder` (a kept one reuses its buffers).
    ///
    /// # Errors
    /// [`InputError::Keys`] naming the clip, joint, property and key for bad keys.
    ///
    /// # Panics
    /// When `looping` has not one flag per clip.
    pub fn build(
        animation: &Animation,
        spec: &CurveSpec,
        looping: &[bool],
        mut builder: BatchBuilder,
    ) -> Result<Self, InputError> {
        assert_eq!(looping.len(), animation.clips.len(), "one loop flag per clip");
        let mut channels: Vec<Vec<ChannelEval>> = vec![Vec::new(); animation.clips.len()];
        let (mut tracks, mut specs, mut track_clips, mut splines) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (c, prepared) in prepare_channels(animation, spec, looping) {
            channels[c].push(match prepared? {
                Prepared::Track(track, spec) => {
                    // The splines before it first, so that the batch keeps the channels' order.
                    extend_splines(&mut builder, &mut splines)?;
                    tracks.push(track);
                    specs.push(spec);
                    track_clips.push(c);
                    ChannelEval::Device(track_clips.len() - 1)
                }
                Prepared::Spline { name, points, knots } => {
                    // Likewise the tracks before it (only a fitted animation has splines, and
                    // it needs no tracks kept for the key error).
                    builder.extend(&std::mem::take(&mut tracks), |i| specs[i])?;
                    specs.clear();
                    splines.push((name, points, knots));
                    track_clips.push(c);
                    ChannelEval::Device(track_clips.len() - 1)
                }
                Prepared::Host(curve) => curve,
            });
        }
        if track_clips.is_empty() {
            return Ok(Self { batch: None, channels, track_clips, tracks });
        }
        // Each on every core (bspline-interp solves a system per track).
        extend_splines(&mut builder, &mut splines)?;
        builder.extend(&tracks, |i| specs[i])?;
        Ok(Self { batch: Some(builder.build()?), channels, track_clips, tracks })
    }
}

/// A fitted rotation channel on its way into the batch: its name, control points and knots.
type PendingSpline<'a> = (String, &'a [[f64; 4]], &'a [f64]);

/// Appends `splines` to `builder` on every core, and empties it.
fn extend_splines(builder: &mut BatchBuilder, splines: &mut Vec<PendingSpline<'_>>) -> Result<(), InputError> {
    if !splines.is_empty() {
        let batch: Vec<Spline<'_>> = splines
            .iter()
            .map(|(name, points, knots)| {
                let order = quatcurve_anim::qcf::fitted::order_of(knots.len(), points.len());
                let curve = quatcurve_anim::qcf::fitted::spline_spec(order).curve;
                Spline { name: Some(name), points, knots, curve }
            })
            .collect();
        builder.extend_splines(&batch)?;
        splines.clear();
    }
    Ok(())
}

/// A channel on its way to its curve: a device track, a fitted rotation's spline (control
/// points and knots as the animation holds them, packed with no track between), or a host
/// curve.
enum Prepared<'a> {
    Track(Track, CurveSpec),
    Spline { name: String, points: &'a [[f64; 4]], knots: &'a [f64] },
    Host(ChannelEval),
}

/// Every channel, prepared on every core, with its clip's index. The results are in channel
/// order, so that the first error reported is the first channel's.
fn prepare_channels<'a>(
    animation: &'a Animation,
    spec: &CurveSpec,
    looping: &[bool],
) -> Vec<(usize, Result<Prepared<'a>, InputError>)> {
    let channels: Vec<(usize, usize)> = animation
        .clips
        .iter()
        .enumerate()
        .flat_map(|(c, clip)| (0..clip.channels.len()).map(move |k| (c, k)))
        .collect();
    let prepare = |c: usize, k: usize| -> Result<Prepared<'a>, InputError> {
        let (clip, channel) = (&animation.clips[c], &animation.clips[c].channels[k]);
        let spec = CurveSpec { looping: looping[c], ..*spec };
        let id = TrackId { index: k, name: Some(animation.label(clip, channel)) };
        let (times, values) = match &channel.curve {
            Stored::Keys { times, values } => (times, values),
            Stored::Spline { knots, controls } => return fitted_channel(channel.property, knots, controls, id),
        };
        Ok(match (channel.property, values.len()) {
            (_, 1) => Prepared::Host(ChannelEval::Constant(constant(&id, channel.property, values[0])?)),
            (Property::Rotation, _) => Prepared::Track(
                Track { name: id.name, times: Some(times.clone()), ..Track::from_rotations(values.clone()) },
                spec,
            ),
            _ => {
                let keys: Vec<[f64; 3]> = values.iter().map(|v| [v[0], v[1], v[2]]).collect();
                Prepared::Host(ChannelEval::Vector(VectorCurve::new(&id, Some(times), &keys, None, &spec)?))
            }
        })
    };
    channels.par_iter().with_min_len(16).map(|&(c, k)| (c, prepare(c, k))).collect()
}

/// A fitted channel ([`Stored::Spline`]): its control points on its knots, as the fit's curve
/// family of the order they make ([`quatcurve_anim::qcf::fitted::spline_spec`]); rotations on
/// the device, vectors here.
fn fitted_channel<'a>(
    property: Property,
    knots: &'a [f64],
    controls: &'a [[f64; 4]],
    id: TrackId,
) -> Result<Prepared<'a>, InputError> {
    if property == Property::Rotation {
        let name = id.name.unwrap_or_default();
        return Ok(Prepared::Spline { name, points: controls, knots });
    }
    let spec =
        quatcurve_anim::qcf::fitted::spline_spec(quatcurve_anim::qcf::fitted::order_of(knots.len(), controls.len()));
    let controls: Vec<[f64; 3]> = controls.iter().map(|v| [v[0], v[1], v[2]]).collect();
    Ok(Prepared::Host(ChannelEval::Vector(VectorCurve::new(&id, None, &controls, Some(knots), &spec)?)))
}

/// A one-key channel's value, checked like any key.
fn constant(id: &TrackId, property: Property, value: [f64; 4]) -> Result<[f32; 4], InputError> {
    let value = if property == Property::Rotation {
        quatcurve_eval::batch::normalized_key(id, 0, value)?.to_array()
    } else if value.iter().all(|v| v.is_finite()) {
        value
    } else {
        return Err(quatcurve_eval::error::Error::NonFiniteValue {
            track: id.clone(),
            key: 0,
            value: [value[0], value[1], value[2]],
        }
        .into());
    };
    Ok(value.map(|v| v as f32))
}
