//! The GPU kernel against the f64 reference (DESIGN section 18 bars). Runs on any adapter,
//! lavapipe included; without one it prints "skipped: no GPU adapter" and passes, unless
//! QUATCURVE_REQUIRE_GPU=1 (set by .ci/run), which makes a missing adapter a failure.

mod accuracy;
mod api;
