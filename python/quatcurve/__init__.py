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

import json as _json
import math as _math
import os as _os

import numpy as _np

from ._quatcurve import (
    BAKE_OPTIONS as _BAKE_OPTIONS,
    DEFAULT_CURVE,
    DEFAULT_RATE,
    EVAL_OPTIONS as _EVAL_OPTIONS,
    FIT_OPTIONS as _FIT_OPTIONS,
    __version__,
    bake_files as _bake_files,
    decode_container as _decode_container,
    evaluate_tracks as _evaluate_tracks,
    fit_files as _fit_files,
    resample_pose_arrays as _resample_pose_arrays,
)

__all__ = [
    "evaluate",
    "bake",
    "fit",
    "decode",
    "resample_poses",
    "Curve",
    "EVAL_OPTIONS",
    "BAKE_OPTIONS",
    "FIT_OPTIONS",
    "DEFAULT_CURVE",
    "DEFAULT_RATE",
    "__version__",
]

# Each job's options by name with the library's defaults (what :func:`evaluate`, :func:`bake`
# and :func:`fit` take as keywords).
EVAL_OPTIONS = _json.loads(_EVAL_OPTIONS)
BAKE_OPTIONS = _json.loads(_BAKE_OPTIONS)
FIT_OPTIONS = _json.loads(_FIT_OPTIONS)


def _float64(name, value, ndims):
    """`value` as a C-contiguous float64 array of one of the ranks in `ndims`."""
    try:
        array = _np.asarray(value)
    except Exception as e:  # ragged lists
        raise ValueError(f"{name} must be a rectangular array of numbers: {e}") from None
    if array.dtype == object or not (_np.issubdtype(array.dtype, _np.floating) or _np.issubdtype(array.dtype, _np.integer)):
        raise ValueError(f"{name} must hold real numbers (float or int), got dtype {array.dtype}")
    if array.ndim not in ndims:
        shapes = " or ".join(f"{n} dimensions" for n in ndims)
        raise ValueError(f"{name} must have {shapes}, got shape {array.shape}")
    return _np.ascontiguousarray(array, dtype=_np.float64)


# Floats per rotation, and the trailing shape of one, for each way of writing rotations.
_WIDTHS = {"quat": (4, (4,)), "rotvec": (3, (3,)), "matrix": (9, (3, 3))}


def _rotations(name, value, rotation_type, ranks):
    """`value` (a scipy Rotation, or an array of quaternions, rotation vectors or matrices) as
    float64 rows of one rotation each, with its leading shape and its type. `ranks` are the
    leading ranks allowed (1 for one track, 2 for a batch)."""
    if hasattr(value, "as_quat"):
        value, rotation_type = value.as_quat(), "quat"
    array = _float64(name, value, range(1, 6))
    if rotation_type == "auto":
        # Trailing (3, 3) are matrices, a last axis of 4 quaternions. Three numbers are not
        # guessed: rotation vectors and Euler angles look alike, and a guess would be silent.
        if array.ndim >= 3 and array.shape[-2:] == (3, 3):
            rotation_type = "matrix"
        elif array.shape[-1] == 4:
            rotation_type = "quat"
        elif array.shape[-1] == 3:
            raise ValueError(
                f"{name} end in 3 numbers (shape {array.shape}): say rotation_type='rotvec' for rotation vectors "
                f"(axis times angle, radians); rotation_type='auto' reads only quaternions (..., 4) and matrices "
                f"(..., 3, 3), since 3 numbers could as well be Euler angles, which quatcurve does not read"
            )
        else:
            raise ValueError(
                f"{name} must end in 4 (quaternions x, y, z, w), 3 (rotation vectors, with "
                f"rotation_type='rotvec') or 3 x 3 (matrices), got shape {array.shape}"
            )
    if rotation_type not in _WIDTHS:
        raise ValueError(f"rotation_type must be auto, quat, rotvec or matrix, got {rotation_type!r}")
    width, trailing = _WIDTHS[rotation_type]
    lead = array.shape[: array.ndim - len(trailing)]
    if array.shape[len(lead):] != trailing or len(lead) not in ranks:
        want = " or ".join(f"({', '.join(['n'] * r + [str(t) for t in trailing])})" for r in ranks)
        raise ValueError(f"{name} as {rotation_type} must have shape {want}, got {array.shape}")
    return _np.ascontiguousarray(array.reshape(-1, width)), lead, rotation_type


