#!/usr/bin/env python3
"""quatcurve's C2-through-keys curve against scipy's RotationSpline, side by side in one run.

Both build a C2 rotation spline through every key of the same workload (the walk tracks of
`quatcurve bench`: 32 keys at 30 Hz per track) and evaluate 1,000 samples per track from the
first key to the last. scipy builds and evaluates one track at a time (its API); quatcurve
builds the whole batch (`bench --curve bspline-interp` times the build and the CPU evaluation
separately and reports both in its JSON). End to end is samples / (build + evaluation).

The two curves are not the same curve (scipy's RotationSpline is C2 in rotation-vector
coordinates, quatcurve's is KKS's cumulative B-spline; both pass through every key), so this
compares the cost of the same job, not outputs.

With the Python package installed (`pip install ./python`), the same batch also goes through
`quatcurve.evaluate` (build and evaluate in one call, median of 5 runs), so the Python
overhead over the Rust bench reads directly.

Run (after `cargo build --release`):
    python3 benches/scipy_rotation_spline.py [--tracks 2000] [--samples 1000]
Needs numpy and scipy.
"""
import argparse
import json
import shutil
import subprocess
import sys
import time

import numpy as np

KEYS = 32
RATE = 30.0


def walk_tracks(tracks):
    """The synthetic walk tracks of `quatcurve::synthetic::walk_tracks`, x,y,z,w."""
    out = []
    for i in range(tracks):
        def h(k):
            return ((((i + 1) * (0x9E3779B97F4A7C15 ^ k)) % 2**64) >> 40) / float(1 << 24)
        phase, amplitude, twist = 6.3 * h(1), 0.2 + 0.5 * h(2), 0.3 * h(3) - 0.15
        frequency = 0.8 + 0.6 * h(4)
        t = np.arange(KEYS) / RATE
        a = np.sin(2 * np.pi * frequency * t + phase)
        v = np.stack([amplitude * a, 0.3 * amplitude * np.cos(2 * a), np.full_like(a, twist)], axis=1)
        th = np.linalg.norm(v, axis=1, keepdims=True)  # half angle (quatcurve's exp)
        q = np.concatenate([np.sin(th) / th * v, np.cos(th)], axis=1)
        out.append((t, q))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tracks", type=int, default=2000)
    parser.add_argument("--samples", type=int, default=1000)
    parser.add_argument("--quatcurve", default="target/release/quatcurve")
    args = parser.parse_args()
    # The binary is checked before the slow scipy half, and a missing one is one line, not a
    # traceback.
    if shutil.which(args.quatcurve) is None:
        sys.exit(f"error: no quatcurve binary at {args.quatcurve}: build it with `cargo build --release`, "
                 "or give its path with --quatcurve")
    try:
        from scipy.spatial.transform import Rotation, RotationSpline
    except ImportError:
        sys.exit("error: scipy is not installed (pip install scipy)")

    tracks = walk_tracks(args.tracks)
    start = time.perf_counter()
    for t, q in tracks:
        spline = RotationSpline(t, Rotation.from_quat(q))
        spline(np.linspace(t[0], t[-1], args.samples))
    scipy_seconds = time.perf_counter() - start
    samples = args.tracks * args.samples

    command = [args.quatcurve, "bench", "--curve", "bspline-interp", "--devices", "cpu", "--json",
               "--tracks", str(args.tracks), "--samples", str(args.samples), "--keys", str(KEYS)]
    run = subprocess.run(command, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"error: {' '.join(command)} failed (exit {run.returncode}): {run.stderr.strip()}")
    report = json.loads(run.stdout)
    build = report["workload"]["build_seconds"]
    evaluate = report["results"][0]["seconds"]
    ours = samples / (build + evaluate)
    theirs = samples / scipy_seconds
    print(f"workload: {args.tracks} tracks x {KEYS} keys -> {args.samples} samples each")
    print(f"scipy RotationSpline: {scipy_seconds:.3f} s  {theirs / 1e6:.3f} M samples/s  "
          f"(build + evaluate, one track at a time)")
    print(f"quatcurve cpu:        {build + evaluate:.3f} s  {ours / 1e6:.3f} M samples/s  "
          f"(build {build:.3f} s = {report['workload']['build_keys_per_s'] / 1e6:.2f} M keys/s, "
          f"evaluate {evaluate:.3f} s; {report['results'][0]['adapter']})")
    print(f"ratio: {ours / theirs:.1f}x")
    try:
        import quatcurve
    except ImportError:
        print("python package: not installed (pip install ./python)")
        return
    times = np.stack([t for t, _ in tracks])
    keys = np.stack([q for _, q in tracks])
    runs = []
    for _ in range(5):
        start = time.perf_counter()
        out = quatcurve.evaluate(keys, times, samples=args.samples, curve="bspline-interp", device="cpu")
        runs.append(time.perf_counter() - start)
    assert out.shape == (args.tracks, args.samples, 4)
    python_seconds = float(np.median(runs))
    print(f"quatcurve.evaluate:   {python_seconds:.3f} s  {samples / python_seconds / 1e6:.3f} M samples/s  "
          f"(build + evaluate from numpy; {scipy_seconds / python_seconds:.1f}x scipy, "
          f"{python_seconds / (build + evaluate):.2f}x the Rust bench's time)")


if __name__ == "__main__":
    main()
