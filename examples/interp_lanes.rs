//! The `bspline-interp` solve on one core, one track at a time (`interp::solve_rotations`)
//! against four tracks per SIMD lane group (`interp::solve_rotations_batch`), on the bench
//! workload: keys per second and Newton iterations, alternating the two a few times.
//!
//! Run: `cargo run --release --example interp_lanes [-- TRACKS [KEYS]]`.

use quatcurve::curve::{Curve, CurveSpec};
use quatcurve::interp::{self, Problem};
use quatcurve::quat::QuatF64;
use quatcurve::synthetic::workload_tracks;
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1).map(|a| a.parse::<usize>().expect("TRACKS and KEYS are counts"));
    let (tracks, keys) = (args.next().unwrap_or(4000), args.next().unwrap_or(32));
    for looping in [false, true] {
        let spec = CurveSpec { curve: Curve::BSplineInterp, looping, ..CurveSpec::default() };
        let data: Vec<(Vec<QuatF64>, Vec<f64>)> = workload_tracks(tracks, keys, &spec)
            .iter()
            .map(|t| {
                let mut q: Vec<QuatF64> = t.rotations.iter().map(|&r| QuatF64::from_array(r).normalize()).collect();
                for i in 1..q.len() {
                    q[i] = q[i].aligned_with(q[i - 1]);
                }
                (q, t.times.clone().expect("workload tracks carry times"))
            })
            .collect();
        let problems: Vec<Problem> =
            data.iter().map(|(k, t)| Problem { keys: k, times: t, periodic: looping }).collect();
        let total = (tracks * keys) as f64;
        for round in 0..3 {
            let timer = Instant::now();
            let scalar: Vec<_> =
                problems.iter().map(|p| interp::solve_rotations(p.keys, p.times, p.periodic)).collect();
            let scalar_s = timer.elapsed().as_secs_f64();
            let timer = Instant::now();
            let lanes = interp::solve_rotations_batch(&problems);
            let lanes_s = timer.elapsed().as_secs_f64();
            let mean = |r: &[Result<interp::Solved, interp::NoConvergence>]| {
                r.iter().map(|s| s.as_ref().map_or(0, |s| s.iterations)).sum::<usize>() as f64 / r.len() as f64
            };
            println!(
                "{} round {round}: scalar {:.2} M keys/s ({:.2} iterations), lanes {:.2} M keys/s ({:.2}): {:.2}x",
                if looping { "loop" } else { "open" },
                total / scalar_s / 1e6,
                mean(&scalar),
                total / lanes_s / 1e6,
                mean(&lanes),
                scalar_s / lanes_s
            );
        }
    }
}
