"""benchmarks/visibility_misses.py puts every missed pedestrian in the class that fits."""

from __future__ import annotations

import sys

import numpy as np
from conftest import REPO, shared_path

sys.path.insert(0, str(REPO / "benchmarks"))
import accuracy_grid as grid  # noqa: E402
import visibility_misses as vm  # noqa: E402


def _frame(
    gt: list[list[float]],
    fed: list[list[float]],
    scores: list[float],
    out: list[list[float]],
    out_ids: list[int],
    out_fed: list[int],
) -> vm.Frame:
    def boxes(b: list[list[float]]) -> np.ndarray:
        return np.asarray(b, np.float64).reshape(-1, 4)

    return vm.Frame(
        boxes(gt),
        np.arange(1, len(gt) + 1),
        boxes(fed),
        np.asarray(scores, np.float64),
        boxes(out),
        np.asarray(out_ids, np.int64),
        np.asarray(out_fed, np.int64),
    )


PEOPLE = [[0, 0, 40, 100], [100, 0, 140, 100], [200, 0, 240, 100], [300, 0, 340, 100]]


def test_each_miss_is_classed_by_what_the_tracker_had() -> None:
    frame = _frame(
        PEOPLE,
        # person 1 detected whole; person 2 a part (its upper half), matched to a track reported
        # off; person 3 a part at 0.5, person 4 a part at 0.1, neither matched
        [[0, 0, 40, 100], [100, 0, 140, 45], [300, 0, 320, 50], [200, 0, 220, 50]],
        [0.9, 0.9, 0.1, 0.5],
        [[60, 0, 100, 100], [112, 30, 152, 130]],
        [7, 8],
        [-1, 1],
    )
    last: dict[int, int] = {}
    classes = vm.classify(frame, np.ones(4, bool), last, det_threshold=0.3)
    assert classes == [0, 1, 2, 3]
    assert last == {}  # nobody was covered
    # Only the band is classed.
    assert vm.classify(frame, np.array([False, True, False, False]), {}, 0.3) == [1]


def test_a_person_without_detection_is_classed_by_their_last_track() -> None:
    first = _frame(PEOPLE[:3], PEOPLE[:3], [0.9] * 3, PEOPLE[:3], [1, 2, 3], [0, 1, 2])
    last: dict[int, int] = {}
    assert vm.classify(first, np.ones(3, bool), last, 0.3) == []
    assert last == {1: 1, 2: 2, 3: 3}
    # Next frame: nothing detected; track 1 moved onto a fourth person, track 2 is reported
    # on nobody, track 3 is gone; the fourth person had never been covered: a hit now.
    second = _frame(
        [*PEOPLE[:3], [60, 0, 100, 100], [500, 0, 540, 100]],
        [],
        [],
        [[60, 0, 100, 100], [400, 0, 440, 100]],
        [1, 2],
        [-1, -1],
    )
    classes = vm.classify(second, np.ones(5, bool), last, 0.3)
    assert classes == [4, 5, 6, 7]
    assert last[4] == 1


def test_the_fed_box_of_each_reported_track_is_the_one_it_was_matched_to() -> None:
    shared_path("data", "PETS09-S2L1-dev", "det", "det.txt")
    cell = grid.Cell("PETS09-S2L1-dev", "det")
    data = grid.load_cell(cell, REPO / "out" / "cache", quiet=True)
    data.dets = data.dets[:60]
    frames, det_threshold = vm.cell_frames(data, grid.Config())
    from densepeds.boxes import iou_matrix
    from densepeds.pipeline import Pipeline

    assert len(frames) == 60 and det_threshold == Pipeline(None).params["det_threshold"]

    pairs = 0
    for f in frames:
        for t in np.flatnonzero(f.out_fed >= 0):
            pairs += 1
            # The reported box is smoothed, never far from the detection it was matched to.
            assert iou_matrix(f.out[t : t + 1], f.fed[f.out_fed[t] : f.out_fed[t] + 1])[0, 0] > 0.5
    assert pairs > 100
