//! The GPU kernel against the f64 reference (DESIGN section 6 bars). Runs on any adapter,
//! lavapipe included; without one it prints "skipped: no GPU adapter" and passes, unless
//! QUATCURVE_REQUIRE_GPU=1 (set by .ci/run), which makes a missing adapter a failure.

#[path = "../reference/common.rs"]
#[allow(dead_code)]
mod common;

#[path = "../shared/fast.rs"]
#[allow(dead_code)]
mod fast;

mod accuracy;
mod api;
