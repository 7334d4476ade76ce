//! Segment lookup and clamping: the one place that decides which piece of a curve a sample
//! time falls in.

/// Clamps `t` to `[knots[first], knots[last + 1]]` and returns `(span, t_clamped)` where
/// `span` is the largest index in `first..=last` with `knots[span] <= t < knots[span + 1]`
/// among non-empty spans; at the right end of the domain the last non-empty span is used
/// (closed on the right), so a sample exactly at a knot belongs to the span that starts there.
///
/// Piecewise families pass their key times (`first = 0`, `last = n - 1`); B-splines of order
/// `k` pass their knot vector (`first = k - 1`, `last = n`). NaN is clamped to the domain start.
///
/// # Preconditions
/// `knots` is non-decreasing and `knots[first] < knots[last + 1]` (the builder checks both).
#[must_use]
pub fn locate(knots: &[f64], first: usize, last: usize, t: f64) -> (usize, f64) {
    let lo = knots[first];
    let hi = knots[last + 1];
    let t = if t >= lo { t.min(hi) } else { lo };
    // Count of knots[first..=last] that are <= t is at least 1 because t >= knots[first].
    let below = knots[first..=last].partition_point(|&k| k <= t);
    let mut span = first + below - 1;
    while knots[span] == knots[span + 1] && span > first {
        span -= 1;
    }
    (span, t)
}

/// [`locate`] of each of `times` in ascending order, walking the knots from the last span
/// instead of bisecting for each: a fit evaluates every sample of a channel on each knot
/// vector it tries, and bisecting for each costs it a tenth of its time.
///
/// # Panics
/// When `times` are not ascending (NaN included).
pub fn locate_ascending<'a>(
    knots: &'a [f64],
    first: usize,
    last: usize,
    times: &'a [f64],
) -> impl Iterator<Item = (usize, f64)> + 'a {
    let (lo, hi) = (knots[first], knots[last + 1]);
    // How many of knots[first..=last] are <= the time before.
    let mut below = 1;
    let mut before = f64::NEG_INFINITY;
    times.iter().map(move |&t| {
        assert!(t >= before, "times in ascending order");
        before = t;
        let t = if t >= lo { t.min(hi) } else { lo };
        while first + below <= last && knots[first + below] <= t {
            below += 1;
        }
        let mut span = first + below - 1;
        while knots[span] == knots[span + 1] && span > first {
            span -= 1;
        }
        (span, t)
    })
}

/// [`locate`] on strictly increasing, about equally spaced knots (`inv_step` their inverse
/// mean spacing, [`arithmetic_span_step`]) with the domain `[lo, hi]` (`knots[first]`, `knots[last + 1]`) given: the span
/// from the spacing, then corrected by a step where rounding put it one off, so the result is
/// [`locate`]'s.
#[inline(always)]
#[must_use]
pub fn locate_uniform(
    knots: &[f64],
    first: usize,
    last: usize,
    [lo, hi]: [f64; 2],
    t: f64,
    inv_step: f64,
) -> (usize, f64) {
    let t = if t >= lo { t.min(hi) } else { lo };
    // Clamped before the cast: a tiny domain can make the spacing's inverse infinite.
    let guess = ((t - lo) * inv_step).floor().min((last - first) as f64);
    // Through u32, a shorter conversion than to usize: no track has 2^32 spans (32 GB of knots).
    let mut span = if guess > 0.0 { first + guess as u32 as usize } else { first };
    while span < last && knots[span + 1] <= t {
        span += 1;
    }
    while span > first && knots[span] > t {
        span -= 1;
    }
    (span, t)
}

/// Knots whose largest spacing is at most this many times their smallest have their spans
/// guessed by arithmetic and walked to the right one: a glTF's f32 key times are equally
/// spaced only to about 1e-5, too loosely for the fixed span bases of uniform knots, yet a
/// guess from the mean spacing is at most a step or two off.
pub const ARITHMETIC_SPAN_RATIO: f64 = 4.0;

/// `(knots - 1) / (last - first)` of the knots bounding the spans a lookup searches
/// (`knots[first..=last + 1]`), strictly increasing and within [`ARITHMETIC_SPAN_RATIO`], for
/// [`locate_uniform`]; else 0 (bisection). On strictly increasing knots the walked guess ends
/// on the span [`locate`] finds (which steps back only over repeated knots).
#[must_use]
pub fn arithmetic_span_step(knots: &[f64]) -> f64 {
    if knots.len() <= 2 {
        return 0.0;
    }
    // One pass, ending at the first spacing that settles it: every track's lookup asks, and
    // a fitted curve's knots (a sample apart here, dozens there) settle it within a few.
    let (mut smallest, mut largest) = (f64::INFINITY, 0.0f64);
    for w in knots.windows(2) {
        let spacing = w[1] - w[0];
        (smallest, largest) = (smallest.min(spacing), largest.max(spacing));
        if smallest <= 0.0 || largest > ARITHMETIC_SPAN_RATIO * smallest {
            return 0.0;
        }
    }
    (knots.len() - 1) as f64 / (knots[knots.len() - 1] - knots[0])
}

/// Locates `t` among a piecewise track's key times: `(segment, clamped t, segment length)`.
#[must_use]
pub fn key_segment(knots: &[f64], t: f64) -> (usize, f64, f64) {
    let (i, t) = locate(knots, 0, knots.len() - 2, t);
    (i, t, knots[i + 1] - knots[i])
}

