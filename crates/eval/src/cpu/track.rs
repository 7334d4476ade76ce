//! One track's samples on the CPU: which kernel its family takes. Vectorized families go to a
//! [`Piece`] (its basis chosen here), squad and Nam-Kim values to the great-arc kernel,
//! uniformly sampled slerp and Nam-Kim to forward differences when asked, and what has no
//! SIMD kernel (squad and Nam-Kim derivatives, Bezier curves above degree 7) to the f64
//! reference per sample.

use super::bases::Basis;
use super::lanes::MAX_FACTORS;
use super::piece::{spans, Piece, Shared};
use crate::batch::TrackView;
use crate::job::JobOptions;
use crate::reference;
use crate::sampling::SampleTimes;
use quatcurve_core::curve::{Curve, MIN_ORDER};
use std::ops::Range;

/// Evaluates samples `range` of track `index` into `out` (`range.len()` [`crate::output::Row`]s).
pub fn evaluate(
    shared: &Shared<'_>,
    view: TrackView<'_>,
    times: &SampleTimes,
    index: usize,
    range: Range<usize>,
    options: &JobOptions,
    out: &mut [f32],
) {
    let row = options.row();
    let channels = row.channels();
    if super::forward::applies(view, times, index, options) {
        super::forward::evaluate(view, times, index, range, options, out);
        return;
    }
    let track = view.track;
    let (basis, factors) = match track.curve() {
        Curve::Slerp => (Basis::Poly(&shared.bases.slerp), 1),
        Curve::Hermite => (Basis::Poly(&shared.bases.hermite), 3),
        // bspline-interp is packed as a cubic B-spline on explicit knots. A normalized
        // B-spline takes the same cumulative basis (its kernel differences it).
        Curve::BSpline | Curve::NormalizedBSpline | Curve::BSplineInterp => {
            let k = track.order();
            let basis = if track.uniform_knots() {
                Basis::Poly(&shared.bases.bspline[k - MIN_ORDER])
            } else {
                Basis::CoxDeBoor
            };
            (basis, k - 1)
        }
        // One segment; degrees beyond the product's capacity take the reference below.
        Curve::Bezier if (1..=MAX_FACTORS).contains(&track.bezier_degree()) => {
            (Basis::Bernstein, track.bezier_degree())
        }
        Curve::Squad | Curve::NamKim if !options.derivatives => {
            super::arcs::evaluate(shared.isa, view, times, index, range.start, range.len(), channels, out);
            out.chunks_exact_mut(channels).for_each(|r| row.fill_matrix(r));
            return;
        }
        Curve::Squad | Curve::NamKim | Curve::Bezier => {
            for (dst, j) in out.chunks_exact_mut(channels).zip(range) {
                let t = times.time(index, j);
                if options.derivatives {
                    let s = reference::evaluate(view, t);
                    let f = |v: quatcurve_core::quat::Vec3F64| v.to_array().map(|c| c as f32);
                    row.write(
                        dst,
                        s.rotation.to_array().map(|v| v as f32),
                        f(s.angular_velocity),
                        f(s.angular_acceleration),
                    );
                } else {
                    row.write(
                        dst,
                        reference::evaluate_rotation(view, t).to_array().map(|v| v as f32),
                        [0.0; 3],
                        [0.0; 3],
                    );
                }
            }
            return;
        }
    };
    let (first, last) = spans(view);
    let piece = Piece { shared, view, times, index, from: range.start, options, basis, factors, first, last };
    piece.evaluate(range.len(), out);
}
