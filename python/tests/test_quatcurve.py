"""quatcurve's Python package against scipy, the CLI, and its own contract (DESIGN section 15)."""

import json
import os
import pathlib
import shutil
import subprocess

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation, RotationSpline, Slerp

import quatcurve

REPO = pathlib.Path(__file__).resolve().parents[2]


def random_keys(rng, tracks, keys, max_step=1.2):
    """Sign-continuous random keys: each a turn of up to `max_step` rad from the previous."""
    out = np.empty((tracks, keys, 4))
    for i in range(tracks):
        q = Rotation.random(random_state=rng)
        for k in range(keys):
            out[i, k] = q.as_quat()
            axis = rng.normal(size=3)
            q = q * Rotation.from_rotvec(axis / np.linalg.norm(axis) * rng.uniform(0.0, max_step))
    return out


def angle(a, b):
    """Angle between rotations (sign-blind), elementwise over the last axis; the atan2 form
    stays accurate for nearly equal rotations, where arccos of a dot product cannot go below
    ~3e-8 rad."""
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)
    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))


def test_the_namespace_is_what_the_docs_list():
    """Every public name is in ``__all__`` (no ``np``, ``os`` or compiled helpers), and every
    name there exists."""
    public = {name for name in dir(quatcurve) if not name.startswith("_")}
    assert public == set(quatcurve.__all__) - {"__version__"}
    assert all(hasattr(quatcurve, name) for name in quatcurve.__all__)


def test_slerp_matches_scipy():
    rng = np.random.default_rng(1)
    keys = random_keys(rng, 1, 6)[0]
    times = np.cumsum(rng.uniform(0.2, 1.0, 6))
    t = np.linspace(times[0], times[-1], 101)
    expected = Slerp(times, Rotation.from_quat(keys))(t).as_quat()
    got = quatcurve.evaluate(keys, times, t, curve="slerp", device="reference")
    assert got.shape == (101, 4) and got.dtype == np.float64
    assert angle(got, expected).max() < 1e-9
    fast = quatcurve.evaluate(keys, times, t, curve="slerp", device="cpu")
    assert fast.dtype == np.float32 and angle(fast.astype(np.float64), expected).max() < 1e-5


def about_z(angles):
    half = 0.5 * np.asarray(angles)
    return np.stack([np.zeros_like(half), np.zeros_like(half), np.sin(half), np.cos(half)], axis=-1)


@pytest.mark.parametrize("periodic", [False, True])
def test_bspline_interp_about_one_axis_is_scipys_cubic_spline(periodic):
    rng = np.random.default_rng(2)
    times = np.cumsum(rng.uniform(0.3, 1.2, 8))
    angles = np.cumsum(rng.uniform(-1.0, 1.0, 8))
    if periodic:
        angles[-1] = angles[0]
    spline = CubicSpline(times, angles, bc_type="periodic" if periodic else "natural")
    t = np.linspace(times[0], times[-1], 200)
    q, omega, alpha = quatcurve.evaluate(about_z(angles), times, t, curve="bspline-interp", loop="on" if periodic else "off", derivatives=True, device="reference")
    assert angle(q, about_z(spline(t))).max() < 1e-9
    # Body rates about z are the spline's derivatives.
    assert np.abs(omega[:, 2] - spline(t, 1)).max() < 1e-8
    assert np.abs(alpha[:, 2] - spline(t, 2)).max() < 1e-7
    assert np.abs(omega[:, :2]).max() < 1e-12


def cli():
    for build in ("release", "debug"):
        path = REPO / "target" / build / "quatcurve"
        if path.exists():
            return path
    if os.environ.get("QUATCURVE_REQUIRE_CLI") == "1":
        pytest.fail("QUATCURVE_REQUIRE_CLI=1 but no target/*/quatcurve binary")
    pytest.skip("no quatcurve binary built (cargo build)")


CURVES = ["slerp", "squad", "bezier", "hermite", "nam-kim", "bspline", "normalized-bspline", "bspline-interp"]


