"""benchmarks/recall_gap.py: ground-truth boxes one tracker covers and the other does not,
classed by the frame's detection and the other tracker's rows, on constructed rows."""

from __future__ import annotations

import sys
from types import SimpleNamespace

import numpy as np
from conftest import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import recall_gap  # noqa: E402


def _box(x: float) -> list[float]:
    return [x, 0.0, x + 40.0, 100.0]


def _rows(spec: list[tuple[int, int, float, int]]) -> np.ndarray:
    """Rows (frame, id, box, score, matched) from (frame, id, box x, matched)."""
    return np.array([[f, i, *_box(x), 1.0, m] for f, i, x, m in spec], np.float64)


def _dets(spec: list[list[tuple[float, float]]]) -> list[SimpleNamespace]:
    """Per frame, (box x, score) pairs."""
    return [
        SimpleNamespace(
            boxes=np.array([_box(x) for x, _ in fr], np.float64).reshape(-1, 4),
            scores=np.array([s for _, s in fr], np.float64),
        )
        for fr in spec
    ]


def test_boxes_are_classed_by_detection_and_what_the_other_tracker_reported() -> None:
    # Person 1 at x 0 and person 2 at x 500, frames 1-3.
    ids = np.array([1, 2])
    gt = {f: (ids, np.array([_box(0.0), _box(500.0)]), np.ones(2)) for f in (1, 2, 3)}
    # Person 1: confident, then weak, then not detected; person 2: confident throughout.
    dets = _dets([[(0.0, 0.9), (500.0, 0.9)], [(0.0, 0.2), (500.0, 0.9)], [(500.0, 0.9)]])
    # The peer covers person 1 in every frame and person 2 in frame 1 only, then 30 px off it.
    peer = _rows([(1, 1, 0.0, 1), (2, 1, 0.0, 0), (3, 1, 0.0, 0)])
    peer = np.r_[peer, _rows([(1, 2, 500.0, 1), (2, 2, 530.0, 0), (3, 2, 530.0, 0)])]
    # Ours covers person 1 in frame 1 only (a lost track we do not report covers it in frame 3)
    # and person 2 throughout.
    ours = _rows([(1, 7, 0.0, 1), *((f, 8, 500.0, 1) for f in (1, 2, 3))])
    hidden = np.r_[ours, _rows([(3, 7, 0.0, 0)])]
    t = recall_gap.tally(gt, dets, {"ours": ours, "peer": peer}, hidden)
    assert dict(t.classes["peer"]) == {
        "det weak: ours nothing": 1,
        "no det: ours nothing (a live track unreported covers it)": 1,
    }
    assert dict(t.classes["ours"]) == {"det confident: peer coasted near": 2}
    # At alpha 0.5: ours covers 4 of 6 boxes with 4 rows, the peer 4 of 6 with 6 rows.
    a = recall_gap.ALPHAS.index(0.5)
    assert list(t.per_alpha["ours"][a]) == [4, 6, 4]
    assert list(t.per_alpha["peer"][a]) == [4, 6, 6]
    # At alpha 0.05 the peer's boxes 30 px off (IoU 10/70) cover person 2 too.
    assert list(t.per_alpha["peer"][recall_gap.ALPHAS.index(0.05)]) == [6, 6, 6]
