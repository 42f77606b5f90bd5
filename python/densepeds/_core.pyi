"""Type stubs for the Rust extension `densepeds._core` (hand-checked against the bindings)."""

import numpy as np
import numpy.typing as npt

__version__: str

# --- crowd (frvo) -------------------------------------------------------------------------------

def step_crowd(
    positions: npt.ArrayLike,
    velocities: npt.ArrayLike,
    pref_velocities: npt.ArrayLike,
    axes: npt.ArrayLike,
    *,
    motion: str = "frvo",
    dt: float = 1.0,
    neighbor_radius: float | None = None,
    max_neighbors: int | None = None,
    time_horizon: float | None = None,
    max_speed: float | None = None,
    polygon_sides: int | None = None,
    sf_relaxation_time: float | None = None,
    sf_strength: float | None = None,
    sf_range: float | None = None,
    threads: int | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """One step of a crowd motion model ("frvo", "rvo", "sf" or "cv") on [N, 2] arrays.

    axes[:, 0] is the ellipse extent along the direction of motion (l), axes[:, 1] across it (w),
    in pixels; velocities in pixels per frame. Parameters left as None take the Rust defaults
    (neighbor_radius 150, max_neighbors 10, time_horizon 5, max_speed 50, polygon_sides 8,
    sf_relaxation_time 2, sf_strength 1, sf_range 10, threads 0). threads: 0 spreads a large
    crowd's step (10,000 agent-neighbour pairs or more) over every core (a thread pool made once
    per process), 1 keeps it on the calling thread, n uses at most n threads; the velocities are
    the same whatever the number. Returns (new_velocities, new_positions) with new_positions =
    positions + dt * new_velocities. Raises ValueError for bad shapes and
    densepeds.errors.ParameterError (a ValueError) for bad parameters. Releases the GIL.
    """

# --- tracker (assoc) ----------------------------------------------------------------------------

FloatArray = npt.NDArray[np.float32] | npt.NDArray[np.float64]

class Tracker:
    """Online tracker; keyword parameters as in densepeds.tracking.Tracker (ValueError if bad)."""

    def __init__(self, motion: str = "frvo", **params: float | int | bool) -> None: ...
    def update(
        self, boxes: FloatArray, scores: FloatArray, embeddings: FloatArray | None = None
    ) -> tuple[
        npt.NDArray[np.int64],
        npt.NDArray[np.float64],
        npt.NDArray[np.float32],
        npt.NDArray[np.int64],
    ]: ...
    def reset(self) -> None: ...
    @property
    def params(self) -> dict[str, str | float | int | bool]: ...
    @property
    def frame_count(self) -> int: ...

def linear_sum_assignment(
    cost: FloatArray,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]: ...
def iou_matrix(a: FloatArray, b: FloatArray) -> npt.NDArray[np.float64]: ...
def cosine_distance_matrix(a: FloatArray, b: FloatArray) -> npt.NDArray[np.float64]: ...