def evaluate(
    rotations,
    times=None,
    sample_times=None,
    *,
    angular_velocities=None,
    rotation_type="auto",
    output="quat",
    **options,
):
    """Evaluates rotation curves through keys (DESIGN section 15).

    The options (every keyword below but ``angular_velocities``, ``rotation_type`` and
    ``output``) are the library's eval options by name, each at the library's default when
    not given (``EVAL_OPTIONS`` holds the defaults); an unknown name or a value its option
    does not take is a ``ValueError`` naming it.

    Parameters
    ----------
    rotations : array_like, a scipy ``Rotation``, or a list of them
        One track ``(keys, R)``, a batch ``(tracks, keys, R)`` whose tracks have one key count,
        or a **list of tracks** ``[(keys_0, R), (keys_1, R), ...]`` of their own key counts
        (a ragged batch, built and evaluated as one). ``R`` is ``4`` for quaternions ``x, y, z,
        w``, ``3`` for rotation vectors (axis times angle, radians) or ``3, 3`` for rotation
        matrices (see ``rotation_type``). Keys are normalized and made sign-continuous here.
    times : array_like, ``(keys,)`` shared or ``(tracks, keys)``, or a list, optional
        Strictly increasing key times in seconds; default ``0, 1, 2, ...``. For a list of
        tracks, a list of arrays (one per track).
    sample_times : array_like, ``(m,)`` shared or ``(tracks, m)``, or a list, optional
        Where to evaluate. Otherwise ``samples`` (N per track from domain start to end) or
        ``rate`` (Hz from the domain start, 30 by default, as ``quatcurve eval``).
    rate, samples : float, int
        Samples per second, or samples per track (which replaces the rate).
    curve : str, default ``"bspline-interp"``
        ``bspline-interp`` (the default of every front end: C2 and through every key, on any
        key times), ``slerp``, ``squad``, ``bezier``, ``hermite``, ``nam-kim``, ``bspline``
        (KKS order-k B-spline with the keys as control points, ``knots``
        phantom/uniform/clamped: it approximates the keys, passing only through the ends) or
        ``normalized-bspline`` (the same B-spline on the keys' components, normalized: cheaper,
        for keys less than a half turn apart within a span).
    order, knots, tangents, blend_function
        B-spline order, knot mode (default phantom), tangent source of hermite/nam-kim
        (``catmull-rom``, ``zero``, ``given`` with ``angular_velocities``), Nam-Kim blend
        function (``cubic``, ``quadratic``).
    loop : str
        ``auto`` (the tracks whose last key is their first rotation loop, each on its own),
        ``on`` (every track; one that does not close is an error) or ``off``.
    derivatives : bool
        Also return body angular velocity and acceleration.
    rotation_type : str, default ``"auto"``
        How ``rotations`` are written: ``quat``, ``rotvec`` or ``matrix``. ``auto`` reads it
        from the shape: trailing ``(3, 3)`` are matrices, a last axis of 4 quaternions. A
        last axis of 3 is refused under ``auto``: rotation vectors and Euler angles look
        alike, so rotation vectors are named, ``rotation_type="rotvec"``.
    output : str, default ``"quat"``
        ``quat`` (``x, y, z, w``), ``rotvec`` (angle in ``[0, pi]``, as scipy's
        ``as_rotvec``) or ``matrix`` (``(..., 3, 3)``).
    device : str
        ``auto`` (a hardware GPU if any, else the CPU path), ``gpu``, ``cpu`` or
        ``reference`` (f64).
    angular_velocities : array_like, ``(…, keys, 3)``, optional
        Body rad/s at each key, for ``tangents="given"``.

    Returns
    -------
    numpy.ndarray ``(..., m, R)``, or with ``derivatives`` a tuple ``(q, omega, alpha)`` of
    ``(..., m, R)``, ``(..., m, 3)``, ``(..., m, 3)`` (views of one array). float64 from
    ``device="reference"``, float32 otherwise. One track in, no track axis out. For a list of
    tracks, a list of per-track arrays (views of one array; with ``derivatives``, a tuple of
    three such lists).

    Raises
    ------
    ValueError
        Bad shapes or dtypes, and every rule the library checks, with its message naming
        the track and key (``track 3: key 7 has norm 0, ...``).
    """
    if output not in _WIDTHS:
        raise ValueError(f"output must be quat, rotvec or matrix, got {output!r}")
    ragged = isinstance(rotations, (list, tuple)) and len(rotations) > 0 and all(
        isinstance(r, _np.ndarray) or hasattr(r, "as_quat") for r in rotations
    )
    if ragged:
        parts = [_rotations(f"rotations[{i}]", r, rotation_type, (1,)) for i, r in enumerate(rotations)]
        if len({p[2] for p in parts}) > 1:
            raise ValueError("every track of a list must write its rotations the same way")
        counts = [p[1][0] for p in parts]
        flat, kind, single = _np.concatenate([p[0] for p in parts]), parts[0][2], False
    else:
        flat, lead, kind = _rotations("rotations", rotations, rotation_type, (1, 2))
        single = len(lead) == 1
        tracks, keys = (1, lead[0]) if single else lead
        counts = [keys] * tracks
    tracks = len(counts)
    key_offsets = _np.concatenate([[0], _np.cumsum(counts)]).astype(_np.int64)

    def per_key(name, value, width):
        """Per-key values of every track, flat: shared, per track, or (ragged) a list."""
        if value is None:
            return None
        if ragged:
            if not isinstance(value, (list, tuple)) or len(value) != tracks:
                raise ValueError(f"{name} for a list of {tracks} tracks must be a list of {tracks} arrays")
            arrays = [_float64(f"{name}[{i}]", v, (1,) if width is None else (2,)) for i, v in enumerate(value)]
            for i, (a, n) in enumerate(zip(arrays, counts)):
                if a.shape[0] != n or (width is not None and a.shape[1] != width):
                    raise ValueError(f"{name}[{i}] must have {n} entries of track {i}'s {n} keys, got shape {a.shape}")
            return _np.ascontiguousarray(_np.concatenate(arrays))
        ndim = 1 if width is None else 2
        a = _float64(name, value, (ndim, ndim + 1))
        if a.ndim == ndim:
            a = _np.broadcast_to(a, (tracks,) + a.shape)
        keys = counts[0]
        if a.shape[0] != tracks or a.shape[1] != keys or (width is not None and a.shape[2] != width):
            tail = "" if width is None else f", {width}"
            raise ValueError(
                f"{name} must have shape ({keys}{tail}) or ({tracks}, {keys}{tail}) for {tracks} track(s) of "
                f"{keys} keys, got {_np.shape(value)}"
            )
        return _np.ascontiguousarray(a.reshape((-1,) if width is None else (-1, width)))

    t = per_key("times", times, None)
    w = per_key("angular_velocities", angular_velocities, 3)
    s = s_offsets = None
    if sample_times is not None:
        if ragged and isinstance(sample_times, (list, tuple)) and len(sample_times) == tracks and all(
            _np.ndim(v) == 1 for v in sample_times
        ):
            lists = [_float64(f"sample_times[{i}]", v, (1,)) for i, v in enumerate(sample_times)]
        else:
            shared = _float64("sample_times", sample_times, (1,) if ragged else (1, 2))
            if shared.ndim == 2 and shared.shape[0] != tracks:
                raise ValueError(f"sample_times must have shape (m,) or ({tracks}, m), got {shared.shape}")
            lists = list(shared) if shared.ndim == 2 else [shared] * tracks
        s = _np.ascontiguousarray(_np.concatenate(lists)) if lists else _np.zeros(0)
        s_offsets = _np.concatenate([[0], _np.cumsum([len(v) for v in lists])]).astype(_np.int64)
    samples = options.get("samples")
    if samples is not None:
        if isinstance(samples, bool) or int(samples) != samples or samples < 1:
            raise ValueError(f"samples must be a positive integer, got {samples}")
        options["samples"] = int(samples)
    derivatives = bool(options.get("derivatives", EVAL_OPTIONS["derivatives"]))
    data, offsets = _evaluate_tracks(flat, kind, key_offsets, t, s, s_offsets, w, str(output), not ragged, _named(options))
    width, trailing = _WIDTHS[output]

    def shaped(block):
        """`block` rows `[n, width + 6?]` split into the rotation (in its trailing shape) and derivatives."""
        q = block[..., :width].reshape(block.shape[:-1] + trailing)
        return (q, block[..., width:width + 3], block[..., width + 3:]) if derivatives else q

    if ragged:
        per_track = [shaped(data[offsets[i]:offsets[i + 1]]) for i in range(tracks)]
        return tuple(map(list, zip(*per_track))) if derivatives else per_track
    block = data.reshape((tracks, -1, data.shape[-1]))
    return shaped(block[0] if single else block)


