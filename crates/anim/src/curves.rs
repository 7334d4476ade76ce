//! An animation's channels as curves, built once and evaluated at any times: rotations as the
//! tracks of one batch (evaluated on a device, `quatcurve_device::Device`), vectors as their
//! Euclidean analogue, one-key channels as constants, and keys a source declares STEP or
//! CUBICSPLINE as glTF defines them (on the host, f64). The bake evaluates them on frame
//! grids; the playback runtime at each instance's own time.

use crate::error::InputError;
use crate::{Animation, ChannelCurve as Stored, Interpolation, Property};
use quatcurve_core::curve::{Curve, CurveSpec, UnknownName};
use quatcurve_eval::batch::{Batch, BatchBuilder, Spline};
use quatcurve_eval::error::TrackId;
use quatcurve_eval::euclidean::VectorCurve;
use quatcurve_eval::options::CurveOptions;
use quatcurve_eval::track::Track;
use rayon::prelude::*;

/// What keys are interpolated with (DESIGN section 6): as the source plays them, or one curve
/// family for every channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CurveChoice {
    /// Each channel as its source interpolates it ([`Interpolation`]): linear keys by slerp and
    /// lerp, glTF's STEP and CUBICSPLINE as glTF defines them. What engines play a file with.
    Source,
    /// This family for every channel (`--curve`), whatever the source declares.
    Family(CurveSpec),
}

impl CurveChoice {
    /// [`CurveChoice::Source`]'s name in sidecars and summaries.
    pub const SOURCE: &'static str = "source";

    /// `curve` with `options` (B-spline knots phantom unless given); `None`: the source's.
    #[must_use]
    pub fn new(curve: Option<Curve>, options: &CurveOptions) -> Self {
        match curve {
            Some(curve) => CurveChoice::Family(options.spec(curve, false)),
            None => CurveChoice::Source,
        }
    }

    /// The family of its device tracks and vector curves: the one asked for, or slerp (and
    /// lerp) for a source's linear keys.
    #[must_use]
    pub fn spec(&self) -> CurveSpec {
        match self {
            CurveChoice::Source => CurveSpec::new(Curve::Slerp),
            CurveChoice::Family(spec) => *spec,
        }
    }

    /// Its name: [`CurveChoice::SOURCE`] or the family's.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            CurveChoice::Source => Self::SOURCE,
            CurveChoice::Family(spec) => spec.curve.name(),
        }
    }

    /// The choice a sidecar names ([`CurveChoice::name`]), a family with the front ends'
    /// defaults for its other options.
    ///
    /// # Errors
    /// For a name that is neither.
    pub fn from_name(name: &str) -> Result<Self, UnknownName> {
        if name == Self::SOURCE {
            return Ok(CurveChoice::Source);
        }
        Ok(Self::new(Some(name.parse()?), &CurveOptions::DEFAULT))
    }

    /// Whether its curves pass through every key (the others approximate them).
    #[must_use]
    pub fn interpolates(&self) -> bool {
        matches!(self.spec().curve, Curve::Slerp | Curve::Squad | Curve::Hermite | Curve::NamKim | Curve::BSplineInterp)
    }

    /// Whether its curves turn a corner at keys (slerp), where frames off the keys cut it.
    #[must_use]
    pub fn corners_at_keys(&self) -> bool {
        self.spec().curve == Curve::Slerp
    }
}

/// How one channel is evaluated.
#[derive(Clone, Debug, PartialEq)]
pub enum ChannelEval {
    /// Track `i` of [`Curves::batch`] (a rotation with two keys or more, or a fitted rotation).
    Device(usize),
    /// A translation or scale of two keys or more, or fitted.
    Vector(VectorCurve),
    /// A channel of one key, held: `x, y, z, w` (a vector's `w` is 0).
    Constant([f32; 4]),
    /// Keys of two or more a source declares STEP or CUBICSPLINE ([`CurveChoice::Source`]).
    Declared(DeclaredCurve),
}

/// Keys a source interpolates by glTF's STEP or CUBICSPLINE, evaluated as glTF defines them
/// (clamped outside the keys; in a loop wrapped to them, a vector moved by its per-cycle
/// offset as [`VectorCurve`] moves it).
#[derive(Clone, Debug, PartialEq)]
pub struct DeclaredCurve {
    times: Vec<f64>,
    values: Vec<[f64; 4]>,
    /// `[in, out]` per key for CUBICSPLINE; `None` for STEP.
    tangents: Option<Vec<[[f64; 4]; 2]>>,
    rotation: bool,
    looping: bool,
}

