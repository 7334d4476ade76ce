import os
import pathlib
from typing import Any, Literal, Sequence, TypedDict, overload

import numpy as np
import numpy.typing as npt

__version__: str

CurveName = Literal["slerp", "squad", "bezier", "hermite", "nam-kim", "bspline", "bspline-interp"]
DeviceName = Literal["auto", "gpu", "cpu", "reference"]

@overload
def evaluate(
    rotations: npt.ArrayLike,
    times: npt.ArrayLike | None = ...,
    sample_times: npt.ArrayLike | None = ...,
    *,
    rate: float | None = ...,
    samples: int | None = ...,
    curve: CurveName = ...,
    order: int = ...,
    knots: Literal["phantom", "uniform", "clamped"] = ...,
    tangents: Literal["catmull-rom", "zero", "given"] = ...,
    blend: Literal["cubic", "quadratic"] = ...,
    loop: bool = ...,
    angular_velocities: npt.ArrayLike | None = ...,
    derivatives: Literal[False] = ...,
    device: DeviceName = ...,
) -> npt.NDArray[np.floating[Any]]: ...
@overload
def evaluate(
    rotations: npt.ArrayLike,
    times: npt.ArrayLike | None = ...,
    sample_times: npt.ArrayLike | None = ...,
    *,
    rate: float | None = ...,
    samples: int | None = ...,
    curve: CurveName = ...,
    order: int = ...,
    knots: Literal["phantom", "uniform", "clamped"] = ...,
    tangents: Literal["catmull-rom", "zero", "given"] = ...,
    blend: Literal["cubic", "quadratic"] = ...,
    loop: bool = ...,
    angular_velocities: npt.ArrayLike | None = ...,
    derivatives: Literal[True],
    device: DeviceName = ...,
) -> tuple[npt.NDArray[np.floating[Any]], npt.NDArray[np.floating[Any]], npt.NDArray[np.floating[Any]]]: ...

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

def bake(
    inputs: str | os.PathLike[str] | Sequence[str | os.PathLike[str]] | None = ...,
    output: str | os.PathLike[str] = ...,
    *,
    rate: float = ...,
    exact_rate: bool = ...,
    curve: CurveName = ...,
    order: int = ...,
    knots: Literal["phantom", "uniform", "clamped"] = ...,
    tangents: Literal["catmull-rom", "zero", "given"] = ...,
    blend: Literal["cubic", "quadratic"] = ...,
    loop: Literal["auto", "on", "off"] = ...,
    texture: Literal["local", "model", "skin"] = ...,
    precision: Literal["f32", "f16"] = ...,
    atlas: bool = ...,
    preview: bool = ...,
    characters: int = ...,
    shard: str | None = ...,
    resume: bool = ...,
    jobs: int = ...,
    allow_external_uris: bool = ...,
    device: DeviceName = ...,
    errors: Literal["raise", "report"] = ...,
) -> list[BakeRow]: ...

class Curve:
    rotations: npt.NDArray[np.float64]
    times: npt.NDArray[np.float64]
    curve: CurveName
    def __init__(self, times: npt.ArrayLike, rotations: Any, curve: CurveName = ..., **options: Any) -> None: ...
    def __call__(self, t: float | npt.ArrayLike, order: Literal[0, 1, 2] = ...) -> npt.NDArray[np.floating[Any]]: ...
