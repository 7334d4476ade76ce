"""Bake a motion library on Ray: every file of a directory resampled to one rate by a pool of
workers, each of which opens its device once.

    python examples/ray_bake.py LIBRARY OUT [--rate 30] [--workers 2] [--device cpu] [--address ADDR]

- ``.bvh``, ``.gltf``, ``.glb``, and ``.npz`` SMPL-family poses in AMASS's layout
  (docs/DATASETS.md): baked as ``quatcurve bake`` bakes them (the same job, so the same
  bytes: ``OUT`` holds what ``quatcurve bake --input LIBRARY --output OUT`` writes, its
  manifest aside); an archive comes back as ``OUT/<stem>.npz`` in its own layout at the
  new rate.

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

MOTION = (".bvh", ".gltf", ".glb", ".npz")


def library(directory):
    """The motion files of `directory`, sorted by name; two with one stem would write the same
    outputs, and are refused (as `quatcurve bake` refuses them)."""
    files = sorted(str(p) for p in pathlib.Path(directory).iterdir() if p.suffix.lower() in MOTION)
    stems = {}
    for f in files:
        stem = pathlib.Path(f).stem
        if stem in stems:
            raise ValueError(f"{stems[stem]} and {f} would both write {stem}.*")
        stems[stem] = f
    return files


def bake_file(path, out_dir, rate, device):
    """One motion file baked as `quatcurve bake` bakes it; returns the files written."""
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
                files.append(len(bake_file(path, self.out_dir, self.rate, self.device)))
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