def _rebuild_curve(times, rotations, curve, options):
    """`Curve` as pickled (`Curve.__reduce__`): built again from its keys and options."""
    return Curve(times, rotations, curve, **options)


class Curve:
    """One rotation curve through keys, called like ``scipy``'s ``RotationSpline``.

    ``Curve(times, rotations)`` builds the C2 cubic B-spline through every key
    (``curve="bspline-interp"``, KKS section 6.2; natural ends, or periodic with
    ``loop="on"``, or by default where the last key is the first rotation) — the same conditions as ``RotationSpline`` but in the KKS cumulative
    form. Any other curve and option of :func:`evaluate` can be given by keyword
    (``rotation_type``, ``output``, ``device``, ...). ``rotations`` may be a
    ``scipy.spatial.transform.Rotation``, quaternions, rotation vectors or matrices.

    ``curve(t, order=0)`` returns rotations (quaternions ``x, y, z, w`` unless ``output``
    says otherwise; ``(4,)`` for a scalar ``t``, ``(m, 4)`` otherwise; wrap with
    ``Rotation.from_quat`` for a Rotation); ``order=1`` the angular velocity and ``order=2``
    the angular acceleration, rad/s and rad/s^2, in the body frame, as ``RotationSpline``'s
    are (for the world frame, rotate them by the orientation:
    ``Rotation.from_quat(q).apply(omega)``). ``order`` may be an int or a float with an
    integer value, as scipy takes it. A ``Curve`` pickles (its keys, times and options; it is
    built again on load), so it crosses process boundaries (multiprocessing, Ray, Dask).
    """

    def __init__(self, times, rotations, curve=DEFAULT_CURVE, **options):
        if hasattr(rotations, "as_quat"):
            rotations = rotations.as_quat()
        self.rotations = _float64("rotations", rotations, (2, 3))
        self.times = _float64("times", times, (1,))
        self.curve = curve
        self.options = options
        # Build once: errors in the keys surface here, as in scipy.
        evaluate(self.rotations, self.times, self.times[:1], curve=curve, **options)

    def __reduce__(self):
        return (_rebuild_curve, (self.times, self.rotations, self.curve, dict(self.options)))

    def __call__(self, t, order=0):
        if isinstance(order, bool) or order not in (0, 1, 2):
            raise ValueError(f"order must be 0, 1 or 2, got {order!r}")
        order = int(order)
        scalar = _np.ndim(t) == 0
        samples = _np.atleast_1d(_np.asarray(t, dtype=_np.float64))
        result = evaluate(self.rotations, self.times, samples, curve=self.curve, derivatives=order > 0, **self.options)
        value = result if order == 0 else result[order]
        return value[0] if scalar else value


