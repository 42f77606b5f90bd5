"""Adapters giving every tracker in the comparison one interface on NumPy arrays.

update(boxes float32 [N, 4] (x1, y1, x2, y2), scores float32 [N] in [0, 1],
       embeddings float32 [N, D] or None)
    -> (ids int64 [M], boxes float64 [M, 4] (x1, y1, x2, y2), scores float64 [M])

Each adapter returns what its tracker reports for the frame; conversion to and from the tracker's
own input format is part of the adapter (and of the timed call: it is the cost of using that
tracker from NumPy). Peers run with their published defaults; only the frame rate is passed
where the tracker takes it. A peer that can use appearance gets the embeddings our tracker gets
(``APPEARANCE``); the others ignore them. A peer that cannot run without embeddings
(``NEEDS_EMBEDDINGS``) is not run on motion-only input. Where a package leaves to its caller
which tracks to report (deep-sort-realtime), the adapter reports confirmed tracks matched in this
frame or the one before, as the original DeepSORT application does.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
from densepeds.boxes import iou_matrix
from scipy.optimize import linear_sum_assignment

Boxes = npt.NDArray[np.float32]
Output = tuple[npt.NDArray[np.int64], npt.NDArray[np.float64], npt.NDArray[np.float64]]
Embeddings = npt.NDArray[np.float32] | None

MOTIONS = ("frvo", "rvo", "sf", "cv")


class Adapter(Protocol):
    def update(
        self, boxes: Boxes, scores: npt.NDArray[np.float32], embeddings: Embeddings = None
    ) -> Output: ...


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


TRACKFORGE = {
    "bytetrack": "BYTETRACK",
    "ocsort": "OCSORT",
    "sort": "SORT",
    "deepsort": "DEEPSORT",
    "deepocsort": "DEEPOCSORT",
    "botsort": "BOTSORT",
    "tracktrack": "TRACKTRACK",
}
TRACKFORGE_APPEARANCE = ("deepsort", "deepocsort", "botsort", "tracktrack")


class TrackforgeAdapter:
    """trackforge (Rust): takes [(tlwh, score, class)] (and embeddings), returns
    [(id, tlwh, score, class)]."""

    def __init__(self, kind: str) -> None:
        import trackforge

        self.kind = kind
        self.tracker = getattr(trackforge, TRACKFORGE[kind])()

    def update(
        self, boxes: Boxes, scores: npt.NDArray[np.float32], embeddings: Embeddings = None
    ) -> Output:
        tlwh = boxes.astype(np.float64).reshape(-1, 4)
        tlwh[:, 2:] -= tlwh[:, :2]
        dets = list(zip(tlwh.tolist(), scores.tolist(), [0] * len(scores), strict=True))
        if self.kind in TRACKFORGE_APPEARANCE:
            emb = [] if embeddings is None else embeddings.astype(np.float64).tolist()
            if self.kind == "deepsort" and embeddings is None:
                raise ValueError("trackforge DEEPSORT needs embeddings")
            out = self.tracker.update(dets, emb)
        else:
            out = self.tracker.update(dets)
        return _pack([(t[0], t[1], t[2]) for t in out], tlwh=True)


class DeepSortRealtimeAdapter:
    """deep-sort-realtime's DeepSort fed our embeddings (its own embedder off)."""

    def __init__(self) -> None:
        from deep_sort_realtime.deepsort_tracker import DeepSort

        self.tracker = DeepSort(embedder=None)

    def update(
        self, boxes: Boxes, scores: npt.NDArray[np.float32], embeddings: Embeddings = None
    ) -> Output:
        if embeddings is None:
            raise ValueError("deep-sort-realtime without its embedder needs embeddings")
        tlwh = boxes.astype(np.float64).reshape(-1, 4)
        tlwh[:, 2:] -= tlwh[:, :2]
        raw = [(b, float(s), 0) for b, s in zip(tlwh.tolist(), scores.tolist(), strict=True)]
        tracks = self.tracker.update_tracks(raw, embeds=list(embeddings))
        rows = [
            (int(t.track_id), list(t.to_ltrb()), float(t.det_conf or 0.0))
            for t in tracks
            if t.is_confirmed() and t.time_since_update <= 1
        ]
        return _pack(rows, tlwh=False)