@pytest.mark.parametrize("curve", CURVES)
def test_every_curve_matches_the_cli(curve, tmp_path):
    binary = cli()
    rng = np.random.default_rng(3)
    # A normalized B-spline's span (four keys) must turn by less than a half turn.
    keys = random_keys(rng, 3, 6, max_step=0.9 if curve == "normalized-bspline" else 1.2)
    times = np.arange(6) * 0.4
    tracks = [{"name": f"t{i}", "times": times.tolist(), "rotations": keys[i].tolist()} for i in range(3)]
    path = tmp_path / "tracks.json"
    path.write_text(json.dumps({"tracks": tracks}))
    run = subprocess.run(
        [str(binary), "eval", "--input", str(path), "--curve", curve, "--samples", "9", "--derivatives", "--device", "reference"],
        capture_output=True, text=True, check=True,
    )
    doc = json.loads(run.stdout)
    q, omega, alpha = quatcurve.evaluate(keys, times, samples=9, curve=curve, derivatives=True, device="reference")
    assert q.shape == (3, 9, 4)
    for i, track in enumerate(doc["tracks"]):
        np.testing.assert_allclose(q[i], track["rotations"], atol=1e-12)
        np.testing.assert_allclose(omega[i], track["angular_velocity"], atol=1e-9)
        np.testing.assert_allclose(alpha[i], track["angular_acceleration"], atol=1e-7)


def test_batch_shapes_dtypes_and_per_track_sample_times():
    rng = np.random.default_rng(4)
    keys = random_keys(rng, 5, 7)
    shared = quatcurve.evaluate(keys, np.arange(7.0), np.linspace(0, 6, 13), device="cpu")
    assert shared.shape == (5, 13, 4) and shared.dtype == np.float32
    # Per-track times and sample times: each track on its own clock.
    times = np.arange(7.0) + np.arange(5.0)[:, None] * 10.0
    own = np.linspace(0, 6, 13) + np.arange(5.0)[:, None] * 10.0
    moved = quatcurve.evaluate(keys, times, own, device="reference")
    assert moved.shape == (5, 13, 4) and moved.dtype == np.float64
    assert angle(moved, shared.astype(np.float64)).max() < 1e-5
    # rate and samples; float32 and int inputs are accepted.
    assert quatcurve.evaluate(keys.astype(np.float32), rate=2.0).shape == (5, 13, 4)
    assert quatcurve.evaluate(np.array([[0, 0, 0, 1], [0, 0, 1, 0]]), samples=3).shape == (3, 4)
    # Derivatives are views of one array.
    q, omega, alpha = quatcurve.evaluate(keys, samples=4, derivatives=True, device="cpu")
    assert q.shape == (5, 4, 4) and omega.shape == (5, 4, 3) and alpha.shape == (5, 4, 3)
    assert q.base is not None and q.base is omega.base


def test_curve_mirrors_rotation_spline_and_takes_rotations():
    rng = np.random.default_rng(5)
    keys = random_keys(rng, 1, 6, max_step=0.5)[0]
    times = np.cumsum(rng.uniform(0.3, 1.0, 6))
    curve = quatcurve.Curve(times, Rotation.from_quat(keys), device="reference")
    t = np.linspace(times[0], times[-1], 50)
    q = curve(t)
    assert q.shape == (50, 4) and curve(times[2]).shape == (4,)
    assert angle(curve(times), keys).max() < 1e-12
    # Body rates rotated by the orientation are the world-frame rates, here by central
    # differences of the curve itself.
    inner = t[1:-1]
    omega = curve(inner, 1)
    world = Rotation.from_quat(curve(inner)).apply(omega)
    eps = 1e-6
    dq = (Rotation.from_quat(curve(inner + eps)) * Rotation.from_quat(curve(inner - eps)).inv()).as_rotvec() / (2 * eps)
    np.testing.assert_allclose(world, dq, atol=1e-5)
    assert curve(t, 2).shape == (50, 3)
    with pytest.raises(ValueError, match="order"):
        curve(t, 3)
    # Orders as floats, as scipy takes them.
    np.testing.assert_array_equal(curve(t, 1.0), curve(t, 1))
    with pytest.raises(ValueError, match="order"):
        curve(t, 1.5)


