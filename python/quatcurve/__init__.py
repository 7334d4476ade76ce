"""Smooth rotation curves for batches of animation tracks, numpy in and out.

quatcurve evaluates the quaternion curves of Kim, Kim & Shin (the cumulative form: Bezier,
Hermite, order-k B-splines, the C2 cubic B-spline through every key), Nam & Kim's great-arc
blends, slerp and squad, for one track or thousands at once, on the GPU (wgpu) or a
multi-threaded SIMD CPU path, with an f64 reference. Conventions (docs/DESIGN.md in the
repository): quaternions are ``x, y, z, w``; angular velocity and acceleration are in the
body frame (``omega = 2 vec(q^-1 q')``), rad/s and rad/s^2.

>>> import numpy as np, quatcurve
>>> keys = np.array([[0, 0, 0, 1], [0, 0, 0.7071068, 0.7071068], [0, 0, 1, 0]], float)
>>> q = quatcurve.evaluate(keys, [0.0, 0.5, 1.0], rate=60, curve="bspline-interp")
>>> q.shape
(61, 4)
"""

from __future__ import annotations

import os

import numpy as np

from ._quatcurve import DEFAULT_CHARACTERS, DEFAULT_CURVE, DEFAULT_RATE, __version__, bake_files, evaluate_batch

__all__ = ["evaluate", "bake", "Curve", "__version__"]


def _float64(name, value, ndims):
    """`value` as a C-contiguous float64 array of one of the ranks in `ndims`."""
    try:
        array = np.asarray(value)
    except Exception as e:  # ragged lists
        raise ValueError(f"{name} must be a rectangular array of numbers: {e}") from None
    if array.dtype == object or not (np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)):
        raise ValueError(f"{name} must hold real numbers (float or int), got dtype {array.dtype}")
    if array.ndim not in ndims:
        shapes = " or ".join(f"{n} dimensions" for n in ndims)
        raise ValueError(f"{name} must have {shapes}, got shape {array.shape}")
    return np.ascontiguousarray(array, dtype=np.float64)


def evaluate(
    rotations,
    times=None,
    sample_times=None,
    *,
    rate=None,
    samples=None,
    curve=DEFAULT_CURVE,
    order=4,
    knots="phantom",
    tangents="catmull-rom",
    blend="cubic",
    loop=False,
    angular_velocities=None,
    derivatives=False,
    device="auto",
):
    """Evaluates rotation curves through keys (DESIGN section 9).

    Parameters
    ----------
    rotations : array_like, ``(keys, 4)`` for one track or ``(tracks, keys, 4)``
        Key quaternions ``x, y, z, w`` (normalized and made sign-continuous here), or a
        ``scipy.spatial.transform.Rotation`` (its ``as_quat()``).
    times : array_like, ``(keys,)`` shared or ``(tracks, keys)``, optional
        Strictly increasing key times in seconds; default ``0, 1, 2, ...``.
    sample_times : array_like, ``(m,)`` shared or ``(tracks, m)``, optional
        Where to evaluate. Otherwise ``samples`` (N per track from domain start to end) or
        ``rate`` (Hz from the domain start); one of the three is required.
    curve : str, default ``"bspline-interp"``
        ``bspline-interp`` (the default of every front end: C2 and through every key, on any
        key times), ``slerp``, ``squad``, ``bezier``, ``hermite``, ``nam-kim`` or ``bspline``
        (KKS order-k B-spline with the keys as control points, ``knots``
        phantom/uniform/clamped: it approximates the keys, passing only through the ends).
    order, knots, tangents, blend
        B-spline order, knot mode, tangent source of hermite/nam-kim (``catmull-rom``,
        ``zero``, ``given`` with ``angular_velocities`` ``(…, keys, 3)`` body rad/s), Nam-Kim
        blend (``cubic``, ``quadratic``).
    loop : bool
        Periodic curves; the last key must be the first rotation.
    derivatives : bool
        Also return body angular velocity and acceleration.
    device : str
        ``auto`` (a hardware GPU if any, else the CPU path), ``gpu``, ``cpu`` or
        ``reference`` (f64).

    Returns
    -------
    numpy.ndarray ``(..., m, 4)``, or with ``derivatives`` a tuple ``(q, omega, alpha)`` of
    ``(..., m, 4)``, ``(..., m, 3)``, ``(..., m, 3)`` (views of one array). float64 from
    ``device="reference"``, float32 otherwise. One track in, no track axis out.

    Raises
    ------
    ValueError
        Bad shapes or dtypes, and every rule the library checks, with its message naming
        the track and key (``track 3: key 7 has norm 0, ...``).
    """
    if hasattr(rotations, "as_quat"):
        rotations = rotations.as_quat()
    q = _float64("rotations", rotations, (2, 3))
    single = q.ndim == 2
    if single:
        q = q[np.newaxis]
    if q.shape[2] != 4:
        raise ValueError(f"rotations must end in 4 components (x, y, z, w), got shape {np.shape(rotations)}")
    tracks, keys = q.shape[0], q.shape[1]

    def per_track(name, value, width, last=None):
        a = _float64(name, value, (1, 2) if last is None else (2, 3))
        if a.ndim == (1 if last is None else 2):
            a = np.broadcast_to(a, (tracks,) + a.shape)
        if a.shape[0] != tracks or (width is not None and a.shape[1] != width) or (last is not None and a.shape[2] != last):
            want = f"({width}{', ' + str(last) if last else ''}) or ({tracks}, {width}{', ' + str(last) if last else ''})"
            raise ValueError(f"{name} must have shape {want} for {tracks} track(s) of {keys} keys, got {np.shape(value)}")
        return np.ascontiguousarray(a)

    t = None if times is None else per_track("times", times, keys)
    w = None if angular_velocities is None else per_track("angular_velocities", angular_velocities, keys, 3)
    s = None
    if sample_times is not None:
        s = _float64("sample_times", sample_times, (1, 2))
        s = per_track("sample_times", s, s.shape[-1])
    elif rate is None and samples is None:
        raise ValueError("give sample_times, samples=N or rate=HZ")
    if samples is not None and (int(samples) != samples or samples < 1):
        raise ValueError(f"samples must be a positive integer, got {samples}")
    out = evaluate_batch(
        q, t, s, None if rate is None else float(rate), None if samples is None else int(samples),
        str(curve), int(order), str(knots), str(tangents), str(blend), bool(loop), w, bool(derivatives), str(device),
    )
    if single:
        out = out[0]
    if not derivatives:
        return out
    return out[..., :4], out[..., 4:7], out[..., 7:10]


