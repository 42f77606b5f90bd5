"""``supervision.Detections`` in and out of the tracker, for a loop around any detector.

``Tracker.update(sv_detections)`` and ``Pipeline.step(frame, sv_detections)`` return a new
``sv.Detections`` (the input is not changed):

- every input detection, in the input's order, with its ``tracker_id``; ``-1`` where it belongs to
  no reported track (a tentative track not yet confirmed, a duplicate, a low score), as Roboflow
  ``trackers`` does; its ``mask``, ``class_id``, ``confidence`` and ``data`` are kept;
- then one row per *coasted* person: a confirmed track reported without a detection this frame
  (hidden behind others, missed by the detector), at its predicted box, with the tracker's
  score as ``confidence``, an empty mask (where the input has masks), and ``class_id`` and
  ``data`` copied from that person's last detection;
- ``data["coasted"]``: ``True`` on those rows, ``False`` on the input's.

``out[out.tracker_id != -1]`` is what DensePeds reports for the frame (the rows of ``densepeds
run``'s tracks file); ``out[~out.data["coasted"]]`` is the input with ids, as Roboflow
``trackers`` returns it. ``supervision`` is imported only when such an object is given: it is an
optional dependency (``pip install 'densepeds[supervision]'``).
"""

from __future__ import annotations

import dataclasses
import sys
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from densepeds.errors import InputError
from densepeds.types import Detections

if TYPE_CHECKING:
    from densepeds.tracking import Tracks

__all__ = ["SvTracks", "is_sv_detections"]

COASTED = "coasted"


def is_sv_detections(obj: object) -> bool:
    """Whether ``obj`` is a ``supervision.Detections`` (without importing supervision: an object
    of that type exists only where it was imported)."""
    sv = sys.modules.get("supervision")
    return sv is not None and isinstance(obj, sv.Detections)


def boxes_and_scores(dets: Any) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float32]]:
    """The boxes (``xyxy``) and scores (``confidence``; 1 for a detector that gives none)."""
    boxes = np.asarray(dets.xyxy, dtype=np.float64).reshape(-1, 4)
    if dets.confidence is None:
        return boxes, np.ones(len(boxes), np.float32)
    return boxes, np.asarray(dets.confidence, dtype=np.float32).reshape(-1)


def to_detections(dets: Any) -> Detections:
    """DensePeds' ``Detections`` of an ``sv.Detections``: boxes, scores and, where it has masks,
    each mask cut to its box (a dense mask: the box rounded outwards and clipped to the image; a
    ``CompactMask``: its own crop)."""
    boxes, scores = boxes_and_scores(dets)
    if dets.mask is None or len(boxes) == 0:
        return Detections(boxes.astype(np.float32), scores)
    mask = dets.mask
    if isinstance(mask, np.ndarray):
        if mask.ndim != 3 or len(mask) != len(boxes):
            raise InputError(
                f"mask must be [N, H, W] for {len(boxes)} detections, got {mask.shape}"
            )
        height, width = mask.shape[1:]
        mask_boxes = np.empty((len(boxes), 4), np.int32)
        mask_boxes[:, :2] = np.floor(boxes[:, :2])
        mask_boxes[:, 2:] = np.ceil(boxes[:, 2:])
        np.clip(mask_boxes, 0, [width, height, width, height], out=mask_boxes)
        masks = [
            mask[i, y0:y1, x0:x1].astype(bool, copy=False)
            for i, (x0, y0, x1, y1) in enumerate(mask_boxes.tolist())
        ]
    else:  # supervision's CompactMask: a crop per detection, its box inclusive
        mask_boxes = np.asarray(mask.bbox_xyxy, np.int32).reshape(-1, 4).copy()
        mask_boxes[:, 2:] += 1
        masks = [np.asarray(mask.crop(i), bool) for i in range(len(boxes))]
    return Detections(boxes.astype(np.float32), scores, masks, mask_boxes)


class SvTracks:
    """Builds each frame's ``sv.Detections`` with ids from the tracker's reported tracks, and
    remembers every track's last detection (without its mask) for its coasted rows.

    ``horizon``: frames after its last detection that a track can still be reported (the
    tracker's ``max_age``); older memories are dropped. None keeps them all.
    """

    def __init__(self, horizon: int | None = None) -> None:
        self.horizon = horizon
        self._frame = 0
        self._last: dict[int, tuple[int, Any, int]] = {}  # id -> (frame, frame's rows, row)

    def reset(self) -> None:
        self._frame = 0
        self._last.clear()

    def result(self, dets: Any, tracks: Tracks) -> Any:
        """``dets`` (the frame's input) with ``tracker_id`` and ``data["coasted"]``, then the
        coasted tracks' rows (see the module docstring)."""
        import supervision as sv

        self._frame += 1
        n = len(dets)
        tracker_id = np.full(n, -1, np.int64)
        matched = tracks.det_index >= 0
        tracker_id[tracks.det_index[matched]] = tracks.ids[matched]
        out = dataclasses.replace(
            dets, tracker_id=tracker_id, data={**dets.data, COASTED: np.zeros(n, bool)}
        )
        kept = dataclasses.replace(out, mask=None)  # memory: the rows without their masks
        ids, rows_of = tracks.ids[matched].tolist(), tracks.det_index[matched].tolist()
        for tid, row in zip(ids, rows_of, strict=True):
            self._last[tid] = (self._frame, kept, row)
        if self.horizon is not None:
            oldest = self._frame - self.horizon - 1
            for tid in [t for t, (f, _, _) in self._last.items() if f < oldest]:
                del self._last[tid]
        coasted = np.flatnonzero(~matched)
        if len(coasted) == 0:
            return out
        rows = []
        for k in coasted.tolist():
            tid = int(tracks.ids[k])
            if tid not in self._last:
                raise InputError(
                    f"track {tid} was last matched from plain arrays: give one tracker "
                    "supervision Detections every frame, or arrays every frame"
                )
            _, frame_rows, row = self._last[tid]
            rows.append(frame_rows[row : row + 1])
        extra = sv.Detections.merge(rows)
        extra.xyxy = np.asarray(tracks.boxes[coasted], dtype=np.asarray(dets.xyxy).dtype)
        extra.tracker_id = tracks.ids[coasted].astype(np.int64)
        extra.confidence = (
            None if dets.confidence is None else tracks.scores[coasted].astype(np.float32)
        )
        extra.data[COASTED] = np.ones(len(coasted), bool)
        if dets.mask is not None:
            height, width = dets.mask.shape[1:]
            extra.mask = np.zeros((len(coasted), height, width), bool)
        if n == 0:
            return extra
        return sv.Detections.merge([out, extra])
