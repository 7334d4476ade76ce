"""Bake a motion library on Ray: every file of a directory resampled to one rate by a pool of
workers, each of which opens its device once.

    python examples/ray_bake.py LIBRARY OUT [--rate 30] [--workers 2] [--device cpu] [--address ADDR]

- ``.bvh``, ``.gltf``, ``.glb``: baked as ``quatcurve bake`` bakes them (the same job, so the
  same bytes: ``OUT`` holds what ``quatcurve bake --input LIBRARY --output OUT`` writes, its
  manifest aside).
- ``.npz`` of axis-angle clips (``poses`` ``[frames, joints, 3]`` in radians, ``fps``, the
  layout of AMASS-style datasets): each joint's rotations resampled with the curve through
  every key, on a grid fitted to the clip as the bake fits it (``round(span x rate)``
  intervals from the first frame to the last), written as ``OUT/<stem>.npz`` with ``poses``
  and the clip's own ``fps``.

The dataset is the list of paths (``ray.data.from_items``); ``map_batches`` hands each worker
of an actor pool (a callable class, ``Resampler``) dicts of numpy arrays of paths, and the
worker writes each file's outputs atomically (a bake goes to a private directory first, then
its files are renamed into place). Without ``--address`` Ray starts on this machine with
``--workers`` CPUs; on a cluster, pass its address (``--address auto`` on a node of it, or
``ray://HOST:10001``): nothing else changes.
"""

import argparse
import os
import pathlib
import shutil
import tempfile
import time

import numpy as np

import quatcurve

BAKED = (".bvh", ".gltf", ".glb")
CLIPS = (".npz",)


def library(directory):
    """The motion files of `directory`, sorted by name; two with one stem would write the same
    outputs, and are refused (as `quatcurve bake` refuses them)."""
    files = sorted(str(p) for p in pathlib.Path(directory).iterdir() if p.suffix.lower() in BAKED + CLIPS)
    stems = {}
    for f in files:
        stem = pathlib.Path(f).stem
        if stem in stems:
            raise ValueError(f"{stems[stem]} and {f} would both write {stem}.*")
        stems[stem] = f
    return files


def resample_clip(path, out_dir, rate, device):
    """One npz of axis-angle clips resampled (module docs); returns the file written."""
    with np.load(path) as clip:
        poses = np.asarray(clip["poses"], dtype=np.float64)
        fps = float(clip["fps"])
    frames = poses.shape[0]
    span = (frames - 1) / fps
    intervals = max(1, round(span * rate)) if frames > 1 else 0
    times = np.arange(frames) / fps
    grid = np.linspace(0.0, span, intervals + 1)
    clip_rate = intervals / span if intervals else rate
    tracks = np.ascontiguousarray(poses.transpose(1, 0, 2))  # one track per joint
    out = quatcurve.evaluate(tracks, times, grid, rotation_type="rotvec", output="rotvec", device=device)
    target = pathlib.Path(out_dir) / (pathlib.Path(path).stem + ".npz")
    # Written whole, then renamed: nothing half-written under the final name.
    with tempfile.NamedTemporaryFile(dir=out_dir, prefix=".clip-", suffix=".npz", delete=False) as tmp:
        np.savez(tmp, poses=np.ascontiguousarray(out.transpose(1, 0, 2)), fps=np.float64(clip_rate))
    os.replace(tmp.name, target)
    return [str(target)]


def bake_file(path, out_dir, rate, device):
    """One BVH or glTF baked as `quatcurve bake` bakes it; returns the files written."""
    private = tempfile.mkdtemp(dir=out_dir, prefix=".bake-")
    try:
        rows = quatcurve.bake([path], private, rate=rate, device=device)
        written = []
        for name in sorted(os.listdir(private)):
            if not name.startswith("manifest."):
                os.replace(os.path.join(private, name), os.path.join(out_dir, name))
                written.append(os.path.join(out_dir, name))
        return written if rows[0]["status"] == "ok" else []
    finally:
        shutil.rmtree(private, ignore_errors=True)


def resample(path, out_dir, rate, device):
    """Any motion file of the library; returns the files written."""
    if pathlib.Path(path).suffix.lower() in CLIPS:
        return resample_clip(path, out_dir, rate, device)
    return bake_file(path, out_dir, rate, device)


class Resampler:
    """A Ray Data worker: opens its device once, then resamples the paths of each batch."""

    def __init__(self, out_dir, rate, device):
        self.out_dir, self.rate, self.device = out_dir, rate, device
        # The extension keeps each device it opens for the process: open it now, once.
        quatcurve.evaluate(np.array([[0.0, 0.0, 0.0, 1.0]] * 2), samples=2, device=device)

    def __call__(self, batch):
        paths, files, errors = [], [], []
        for path in batch["path"]:
            path = str(path)
            try:
                files.append(len(resample(path, self.out_dir, self.rate, self.device)))
                errors.append("")
            except ValueError as e:  # the file's own fault, named by the library
                files.append(0)
                errors.append(str(e))
            paths.append(path)
        return {"path": np.array(paths), "files": np.array(files), "error": np.array(errors)}


def run(directory, out_dir, rate=30.0, workers=2, device="cpu", address=None, batch_size=4):
    """Resamples every file of `directory` into `out_dir` on Ray; one result row per file."""
    import ray

    os.makedirs(out_dir, exist_ok=True)
    if not ray.is_initialized():
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    dataset = ray.data.from_items([{"path": p} for p in library(directory)])
    results = dataset.map_batches(
        Resampler,
        fn_constructor_kwargs={"out_dir": str(out_dir), "rate": rate, "device": device},
        batch_size=batch_size,
        batch_format="numpy",
        compute=ray.data.ActorPoolStrategy(size=workers),
    )
    return sorted(results.take_all(), key=lambda row: row["path"])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("library")
    parser.add_argument("out")
    parser.add_argument("--rate", type=float, default=quatcurve.DEFAULT_RATE)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--address", default=None, help="a running Ray cluster (default: start one here)")
    args = parser.parse_args()
    start = time.perf_counter()
    rows = run(args.library, args.out, args.rate, args.workers, args.device, args.address)
    seconds = time.perf_counter() - start
    failed = [row for row in rows if row["error"]]
    for row in failed:
        print(f"FAILED {row['path']}: {row['error']}")
    print(f"{len(rows) - len(failed)} of {len(rows)} files in {seconds:.1f} s ({len(rows) / seconds:.1f} files/s)")
    raise SystemExit(2 if failed else 0)


if __name__ == "__main__":
    main()
