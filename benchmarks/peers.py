"""Adapters giving every tracker in the comparison one interface on NumPy arrays.

update(boxes float32 [N, 4] (x1, y1, x2, y2), scores float32 [N] in [0, 1])
    -> (ids int64 [M], boxes float64 [M, 4] (x1, y1, x2, y2), scores float64 [M])

Each adapter returns what its tracker reports for the frame; conversion to and from the tracker's
own input format is part of the adapter (and of the timed call: it is the cost of using that
tracker from NumPy). Peers run with their published defaults; only the frame rate is passed
where the tracker takes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib import metadata
from typing import Protocol

import numpy as np
import numpy.typing as npt
from densepeds.boxes import iou_matrix
from scipy.optimize import linear_sum_assignment

Boxes = npt.NDArray[np.float32]
Output = tuple[npt.NDArray[np.int64], npt.NDArray[np.float64], npt.NDArray[np.float64]]

MOTIONS = ("frvo", "rvo", "sf", "cv")


class Adapter(Protocol):
    def update(self, boxes: Boxes, scores: npt.NDArray[np.float32]) -> Output: ...


def _empty() -> Output:
    return np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros(0)


def _pack(rows: list[tuple[int, list[float], float]], tlwh: bool) -> Output:
    if not rows:
        return _empty()
    ids = np.array([r[0] for r in rows], np.int64)
    boxes = np.array([r[1] for r in rows], np.float64)
    if tlwh:
        boxes[:, 2:] += boxes[:, :2]
    return ids, boxes, np.array([r[2] for r in rows], np.float64)


class TrackforgeAdapter:
    """trackforge (Rust): takes [(tlwh, score, class)], returns (id, tlwh, score, cls, det)."""

    def __init__(self, kind: str) -> None:
        import trackforge

        self.tracker = trackforge.BYTETRACK() if kind == "bytetrack" else trackforge.OCSORT()

    def update(self, boxes: Boxes, scores: npt.NDArray[np.float32]) -> Output:
        tlwh = boxes.astype(np.float64)
        tlwh[:, 2:] -= tlwh[:, :2]
        dets = list(zip(tlwh.tolist(), scores.tolist(), [0] * len(scores), strict=True))
        out = self.tracker.update(dets)
        return _pack([(t[0], t[1], t[2]) for t in out], tlwh=True)


class RoboflowByteTrackAdapter:
    """Roboflow `trackers` ByteTrackTracker on supervision Detections; id -1 = not (yet) tracked."""

    def __init__(self, fps: float) -> None:
        import supervision as sv
        from trackers import ByteTrackTracker

        self.sv = sv
        self.tracker = ByteTrackTracker(frame_rate=fps)

    def update(self, boxes: Boxes, scores: npt.NDArray[np.float32]) -> Output:
        dets = self.sv.Detections(
            xyxy=boxes.astype(np.float32).reshape(-1, 4),
            confidence=scores.astype(np.float32),
            class_id=np.zeros(len(scores), int),
        )
        out = self.tracker.update(dets)
        if len(out) == 0 or out.tracker_id is None or out.confidence is None:
            return _empty()
        keep = out.tracker_id >= 0
        return (
            out.tracker_id[keep].astype(np.int64),
            out.xyxy[keep].astype(np.float64),
            out.confidence[keep].astype(np.float64),
        )


@dataclass
class IoUBaseline:
    """No motion model: match each detection to a track's last box by IoU (optimal assignment).

    Unmatched tracks keep their last box for ``max_age`` frames; every unmatched detection scoring
    at least ``min_score`` starts a track. Reports the tracks matched in this frame.
    """

    iou_threshold: float = 0.3
    max_age: int = 10
    min_score: float = 0.0
    _ids: list[int] = field(default_factory=list)
    _boxes: list[npt.NDArray[np.float64]] = field(default_factory=list)
    _age: list[int] = field(default_factory=list)
    _next: int = 1

    def update(self, boxes: Boxes, scores: npt.NDArray[np.float32]) -> Output:
        det = boxes.astype(np.float64)
        matched_det: dict[int, int] = {}  # det index -> track index
        if self._ids and len(det):
            iou = iou_matrix(np.array(self._boxes), det)
            rows, cols = linear_sum_assignment(-iou)
            for r, c in zip(rows, cols, strict=True):
                if iou[r, c] >= self.iou_threshold:
                    matched_det[int(c)] = int(r)
        self._age = [a + 1 for a in self._age]
        for d, t in matched_det.items():
            self._boxes[t] = det[d]
            self._age[t] = 0
        for d in range(len(det)):
            if d not in matched_det and scores[d] >= self.min_score:
                self._ids.append(self._next)
                self._boxes.append(det[d])
                self._age.append(0)
                matched_det[d] = len(self._ids) - 1
                self._next += 1
        out_idx = sorted(matched_det.items())
        ids = np.array([self._ids[t] for _, t in out_idx], np.int64)
        out_boxes = np.array([det[d] for d, _ in out_idx]).reshape(-1, 4)
        out_scores = np.array([scores[d] for d, _ in out_idx], np.float64)
        alive = [i for i, a in enumerate(self._age) if a <= self.max_age]
        self._ids = [self._ids[i] for i in alive]
        self._boxes = [self._boxes[i] for i in alive]
        self._age = [self._age[i] for i in alive]
        return ids, out_boxes, out_scores


class DensePedsAdapter:
    """Our tracker, motion only (no embeddings): densepeds.tracking.Tracker."""

    def __init__(self, motion: str, **params: float | int | bool) -> None:
        from densepeds.tracking import Tracker

        self.tracker = Tracker(motion=motion, **params)

    def update(self, boxes: Boxes, scores: npt.NDArray[np.float32]) -> Output:
        t = self.tracker.update(boxes.astype(np.float64), scores.astype(np.float32))
        return (
            np.asarray(t.ids, np.int64),
            np.asarray(t.boxes, np.float64).reshape(-1, 4),
            np.asarray(t.scores, np.float64),
        )


def densepeds_available() -> str | None:
    """None when our tracker can run, else why not (it lands separately from this script)."""
    try:
        from densepeds.tracking import Tracker  # noqa: F401
    except ImportError as err:
        return f"densepeds.tracking.Tracker not importable ({err})"
    return None


PEERS = ("trackforge-bytetrack", "trackforge-ocsort", "roboflow-bytetrack", "iou-baseline")


def make_tracker(name: str, fps: float, params: dict[str, object] | None = None) -> Adapter:
    """A fresh tracker for one sequence. Ours are named densepeds-<motion>."""
    if name == "trackforge-bytetrack":
        return TrackforgeAdapter("bytetrack")
    if name == "trackforge-ocsort":
        return TrackforgeAdapter("ocsort")
    if name == "roboflow-bytetrack":
        return RoboflowByteTrackAdapter(fps)
    if name == "iou-baseline":
        return IoUBaseline()
    if name.startswith("densepeds-") and name.removeprefix("densepeds-") in MOTIONS:
        return DensePedsAdapter(name.removeprefix("densepeds-"), **(params or {}))  # type: ignore[arg-type]
    raise ValueError(f"unknown tracker {name!r}")


def versions() -> dict[str, str]:
    """Installed versions of the packages the comparison depends on."""
    out = {}
    for pkg in (
        "densepeds",
        "trackforge",
        "trackers",
        "supervision",
        "trackeval",
        "numpy",
        "scipy",
    ):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out
