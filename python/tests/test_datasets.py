"""What resampling a motion dataset needs: curves that pickle, rotation vectors and matrices
in and out as scipy's Rotation writes them, tracks of their own lengths in one batch, and
SMPL-family pose archives (AMASS's layout) resampled at exact times as scipy's Slerp does."""

import pathlib
import pickle
import tempfile

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

import quatcurve
from test_quatcurve import angle, data_files, random_keys


def test_curves_pickle_and_give_the_same_bits_after():
    rng = np.random.default_rng(11)
    keys = random_keys(rng, 1, 9, max_step=0.8)[0]
    times = np.cumsum(rng.uniform(0.2, 0.9, 9))
    t = np.linspace(times[0], times[-1], 101)
    for options in [{}, {"curve": "hermite", "device": "cpu"}, {"loop": "off", "output": "rotvec", "device": "reference"}]:
        curve = quatcurve.Curve(times, keys, **options)
        again = pickle.loads(pickle.dumps(curve))
        assert again.curve == curve.curve and again.options == curve.options
        for order in (0, 1, 2):
            np.testing.assert_array_equal(again(t, order), curve(t, order))


def test_rotation_vectors_in_agree_with_scipy():
    rng = np.random.default_rng(4)
    rotvecs = Rotation.from_quat(random_keys(rng, 1, 12, max_step=1.0)[0]).as_rotvec()
    rotvecs[3] = 0.0  # the identity: the small-angle branch
    rotvecs[4] = [1e-9, -2e-9, 5e-10]
    times = np.arange(12.0)
    # Sampled at the keys, slerp returns the keys: scipy's quaternions of the same vectors.
    q = quatcurve.evaluate(rotvecs, times, times, curve="slerp", device="reference", rotation_type="rotvec")
    assert angle(q, Rotation.from_rotvec(rotvecs).as_quat()).max() < 1e-12
    # In between too, rotvec in and quaternions in are the same curve.
    t = np.linspace(0.0, 11.0, 97)
    from_quat = quatcurve.evaluate(Rotation.from_rotvec(rotvecs).as_quat(), times, t, device="reference")
    np.testing.assert_allclose(
        quatcurve.evaluate(rotvecs, times, t, device="reference", rotation_type="rotvec"), from_quat, atol=1e-12
    )
    # Not guessed: three numbers could as well be Euler angles.
    with pytest.raises(ValueError, match=r"end in 3 numbers \(shape \(12, 3\)\): say rotation_type='rotvec'"):
        quatcurve.evaluate(rotvecs, times, t)
    with pytest.raises(ValueError, match="say rotation_type='rotvec'"):
        quatcurve.Curve(times, rotvecs)


def test_rotation_vectors_and_matrices_out_agree_with_scipy():
    rng = np.random.default_rng(5)
    keys = random_keys(rng, 3, 8, max_step=1.3)
    t = np.linspace(0.0, 7.0, 50)
    q = quatcurve.evaluate(keys, sample_times=t, device="reference")
    rotvec = quatcurve.evaluate(keys, sample_times=t, output="rotvec", device="reference")
    matrix = quatcurve.evaluate(keys, sample_times=t, output="matrix", device="reference")
    assert rotvec.shape == (3, 50, 3) and matrix.shape == (3, 50, 3, 3)
    scipy_rotations = Rotation.from_quat(q.reshape(-1, 4))
    np.testing.assert_allclose(rotvec.reshape(-1, 3), scipy_rotations.as_rotvec(), atol=1e-12)
    np.testing.assert_allclose(matrix.reshape(-1, 3, 3), scipy_rotations.as_matrix(), atol=1e-12)
    # Matrices in: the same curve as the quaternions they were made from.
    again = quatcurve.evaluate(Rotation.from_quat(keys.reshape(-1, 4)).as_matrix().reshape(3, 8, 3, 3), sample_times=t, device="reference")
    assert angle(again, q).max() < 1e-12
    # Derivatives come after the rotation whatever its form.
    _, omega, alpha = quatcurve.evaluate(keys, sample_times=t, derivatives=True, device="reference")
    m, omega_m, alpha_m = quatcurve.evaluate(keys, sample_times=t, derivatives=True, output="matrix", device="reference")
    assert m.shape == (3, 50, 3, 3)
    np.testing.assert_array_equal(omega_m, omega)
    np.testing.assert_array_equal(alpha_m, alpha)
    # On a fast path, float32 of the same.
    fast = quatcurve.evaluate(keys, sample_times=t, output="rotvec", device="cpu")
    assert fast.dtype == np.float32 and np.abs(fast - rotvec).max() < 1e-5


