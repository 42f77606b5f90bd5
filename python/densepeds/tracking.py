"""The online tracker: Python face of the Rust ``densepeds._core.Tracker``.

Per frame, every live track is predicted with the motion model (FRVO by default; ``rvo``, ``sf``
and ``cv`` for the method's ablation), then matched in stages, each solved optimally: appearance
(cosine distance to the track's gallery <= ``appearance_threshold``, among detections within
``gate_radius`` box heights), then IoU between predicted boxes and the remaining detections. With
``embeddings=None`` it is a motion-only tracker.

Parameters (keyword arguments). Defaults were tuned motion-only on the six dev sequences together,
never per sequence (benchmarks/results/tracker.md). The method's pure form (two optimal stages on
every detection, nothing else) is ``det_threshold=-inf, new_track_threshold=-inf,
second_pass=False, recovery=False, size_smoothing=0, output_lost=0`` (``PURE_PARAMS``).

==========================  =======  ===========================================================
name                        default  meaning
==========================  =======  ===========================================================
n_init                      2        matches before a track is confirmed and reported
max_age                     60       xi: frames a track survives unmatched
appearance_threshold        0.2      lambda: largest cosine distance for an appearance match
gallery_size                20       embeddings kept per track
gate_radius                 1.0      rho in track box heights (``inf`` disables gating)
iou_threshold               0.3      smallest IoU for a motion match
det_threshold               0.3      detections scoring below take no part in the main stages
new_track_threshold         0.3      smallest score that starts a track (low-score detections
                                     only extend tracks)
second_pass                 True     ByteTrack-style pass on [low_threshold, det_threshold)
low_threshold               0.05     lowest score used by the second pass
low_iou_threshold           0.5      smallest IoU for a second-pass match
low_max_age                 60       tracks unmatched up to this many frames join the second
                                     pass (0: only those matched last frame, as ByteTrack)
recovery                    True     OC-SORT-style re-match of lost tracks by their last box
recovery_iou_threshold      0.3      smallest IoU for a recovery match
velocity_smoothing          0.5      weight of the newly observed velocity
pref_window                 20       frames the preferred velocity is averaged over
size_smoothing              0.5      weight of the previous box size (0 = detection's size)
ellipse_l_scale             0.15     FRVO ellipse l = scale * box height (the face)
ellipse_w_scale             0.15     FRVO ellipse w = scale * box width (kept small: overlap
                                     in a front view is occlusion, not collision)
output_lost                 5        also report tracks (at the motion model's prediction) this
                                     many frames after their last match
neighbor_radius, max_neighbors, time_horizon, max_speed, polygon_sides: the motion model's.
threads                     0        threads for the motion model's step (at most 1024): 0 =
                                     every core, used from 10,000 agent-neighbour pairs up; 1 =
                                     the calling thread; results are the same whatever the number
==========================  =======  ===========================================================

Score thresholds are for scores in [0, 1], as our detectors give and as
``densepeds.motio.read_detections`` maps det files by default (files already in [0, 1] untouched,
others min-max rescaled; see ``motio.score_scale``). Scores of any range are accepted and compared
as they are, so pass thresholds that suit them (or ``-inf``) when feeding unmapped scores.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from densepeds import _core
from densepeds.errors import InputError, ParameterError

MOTION_MODELS = ("frvo", "rvo", "sf", "cv")

#: Keyword arguments giving the DensePeds paper's plain tracker (see the module docstring).
PURE_PARAMS: dict[str, float | int | bool] = {
    "det_threshold": float("-inf"),
    "new_track_threshold": float("-inf"),
    "second_pass": False,
    "recovery": False,
    "size_smoothing": 0.0,
    "output_lost": 0,
}


class Tracks(NamedTuple):
    """The tracks reported for one frame, sorted by id."""

    ids: npt.NDArray[np.int64]
    boxes: npt.NDArray[np.float64]
    scores: npt.NDArray[np.float32]
    det_index: npt.NDArray[np.int64]  # -1: not matched this frame


def _as_float_array(x: object, name: str) -> npt.NDArray[np.floating]:
    """Keeps float32/float64 arrays as they are (zero-copy); converts lists and integer arrays."""
    if isinstance(x, np.ndarray) and x.dtype in (np.float32, np.float64):
        return x
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name} must be numeric: {e}") from None


class Tracker:
    """Online pedestrian tracker (see the module docstring for the parameters)."""

    def __init__(self, motion: str = "frvo", **params: float | int | bool) -> None:
        if motion not in MOTION_MODELS:
            raise ParameterError(
                f"unknown motion model {motion!r}: expected one of {', '.join(MOTION_MODELS)}"
            )
        try:
            self._core = _core.Tracker(motion, **params)
        except (ValueError, TypeError) as e:
            raise ParameterError(str(e)) from None

    def update(
        self,
        boxes: npt.ArrayLike,
        scores: npt.ArrayLike,
        embeddings: npt.ArrayLike | None = None,
    ) -> Tracks:
        """One frame: boxes [N, 4] (x1, y1, x2, y2), scores [N], embeddings float32 [N, D] or None.

        Raises InputError for bad shapes, dtypes, NaN/inf, inverted boxes or an embedding
        dimension that differs from earlier frames; the tracker's state is then unchanged.
        """
        b = _as_float_array(boxes, "boxes")
        if b.size == 0:
            b = b.reshape(0, 4)
        s = _as_float_array(scores, "scores")
        e = None if embeddings is None else _as_float_array(embeddings, "embeddings")
        try:
            ids, out_boxes, out_scores, det_index = self._core.update(b, s, e)
        except ValueError as err:
            raise InputError(str(err)) from None
        return Tracks(ids, out_boxes, out_scores, det_index)

    def reset(self) -> None:
        """Forgets all tracks; ids restart at 1."""
        self._core.reset()

    @property
    def params(self) -> dict[str, str | float | int | bool]:
        """Every parameter, ``motion`` included, with its value."""
        return dict(self._core.params)

    @property
    def frame_count(self) -> int:
        return self._core.frame_count

    def __repr__(self) -> str:
        return repr(self._core)
