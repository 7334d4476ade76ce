import os
import pathlib
from typing import Any, Literal, Sequence, TypedDict, overload

import numpy as np
import numpy.typing as npt

__version__: str
DEFAULT_CURVE: str
DEFAULT_RATE: float
EVAL_OPTIONS: dict[str, Any]
BAKE_OPTIONS: dict[str, Any]
FIT_OPTIONS: dict[str, Any]

CurveName = Literal["slerp", "squad", "bezier", "hermite", "nam-kim", "bspline", "bspline-interp"]
DeviceName = Literal["auto", "gpu", "cpu", "reference"]
RotationType = Literal["auto", "quat", "rotvec", "matrix"]

@overload
def evaluate(
    rotations: Any,
    times: Any = None,
    sample_times: Any = None,
    *,
    angular_velocities: npt.ArrayLike | None = None,
    rotation_type: RotationType = "auto",
    output: Literal["quat", "rotvec", "matrix"] = "quat",
    curve: CurveName = "bspline-interp",
    order: int = 4,
    knots: Literal["phantom", "uniform", "clamped"] = "phantom",
    tangents: Literal["catmull-rom", "zero", "given"] = "catmull-rom",
    blend_function: Literal["cubic", "quadratic"] = "cubic",
    loop: Literal["auto", "on", "off"] = "auto",
    device: DeviceName = "auto",
    samples: int | None = None,
    rate: float = 30.0,
    derivatives: Literal[False] = False,
) -> npt.NDArray[np.floating[Any]] | list[npt.NDArray[np.floating[Any]]]: ...
@overload
def evaluate(
    rotations: Any,
    times: Any = None,
    sample_times: Any = None,
    *,
    angular_velocities: npt.ArrayLike | None = None,
    rotation_type: RotationType = "auto",
    output: Literal["quat", "rotvec", "matrix"] = "quat",
    curve: CurveName = "bspline-interp",
    order: int = 4,
    knots: Literal["phantom", "uniform", "clamped"] = "phantom",
    tangents: Literal["catmull-rom", "zero", "given"] = "catmull-rom",
    blend_function: Literal["cubic", "quadratic"] = "cubic",
    loop: Literal["auto", "on", "off"] = "auto",
    device: DeviceName = "auto",
    samples: int | None = None,
    rate: float = 30.0,
    derivatives: Literal[True],
) -> tuple[Any, Any, Any]: ...

class BakeRow(TypedDict):
    source: str
    clips: int
    channels: int
    keys: int
    samples: int
    seconds: float
    max_key_error: float | None
    status: Literal["ok", "resumed", "failed"]
    error: str | None
    files: list[pathlib.Path]
    warnings: list[str]
    rates: list[dict[str, Any]]

def bake(
    inputs: str | os.PathLike[str] | Sequence[str | os.PathLike[str]] | None = None,
    output: str | os.PathLike[str] = "baked",
    *,
    rate: float = 30.0,
    exact_rate: bool = False,
    curve: CurveName | None = None,
    order: int = 4,
    knots: Literal["phantom", "uniform", "clamped"] = "phantom",
    tangents: Literal["catmull-rom", "zero", "given"] = "catmull-rom",
    blend_function: Literal["cubic", "quadratic"] = "cubic",
    loop: Literal["auto", "on", "off"] = "auto",
    player: Literal["three", "babylon", "view"] | None = None,
    texture: Literal["local", "model", "skin", "model-trs", "skin-trs", "vertex"] = "local",
    precision: Literal["f32", "f16"] = "f32",
    format: Literal["npy", "exr", "png16", "babylon"] = "npy",
    max_texture_size: int = 4096,
    atlas: bool = False,
    preview: bool = False,
    usd: bool = False,
    characters: int = 1000,
    allow_external_uris: bool = False,
    device: DeviceName = "auto",
    max_error_deg: float | None = None,
    max_error_cm: float | None = None,
    unit_cm: float | None = None,
    max_rate: float = 480.0,
    root_motion: Literal["keep", "extract"] = "keep",
    shard: str | None = None,
    resume: bool = False,
    jobs: int = 1,
    errors: Literal["raise", "report"] = "raise",
) -> list[BakeRow]: ...

def fit(
    inputs: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    output: str | os.PathLike[str] = "fitted",
    *,
    max_error_cm: float = 0.01,
    between_error_cm: float | None = 0.3,
    vertex_distance_cm: float = 3.0,
    unit_cm: float | None = None,
    clip_library: str | None = None,
    errors: Literal["raise", "report"] = "raise",
) -> dict[str, Any]: ...

class DecodedClip(TypedDict):
    name: str
    times: npt.NDArray[np.float64]
    poses: npt.NDArray[np.float32]

class Decoded(TypedDict):
    joints: list[str]
    parents: list[int]
    clips: list[DecodedClip]

def decode(path: str | os.PathLike[str], rate: float | None = None) -> Decoded: ...

class ResampledPoses(TypedDict):
    poses: npt.NDArray[np.float64]
    trans: npt.NDArray[np.float64] | None
    per_frame: dict[str, npt.NDArray[np.float64]]
    rate: float
    warnings: list[str]

def resample_poses(
    poses: npt.ArrayLike,
    rate: float,
    new_rate: float,
    trans: npt.ArrayLike | None = None,
    per_frame: dict[str, npt.ArrayLike] | None = None,
    *,
    exact_rate: bool = False,
    curve: CurveName | None = None,
    order: int = 4,
    knots: Literal["phantom", "uniform", "clamped"] = "phantom",
    tangents: Literal["catmull-rom", "zero", "given"] = "catmull-rom",
    blend_function: Literal["cubic", "quadratic"] = "cubic",
    loop: Literal["auto", "on", "off"] = "auto",
    device: DeviceName = "auto",
) -> ResampledPoses: ...

class Curve:
    rotations: npt.NDArray[np.float64]
    times: npt.NDArray[np.float64]
    curve: CurveName
    def __init__(self, times: npt.ArrayLike, rotations: Any, curve: CurveName = "bspline-interp", **options: Any) -> None: ...
    def __call__(self, t: float | npt.ArrayLike, order: float = 0) -> npt.NDArray[np.floating[Any]]: ...
    def __reduce__(self) -> tuple[Any, ...]: ...