def test_ambiguous_and_wrong_shapes_are_explained():
    # Three tracks of three rotation vectors look like one track of three matrices.
    rotvecs = np.full((3, 3, 3), 0.1)
    with pytest.raises(ValueError, match=r"track 0: key 0 is not a rotation matrix"):
        quatcurve.evaluate(rotvecs, samples=4)  # read as matrices, which these are not
    q = quatcurve.evaluate(rotvecs, samples=4, rotation_type="rotvec", device="reference")
    assert q.shape == (3, 4, 4)
    with pytest.raises(ValueError, match=r"must end in 4 \(quaternions x, y, z, w\), 3 \(rotation vectors, with"):
        quatcurve.evaluate(np.zeros((5, 6)), samples=3)
    with pytest.raises(ValueError, match="output must be quat, rotvec or matrix"):
        quatcurve.evaluate(rotvecs[0], samples=3, output="euler", rotation_type="rotvec")


def test_tracks_of_their_own_lengths_evaluate_in_one_batch():
    rng = np.random.default_rng(6)
    counts = [2, 9, 5, 17]
    tracks = [random_keys(rng, 1, n, max_step=0.9)[0] for n in counts]
    times = [np.cumsum(rng.uniform(0.1, 0.5, n)) for n in counts]
    out = quatcurve.evaluate(tracks, times, rate=30, device="reference")
    assert isinstance(out, list) and len(out) == 4
    for keys, t, got in zip(tracks, times, out):
        alone = quatcurve.evaluate(keys, t, rate=30, device="reference")
        np.testing.assert_array_equal(got, alone)
    # Rotation vectors in, per-track sample lists, derivatives, rotation vectors out.
    rotvecs = [Rotation.from_quat(k).as_rotvec() for k in tracks]
    sample_lists = [np.linspace(t[0], t[-1], m) for t, m in zip(times, [3, 1, 8, 4])]
    q, omega, alpha = quatcurve.evaluate(
        rotvecs, times, sample_lists, derivatives=True, output="rotvec", device="cpu", rotation_type="rotvec"
    )
    assert [a.shape for a in q] == [(3, 3), (1, 3), (8, 3), (4, 3)] and [a.shape for a in omega] == [(3, 3), (1, 3), (8, 3), (4, 3)]
    for rv, t, s, got in zip(rotvecs, times, sample_lists, q):
        alone = quatcurve.evaluate(rv, t, s, output="rotvec", device="cpu", rotation_type="rotvec")
        np.testing.assert_array_equal(got, alone)
    # A track that breaks a rule is named by its index in the list.
    bad = [tracks[0], np.zeros((3, 4))]
    with pytest.raises(ValueError, match="track 1: key 0 has norm 0"):
        quatcurve.evaluate(bad, samples=3)
    with pytest.raises(ValueError, match=r"times\[1\] must have 3 entries"):
        quatcurve.evaluate([tracks[1][:3], tracks[1][:3]], [times[1][:3], times[0]], samples=3)


def amass_clip(path, rng, frames=97, width=156, rate=60.0, **fields):
    """An AMASS-layout archive (docs/DATASETS.md): smooth random poses, a root path, per-sequence fields."""
    t = np.arange(frames)[:, None] / rate
    poses = 1.2 * np.sin(2 * np.pi * rng.uniform(0.2, 1.5, (1, width)) * t + rng.uniform(0, 6, (1, width)))
    trans = np.cumsum(rng.uniform(-0.02, 0.02, (frames, 3)), axis=0)
    np.savez(path, poses=poses, trans=trans, betas=rng.normal(size=16), gender=np.array("female"), mocap_framerate=np.array(rate), **fields)
    return poses, trans