impl DeclaredCurve {
    /// The curve's value at `t`: `x, y, z, w`, a vector's `w` 0.
    #[must_use]
    pub fn value(&self, t: f64) -> [f64; 4] {
        let (times, values) = (&self.times, &self.values);
        let (first, last) = (times[0], times[times.len() - 1]);
        let (t, cycles) = if self.looping && last > first && !(first..=last).contains(&t) {
            let cycles = ((t - first) / (last - first)).floor();
            (t - cycles * (last - first), cycles)
        } else {
            (t.clamp(first, last), 0.0)
        };
        // Keys k and k + 1 around t (the last key alone at the end).
        let k = times.partition_point(|&x| x <= t).saturating_sub(1).min(times.len() - 1);
        let mut value = match (&self.tangents, values.get(k + 1)) {
            (Some(tangents), Some(next)) => {
                let h = times[k + 1] - times[k];
                let s = (t - times[k]) / h;
                let (s2, s3) = (s * s, s * s * s);
                let weights = [2.0 * s3 - 3.0 * s2 + 1.0, (s3 - 2.0 * s2 + s) * h, -2.0 * s3 + 3.0 * s2, (s3 - s2) * h];
                let (out, into) = (tangents[k][1], tangents[k + 1][0]);
                std::array::from_fn(|c| {
                    weights[0] * values[k][c] + weights[1] * out[c] + weights[2] * next[c] + weights[3] * into[c]
                })
            }
            _ => values[k],
        };
        if self.rotation {
            let norm = value.iter().map(|v| v * v).sum::<f64>().sqrt();
            value.iter_mut().for_each(|v| *v /= norm);
        } else if cycles != 0.0 {
            let (a, b) = (values[0], values[values.len() - 1]);
            (0..3).for_each(|c| value[c] += cycles * (b[c] - a[c]));
        }
        value
    }
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
            ChannelEval::Declared(curve) => Some(curve.value(t).map(|v| v as f32)),
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
    /// Builds the curves of every clip as `choice` says, clip `c` looping where `looping[c]`
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
        choice: &CurveChoice,
        looping: &[bool],
        mut builder: BatchBuilder,
    ) -> Result<Self, InputError> {
        assert_eq!(looping.len(), animation.clips.len(), "one loop flag per clip");
        let mut channels: Vec<Vec<ChannelEval>> = vec![Vec::new(); animation.clips.len()];
        let (mut tracks, mut specs, mut track_clips, mut splines) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (c, prepared) in prepare_channels(animation, choice, looping) {
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
                let order = crate::spline::order_of(knots.len(), points.len());
                let curve = crate::spline::spline_spec(order).curve;
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
    choice: &CurveChoice,
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
        let spec = CurveSpec { looping: looping[c], ..choice.spec() };
        let id = TrackId { index: k, name: Some(animation.label(clip, channel)) };
        let (times, values, interpolation) = match &channel.curve {
            Stored::Keys { times, values, interpolation } => (times, values, interpolation),
            Stored::Spline { knots, controls } => return fitted_channel(channel.property, knots, controls, id),
        };
        let tangents = match (choice, interpolation) {
            (CurveChoice::Source, Interpolation::Step) => Some(None),
            (CurveChoice::Source, Interpolation::CubicSpline { tangents }) => Some(Some(tangents)),
            _ => None,
        };
        Ok(match (channel.property, values.len(), tangents) {
            (_, 1, _) => Prepared::Host(ChannelEval::Constant(constant(&id, channel.property, values[0])?)),
            (property, _, Some(tangents)) => {
                Prepared::Host(ChannelEval::Declared(declared(&id, property, times, values, tangents, spec.looping)?))
            }
            (Property::Rotation, _, None) => Prepared::Track(
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
/// family of the order they make ([`crate::spline::spline_spec`]); rotations on
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
    let spec = crate::spline::spline_spec(crate::spline::order_of(knots.len(), controls.len()));
    let controls: Vec<[f64; 3]> = controls.iter().map(|v| [v[0], v[1], v[2]]).collect();
    Ok(Prepared::Host(ChannelEval::Vector(VectorCurve::new(&id, None, &controls, Some(knots), &spec)?)))
}

/// Keys a source declares STEP (no `tangents`) or CUBICSPLINE, checked as the batch checks
/// keys: times finite and increasing, values finite, rotations not zero.
fn declared(
    id: &TrackId,
    property: Property,
    times: &[f64],
    values: &[[f64; 4]],
    tangents: Option<&Vec<[[f64; 4]; 2]>>,
    looping: bool,
) -> Result<DeclaredCurve, InputError> {
    quatcurve_eval::batch::key_times(id, Some(times), values.len())?;
    let values =
        values.iter().enumerate().map(|(k, &v)| checked_key(id, property, k, v)).collect::<Result<Vec<_>, _>>()?;
    if let Some(tangents) = tangents {
        for (k, pair) in tangents.iter().enumerate() {
            pair.iter().try_for_each(|&t| finite(id, k, t))?;
        }
    }
    Ok(DeclaredCurve {
        times: times.to_vec(),
        values,
        tangents: tangents.cloned(),
        rotation: property == Property::Rotation,
        looping,
    })
}

/// [`quatcurve_eval::error::Error::NonFiniteValue`] for key `key`'s `value` (or tangent) not
/// finite.
fn finite(id: &TrackId, key: usize, value: [f64; 4]) -> Result<(), InputError> {
    if value.iter().all(|v| v.is_finite()) {
        return Ok(());
    }
    Err(quatcurve_eval::error::Error::NonFiniteValue { track: id.clone(), key, value: [value[0], value[1], value[2]] }
        .into())
}

/// A one-key channel's value, checked like any key.
fn constant(id: &TrackId, property: Property, value: [f64; 4]) -> Result<[f32; 4], InputError> {
    Ok(checked_key(id, property, 0, value)?.map(|v| v as f32))
}

/// Key `key` of a channel the host evaluates: a rotation made unit (and not near zero), a
/// vector finite.
fn checked_key(id: &TrackId, property: Property, key: usize, value: [f64; 4]) -> Result<[f64; 4], InputError> {
    if property == Property::Rotation {
        return Ok(quatcurve_eval::batch::normalized_key(id, key, value)?.to_array());
    }
    finite(id, key, value)?;
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vector(times: Vec<f64>, xs: &[f64], tangents: Option<Vec<[[f64; 4]; 2]>>, looping: bool) -> DeclaredCurve {
        let values = xs.iter().map(|&x| [x, 0.0, 0.0, 0.0]).collect();
        DeclaredCurve { times, values, tangents, rotation: false, looping }
    }

    #[test]
    fn step_holds_each_key_until_the_next_and_a_loop_wraps_with_its_per_cycle_offset() {
        let open = vector(vec![0.0, 1.0, 3.0], &[1.0, 2.0, 4.0], None, false);
        let at = |c: &DeclaredCurve, t: f64| c.value(t)[0];
        assert_eq!([-1.0, 0.0, 0.999, 1.0, 2.5, 3.0, 9.0].map(|t| at(&open, t)), [1.0, 1.0, 1.0, 2.0, 2.0, 4.0, 4.0]);
        // A loop of period 3 moves on by 4 - 1 = 3 a cycle.
        let looped = DeclaredCurve { looping: true, ..open };
        assert_eq!([3.5, 4.0, -0.5, 6.0].map(|t| at(&looped, t)), [4.0, 5.0, -1.0, 7.0]);
    }

    #[test]
    fn cubic_spline_is_gltf_s_hermite_with_tangents_per_second() {
        // p(t) = t^3 on [0, 2]: keys 0 and 8, tangents 3 t^2 (0 and 12): exact.
        let tangents = vec![[[0.0; 4], [0.0; 4]], [[12.0, 0.0, 0.0, 0.0], [12.0, 0.0, 0.0, 0.0]]];
        let cubic = vector(vec![0.0, 2.0], &[0.0, 8.0], Some(tangents), false);
        for t in [0.0, 0.3, 1.0, 1.7, 2.0] {
            assert!((cubic.value(t)[0] - t * t * t).abs() < 1e-12, "{t}");
        }
        // A rotation's components, normalized.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let rotation = DeclaredCurve {
            times: vec![0.0, 1.0],
            values: vec![[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, h, h]],
            tangents: Some(vec![[[0.0; 4]; 2]; 2]),
            rotation: true,
            looping: false,
        };
        let q = rotation.value(0.5);
        let expected = [0.0, 0.0, 0.5 * h, 0.5 + 0.5 * h];
        let norm = expected.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(q.iter().zip(expected).all(|(a, b)| (a - b / norm).abs() < 1e-12), "{q:?}");
    }
}
