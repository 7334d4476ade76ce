"""What resampling a motion dataset needs: curves that pickle, rotation vectors and matrices
in and out as scipy's Rotation writes them, and tracks of their own lengths in one batch."""

import pickle

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import quatcurve
from test_quatcurve import angle, random_keys


def test_curves_pickle_and_give_the_same_bits_after():
    rng = np.random.default_rng(11)
    keys = random_keys(rng, 1, 9, max_step=0.8)[0]
    times = np.cumsum(rng.uniform(0.2, 0.9, 9))
    t = np.linspace(times[0], times[-1], 101)
    for options in [{}, {"curve": "hermite", "device": "cpu"}, {"loop": False, "output": "rotvec", "device": "reference"}]:
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