def test_rates_are_in_the_body_frame_as_rotation_splines_are():
    # Through two keys both curves are the geodesic at constant speed, so their rates must be
    # equal in the frame they are given in; a tilted first key tells body from world.
    keys = Rotation.from_rotvec([[0.7, 0.2, 0.1], [0.3, -0.9, 0.4]])
    times, t = [0.0, 1.0], np.array([0.1, 0.5, 0.9])
    ours = quatcurve.Curve(times, keys, device="reference")
    theirs = RotationSpline(times, keys)
    np.testing.assert_allclose(ours(t, 1), theirs(t, 1), atol=1e-12)
    world = Rotation.from_quat(ours(t)).apply(ours(t, 1))
    assert np.abs(world - theirs(t, 1)).max() > 0.1


def test_every_front_end_defaults_to_the_curve_through_every_key():
    import ast
    import inspect
    # evaluate passes through its keys without naming a curve (the phantom B-spline would not).
    rng = np.random.default_rng(3)
    keys = random_keys(rng, 1, 7, max_step=0.6)[0]
    times = np.arange(7.0)
    assert angle(quatcurve.evaluate(keys, times, times, device="reference"), keys).max() < 1e-12
    assert quatcurve.DEFAULT_CURVE == "bspline-interp"
    # The stubs show the defaults the functions have.
    stubs = ast.parse((pathlib.Path(quatcurve.__file__).parent / "__init__.pyi").read_text())
    for function, name in [(quatcurve.evaluate, "evaluate"), (quatcurve.bake, "bake"), (quatcurve.Curve.__init__, "__init__")]:
        stub = next(n for n in ast.walk(stubs) if isinstance(n, ast.FunctionDef) and n.name == name)
        arguments = stub.args.posonlyargs + stub.args.args
        shown = dict(zip([a.arg for a in arguments][::-1], stub.args.defaults[::-1]))
        shown.update({a.arg: d for a, d in zip(stub.args.kwonlyargs, stub.args.kw_defaults) if d is not None})
        for parameter in inspect.signature(function).parameters.values():
            if parameter.default is not inspect.Parameter.empty:
                assert ast.literal_eval(shown[parameter.name]) == parameter.default, (name, parameter.name)


def test_errors_are_value_errors_naming_track_and_key():
    good = np.tile([0.0, 0.0, 0.0, 1.0], (2, 4, 1))
    bad = good.copy()
    bad[1, 2] = 0.0
    with pytest.raises(ValueError, match=r"track 1: key 2 has norm 0"):
        quatcurve.evaluate(bad, samples=3)
    bad = good.copy()
    bad[0, 3, 1] = np.nan
    with pytest.raises(ValueError, match=r"track 0: key 3 is not finite"):
        quatcurve.evaluate(bad, samples=3)
    with pytest.raises(ValueError, match="rectangular"):
        quatcurve.evaluate([[[0, 0, 0, 1]], [[0, 0, 0, 1], [0, 0, 0, 1]]], samples=3)
    with pytest.raises(ValueError, match="dtype"):
        quatcurve.evaluate(np.array([["a", "b", "c", "d"]] * 2), samples=3)
    with pytest.raises(ValueError, match="must end in 4"):
        quatcurve.evaluate(np.zeros((3, 5)), samples=3)
    with pytest.raises(ValueError, match="times must have shape"):
        quatcurve.evaluate(good, np.arange(5.0), samples=3)
    with pytest.raises(ValueError, match="key 2 .* not greater"):
        quatcurve.evaluate(good[0], [0.0, 1.0, 1.0, 2.0], samples=3)
    with pytest.raises(ValueError, match="^curve: unknown curve 'spiral'"):
        quatcurve.evaluate(good, samples=3, curve="spiral")
    # Sampled at eval's default rate when nothing says where.
    np.testing.assert_array_equal(quatcurve.evaluate(good), quatcurve.evaluate(good, rate=30))
    with pytest.raises(ValueError, match="^unknown option 'colour' \\(the options are blend_function, curve, "):
        quatcurve.evaluate(good, samples=3, colour="red")
    with pytest.raises(ValueError, match="^samples: give samples or rate, not both$"):
        quatcurve.evaluate(good, samples=3, rate=12)
    # One vocabulary: a keyword's old spelling names the one that takes its place.
    with pytest.raises(ValueError, match="^'blend' is now 'blend_function' \\(the Nam-Kim curve's blend function\\)$"):
        quatcurve.evaluate(good, samples=3, blend="cubic")


