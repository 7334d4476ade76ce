"""Ragged against padded batches in Python (issue: tracks of their own lengths in one batch):
10,000 tracks of 8 to 64 keys evaluated as a list of tracks, against the same keys padded to
64 per track (the last key held at later times) as one rectangular array, 100 samples per
track, on one device; the median of 5 runs each, alternated.

    python3 benches/python_ragged.py [--device cpu]
"""

import argparse
import time

import numpy as np

import quatcurve


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--tracks", type=int, default=10_000)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    counts = rng.integers(8, 65, args.tracks)
    steps = rng.normal(size=(args.tracks, 64, 3)) * 0.05
    padded = np.concatenate([np.sin(np.cumsum(steps, axis=1)), np.ones((args.tracks, 64, 1))], axis=-1)
    padded /= np.linalg.norm(padded, axis=-1, keepdims=True)
    for i, n in enumerate(counts):
        padded[i, n:] = padded[i, n - 1]
    times = np.arange(64) / 30.0
    ragged = [padded[i, :n] for i, n in enumerate(counts)]
    ragged_times = [times[:n] for n in counts]
    runs = {"ragged": [], "padded": []}
    for _ in range(5):
        start = time.perf_counter()
        quatcurve.evaluate(ragged, ragged_times, samples=100, device=args.device)
        runs["ragged"].append(time.perf_counter() - start)
        start = time.perf_counter()
        quatcurve.evaluate(padded, times, samples=100, device=args.device)
        runs["padded"].append(time.perf_counter() - start)
    ragged_s, padded_s = np.median(runs["ragged"]), np.median(runs["padded"])
    print(f"{args.tracks} tracks, {counts.sum()} keys ragged / {64 * args.tracks} padded, 100 samples each, {args.device}:")
    print(f"ragged {ragged_s:.3f} s (runs {min(runs['ragged']):.3f}-{max(runs['ragged']):.3f}), "
          f"padded {padded_s:.3f} s (runs {min(runs['padded']):.3f}-{max(runs['padded']):.3f}), "
          f"ratio {ragged_s / padded_s:.2f}")


if __name__ == "__main__":
    main()
