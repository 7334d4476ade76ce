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
    use super::{locate, wrap};

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
}