DATA = REPO.parent / "shared" / "data"


def data_files(*names):
    """Files of ../shared/data (real animation made by others), required where CI says so."""
    missing = [n for n in names if not (DATA / n).exists()]
    if missing:
        if os.environ.get("QUATCURVE_REQUIRE_DATA") == "1":
            pytest.fail(f"QUATCURVE_REQUIRE_DATA=1 but {missing} are not in {DATA}")
        pytest.skip(f"{DATA} lacks {missing}")
    return [str(DATA / n) for n in names]


def outputs(directory):
    """Every output file's bytes by name, manifests left out (they hold times and hosts)."""
    return {p.name: p.read_bytes() for p in sorted(pathlib.Path(directory).iterdir()) if not p.name.startswith("manifest.")}


@pytest.mark.parametrize("options, kwargs", [
    (["--texture", "model"], {"texture": "model"}),
    (["--precision", "f16", "--atlas", "--curve", "hermite"], {"precision": "f16", "atlas": True, "curve": "hermite"}),
    (["--rate", "24", "--exact-rate"], {"rate": 24, "exact_rate": True}),
    (["--max-error-deg", "2", "--max-rate", "1000", "--texture", "skin-trs", "--format", "exr", "--root-motion", "extract"],
     {"max_error_deg": 2, "max_rate": 1000, "texture": "skin-trs", "format": "exr", "root_motion": "extract"}),
])
def test_bake_writes_what_the_cli_writes(options, kwargs, tmp_path):
    binary = cli()
    inputs = data_files("CesiumMan.glb", "Fox.fbx", "cmu_131_01.bvh")
    subprocess.run([str(binary), "bake", "--input", *inputs, "--output", str(tmp_path / "cli"), "--device", "cpu", *options],
                   capture_output=True, text=True, check=True)
    rows = quatcurve.bake(inputs, tmp_path / "py", device="cpu", **kwargs)
    assert [row["source"] for row in rows] == inputs
    assert all(row["status"] == "ok" and row["error"] is None and row["samples"] > 0 for row in rows), rows
    expected = outputs(tmp_path / "cli")
    assert outputs(tmp_path / "py") == expected
    assert sorted(pathlib.Path(f).name for row in rows for f in row["files"]) == sorted(expected)
    manifest = json.loads((tmp_path / "py" / "manifest.0-of-1.json").read_text())
    assert [record["status"] for record in manifest["inputs"]] == ["ok", "ok", "ok"]
    if "max_error_deg" in kwargs:
        for row in rows:
            assert row["rates"] and all(c["rotation"]["value"] <= kwargs["max_error_deg"] for c in row["rates"]), row["rates"]
    else:
        assert all(row["rates"] == [] for row in rows)


