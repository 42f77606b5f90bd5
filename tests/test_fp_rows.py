"""benchmarks/fp_rows.py: rows on nobody classified as trackeval's preprocessing sees them, on
constructed rows whose answer is known."""

from __future__ import annotations

import sys

import numpy as np
from conftest import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import fp_rows  # noqa: E402


def _box(x: float, w: float = 40.0) -> list[float]:
    return [x, 0.0, x + w, 100.0]


def _row(frame: int, tid: int, box: list[float], matched: bool) -> list[float]:
    return [frame, tid, *box, 0.9, float(matched)]


def test_each_class_of_row_on_nobody() -> None:
    # Frame 1 gt: scored people at x 0 and 500, a static person (class 7, a distractor) at
    # x 1000, a zero-marked pedestrian at x 1500, an occluder (class 11) at x 2000.
    g = [
        [1, *_box(0.0), 1, 1, 1.0],
        [2, *_box(500.0), 1, 1, 0.5],
        [3, *_box(1000.0), 1, 7, 1.0],
        [4, *_box(1500.0), 0, 1, 1.0],
        [5, *_box(2000.0), 1, 11, 1.0],
    ]
    gt = {1: np.array(g, np.float64)}
    rows = np.array(
        [
            _row(1, 10, _box(0.0), True),  # on person 1
            _row(1, 11, _box(5.0), True),  # a second box on person 1 (IoU ~0.78): duplicate
            _row(1, 12, _box(500.0, 18.0), True),  # narrow on person 2 (IoU 0.45): localised
            _row(1, 13, _box(1000.0), True),  # on the static person: distractor
            _row(1, 14, _box(1500.0), True),  # on the zero-marked pedestrian: unscored
            _row(1, 15, _box(2000.0), True),  # on the occluder: unscored
            _row(1, 16, _box(3000.0), True),  # on nothing: clutter
            _row(1, 17, _box(3000.0), False),  # unmatched: coasted, wherever it is
        ]
    )
    kind, near, best = fp_rows.classify(rows, gt, mot20=True)
    assert kind == [
        "person",
        "duplicate",
        "localised",
        "distractor",
        "unscored",
        "unscored",
        "clutter",
        "coasted",
    ]
    assert list(near[:4]) == [0, 0, 1, 2]
    assert abs(best[2] - 18.0 / 40.0) < 1e-12
    # Class 6 (non-MOT vehicle) is a distractor under MOT20 rules only.
    gt6 = {1: np.array([[9, *_box(0.0), 1, 6, 1.0]], np.float64)}
    one = rows[:1]
    assert fp_rows.classify(one, gt6, mot20=True)[0] == ["distractor"]
    assert fp_rows.classify(one, gt6, mot20=False)[0] == ["unscored"]


def test_track_age_and_hits_count_the_birth_frame() -> None:
    rows = np.array(
        [_row(f, 1, _box(0.0), f != 3) for f in (2, 3, 4)] + [_row(4, 2, _box(100.0), True)]
    )
    age, hits = fp_rows.track_history(rows)
    assert list(age) == [2, 3, 4, 2]
    assert list(hits) == [2, 2, 3, 2]
