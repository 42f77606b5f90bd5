"""motion_person_height: a real sequence seen at twice the resolution gives the same tracks."""

from __future__ import annotations

from typing import Any

import numpy as np
from densepeds.motio import read_detections
from densepeds.tracking import Tracker

from tests.conftest import shared_path


def _track(scale: float, **params: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """Ids and boxes (scaled back) per frame of Venice-2's Faster R-CNN frames 1-120."""
    dets = read_detections(shared_path("data", "Venice-2", "det", "det-frcnn.txt"))
    t = Tracker("frvo", **params)
    out = []
    for f in range(1, 121):
        d = dets.get(f)
        boxes = np.zeros((0, 4)) if d is None else d.boxes.astype(np.float64) * scale
        scores = np.zeros(0) if d is None else d.scores.astype(np.float64)
        r = t.update(boxes, scores)
        out.append((r.ids.copy(), r.boxes / scale))
    return out


def _same(a: list[tuple[np.ndarray, np.ndarray]], b: list[tuple[np.ndarray, np.ndarray]]) -> bool:
    return all(
        np.array_equal(ia, ib) and np.allclose(ba, bb, rtol=0, atol=1e-6)
        for (ia, ba), (ib, bb) in zip(a, b, strict=True)
    )


def test_person_units_give_the_same_tracks_at_twice_the_resolution() -> None:
    one = _track(1.0)
    assert sum(len(ids) for ids, _ in one) > 500
    assert _same(one, _track(2.0))


def test_image_pixels_do_not() -> None:
    # A speed limit in pixels that binds: at twice the resolution it is half the speed.
    p = {"motion_person_height": 0.0, "max_speed": 1.0}
    assert not _same(_track(1.0, **p), _track(2.0, **p))
    q = {"motion_person_height": 160.0, "max_speed": 1.0}
    assert _same(_track(1.0, **q), _track(2.0, **q))
