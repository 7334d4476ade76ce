//! How `bspline-interp`'s Newton solve behaves on hard keys: iteration counts and failures on
//! 3,000 random 13-key tracks per case, each step a random rotation of up to `--max-degrees`
//! (default 170) about a random axis, key spacing random in [0.1, 1] s (10x apart), open
//! (natural ends) and looping (the last key replaced by the first); solved one track at a time
//! and four per SIMD lane group, which must count alike.
//!
//! Run: `cargo run --release --example interp_convergence [-- MAX_DEGREES]`.

use quatcurve::interp::{self, Problem};
use quatcurve::quat::{QuatF64, Vec3F64};
use std::collections::BTreeMap;

fn main() {
    let max_degrees: f64 = std::env::args().nth(1).map_or(170.0, |a| a.parse().expect("MAX_DEGREES is a number"));
    // xorshift64: deterministic, no dependency.
    let mut seed = 12_345u64;
    let mut uniform = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for periodic in [false, true] {
        let tracks: Vec<(Vec<QuatF64>, Vec<f64>)> = (0..3_000)
            .map(|_| {
                let n = 12;
                let mut keys = vec![QuatF64::from_xyzw(0.0, 0.0, 0.0, 1.0)];
                let mut times = vec![0.0];
                for _ in 0..n {
                    let axis = Vec3F64::new(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5);
                    let half = 0.5 * uniform() * max_degrees.to_radians();
                    let step = axis.scale(half / axis.length());
                    let last = *keys.last().unwrap();
                    keys.push(last * QuatF64::exp(step));
                    times.push(times.last().unwrap() + 0.1 + 0.9 * uniform());
                }
                if periodic {
                    keys[n] = keys[0].aligned_with(keys[n - 1]);
                }
                (keys, times)
            })
            .collect();
        let scalar: Vec<_> = tracks.iter().map(|(k, t)| interp::solve_rotations(k, t, periodic)).collect();
        let problems: Vec<Problem> = tracks.iter().map(|(k, t)| Problem { keys: k, times: t, periodic }).collect();
        let lanes = interp::solve_rotations_batch(&problems);
        for (path, results) in [("one track at a time", scalar), ("four tracks per SIMD lane group", lanes)] {
            let mut iterations = BTreeMap::new();
            let mut failures = Vec::new();
            let mut worst = 0.0f64;
            for (track, result) in results.into_iter().enumerate() {
                match result {
                    Ok(solved) => {
                        *iterations.entry(solved.iterations).or_insert(0) += 1;
                        worst = worst.max(solved.key_error);
                    }
                    Err(e) => failures.push((track, e)),
                }
            }
            let solved: usize = iterations.values().sum();
            let median = iterations.iter().scan(0, |seen, (k, v)| {
                *seen += v;
                Some((*k, *seen))
            });
            let median = median.into_iter().find(|&(_, seen)| 2 * seen >= solved).map_or(0, |(k, _)| k);
            println!(
                "{}, {path}: {solved} solved (worst key error {worst:.1e} rad), median {median} iterations, most {}; {} failed{}",
                if periodic { "loop" } else { "open" },
                iterations.keys().last().copied().unwrap_or(0),
                failures.len(),
                failures.first().map_or(String::new(), |(t, e)| format!(" (first: track {t}, {e:?})"))
            );
            println!("  iterations: {iterations:?}");
        }
    }
}