def test_bake_of_vertex_textures_writes_what_the_cli_writes_and_counts_the_skinning(tmp_path):
    binary = cli()
    inputs = data_files("CesiumMan.glb")
    subprocess.run([str(binary), "bake", "--input", *inputs, "--output", str(tmp_path / "cli"), "--device", "cpu",
                    "--texture", "vertex"], capture_output=True, text=True, check=True)
    rows = quatcurve.bake(inputs, tmp_path / "py", device="cpu", texture="vertex")
    assert outputs(tmp_path / "py") == outputs(tmp_path / "cli")
    sidecar = json.loads((tmp_path / "py" / "CesiumMan.json").read_text())
    (primitive,) = sidecar["vertex"]["primitives"]
    (clip,) = sidecar["clips"]
    vertices = np.load(tmp_path / "py" / clip["file"])
    assert vertices.shape == (clip["frames"], primitive["vertices"], 6)
    np.testing.assert_allclose(np.linalg.norm(vertices[..., 3:], axis=-1), 1.0, atol=1e-6)
    assert rows[0]["skinning"]["vertex_frames"] == clip["frames"] * primitive["vertices"]
    assert rows[0]["skinning"]["seconds"] > 0


def test_bake_of_the_built_in_crowd_is_a_texture_per_clip(tmp_path):
    rows = quatcurve.bake(output=tmp_path, characters=2, rate=10, texture="model", device="cpu")
    assert len(rows) == 1 and rows[0]["status"] == "ok" and rows[0]["source"].startswith("built-in crowd: 2 x")
    sidecar = json.loads((tmp_path / "crowd.json").read_text())
    texture = np.load(tmp_path / sidecar["clips"][0]["file"])
    assert texture.dtype == np.float32
    assert texture.shape == (sidecar["clips"][0]["frames"], len(sidecar["joints"]), 12)
    # Rotation blocks of model matrices are rotations: orthonormal rows.
    r = texture[..., [0, 1, 2, 4, 5, 6, 8, 9, 10]].reshape(texture.shape[:2] + (3, 3))
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-5)
    # Resumed: the outputs are verified and kept, not baked again.
    again = quatcurve.bake(output=tmp_path, characters=2, rate=10, texture="model", device="cpu", resume=True)
    assert again[0]["status"] == "resumed" and again[0]["samples"] == 0


def test_evaluate_bake_and_fit_take_the_library_options_and_their_stubs_and_docstrings_say_each_with_its_default():
    import ast
    import pathlib

    assert quatcurve.BAKE_OPTIONS["rate"] == quatcurve.DEFAULT_RATE
    assert quatcurve.BAKE_OPTIONS["curve"] is None  # each input's own interpolation
    assert quatcurve.FIT_OPTIONS["max_error_cm"] == 0.01
    assert quatcurve.EVAL_OPTIONS["curve"] == quatcurve.DEFAULT_CURVE
    stub = ast.parse((pathlib.Path(quatcurve.__file__).parent / "__init__.pyi").read_text())
    for function, options, job in [
        (quatcurve.evaluate, quatcurve.EVAL_OPTIONS, {"angular_velocities", "rotation_type", "output"}),
        (quatcurve.bake, quatcurve.BAKE_OPTIONS, {"shard", "resume", "jobs", "errors"}),
        (quatcurve.fit, quatcurve.FIT_OPTIONS, {"errors"}),
    ]:
        # The first of evaluate's overloads shows every default.
        signature = next(f for f in stub.body if isinstance(f, ast.FunctionDef) and f.name == function.__name__)
        stubbed = {a.arg: ast.literal_eval(d) for a, d in zip(signature.args.kwonlyargs, signature.args.kw_defaults)}
        assert set(stubbed) - job == set(options), function.__name__
        assert {name: stubbed[name] for name in options} == options, function.__name__
        documented = set()
        for line in function.__doc__.splitlines():
            names = line.strip().partition(" :")[0].split(",")
            if line.startswith("    ") and not line.startswith("     ") and all(n.strip().isidentifier() for n in names):
                documented.update(n.strip() for n in names)
        assert set(options) | job <= documented, (function.__name__, (set(options) | job) - documented)