def _named(options):
    """Keyword options as the JSON object the library reads them from (numpy scalars as
    Python's; NaN and infinities, which JSON has no word for, refused here)."""
    given = {}
    for name, value in options.items():
        value = value.item() if isinstance(value, _np.generic) else value
        if isinstance(value, float) and not _math.isfinite(value):
            raise ValueError(f"{name} must be a finite number, got {value!r}")
        if not (value is None or isinstance(value, (bool, int, float, str))):
            raise ValueError(f"{name}: {value!r} is not a number, a string, a bool or None")
        given[name] = value
    return _json.dumps(given)


def bake(inputs=None, output="baked", *, shard=None, resume=False, jobs=1, errors="raise", **options):
    """Resamples animation files at a fixed rate into animation textures, as ``quatcurve bake``
    does (DESIGN section 6), and returns one summary row per input.

    The options (every keyword below but ``shard``, ``resume``, ``jobs`` and ``errors``) are
    the library's bake options by name, each at the library's default when not given
    (``BAKE_OPTIONS`` holds the defaults); an unknown name or a value its option does not
    take is a ``ValueError`` naming it.

    Parameters
    ----------
    inputs : str, os.PathLike or a list of them, optional
        ``.gltf``, ``.glb``, ``.fbx``, USD (``.usd``, ``.usda``, ``.usdc``, ``.usdz``), ``.bvh``, ``.npz`` (SMPL-family poses in AMASS's
        layout, docs/DATASETS.md) and ``.qcf`` files, or directories of them. None (or an empty
        list): the built-in synthetic crowd of ``characters`` characters.
    output : str or os.PathLike
        Output directory, created if missing. Per input ``<stem>``: the baked file
        (``<stem>.glb``, ``<stem>.bvh`` or ``<stem>.npz``), textures ``<stem>.<clip>.npy`` (or one
        ``<stem>.npy`` with ``atlas``), the sidecar ``<stem>.json``; per shard a manifest.
    rate : float
        Frames per second, fitted per clip: each clip takes the nearest rate that puts a
        whole number of frames between its first and last keys, so both are baked (the
        clip's own rate is in the sidecar).
    exact_rate : bool
        Bake open clips at exactly ``rate`` (frames ``start + i / rate`` while not past the
        last key); a clip's end off that grid is not baked, and the row's ``warnings`` say
        how much. Loops always fit.
    curve, order, knots, tangents, blend_function
        As :func:`evaluate`; the curve's default (None) is each channel as its
        source plays it (glTF's samplers: LINEAR slerp and lerp, STEP, CUBICSPLINE; the frames
        of BVH, FBX and SMPL poses slerped; the sidecar's ``curve`` is ``source``).
    loop : str
        ``auto`` (clips whose rotations end where they start), ``on`` or ``off``.
    player : str or None
        Bake for this player: ``three`` (skin-trs EXR, one atlas), ``babylon`` (skin textures
        as Babylon's JSON) or ``view`` (skin-trs EXR), where texture, format and atlas are
        left at their defaults; a texture or format it cannot play is refused.
    texture : str
        ``local`` ``[frames, joints, 10]`` (rotation, translation, scale), ``model``
        ``[frames, joints, 12]`` (3x4 matrices by forward kinematics), ``skin`` (model
        times inverse bind matrix, per glTF skin), ``model-trs`` and ``skin-trs`` (those
        transforms as rotation, translation, scale, which a shader interpolates rigidly), or
        ``vertex`` (glTF and FBX: every skinned mesh primitive skinned at every frame, with
        ``<stem>.mesh.glb`` the mesh to draw; DESIGN section 8).
    precision : str
        ``f32`` or ``f16`` (``npy`` and ``exr``).
    format : str
        ``npy`` arrays, or 2D RGBA images engines import: ``exr`` (float or half) or
        ``png16`` (each channel remapped to its range, recorded in the sidecar); or
        ``babylon`` (Babylon.js's baked vertex animation JSON, of ``skin`` textures;
        DESIGN section 10).
    max_texture_size : int
        Largest side of an image texture, in texels.
    atlas, preview, usd : bool
        Stack every clip of an input in one texture; draw a skeleton PNG per clip; also
        write ``<stem>.usda``, OpenUSD skeletal animation (each clip a ``SkelAnimation``
        chosen by the skeleton's variant set ``clip``; DESIGN section 7).
    characters : int
        Characters in the built-in crowd, baked when no input is named.
    allow_external_uris : bool
        Read glTF buffers from anywhere their URIs point, not only data URIs and files
        beside the input.
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
    max_error_deg : float, optional
        Rotation budget in degrees, in place of ``rate``: each clip at the lowest rate whose
        frames, blended as the shipped shader does (``quatcurve shaders``), stay within it
        of the curve at 16 points of every frame interval, every joint (textures ``local``,
        ``model-trs``, ``skin-trs``; DESIGN section 7).
    max_error_cm : float, optional
        Position budget in cm for joints in model space, with or without ``max_error_deg``.
    unit_cm : float, optional
        The length of one file unit in cm (default: glTF's metre, 100); BVH files and fitted
        containers need it with ``max_error_cm`` (CMU's BVH is 5.644).
    max_rate : float
        The highest rate a budget may choose; a clip no rate up to it keeps within fails.
    root_motion : str
        ``keep``, or ``extract``: the root's horizontal motion and heading go to the sidecar's
        per-clip ``root_motion`` track and the textures play in place.

    Returns
    -------
    list of dict
        Per input: ``source``, ``clips``, ``channels``, ``keys``, ``samples``, ``seconds``,
        ``max_key_error`` (rad, or None), ``status`` (``ok``, ``resumed`` or ``failed``),
        ``error`` (the message, or None), ``files`` (``pathlib.Path``s written or kept) and
        ``warnings`` (probably broken source keys, clip ends an exact rate did not bake) and
        ``rates`` (with a budget, per clip: ``clip``, ``rate``, ``frames``, ``rotation`` and
        ``position`` as ``{value, joint, time}`` in degrees and cm, ``bytes`` and
        ``fixed_rate_bytes`` at ``rate``) and ``skinning`` (``texture="vertex"``:
        ``{vertex_frames, seconds}`` skinned on the device, else None).

    Raises
    ------
    ValueError
        An option outside its rules, or with ``errors="raise"`` any input that failed.
    """
    if errors not in ("raise", "report"):
        raise ValueError(f"errors must be 'raise' or 'report', got {errors!r}")
    if inputs is None:
        inputs = []
    elif isinstance(inputs, (str, _os.PathLike)):
        inputs = [inputs]
    paths = [_os.fspath(p) for p in inputs]
    if isinstance(jobs, bool) or int(jobs) != jobs or jobs < 0:
        raise ValueError(f"jobs must be a non-negative integer, got {jobs!r}")
    rows = _bake_files(paths, _os.fspath(output), _named(options), None if shard is None else str(shard), bool(resume), int(jobs))
    failed = [row for row in rows if row["status"] == "failed"]
    if failed and errors == "raise":
        lines = "; ".join(f"{row['source']}: {row['error']}" for row in failed)
        baked = len(rows) - len(failed)
        rest = "nothing was baked" if baked == 0 else "the other was baked" if baked == 1 else "the others were baked"
        raise ValueError(f"{len(failed)} of {len(rows)} inputs failed ({rest}): {lines}")
    return rows


