from typing import Any, Literal, overload

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

class Curve:
    rotations: npt.NDArray[np.float64]
    times: npt.NDArray[np.float64]
    curve: CurveName
    def __init__(self, times: npt.ArrayLike, rotations: Any, curve: CurveName = ..., **options: Any) -> None: ...
    def __call__(self, t: float | npt.ArrayLike, order: Literal[0, 1, 2] = ...) -> npt.NDArray[np.floating[Any]]: ...