class MotpyAdapter:
    """motpy's MultiObjectTracker (dt = 1 / frame rate); its string ids numbered in order."""

    def __init__(self, fps: float) -> None:
        from motpy import MultiObjectTracker

        self.tracker = MultiObjectTracker(dt=1.0 / fps)
        self.ids: dict[str, int] = {}

    def update(
        self, boxes: Boxes, scores: npt.NDArray[np.float32], embeddings: Embeddings = None
    ) -> Output:
        from motpy import Detection

        dets = [
            Detection(
                box=np.asarray(b, np.float64),
                score=float(s),
                feature=None if embeddings is None else embeddings[i],
            )
            for i, (b, s) in enumerate(zip(boxes, scores, strict=True))
        ]
        self.tracker.step(detections=dets)
        rows = [
            (self.ids.setdefault(t.id, len(self.ids) + 1), list(t.box), float(t.score or 0.0))
            for t in self.tracker.active_tracks()
        ]
        return _pack(rows, tlwh=False)


class RoboflowAdapter:
    """Roboflow `trackers` (ByteTrack, OC-SORT, SORT) on supervision Detections; id -1 = not (yet)
    tracked."""

    def __init__(self, kind: str, fps: float) -> None:
        import supervision as sv
        import trackers

        self.sv = sv
        cls = {
            "bytetrack": trackers.ByteTrackTracker,
            "ocsort": trackers.OCSORTTracker,
            "sort": trackers.SORTTracker,
        }[kind]
        self.tracker = cls(frame_rate=fps)

    def update(
        self, boxes: Boxes, scores: npt.NDArray[np.float32], embeddings: Embeddings = None
    ) -> Output:
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

    def update(
        self, boxes: Boxes, scores: npt.NDArray[np.float32], embeddings: Embeddings = None
    ) -> Output:
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

    def update(
        self, boxes: Boxes, scores: npt.NDArray[np.float32], embeddings: Embeddings = None
    ) -> Output:
        t = self.tracker.update(boxes.astype(np.float64), scores.astype(np.float32), embeddings)
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


PEERS = (
    *(f"trackforge-{k}" for k in TRACKFORGE),
    "roboflow-bytetrack",
    "roboflow-ocsort",
    "roboflow-sort",
    "deep-sort-realtime",
    "motpy",
    "iou-baseline",
)
# Peers that use appearance embeddings when given them; those that need them to run at all.
APPEARANCE = (*(f"trackforge-{k}" for k in TRACKFORGE_APPEARANCE), "deep-sort-realtime")
NEEDS_EMBEDDINGS = ("trackforge-deepsort", "deep-sort-realtime")


def make_tracker(name: str, fps: float, params: dict[str, object] | None = None) -> Adapter:
    """A fresh tracker for one sequence. Ours are named densepeds-<motion>."""
    if name.startswith("trackforge-") and name.removeprefix("trackforge-") in TRACKFORGE:
        return TrackforgeAdapter(name.removeprefix("trackforge-"))
    if name.startswith("roboflow-"):
        return RoboflowAdapter(name.removeprefix("roboflow-"), fps)
    if name == "deep-sort-realtime":
        return DeepSortRealtimeAdapter()
    if name == "motpy":
        return MotpyAdapter(fps)
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
        "deep-sort-realtime",
        "motpy",
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


class PipelineTracker:
    """An adapter as ``densepeds.Pipeline``'s ``tracker``: update(boxes, scores, embeddings) ->
    Tracks, reset(). Peers do not say which detection a track took: ``det_index`` is -1."""

    def __init__(self, make: Callable[[], Adapter]) -> None:
        self.make = make
        self.adapter = make()

    def update(
        self,
        boxes: npt.NDArray[np.float64],
        scores: npt.NDArray[np.float32],
        embeddings: Embeddings,
    ) -> Any:
        from densepeds.tracking import Tracks

        ids, out_boxes, out_scores = self.adapter.update(
            boxes.astype(np.float32), np.asarray(scores, np.float32), embeddings
        )
        order = np.argsort(ids, kind="stable")
        return Tracks(
            ids[order],
            out_boxes[order].reshape(-1, 4),
            out_scores[order].astype(np.float32),
            np.full(len(ids), -1, np.int64),
        )

    def reset(self) -> None:
        self.adapter = self.make()