def fit(inputs, output="fitted", *, errors="raise", **options):
    """Fits every clip of glTF/BVH files as quantized B-splines within an error budget, one
    ``<stem>.qcf`` container per input, as ``quatcurve fit`` does (DESIGN section 16).
    :func:`bake` reads the containers as it reads their sources. The options (every keyword
    below but ``errors``) are the library's fit options by name, each at the library's default
    when not given (``FIT_OPTIONS`` holds the defaults).

    Parameters
    ----------
    inputs : str, os.PathLike or a list of them
        ``.gltf``, ``.glb``, ``.fbx``, USD and ``.bvh`` files, or directories of them.
    output : str or os.PathLike
        Output directory, created if missing.
    max_error_cm : float
        The largest distance in cm a virtual vertex may move at any source frame (ACL's
        metric: object space, so a parent's error counts in its children's).
    between_error_cm : float or None
        The largest between source frames, in cm, against the source's interpolation; None:
        not checked.
    vertex_distance_cm : float
        The virtual vertices' distance from each joint, cm.
    unit_cm : float, optional
        The length of one file unit in cm (default: glTF's metre, 100); BVH files and fitted
        containers need it (CMU's BVH is 5.644).
    clip_library : str, optional
        One container, ``<output>/<clip_library>.qcf``, holding every input's clips on their one
        skeleton, stored once (a clip library; inputs on another skeleton are refused); a clip
        name two inputs share is prefixed with its input's stem and a slash. None: one
        container per input.
    errors : str
        ``raise`` (default): raise ``ValueError`` if any input failed, naming each;
        ``report``: return the report, failures included.

    Returns
    -------
    dict
        The report: ``max_error_cm``, ``between_error_cm``, ``vertex_distance_cm``,
        ``inputs`` and ``clip_library`` (None, or ``output``, ``clips``, ``raw_bytes``,
        ``clip_bytes``, ``container_bytes``, ``ratio`` and ``whole_file_ratio``), per input
        ``input``, ``output``, ``unit_cm``, ``container_bytes``, ``whole_file_ratio``,
        ``error`` and ``clips``, per clip ``clip``, ``frames``, ``joints``, ``raw_bytes``,
        ``compressed_bytes``, ``ratio``, ``at_frames`` and ``between_frames`` (each
        ``{error_cm, joint, time}``) and ``seconds``.

    Raises
    ------
    ValueError
        A job refused before the work (a length that is not positive, a BVH input without
        ``unit_cm``, an output that cannot be written), or with ``errors="raise"`` any input
        that failed.
    """
    if errors not in ("raise", "report"):
        raise ValueError(f"errors must be 'raise' or 'report', got {errors!r}")
    if isinstance(inputs, (str, _os.PathLike)):
        inputs = [inputs]
    report = _json.loads(_fit_files([_os.fspath(p) for p in inputs], _os.fspath(output), _named(options)))
    failed = [row for row in report["inputs"] if row["error"] is not None]
    if failed and errors == "raise":
        lines = "; ".join(f"{row['input']}: {row['error']}" for row in failed)
        raise ValueError(f"{len(failed)} of {len(report['inputs'])} inputs failed (no container written for them): {lines}")
    return report