/// A looping track's sample time inside its period: times within `[start, end]` are kept as
/// they are (so a sample at the end evaluates the end, not the start), others become
/// `start + ((t - start) mod (end - start))`. NaN stays NaN (and is clamped later).
#[must_use]
pub fn wrap(t: f64, [start, end]: [f64; 2]) -> f64 {
    if t >= start && t <= end || t.is_nan() {
        return t;
    }
    let wrapped = start + (t - start).rem_euclid(end - start);
    // rem_euclid can round up to the period itself.
    if wrapped > end {
        start
    } else {
        wrapped
    }
}

#[cfg(test)]
mod tests {
    use super::{arithmetic_span_step, locate, locate_ascending, locate_uniform, wrap, ARITHMETIC_SPAN_RATIO};

    /// Numbers in `[0, 1)` from a linear congruential generator seeded with `seed`.
    fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    #[test]
    fn arithmetic_lookup_finds_the_span_bisection_finds_on_about_equally_spaced_knots() {
        // f32 key times (spacings off by ~1e-5), jittered ones, and clamped B-spline knots
        // whose inner spans are the ones searched; times inside, outside and on knots.
        let mut unit = uniform(7);
        let mut checked = 0;
        for case in 0..300 {
            let n = 3 + case % 40;
            let jitter = [1e-5, 0.3, 0.7][case % 3];
            let mut knots: Vec<f64> = (0..n).map(|i| (i as f64 + jitter * (unit() - 0.5)) / 24.0).collect();
            let (first, last) = if case % 4 == 0 {
                // Clamped: the ends repeated three times more, the spans searched inside them.
                let (a, b) = (knots[0], knots[n - 1]);
                knots.splice(0..0, [a; 3]);
                knots.extend([b; 3]);
                (3, n + 1)
            } else {
                (0, n - 2)
            };
            let step = arithmetic_span_step(&knots[first..=last + 1]);
            assert!(step > 0.0 || jitter > 0.5, "case {case}: about equal spacings take the arithmetic");
            if step == 0.0 {
                continue;
            }
            let domain = [knots[first], knots[last + 1]];
            let mut times: Vec<f64> = (0..50).map(|_| (unit() * 1.4 - 0.2) * domain[1]).collect();
            times.extend(&knots);
            for t in times {
                assert_eq!(
                    locate_uniform(&knots, first, last, domain, t, step),
                    locate(&knots, first, last, t),
                    "case {case}, t {t}"
                );
                checked += 1;
            }
        }
        assert!(checked > 5_000);
        // Spacings further apart than the ratio, or a repeated knot, take bisection.
        assert_eq!(arithmetic_span_step(&[0.0, 1.0, 1.0 + 0.9 / ARITHMETIC_SPAN_RATIO]), 0.0);
        assert_eq!(arithmetic_span_step(&[0.0, 1.0, 1.0, 2.0]), 0.0);
    }

    #[test]
    fn wrap_keeps_the_period_and_moves_the_rest() {
        let d = [1.0, 3.0];
        assert_eq!(wrap(1.0, d), 1.0);
        assert_eq!(wrap(3.0, d), 3.0);
        assert_eq!(wrap(3.5, d), 1.5);
        assert_eq!(wrap(0.5, d), 2.5);
        assert_eq!(wrap(-5.0, d), 1.0);
        assert_eq!(wrap(1.0 + 6.0 * 2.0 + 0.25, d), 1.25);
        assert!(wrap(f64::NAN, d).is_nan());
    }

    #[test]
    fn spans_are_right_open_except_the_last() {
        let times = [0.0, 1.0, 2.0, 4.0];
        assert_eq!(locate(&times, 0, 2, -5.0), (0, 0.0));
        assert_eq!(locate(&times, 0, 2, 0.0), (0, 0.0));
        assert_eq!(locate(&times, 0, 2, 1.0), (1, 1.0));
        assert_eq!(locate(&times, 0, 2, 3.9), (2, 3.9));
        assert_eq!(locate(&times, 0, 2, 4.0), (2, 4.0));
        assert_eq!(locate(&times, 0, 2, 9.0), (2, 4.0));
        assert_eq!(locate(&times, 0, 2, f64::NAN), (0, 0.0));
    }

    #[test]
    fn repeated_knots_skip_empty_spans() {
        // Order 3, n = 5: domain [knots[2], knots[6]] = [0, 3]; knot 2 has multiplicity 2.
        let knots = [0.0, 0.0, 0.0, 1.0, 2.0, 2.0, 3.0, 3.0, 3.0];
        assert_eq!(locate(&knots, 2, 5, 2.0), (5, 2.0));
        assert_eq!(locate(&knots, 2, 5, 1.999), (3, 1.999));
        assert_eq!(locate(&knots, 2, 5, 3.0), (5, 3.0));
        assert_eq!(locate(&knots, 2, 5, 0.0), (2, 0.0));
    }

    #[test]
    fn walking_ascending_times_finds_the_spans_bisection_finds() {
        // Clamped knots with repeated inner knots; times before, inside, on knots and after.
        let mut unit = uniform(11);
        for case in 0..200 {
            let inner = case % 30;
            let mut knots: Vec<f64> = (0..inner).map(|_| (unit() * 8.0).round() / 8.0).collect();
            if case % 3 == 0 {
                knots.extend(knots.clone());
            }
            knots.extend([0.0; 4]);
            knots.extend([1.0; 4]);
            knots.sort_by(f64::total_cmp);
            let (first, last) = (3, knots.len() - 5);
            let mut times: Vec<f64> = (0..60).map(|_| unit() * 1.4 - 0.2).collect();
            times.extend(&knots);
            times.sort_by(f64::total_cmp);
            let walked: Vec<(usize, f64)> = locate_ascending(&knots, first, last, &times).collect();
            let bisected: Vec<(usize, f64)> = times.iter().map(|&t| locate(&knots, first, last, t)).collect();
            assert_eq!(walked, bisected, "case {case}, knots {knots:?}");
        }
    }
}
