//! Control points in fewer bits: per channel, each stored component's smallest value over its
//! control points (`low`), the widest component's range (`span`, one step for the three) and
//! the fewest bits (at most [`MAX_BITS`]) whose rounding moves a
//! control point by at most a given amount. A B-spline point is a blend of its control points,
//! so the curve moves by about as much; the clip measures it after quantization anyway.
//! Rotations store their three smallest components (the batch builder makes the decoded control
//! points sign-continuous again). Ranges are `f32` values, as the container stores them, so a
//! fit's decoded control points are the container's to the bit.

use quatcurve_core::quat::QuatF64;
use std::ops::{Add, Div, Mul, Sub};

/// The most bits a component takes.
pub const MAX_BITS: u32 = 24;

/// A channel's control points as `bits`-bit codes of three components in `[low, low + span]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Quantized {
    /// Bits per component.
    pub bits: u32,
    /// Each component's smallest value.
    pub low: [f64; 3],
    /// The widest component's range, every component's: one step for the three, as the error
    /// is a distance over all three (a finer step on a narrow component buys little, and its
    /// residuals would take more bits: CMU at 24 Hz 14.0:1, not 13.2:1).
    pub span: f64,
    /// Per control point, its three codes.
    pub codes: Vec<[u32; 3]>,
}

impl Quantized {
    /// `components` in the fewest bits that keep each control point within `error`
    /// (Euclidean, over its three components).
    #[must_use]
    pub fn of(components: &[[f64; 3]], error: f64) -> Self {
        Self::with_bits(components, Self::bits_within(components, error))
    }

    /// The fewest bits (at most [`MAX_BITS`]) whose rounding moves no point of `components` by
    /// more than `error`: each component by at most half a step, `sqrt(3) / 2` steps in all.
    #[must_use]
    pub fn bits_within(components: &[[f64; 3]], error: f64) -> u32 {
        let (_, span) = ranges(components);
        (1..=MAX_BITS).find(|&b| 3f64.sqrt() / 2.0 * span / f64::from((1u32 << b) - 1) <= error).unwrap_or(MAX_BITS)
    }

    /// `components` as `bits`-bit codes (1 to [`MAX_BITS`]) over their ranges.
    #[must_use]
    pub fn with_bits(components: &[[f64; 3]], bits: u32) -> Self {
        let (low, span) = ranges(components);
        let levels = f64::from((1u32 << bits) - 1);
        let codes = components
            .iter()
            .map(|v| {
                std::array::from_fn(|c| {
                    if span > 0.0 {
                        ((v[c] - low[c]) / span * levels).round().clamp(0.0, levels) as u32
                    } else {
                        0
                    }
                })
            })
            .collect();
        Self { bits, low, span, codes }
    }

    /// The components the codes stand for.
    #[must_use]
    pub fn values(&self) -> Vec<[f64; 3]> {
        self.decoded().collect()
    }

    /// [`Quantized::values`] one at a time.
    pub fn decoded(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        let step = step(self.span, self.bits);
        self.codes.iter().map(move |code| value(&self.low, step, code))
    }
}

/// The value between two codes of width `bits` over `span`.
pub(crate) fn step(span: f64, bits: u32) -> f64 {
    span / f64::from((1u32 << bits) - 1)
}

/// A point's three components from its codes: one step multiplied, not a division per
/// component (a fifth of loading a container).
#[inline(always)]
pub(crate) fn value(low: &[f64; 3], step: f64, code: &[u32; 3]) -> [f64; 3] {
    std::array::from_fn(|c| low[c] + f64::from(code[c]) * step)
}

/// Each component's smallest value over `components`, and the widest component's range
/// ([`Quantized::span`]), as `f32` values that hold every value.
fn ranges(components: &[[f64; 3]]) -> ([f64; 3], f64) {
    let low: [f64; 3] =
        std::array::from_fn(|c| f32_at_most(components.iter().map(|v| v[c]).fold(f64::INFINITY, f64::min)));
    let widest =
        (0..3).map(|c| f32_at_least(components.iter().map(|v| v[c] - low[c]).fold(0.0, f64::max))).fold(0.0, f64::max);
    (low, widest)
}

/// The largest `f32` value at most `v`.
fn f32_at_most(v: f64) -> f64 {
    let r = v as f32;
    f64::from(if f64::from(r) > v { f32_step(r, false) } else { r })
}

/// The smallest `f32` value at least `v`.
fn f32_at_least(v: f64) -> f64 {
    let r = v as f32;
    f64::from(if f64::from(r) < v { f32_step(r, true) } else { r })
}