def decode(path, rate=None):
    """Decodes a fitted container (``.qcf``, :func:`fit`'s output) to each clip's local poses
    with the runtime decoder (DESIGN section 16): from the file's bytes straight to f32 poses,
    frame after frame, as a data loader or a game reads them, no bake. The poses are the
    ``local`` texture a :func:`bake` of the container writes at the same rate.

    Parameters
    ----------
    path : str or os.PathLike
        The container.
    rate : float, optional
        Frames per second, fitted to each clip's span as a bake's (default: each clip's
        source rate).

    Returns
    -------
    dict
        ``joints`` (names) and ``parents`` (index, -1 for a root), and ``clips``, per clip
        ``name``, ``times`` (float64 ``[frames]``, seconds) and ``poses`` (float32
        ``[frames, joints, 10]``: rotation ``x, y, z, w``, translation, scale, relative to the
        parent; the rest pose where the clip does not animate a joint).

    Raises
    ------
    ValueError
        The file cannot be read or is not a container of this version (the field and byte
        named), or a rate that is not positive.
    """
    names, parents, clips = _decode_container(_os.fspath(path), None if rate is None else float(rate))
    joints = len(names)
    return {
        "joints": names,
        "parents": parents,
        "clips": [
            {"name": name, "times": times, "poses": poses.reshape(len(times), joints, 10)}
            for name, times, poses in clips
        ],
    }


