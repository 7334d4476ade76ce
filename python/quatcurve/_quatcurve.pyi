from typing import Any

import numpy as np
import numpy.typing as npt

__version__: str
DEFAULT_CURVE: str
DEFAULT_RATE: float
DEFAULT_CHARACTERS: int
DEFAULT_MAX_TEXTURE_SIZE: int
DEFAULT_MAX_RATE: float
GLTF_UNIT_MM: float
DEFAULT_BETWEEN_ERROR_CM: float
DEFAULT_VERTEX_DISTANCE_CM: float

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
    rate: float,
    exact_rate: bool,
    curve: str,
    order: int,
    knots: str,
    tangents: str,
    blend: str,
    looping: str,
    texture: str,
    precision: str,
    format: str,
    max_texture_size: int,
    atlas: bool,
    preview: bool,
    characters: int,
    shard: str | None,
    resume: bool,
    jobs: int,
    allow_external_uris: bool,
    device: str,
    max_error: float | None,
    max_error_mm: float | None,
    unit_mm: float,
    max_rate: float,
    root_motion: str,
) -> list[dict[str, Any]]: ...

def fit_files(
    inputs: list[str],
    output: str,
    max_error_cm: float,
    between_error_cm: float | None,
    vertex_distance_cm: float,
    unit_cm: float | None,
) -> str: ...
