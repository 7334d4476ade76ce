//! What a fitted channel's spline is ([`crate::ChannelCurve::Spline`]): a clamped B-spline whose
//! order its knots and control points make, of the family that order names. The fit writes
//! such splines, the container stores them, and every evaluator reads them by these rules.

use quatcurve_core::curve::{Curve, CurveSpec};

/// Order of the fitted B-splines (cubic), as [`CurveSpec::order`] counts it.
pub const ORDER: usize = 4;

/// The rotation form of a fitted cubic: the normalized B-spline, whose decode is a basis, a
/// weighted sum and a normalization (no exponential, nothing prepared per control point),
/// and which fits mocap in as few control points as KKS's cumulative form (DESIGN section 10).
pub const CUBIC_ROTATIONS: Curve = Curve::NormalizedBSpline;

/// The curve family of a fit of `order`: a clamped B-spline on explicit knots, open; a cubic
/// ([`ORDER`]) [`CUBIC_ROTATIONS`], keys (order 2) slerped (KKS's order 2) or lerped
/// between. Vectors take either's Euclidean analogue, the plain B-spline.
#[must_use]
pub fn spline_spec(order: usize) -> CurveSpec {
    CurveSpec::open_spline(if order == ORDER { CUBIC_ROTATIONS } else { Curve::BSpline }, order)
}

/// The order of a clamped B-spline of `knots` knots and `controls` control points: what a
/// fitted channel's knot vector says of its curve.
#[must_use]
pub fn order_of(knots: usize, controls: usize) -> usize {
    knots.saturating_sub(controls)
}