class Curve:
    """One rotation curve through keys, called like ``scipy``'s ``RotationSpline``.

    ``Curve(times, rotations)`` builds the C2 cubic B-spline through every key
    (``curve="bspline-interp"``, KKS section 6.2; natural ends, or periodic with
    ``loop=True``) — the same conditions as ``RotationSpline`` but in the KKS cumulative
    form. Any other curve and option of :func:`evaluate` can be given by keyword.
    ``rotations`` may be a ``scipy.spatial.transform.Rotation``.

    ``curve(t, order=0)`` returns quaternions ``x, y, z, w`` (``(4,)`` for a scalar ``t``,
    ``(m, 4)`` otherwise; wrap with ``Rotation.from_quat`` for a Rotation); ``order=1`` the
    angular velocity and ``order=2`` the angular acceleration, rad/s and rad/s^2, in the
    body frame, as ``RotationSpline``'s are (for the world frame, rotate them by the
    orientation: ``Rotation.from_quat(q).apply(omega)``). ``order`` may be an int or a
    float with an integer value, as scipy takes it.
    """

    def __init__(self, times, rotations, curve=DEFAULT_CURVE, **options):
        if hasattr(rotations, "as_quat"):
            rotations = rotations.as_quat()
        self.rotations = _float64("rotations", rotations, (2,))
        self.times = _float64("times", times, (1,))
        self.curve = curve
        self.options = options
        # Build once: errors in the keys surface here, as in scipy.
        evaluate(self.rotations, self.times, self.times[:1], curve=curve, **options)

    def __call__(self, t, order=0):
        if isinstance(order, bool) or order not in (0, 1, 2):
            raise ValueError(f"order must be 0, 1 or 2, got {order!r}")
        order = int(order)
        scalar = np.ndim(t) == 0
        samples = np.atleast_1d(np.asarray(t, dtype=np.float64))
        result = evaluate(self.rotations, self.times, samples, curve=self.curve, derivatives=order > 0, **self.options)
        value = result if order == 0 else result[order]
        return value[0] if scalar else value