# The bake options that apply to arrays in memory (the rest are about files and textures).
_POSE_OPTIONS = ("exact_rate", "curve", "order", "knots", "tangents", "blend_function", "loop", "device")


def resample_poses(poses, rate, new_rate, trans=None, per_frame=None, **options):
    """Resamples SMPL-family poses at a new rate in memory, by the rules of :func:`bake`
    (DESIGN section 6; docs/DATASETS.md): what replaces a dataset pipeline's
    ``poses[::stride]``.

    Parameters
    ----------
    poses : array_like
        ``[frames, joints * 3]`` axis-angle rotations (radians) relative to each joint's
        parent, 72 (SMPL), 156 (SMPL-H, AMASS) or 165 (SMPL-X) wide.
    rate : float
        Their frames per second (AMASS's ``mocap_framerate``).
    new_rate : float
        The frames per second wanted: fitted so that the first and last frames are kept,
        or exactly with ``exact_rate=True`` (frames ``k / new_rate``).
    trans : array_like, optional
        ``[frames, 3]``: the root's translation, resampled with the poses.
    per_frame : dict of array_like, optional
        Other arrays of ``frames`` rows by name (``dmpls``, ``marker_data``, ...), each
        resampled linearly at the new times, as a bake of the archive writes them.
    exact_rate, curve, order, knots, tangents, blend_function, loop, device
        As :func:`bake`; the curve is slerp unless asked otherwise.

    Returns
    -------
    dict
        ``poses`` ``[new frames, joints * 3]`` (angles in ``[0, pi]``), ``trans``
        ``[new frames, 3]`` or None, ``per_frame`` (each array given, at the new frames),
        ``rate`` (the frames' rate) and ``warnings``. With the default curve (the frames
        slerped) everything is computed in float64, as scipy's ``Slerp`` and ``np.interp``.

    Raises
    ------
    ValueError
        A width no family has, a value that is not finite (naming the frame and joint), a
        rate that is not positive, or an option outside its rules.
    """
    unknown = sorted(set(options) - set(_POSE_OPTIONS))
    if unknown:
        raise TypeError(f"resample_poses() got options it does not take: {', '.join(unknown)} (it takes {', '.join(_POSE_OPTIONS)})")
    poses = _float64("poses", poses, (2,))
    trans = None if trans is None else _float64("trans", trans, (2,))
    arrays = []
    for name, values in (per_frame or {}).items():
        values = _np.ascontiguousarray(values, dtype=_np.float64)
        arrays.append((str(name), list(values.shape), values.ravel()))
    out, out_trans, out_fields, out_rate, warnings = _resample_pose_arrays(
        poses, trans, arrays, float(rate), _named({"rate": new_rate, **options})
    )
    fields = {name: values.reshape(shape) for name, values, shape in out_fields}
    return {"poses": out, "trans": out_trans, "per_frame": fields, "rate": out_rate, "warnings": warnings}