/// The next `f32` up or down from finite `r` (`f32::next_up` is newer than the MSRV).
fn f32_step(r: f32, up: bool) -> f32 {
    if r == 0.0 {
        let tiny = f32::from_bits(1);
        return if up { tiny } else { -tiny };
    }
    let away_from_zero = (r > 0.0) == up;
    f32::from_bits(if away_from_zero { r.to_bits() + 1 } else { r.to_bits() - 1 })
}

/// Rotation control points as [`Quantized`] three smallest components and, per control point,
/// the index (0-3, `x, y, z, w`) of the largest, which is rebuilt positive.
#[derive(Clone, Debug, PartialEq)]
pub struct QuantizedRotations {
    /// The three smallest components, in `x, y, z, w` order with the largest left out.
    pub smallest: Quantized,
    /// Per control point, the index of its largest component.
    pub largest: Vec<u8>,
}

impl QuantizedRotations {
    /// The rotations the codes stand for, unit to rounding (the batch normalizes every control
    /// point it packs; a second normalization here was a fifth of loading a container).
    #[must_use]
    pub fn values(&self) -> Vec<QuatF64> {
        self.decoded().collect()
    }

    /// [`QuantizedRotations::values`] one at a time. The largest component goes in by a
    /// `match`, not a store at a computed index, which kept each point in memory: a third of
    /// loading a container.
    pub fn decoded(&self) -> impl Iterator<Item = QuatF64> + '_ {
        self.smallest.decoded().zip(&self.largest).map(|(rest, &largest)| QuatF64::from_array(rotation(rest, largest)))
    }
}

/// The floats a rotation is rebuilt in: `f64` for the container's model, `f32` for the runtime
/// decoder, whose poses are `f32`.
pub(crate) trait Component:
    Copy + PartialOrd + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    const ZERO: Self;
    const ONE: Self;
    #[must_use]
    fn sqrt(self) -> Self;
}

impl Component for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
}

impl Component for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
}

/// A rotation, `x, y, z, w`, from its three smallest components and its largest's index,
/// unit to rounding unless rounding pushed the three past 1 (and the largest to 0). The
/// largest goes in by a `match`, not a store at a computed index, which kept each point in
/// memory.
#[inline(always)]
pub(crate) fn rotation<F: Component>(rest: [F; 3], largest: u8) -> [F; 4] {
    let rest_squared = rest[0] * rest[0] + rest[1] * rest[1] + rest[2] * rest[2];
    let (big, scale) = if rest_squared > F::ONE {
        (F::ZERO, F::ONE / rest_squared.sqrt())
    } else {
        ((F::ONE - rest_squared).sqrt(), F::ONE)
    };
    let [a, b, c] = rest.map(|v| v * scale);
    // The three in `x, y, z, w` order with the largest left out ([`SMALLEST`]).
    match largest {
        0 => [big, a, b, c],
        1 => [a, big, b, c],
        2 => [a, b, big, c],
        _ => [a, b, c, big],
    }
}

/// Rotation control points as their three smallest components, each with the index of its
/// largest, rebuilt positive.
fn smallest_three(controls: &[QuatF64]) -> (Vec<[f64; 3]>, Vec<u8>) {
    controls
        .iter()
        .map(|q| {
            let c = q.normalize().to_array();
            let largest = (0..4).max_by(|&a, &b| c[a].abs().total_cmp(&c[b].abs())).unwrap_or(3);
            let sign = c[largest].signum();
            (SMALLEST[largest].map(|i| c[i] * sign), largest as u8)
        })
        .unzip()
}

/// Per index of the largest component, the other three in `x, y, z, w` order: where a rotation's
/// three stored components go.
const SMALLEST: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];

/// Rotation control points quantized within `angle` radians each, as their three smallest
/// components (moving those by `d` moves the unit quaternion by at most `2 d`, as the largest is
/// at least 1/2, and so the rotation by at most `4 d`).
#[must_use]
pub fn rotations(controls: &[QuatF64], angle: f64) -> QuantizedRotations {
    let (components, largest) = smallest_three(controls);
    QuantizedRotations { smallest: Quantized::of(&components, angle / 4.0), largest }
}

/// Rotation control points in `bits` bits per component (1 to [`MAX_BITS`]).
#[must_use]
pub fn rotations_with_bits(controls: &[QuatF64], bits: u32) -> QuantizedRotations {
    let (components, largest) = smallest_three(controls);
    QuantizedRotations { smallest: Quantized::with_bits(&components, bits), largest }
}