def bake(
    inputs=None,
    output="baked",
    *,
    rate=DEFAULT_RATE,
    exact_rate=False,
    curve=DEFAULT_CURVE,
    order=4,
    knots="phantom",
    tangents="catmull-rom",
    blend="cubic",
    loop="auto",
    texture="local",
    precision="f32",
    atlas=False,
    preview=False,
    characters=DEFAULT_CHARACTERS,
    shard=None,
    resume=False,
    jobs=1,
    allow_external_uris=False,
    device="auto",
    errors="raise",
):
    """Resamples animation files at a fixed rate into animation textures, as ``quatcurve bake``
    does (DESIGN section 5b), and returns one summary row per input.

    Parameters
    ----------
    inputs : str, os.PathLike or a list of them, optional
        ``.gltf``, ``.glb`` and ``.bvh`` files, or directories of them. None (or an empty
        list): the built-in synthetic crowd of ``characters`` characters.
    output : str or os.PathLike
        Output directory, created if missing. Per input ``<stem>``: the baked file
        (``<stem>.glb`` or ``<stem>.bvh``), textures ``<stem>.<clip>.npy`` (or one
        ``<stem>.npy`` with ``atlas``), the sidecar ``<stem>.json``; per shard a manifest.
    rate : float
        Frames per second, fitted per clip: each clip takes the nearest rate that puts a
        whole number of frames between its first and last keys, so both are baked (the
        clip's own rate is in the sidecar).
    exact_rate : bool
        Bake open clips at exactly ``rate`` (frames ``start + i / rate`` while not past the
        last key); a clip's end off that grid is not baked, and the row's ``warnings`` say
        how much. Loops always fit.
    curve, order, knots, tangents, blend
        As :func:`evaluate`; the default is C2 through every key.
    loop : str
        ``auto`` (clips whose rotations end where they start), ``on`` or ``off``.
    texture : str
        ``local`` ``[frames, joints, 10]`` (rotation, translation, scale), ``model``
        ``[frames, joints, 12]`` (3x4 matrices by forward kinematics) or ``skin`` (model
        times inverse bind matrix, per glTF skin).
    precision : str
        ``f32`` or ``f16``.
    atlas, preview : bool
        Stack every clip of an input in one texture; draw a skeleton PNG per clip.
    shard : str, optional
        ``"I/N"``: bake only inputs ``k`` with ``k % N == I`` (default: the share a Slurm,
        Kubernetes, AWS Batch or Google Batch array task is given, else all).
    resume : bool
        Skip inputs whose outputs this shard's manifest records as intact.
    jobs : int
        Inputs baked at once.
    device : str
        As :func:`evaluate`.
    errors : str
        ``raise`` (default): after every input is done, raise ``ValueError`` if any failed,
        naming each with its error; ``report``: return the rows, failures included.

    Returns
    -------
    list of dict
        Per input: ``source``, ``clips``, ``channels``, ``keys``, ``samples``, ``seconds``,
        ``max_key_error`` (rad, or None), ``status`` (``ok``, ``resumed`` or ``failed``),
        ``error`` (the message, or None), ``files`` (``pathlib.Path``s written or kept) and
        ``warnings`` (probably broken source keys, clip ends an exact rate did not bake).

    Raises
    ------
    ValueError
        An option outside its rules, or with ``errors="raise"`` any input that failed.
    """
    if errors not in ("raise", "report"):
        raise ValueError(f"errors must be 'raise' or 'report', got {errors!r}")
    if inputs is None:
        inputs = []
    elif isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    paths = [os.fspath(p) for p in inputs]
    for name, value in (("order", order), ("characters", characters), ("jobs", jobs)):
        if isinstance(value, bool) or int(value) != value or value < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    rows = bake_files(
        paths, os.fspath(output), float(rate), bool(exact_rate), str(curve), int(order), str(knots), str(tangents), str(blend),
        str(loop), str(texture), str(precision), bool(atlas), bool(preview), int(characters),
        None if shard is None else str(shard), bool(resume), int(jobs), bool(allow_external_uris), str(device),
    )
    failed = [row for row in rows if row["status"] == "failed"]
    if failed and errors == "raise":
        lines = "; ".join(f"{row['source']}: {row['error']}" for row in failed)
        baked = len(rows) - len(failed)
        rest = "nothing was baked" if baked == 0 else "the other was baked" if baked == 1 else "the others were baked"
        raise ValueError(f"{len(failed)} of {len(rows)} inputs failed ({rest}): {lines}")
    return rows
