//! User-facing track data, exactly as the JSON format of DESIGN section 5 spells it.

use serde::{Deserialize, Serialize};

/// One animation track: keys and optional per-key data. Only `rotations` is required.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Track {
    /// Name used in messages and outputs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Key times, strictly increasing; default `0, 1, ..., n`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub times: Option<Vec<f64>>,
    /// Key rotations `[x, y, z, w]`; normalized and made sign-continuous on load.
    pub rotations: Vec<[f64; 4]>,
    /// Body angular velocities (rad/s) at the keys, for `tangents = given`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angular_velocities: Option<Vec<[f64; 3]>>,
    /// B-spline knot vector for `knots = explicit` (length n + k + 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub knots: Option<Vec<f64>>,
    /// Hermite extra turns, one integer per segment.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extra_turns: Option<Vec<i64>>,
    /// Sample times for this track, overriding the job's sampling.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_times: Option<Vec<f64>>,
}

/// The input file: `{"tracks": [...]}`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackFile {
    /// The tracks, in batch order.
    pub tracks: Vec<Track>,
}

impl Track {
    /// A track with keys at times `0, 1, ..., n` and nothing else.
    #[must_use]
    pub fn from_rotations(rotations: Vec<[f64; 4]>) -> Self {
        Self { rotations, ..Self::default() }
    }
}
