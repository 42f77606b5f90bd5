"""Type stubs for the Rust extension `densepeds._core` (hand-checked against the bindings)."""

import numpy as np
import numpy.typing as npt

__version__: str

# --- crowd (frvo) -------------------------------------------------------------------------------

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