def test_bake_errors_name_the_option_or_the_input(tmp_path):
    with pytest.raises(ValueError, match="rate must be a positive number of Hz, not -1"):
        quatcurve.bake(output=tmp_path / "a", rate=-1)
    with pytest.raises(ValueError, match="texture: unknown texture 'pretty'"):
        quatcurve.bake(output=tmp_path / "a", texture="pretty")
    with pytest.raises(ValueError, match="unknown option 'colour' \\(the options are allow_external_uris, atlas, "):
        quatcurve.bake(output=tmp_path / "a", colour="red")
    with pytest.raises(ValueError, match="characters: invalid value: integer `-3`"):
        quatcurve.bake(output=tmp_path / "a", characters=-3)
    # Options by their Python names, never as command-line flags.
    with pytest.raises(ValueError, match="^max_texture_size must be at least 1 texel$"):
        quatcurve.bake(output=tmp_path / "a", max_texture_size=0)
    with pytest.raises(ValueError, match="^exact_rate cannot be set with an error budget"):
        quatcurve.bake(output=tmp_path / "a", max_error_deg=1, exact_rate=True)
    with pytest.raises(ValueError, match="shard 3/2: shard 3 of 2 does not exist"):
        quatcurve.bake(output=tmp_path / "a", shard="3/2")
    with pytest.raises(ValueError, match="errors must be"):
        quatcurve.bake(output=tmp_path / "a", errors="ignore")
    assert not (tmp_path / "a").exists()
    # One bad input among good ones: the good one is baked, the bad one named with its rule.
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT hips\n{\n")
    good = data_files("cmu_131_03.bvh")[0]
    with pytest.raises(ValueError, match=r"1 of 2 inputs failed \(the other was baked\): .*bad\.bvh: "):
        quatcurve.bake([bad, good], tmp_path / "b", device="cpu")
    # Rows come in job order (inputs sorted by path), wherever the two files live.
    rows = {pathlib.Path(row["source"]).name: row for row in quatcurve.bake([bad, good], tmp_path / "c", device="cpu", errors="report")}
    assert rows["bad.bvh"]["status"] == "failed" and rows["cmu_131_03.bvh"]["status"] == "ok"
    assert rows["bad.bvh"]["files"] == [] and rows["bad.bvh"]["error"] and "bad.bvh" not in rows["bad.bvh"]["error"]
    assert (tmp_path / "c" / "cmu_131_03.bvh").exists() and not (tmp_path / "c" / "bad.json").exists()
    # What did not fail the bake but should be known: the take's flipping thumb.
    assert any("RThumb rotation" in w for w in rows["cmu_131_03.bvh"]["warnings"]), rows["cmu_131_03.bvh"]["warnings"]
    assert rows["bad.bvh"]["warnings"] == []


def test_fit_writes_what_the_cli_writes_and_bake_reads_the_container(tmp_path):
    binary = cli()
    inputs = data_files("CesiumMan.glb")
    done = subprocess.run([str(binary), "fit", "--input", *inputs, "--output", str(tmp_path / "cli"), "--json"],
                          capture_output=True, text=True, check=True)
    expected = json.loads(done.stdout)
    report = quatcurve.fit(inputs, tmp_path / "py")
    assert outputs(tmp_path / "py") == outputs(tmp_path / "cli")
    (clip,) = report["inputs"][0]["clips"]
    (cli_clip,) = expected["inputs"][0]["clips"]
    assert {k: v for k, v in clip.items() if k != "seconds"} == {k: v for k, v in cli_clip.items() if k != "seconds"}
    assert clip["at_frames"]["error_cm"] <= 0.01 and clip["between_frames"]["error_cm"] <= 0.3
    assert clip["raw_bytes"] == 40 * clip["joints"] * clip["frames"] and clip["ratio"] > 1
    (row,) = quatcurve.bake(tmp_path / "py" / "CesiumMan.qcf", tmp_path / "baked", device="cpu", texture="model")
    assert row["status"] == "ok", row
    assert json.loads((tmp_path / "baked" / "CesiumMan.json").read_text())["curve"] == "fitted-bspline"
    # The runtime decoder gives the poses the bake's `local` texture holds, at the source's
    # rate and at another.
    sidecar = json.loads((tmp_path / "baked" / "CesiumMan.json").read_text())
    for rate in (None, 24.0):
        decoded = quatcurve.decode(tmp_path / "py" / "CesiumMan.qcf", rate=rate)
        assert decoded["joints"] == sidecar["joints"] and decoded["parents"] == sidecar["parents"]
        (clip,) = decoded["clips"]
        baked = tmp_path / f"local{rate}"
        times = clip["times"]
        source_rate = (len(times) - 1) / (times[-1] - times[0])
        (row,) = quatcurve.bake(tmp_path / "py" / "CesiumMan.qcf", baked, device="cpu", rate=rate or source_rate)
        assert row["status"] == "ok", row
        texture = np.load(baked / json.loads((baked / "CesiumMan.json").read_text())["clips"][0]["file"])
        assert clip["poses"].dtype == np.float32 and clip["poses"].shape == texture.shape
        assert clip["times"].shape == (texture.shape[0],)
        # Rotations either sign; every value to f32 rounding of the two paths.
        q, r = clip["poses"][..., :4], texture[..., :4]
        sign = np.where(np.sum(q * r, axis=-1, keepdims=True) < 0, -1.0, 1.0)
        assert np.abs(q - sign * r).max() < 2e-5, np.abs(q - sign * r).max()
        assert np.abs(clip["poses"][..., 4:] - texture[..., 4:]).max() < 1e-4 * max(1.0, np.abs(texture[..., 4:]).max())
    with pytest.raises(ValueError, match="CesiumMan.glb: fitted container byte 0: magic"):
        quatcurve.decode(inputs[0])
    # A library of two copies: one container, the clips named by their inputs' stems, decoded
    # as each copy's own container decodes.
    for stem in ("a", "b"):
        shutil.copy(inputs[0], tmp_path / f"{stem}.glb")
    report = quatcurve.fit([tmp_path / "a.glb", tmp_path / "b.glb"], tmp_path / "library", clip_library="men")
    assert report["clip_library"]["output"] == str(tmp_path / "library" / "men.qcf")
    assert report["clip_library"]["whole_file_ratio"] < report["clip_library"]["ratio"]
    library = quatcurve.decode(tmp_path / "library" / "men.qcf")
    alone = quatcurve.decode(tmp_path / "py" / "CesiumMan.qcf")["clips"][0]
    assert [c["name"] for c in library["clips"]] == [f"{stem}/{alone['name']}" for stem in ("a", "b")]
    for clip in library["clips"]:
        assert np.array_equal(clip["poses"], alone["poses"])
    with pytest.raises(ValueError, match="unit_cm is needed for"):
        quatcurve.fit(data_files("cmu_131_01.bvh"), tmp_path / "bvh")
    with pytest.raises(ValueError, match="max_error_cm is 0; it must be a positive length"):
        quatcurve.fit(inputs, tmp_path / "zero", max_error_cm=0)
    with pytest.raises(ValueError, match="'max_error' is now 'max_error_cm' \\(centimetres\\)"):
        quatcurve.fit(inputs, tmp_path / "old", max_error=0.01)
    with pytest.raises(ValueError, match="'max_error' is now 'max_error_deg' \\(degrees\\)"):
        quatcurve.bake(output=tmp_path / "old", max_error=0.5)


def test_a_bake_for_a_player_gets_the_texture_and_format_it_plays(tmp_path):
    quatcurve.bake(output=tmp_path / "view", characters=1, player="view")
    assert list((tmp_path / "view").glob("crowd.*.exr")), list((tmp_path / "view").iterdir())
    with pytest.raises(ValueError, match="^player view: view plays skin-trs or vertex textures, not model"):
        quatcurve.bake(output=tmp_path / "view", characters=1, player="view", texture="model")
