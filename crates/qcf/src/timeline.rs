//! A channel's key times as a fitted clip stores them, and the samples a fit is made at: every
//! key and [`BETWEEN_POINTS`] evenly spaced points between consecutive keys. A fitted knot is
//! always one of those samples, so the container stores it as a sample index.

/// Points fitted and measured strictly between two consecutive keys.
pub const BETWEEN_POINTS: usize = 4;

/// Keys evenly spaced when none is further than this (seconds, relative to the clip's last
/// time, at least 1) from its even place: then two `f64`s stand for all of them.
const EVEN_TOLERANCE: f64 = 1e-12;

/// Key times (at least two, strictly increasing).
#[derive(Clone, Debug, PartialEq)]
pub enum Timeline {
    /// `count` keys from `first` to `last`, evenly spaced.
    Even {
        /// The first key's time.
        first: f64,
        /// The last key's time.
        last: f64,
        /// How many keys.
        count: usize,
    },
    /// Each key's time.
    Listed(Vec<f64>),
}

impl Timeline {
    /// `times` (at least two, strictly increasing) as evenly spaced keys when they are.
    #[must_use]
    pub fn of(times: &[f64]) -> Self {
        let (first, last, count) = (times[0], times[times.len() - 1], times.len());
        let even = Timeline::Even { first, last, count };
        let tolerance = EVEN_TOLERANCE * last.abs().max(1.0);
        if times.iter().enumerate().all(|(i, &t)| (even.key(i) - t).abs() <= tolerance) {
            even
        } else {
            Timeline::Listed(times.to_vec())
        }
    }

    /// How many keys.
    #[must_use]
    pub fn keys(&self) -> usize {
        match self {
            Timeline::Even { count, .. } => *count,
            Timeline::Listed(times) => times.len(),
        }
    }

    /// Key `i`'s time.
    #[must_use]
    pub fn key(&self, i: usize) -> f64 {
        match self {
            Timeline::Even { first, last, count } => even_key(*first, *last, *count, per_key(*count), i),
            Timeline::Listed(times) => times[i],
        }
    }

    /// How many samples: every key and the points between them.
    #[must_use]
    pub fn samples(&self) -> usize {
        (self.keys() - 1) * (BETWEEN_POINTS + 1) + 1
    }

    /// Sample `s`'s time: key `s / (BETWEEN_POINTS + 1)`, or a point between it and the next.
    #[must_use]
    pub fn sample(&self, s: usize) -> f64 {
        sample(|i| self.key(i), s)
    }

    /// Every sample's time, and whether it is a key.
    #[must_use]
    pub fn sample_times(&self) -> Vec<(f64, bool)> {
        (0..self.samples()).map(|s| (self.sample(s), s % (BETWEEN_POINTS + 1) == 0)).collect()
    }
}

/// Key `i`'s time of `count` keys evenly spaced from `first` to `last`, `per_key` their
/// [`per_key`]: a multiplication, where a division per key was a twentieth of decoding a pose.
#[inline(always)]
fn even_key(first: f64, last: f64, count: usize, per_key: f64, i: usize) -> f64 {
    if i + 1 == count {
        last
    } else {
        first + (last - first) * (i as f64 * per_key)
    }
}

/// The fraction of an even timeline between two of its `count` keys.
fn per_key(count: usize) -> f64 {
    1.0 / (count - 1) as f64
}

/// The fraction of a key's span between two consecutive samples.
const BETWEEN_STEP: f64 = 1.0 / (BETWEEN_POINTS + 1) as f64;

/// Sample `s`'s time of the keys `key` gives.
#[inline(always)]
fn sample(key: impl Fn(usize) -> f64, s: usize) -> f64 {
    let (k, step) = (s / (BETWEEN_POINTS + 1), s % (BETWEEN_POINTS + 1));
    if step == 0 {
        return key(k);
    }
    let (a, b) = (key(k), key(k + 1));
    a + (b - a) * (step as f64 * BETWEEN_STEP)
}

/// A [`Timeline`] as a container's bytes hold it: a listed one's times read where they lie, so
/// that the runtime decoder opens a clip without copying them.
#[derive(Clone, Copy, Debug)]
pub(crate) enum KeyTimes<'a> {
    /// As [`Timeline::Even`], with its [`per_key`].
    Even { first: f64, last: f64, count: usize, per_key: f64 },
    /// Each key's time, a little-endian `f64` each.
    Listed(&'a [u8]),
}

impl KeyTimes<'_> {
    /// An even timeline's key times.
    pub(crate) fn even(first: f64, last: f64, count: usize) -> Self {
        KeyTimes::Even { first, last, count, per_key: per_key(count) }
    }

    /// How many keys.
    pub(crate) fn keys(&self) -> usize {
        match self {
            KeyTimes::Even { count, .. } => *count,
            KeyTimes::Listed(bytes) => bytes.len() / 8,
        }
    }

    /// How many samples ([`Timeline::samples`]).
    pub(crate) fn samples(&self) -> usize {
        (self.keys() - 1) * (BETWEEN_POINTS + 1) + 1
    }

    /// Key `i`'s time.
    #[inline(always)]
    pub(crate) fn key(&self, i: usize) -> f64 {
        match self {
            KeyTimes::Even { first, last, count, per_key } => even_key(*first, *last, *count, *per_key, i),
            // A key past the last is the last (the runtime decoder reads what a checked
            // container held, and panics on nothing).
            KeyTimes::Listed(bytes) => {
                let i = i.min(bytes.len() / 8 - 1);
                f64::from_le_bytes(bytes[8 * i..8 * i + 8].try_into().expect("eight bytes"))
            }
        }
    }

    /// Sample `s`'s time ([`Timeline::sample`]).
    #[inline(always)]
    pub(crate) fn sample(&self, s: usize) -> f64 {
        sample(|i| self.key(i), s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn even_keys_take_two_numbers_and_give_their_times_back() {
        let times: Vec<f64> = (0..=360).map(|f| f64::from(f) / 120.0).collect();
        let line = Timeline::of(&times);
        assert!(matches!(line, Timeline::Even { count: 361, .. }), "{line:?}");
        for (i, &t) in times.iter().enumerate() {
            assert!((line.key(i) - t).abs() <= 1e-12, "key {i}");
            assert_eq!(line.sample(i * (BETWEEN_POINTS + 1)), line.key(i));
        }
        assert_eq!(line.samples(), 360 * (BETWEEN_POINTS + 1) + 1);
        assert!((line.sample(1) - 1.0 / 600.0).abs() < 1e-15);
        let uneven = [0.0, 0.1, 0.3, 0.35];
        assert_eq!(Timeline::of(&uneven), Timeline::Listed(uneven.to_vec()));
    }
}
