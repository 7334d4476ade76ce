from typing import Any

import numpy as np
import numpy.typing as npt

__version__: str
DEFAULT_CURVE: str
DEFAULT_RATE: float
EVAL_OPTIONS: str
BAKE_OPTIONS: str
FIT_OPTIONS: str

def evaluate_tracks(
    rotations: npt.NDArray[np.float64],
    rotation_type: str,
    key_offsets: npt.NDArray[np.int64],
    times: npt.NDArray[np.float64] | None,
    sample_times: npt.NDArray[np.float64] | None,
    sample_offsets: npt.NDArray[np.int64] | None,
    angular_velocities: npt.NDArray[np.float64] | None,
    output: str,
    equal_counts: bool,
    options: str,
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

def resample_pose_arrays(
    poses: npt.NDArray[np.float64],
    trans: npt.NDArray[np.float64] | None,
    per_frame: list[tuple[str, list[int], npt.NDArray[np.float64]]],
    rate: float,
    options: str,
) -> tuple[
    npt.NDArray[np.float64],
    npt.NDArray[np.float64] | None,
    list[tuple[str, npt.NDArray[np.float64], list[int]]],
    float,
    list[str],
]: ...

def decode_container(
    path: str,
    rate: float | None,
) -> tuple[list[str], list[int], list[tuple[str, npt.NDArray[np.float64], npt.NDArray[np.float32]]]]: ...
