from typing import Any

import numpy as np
import numpy.typing as npt

__version__: str
DEFAULT_CURVE: str
DEFAULT_RATE: float
BAKE_OPTIONS: str
FIT_OPTIONS: str

def evaluate_tracks(
    rotations: npt.NDArray[np.float64],
    rotation_type: str,
    key_offsets: npt.NDArray[np.int64],
    times: npt.NDArray[np.float64] | None,
    sample_times: npt.NDArray[np.float64] | None,
    sample_offsets: npt.NDArray[np.int64] | None,
    rate: float | None,
    samples: int | None,
    curve: str,
    order: int,
    knots: str,
    tangents: str,
    blend: str,
    looping: bool,
    angular_velocities: npt.NDArray[np.float64] | None,
    derivatives: bool,
    output: str,
    equal_counts: bool,
    device: str,
) -> tuple[npt.NDArray[np.floating[Any]], npt.NDArray[np.int64]]: ...

def bake_files(
    inputs: list[str],
    output: str,
    options: str,
    shard: str | None,
    resume: bool,
    jobs: int,
) -> list[dict[str, Any]]: ...

def fit_files(
    inputs: list[str],
    output: str,
    options: str,
) -> str: ...
