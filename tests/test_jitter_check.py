"""benchmarks/jitter_check.py: detections moved by sub-pixel amounts, and the summary line."""

from __future__ import annotations

import sys

import numpy as np
from conftest import REPO
from densepeds.types import Detections

sys.path.insert(0, str(REPO / "benchmarks"))
import jitter_check  # noqa: E402


def _frames() -> list[Detections]:
    boxes = [[10.0, 20.0, 50.0, 120.0], [200.0, 30.0, 240.0, 140.0]]
    return [
        Detections(np.array(boxes[: k % 2 + 1]), np.array([0.9, 0.6][: k % 2 + 1]))
        for k in range(40)
    ]


def test_seed_zero_leaves_the_detections_as_they_are() -> None:
    dets = _frames()
    assert all(a is b for a, b in zip(jitter_check.jittered(dets, 0), dets, strict=True))


def test_other_seeds_move_every_coordinate_by_at_most_the_shift_and_repeat() -> None:
    dets = _frames()
    moved = jitter_check.jittered(dets, 3)
    again = jitter_check.jittered(dets, 3)
    other = jitter_check.jittered(dets, 4)
    d = np.concatenate([m.boxes - o.boxes for m, o in zip(moved, dets, strict=True)])
    assert np.all(np.abs(d) <= jitter_check.SHIFT + 1e-5)
    assert np.all(d != 0.0)  # every coordinate its own draw
    assert d.std() > 0.2  # spread over [-0.5, 0.5] (uniform: sd 0.29), not a constant offset
    assert abs(d.mean()) < 0.1
    for m, a, o, src in zip(moved, again, other, dets, strict=True):
        np.testing.assert_array_equal(m.boxes, a.boxes)
        assert not np.array_equal(m.boxes, o.boxes)
        np.testing.assert_array_equal(m.scores, src.scores)
        assert m.boxes.dtype == np.float32


def test_summary_counts_the_seeds_ours_is_ahead_in() -> None:
    ours = np.array([31.0, 30.0, 32.0, 29.0])
    peer = np.array([30.5, 30.5, 31.5, 31.0])
    line = jitter_check.summary(ours, peer)
    assert line.startswith("mean 30.50 (min 29.00, max 32.00, sd 1.12)")
    assert "peer 30.88" in line
    assert "ours - peer -0.38, ahead in 2 of 4 seeds" in line
    assert "peer" not in jitter_check.summary(ours)
