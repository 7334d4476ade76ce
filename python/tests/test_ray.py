"""The Ray Data pipeline of examples/ray_bake.py on a generated library of a few hundred files
(BVH, glTF and SMPL-H pose archives), on this machine (`ray.init(num_cpus=2)`): its outputs are
the CLI's bake of the same files byte for byte (manifests aside). CI requires Ray
(`QUATCURVE_REQUIRE_RAY=1`); elsewhere the test is skipped without it."""

import base64
import importlib.util
import json
import os
import pathlib
import subprocess
import time

import numpy as np
import pytest

import quatcurve
from test_quatcurve import REPO, cli

if importlib.util.find_spec("ray") is None:
    if os.environ.get("QUATCURVE_REQUIRE_RAY") == "1":
        raise RuntimeError("QUATCURVE_REQUIRE_RAY=1 but ray is not installed (pip install 'ray[data]')")
    pytest.skip("ray is not installed (pip install 'ray[data]')", allow_module_level=True)

spec = importlib.util.spec_from_file_location("ray_bake", REPO / "examples" / "ray_bake.py")
ray_bake = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ray_bake)

JOINTS = ["Hips", "Spine", "Neck", "Head"]


def bvh_text(seed, frames=240):
    """A small BVH take (a root with position channels, three joints) of smooth motion."""
    lines = ["HIERARCHY", "ROOT Hips", "{", "  OFFSET 0 0 0", "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    for depth, name in enumerate(JOINTS[1:], 1):
        pad = "  " * depth
        lines += [f"{pad}JOINT {name}", f"{pad}{{", f"{pad}  OFFSET 0 {depth * 1.5} 0", f"{pad}  CHANNELS 3 Zrotation Xrotation Yrotation"]
    lines += ["        End Site", "        {", "          OFFSET 0 1 0", "        }"] + ["  " * d + "}" for d in range(len(JOINTS) - 1, -1, -1)]
    lines += ["MOTION", f"Frames: {frames}", "Frame Time: .0083333"]
    rng = np.random.default_rng(seed)
    phase, amplitude = rng.uniform(0, 6, 15), rng.uniform(5, 60, 15)
    for f in range(frames):
        t = f / 120
        values = amplitude * np.sin(2 * np.pi * 0.7 * t + phase)
        values[:3] *= 0.1
        lines.append(" ".join(f"{v:.4f}" for v in values))
    return "\n".join(lines) + "\n"


def gltf_text(seed, keys=20):
    """A two-node glTF with a rotation and a translation channel, its buffer inline."""
    rng = np.random.default_rng(seed)
    times = np.arange(keys, dtype=np.float32) / 24
    angles = np.cumsum(rng.uniform(0.05, 0.3, keys))
    rotations = np.stack([np.zeros(keys), np.sin(angles / 2), np.zeros(keys), np.cos(angles / 2)], axis=1).astype(np.float32)
    moves = np.cumsum(rng.uniform(0, 0.1, (keys, 3)), axis=0).astype(np.float32)
    data = times.tobytes() + rotations.tobytes() + moves.tobytes()
    views = [(0, times.nbytes), (times.nbytes, rotations.nbytes), (times.nbytes + rotations.nbytes, moves.nbytes)]
    document = {
        "asset": {"version": "2.0"},
        "nodes": [{"name": "root", "children": [1]}, {"name": "arm"}],
        "scenes": [{"nodes": [0]}],
        "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in views],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": keys, "type": "SCALAR", "min": [float(times[0])], "max": [float(times[-1])]},
            {"bufferView": 1, "componentType": 5126, "count": keys, "type": "VEC4"},
            {"bufferView": 2, "componentType": 5126, "count": keys, "type": "VEC3"},
        ],
        "animations": [{
            "name": "swing",
            "samplers": [{"input": 0, "output": 1}, {"input": 0, "output": 2}],
            "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}, {"sampler": 1, "target": {"node": 0, "path": "translation"}}],
        }],
    }
    return json.dumps(document)


def npz_clip(path, seed, frames=150):
    """An AMASS SMPL-H archive: axis-angle `poses` [frames, 156] at 100 fps, `trans`, `betas`, `gender`."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None] / 100
    poses = 0.8 * np.sin(2 * np.pi * rng.uniform(0.2, 1.0, (1, 156)) * t + rng.uniform(0, 6, (1, 156)))
    trans = np.cumsum(rng.uniform(0, 0.01, (frames, 3)), axis=0)
    np.savez(path, poses=poses, trans=trans, betas=rng.normal(size=16), gender=np.array("male"), mocap_framerate=np.array(100.0))


def generate(directory, bvh=160, gltf=40, npz=100):
    directory.mkdir()
    for k in range(bvh):
        (directory / f"take{k:03d}.bvh").write_text(bvh_text(k))
    for k in range(gltf):
        (directory / f"prop{k:03d}.gltf").write_text(gltf_text(k))
    for k in range(npz):
        npz_clip(directory / f"clip{k:03d}.npz", k)
    return bvh + gltf + npz


def contents(directory, suffixes=None):
    """Every file's bytes, by name (manifests aside)."""
    return {
        p.name: p.read_bytes()
        for p in pathlib.Path(directory).iterdir()
        if not p.name.startswith("manifest.") and (suffixes is None or p.suffix in suffixes)
    }


def test_the_ray_pipeline_writes_what_the_cli_writes(tmp_path):
    import ray

    files = generate(tmp_path / "library")
    assert files >= 300
    start = time.perf_counter()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    startup = time.perf_counter() - start
    try:
        start = time.perf_counter()
        rows = ray_bake.run(tmp_path / "library", tmp_path / "ray", rate=30.0, workers=2, device="cpu")
        ray_seconds = time.perf_counter() - start
    finally:
        ray.shutdown()
    assert len(rows) == files and all(not row["error"] for row in rows), [row for row in rows if row["error"]][:3]
    # Every file: the CLI's bake of the same directory, byte for byte.
    start = time.perf_counter()
    subprocess.run([str(cli()), "bake", "--input", str(tmp_path / "library"), "--output", str(tmp_path / "cli"), "--rate", "30",
                    "--device", "cpu"], check=True, capture_output=True)
    cli_seconds = time.perf_counter() - start
    baked = contents(tmp_path / "ray")
    assert baked.keys() == contents(tmp_path / "cli").keys()
    assert baked == contents(tmp_path / "cli")
    with np.load(tmp_path / "ray" / "clip007.npz") as clip:
        # 1.49 s at 30 Hz: 45 intervals, the clip's own rate 45 / 1.49 Hz.
        assert clip["poses"].shape == (46, 156) and float(clip["mocap_framerate"]) == 45 / 1.49
        assert str(clip["gender"]) == "male" and clip["trans"].shape == (46, 3)
    print(f"\n{files} files: Ray with 2 workers {ray_seconds:.1f} s ({files / ray_seconds:.1f} files/s; Ray's own start "
          f"{startup:.1f} s before), the CLI {cli_seconds:.1f} s ({files / cli_seconds:.1f} files/s)")