def slerp_each_joint(poses, rate, new_times):
    """scipy's Slerp of every joint's axis-angles at `new_times` (seconds from the first frame)."""
    times = np.arange(len(poses)) / rate
    return [Slerp(times, Rotation.from_rotvec(poses[:, 3 * j:3 * j + 3]))(new_times) for j in range(poses.shape[1] // 3)]


@pytest.mark.parametrize("width", [156, 165])
def test_smpl_archives_bake_into_their_own_layout_at_exact_times_as_scipy_slerps_them(tmp_path, width):
    rng = np.random.default_rng(width)
    poses, trans = amass_clip(tmp_path / "walk.npz", rng, width=width, dmpls=rng.normal(size=(97, 8)))
    rows = quatcurve.bake(tmp_path / "walk.npz", tmp_path / "out", rate=25, exact_rate=True, device="cpu")
    assert rows[0]["status"] == "ok"
    with np.load(tmp_path / "out" / "walk.npz") as baked, np.load(tmp_path / "walk.npz") as source:
        assert list(baked.keys()) == list(source.keys())
        new_times = np.arange(41) / 25.0  # 1.6 s at exactly 25 Hz
        assert baked["poses"].shape == (41, width) and float(baked["mocap_framerate"]) == 25.0
        # float64 in, float64 out, computed in float64: scipy's Slerp to 1e-12 rad.
        assert baked["poses"].dtype == np.float64 and baked["trans"].dtype == np.float64
        for j, expected in enumerate(slerp_each_joint(poses, 60.0, new_times)):
            got = Rotation.from_rotvec(baked["poses"][:, 3 * j:3 * j + 3])
            assert (expected.inv() * got).magnitude().max() < 1e-12, j
        assert np.linalg.norm(baked["poses"].reshape(-1, 3), axis=1).max() <= np.pi + 1e-9  # angles in [0, pi]
        lerped = np.stack([np.interp(new_times, np.arange(97) / 60, trans[:, c]) for c in range(3)], axis=1)
        np.testing.assert_allclose(baked["trans"], lerped, rtol=0, atol=1e-12 * np.abs(trans).max())
        np.testing.assert_array_equal(baked["betas"], source["betas"])
        assert str(baked["gender"]) == "female"


def test_resample_poses_in_memory_is_the_bake_of_the_same_arrays(tmp_path):
    rng = np.random.default_rng(5)
    poses, trans = amass_clip(tmp_path / "run.npz", rng, frames=121, width=72, rate=120.0)
    # HumanML3D's stride line for 120 -> 20 Hz, and the same at exact times.
    strided = poses[::6]
    out = quatcurve.resample_poses(poses, 120.0, 20.0, trans=trans, exact_rate=True, device="cpu")
    assert out["poses"].shape == strided.shape and out["rate"] == 20.0 and out["warnings"] == []
    # An integer ratio gives the source's own frames, bit for bit.
    np.testing.assert_array_equal(out["poses"], strided)
    np.testing.assert_array_equal(out["trans"], trans[::6])
    # Between frames (120 -> 50 Hz) as scipy's Slerp, and as the bake of the archive writes.
    out = quatcurve.resample_poses(poses, 120.0, 50.0, trans=trans, exact_rate=True, device="cpu")
    for j, expected in enumerate(slerp_each_joint(poses, 120.0, np.arange(51) / 50.0)):
        assert (expected.inv() * Rotation.from_rotvec(out["poses"][:, 3 * j:3 * j + 3])).magnitude().max() < 1e-12, j
    quatcurve.bake(tmp_path / "run.npz", tmp_path / "out", rate=50.0, exact_rate=True, device="cpu")
    with np.load(tmp_path / "out" / "run.npz") as baked:
        np.testing.assert_array_equal(baked["poses"], out["poses"])
        np.testing.assert_array_equal(baked["trans"], out["trans"])
    # Other per-frame arrays, given by name, at the new frames as np.interp puts them.
    dmpls, markers = rng.normal(size=(121, 8)), rng.normal(size=(121, 5, 3))
    out = quatcurve.resample_poses(poses, 120.0, 50.0, per_frame={"dmpls": dmpls, "marker_data": markers}, exact_rate=True)
    assert out["per_frame"]["dmpls"].shape == (51, 8) and out["per_frame"]["marker_data"].shape == (51, 5, 3)
    new_times, times = np.arange(51) / 50.0, np.arange(121) / 120.0
    expected = np.stack([np.interp(new_times, times, markers.reshape(121, -1)[:, c]) for c in range(15)], axis=1)
    np.testing.assert_allclose(out["per_frame"]["marker_data"].reshape(51, -1), expected, rtol=0, atol=1e-12 * np.abs(markers).max())
    with pytest.raises(ValueError, match=r"marker_data: shape \[120, 5, 3\]; expected \[121, ...\]"):
        quatcurve.resample_poses(poses, 120.0, 50.0, per_frame={"marker_data": markers[:120]})


def test_amass_s_own_sample_resamples_whole_in_float64():
    """AMASS's sample archive (601 frames at 120 Hz, float64, marker_data with occluded NaNs,
    dmpls): every per-frame array at the new frames, the source's own at an integer ratio, and
    between frames as scipy's Slerp and np.interp compute them, to 1e-12."""
    (path,) = data_files("amass_sample.npz")
    with np.load(path) as source:
        source = {k: source[k] for k in source.files}
    times = np.arange(601) / 120.0
    for rate, stride in [(30.0, 4), (50.0, None)]:
        out = pathlib.Path(tempfile.mkdtemp()) / "out"
        rows = quatcurve.bake(path, out, rate=rate, exact_rate=True, device="cpu")
        assert rows[0]["status"] == "ok" and rows[0]["warnings"] == [], rows
        with np.load(out / "amass_sample.npz") as baked:
            assert list(baked.keys()) == list(source.keys())
            new_times = np.arange(len(baked["poses"])) / rate
            assert baked["poses"].shape == (int(5 * rate) + 1, 156) and baked["marker_data"].shape == (len(new_times), 85, 3)
            per_frame = ["poses", "trans", "dmpls", "marker_data"]
            assert all(baked[k].dtype == np.float64 for k in per_frame)
            if stride:
                for k in per_frame:
                    np.testing.assert_array_equal(baked[k], source[k][::stride], err_msg=k)
            for j, expected in enumerate(slerp_each_joint(source["poses"], 120.0, new_times)):
                got = Rotation.from_rotvec(baked["poses"][:, 3 * j:3 * j + 3])
                assert (expected.inv() * got).magnitude().max() < 1e-12, (rate, j)
            for k in ["trans", "dmpls", "marker_data"]:
                flat = source[k].reshape(601, -1)
                expected = np.stack([np.interp(new_times, times, flat[:, c]) for c in range(flat.shape[1])], axis=1)
                got = baked[k].reshape(len(new_times), -1)
                # np.interp at a source frame beside a NaN gives NaN; the source's own frame is kept.
                both = ~np.isnan(expected)
                largest = np.nanmax(np.abs(flat))  # 1e-12 of the field's largest value
                np.testing.assert_allclose(got[both], expected[both], rtol=0, atol=1e-12 * largest, err_msg=f"{rate} Hz {k}")
                assert np.isnan(got).sum() <= np.isnan(expected).sum()
            np.testing.assert_array_equal(baked["marker_labels"], source["marker_labels"])
            np.testing.assert_array_equal(baked["betas"], source["betas"])


def test_bad_pose_arrays_are_refused_by_name():
    poses = np.zeros((10, 156))
    poses[4, 3 * 18 + 2] = np.nan
    with pytest.raises(ValueError, match="poses: frame 4: left_elbow value 56 is NaN"):
        quatcurve.resample_poses(poses, 60.0, 30.0)
    with pytest.raises(ValueError, match="poses: shape \\[10, 150\\]; expected \\[frames, width\\] with width 72 for SMPL"):
        quatcurve.resample_poses(np.zeros((10, 150)), 60.0, 30.0)
    with pytest.raises(ValueError, match="mocap_framerate: -60 is not a positive number"):
        quatcurve.resample_poses(np.zeros((10, 72)), -60.0, 30.0)
    with pytest.raises(ValueError, match="trans: shape \\[9, 3\\]; expected \\[10, 3\\]"):
        quatcurve.resample_poses(np.zeros((10, 72)), 60.0, 30.0, trans=np.zeros((9, 3)))
    with pytest.raises(TypeError, match="does not take: texture"):
        quatcurve.resample_poses(np.zeros((10, 72)), 60.0, 30.0, texture="model")


def test_the_scipy_comparison_names_a_missing_binary_before_running_scipy():
    import subprocess
    import sys

    script = pathlib.Path(__file__).resolve().parents[2] / "benches" / "scipy_rotation_spline.py"
    run = subprocess.run([sys.executable, str(script), "--quatcurve", "/nonexistent/quatcurve"],
                         capture_output=True, text=True)
    assert run.returncode == 1
    assert "no quatcurve binary at /nonexistent/quatcurve" in run.stderr
    assert "Traceback" not in run.stderr
    # Refused before the scipy half, which prints its figures first.
    assert run.stdout == "", run.stdout