/// The codes of the fewest bits that `fits` accepts, searched from `start` bits (a bound that
/// usually holds): down while it still fits, else up until it does, [`MAX_BITS`] at most.
/// Rounding bounds each control point's move, not the curve's: the curve is measured, and the
/// bound is loose (rounding errors seldom line up) or, for two rotation control points about
/// half a turn apart that rounding joins the other way round, too tight.
pub fn fewest_bits<Q>(start: u32, codes: impl Fn(u32) -> Q, fits: impl Fn(&Q) -> bool) -> Q {
    let first = codes(start);
    if fits(&first) {
        let mut best = first;
        for bits in (1..start).rev() {
            let fewer = codes(bits);
            if !fits(&fewer) {
                break;
            }
            best = fewer;
        }
        return best;
    }
    (start + 1..=MAX_BITS).map(&codes).find(|c| fits(c)).unwrap_or_else(|| codes(MAX_BITS))
}

#[cfg(test)]
mod tests {
    use super::*;
    use quatcurve_core::quat::Vec3F64;

    #[test]
    fn codes_decode_within_the_error_asked_in_the_fewest_bits() {
        let values: Vec<[f64; 3]> = (0..50).map(|i| [f64::from(i).sin(), 0.5 * f64::from(i).cos(), 2.0]).collect();
        for error in [1e-2, 1e-4, 1e-6] {
            let q = Quantized::of(&values, error);
            let worst = q
                .values()
                .iter()
                .zip(&values)
                .map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>().sqrt())
                .fold(0.0, f64::max);
            assert!(worst <= error, "{error}: {worst} with {} bits", q.bits);
            let fewer = Quantized { bits: q.bits - 1, ..q.clone() };
            let step = q.span / f64::from((1u32 << fewer.bits) - 1);
            assert!(3f64.sqrt() / 2.0 * step > error, "{error}: {} bits is not the fewest", q.bits);
        }
    }

    #[test]
    fn the_three_components_share_one_step_so_a_narrow_one_takes_small_codes() {
        // Ranges 2, 0.01 and 0: the narrow components' codes stay near their low end.
        let values: Vec<[f64; 3]> =
            (0..40).map(|i| f64::from(i) / 39.0).map(|t| [2.0 * t, 0.01 * t * t, 0.5]).collect();
        let q = Quantized::with_bits(&values, 12);
        assert_eq!(q.span, 2.0);
        let most = |c: usize| q.codes.iter().map(|code| code[c]).max().unwrap();
        assert_eq!(most(0), 4095);
        assert!(most(1) <= 21, "{}: 0.01 of a 2.0 span at 12 bits", most(1));
        assert_eq!(most(2), 0);
        for (a, b) in q.values().iter().zip(&values) {
            assert!((0..3).all(|c| (a[c] - b[c]).abs() <= 0.5 * 2.0 / 4095.0 + 1e-12), "{a:?} vs {b:?}");
        }
    }

    #[test]
    fn control_points_half_a_turn_apart_keep_their_way_round() {
        let turn = |z: f64| QuatF64::from_rotation_vector(Vec3F64::new(0.0, 0.0, z));
        let ways = |controls: &[QuatF64]| -> Vec<bool> {
            let c: Vec<[f64; 4]> = controls.iter().map(|q| q.to_array()).collect();
            c.windows(2).map(|w| (0..4).map(|i| w[0][i] * w[1][i]).sum::<f64>() > 0.0).collect()
        };
        let mut flipped = 0;
        for k in 2..60 {
            // The third and fourth control points are half a turn less `gap` apart.
            let gap = f64::from(k) * 1e-3;
            let controls = [turn(1.2), turn(-1.2), turn(-0.5), turn(std::f64::consts::PI - 0.5 - gap), turn(2.0)];
            let same_way = |codes: &QuantizedRotations| ways(&codes.values()) == ways(&controls);
            flipped += usize::from(!same_way(&rotations(&controls, 0.05)));
            let start = rotations(&controls, 0.05).smallest.bits;
            let kept = fewest_bits(start, |bits| rotations_with_bits(&controls, bits), same_way);
            assert!(same_way(&kept), "gap {gap}: {:?}", kept.values());
        }
        assert!(flipped > 0, "rounding within 0.05 never joined a pair the other way round: the case tests nothing");
    }

    #[test]
    fn rotations_decode_within_the_angle() {
        let controls: Vec<QuatF64> = (0..40)
            .map(|i| QuatF64::from_rotation_vector(Vec3F64::new(0.1 * f64::from(i), -0.05 * f64::from(i), 0.3)))
            .collect();
        for angle in [1e-2, 1e-4] {
            let q = rotations(&controls, angle);
            let worst = q.values().iter().zip(&controls).map(|(a, b)| a.angle_to(*b)).fold(0.0, f64::max);
            assert!(worst <= angle, "{angle}: {worst} with {} bits", q.smallest.bits);
        }
    }
}
