"""densepeds.gaps.fill_gaps against a frame-by-frame reference."""

from __future__ import annotations

import numpy as np
import pytest
from densepeds.errors import ParameterError
from densepeds.gaps import fill_gaps


def _reference(rows: np.ndarray, max_gap: int) -> dict[tuple[int, int], np.ndarray]:
    """Each (frame, id) of the output, found frame by frame: between the nearest detections
    before and after (at most max_gap frames apart inside), the interpolation; else the row."""
    out: dict[tuple[int, int], np.ndarray] = {}
    for tid in np.unique(rows[:, 1]):
        own = rows[rows[:, 1] == tid]
        by_frame = {int(r[0]): r for r in own}
        anchors = sorted(int(r[0]) for r in own if r[7] > 0)
        for f in range(int(own[:, 0].min()), int(own[:, 0].max()) + 1):
            before = [a for a in anchors if a < f]
            after = [a for a in anchors if a > f]
            if f not in anchors and before and after and after[0] - before[-1] - 1 <= max_gap:
                a, b = by_frame[before[-1]], by_frame[after[0]]
                w = (f - a[0]) / (b[0] - a[0])
                out[(f, int(tid))] = np.r_[f, tid, (1 - w) * a[2:7] + w * b[2:7]]
            elif f in by_frame:
                out[(f, int(tid))] = by_frame[f][:7]
    return out


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("max_gap", [0, 1, 3, 10])
def test_fill_gaps_matches_the_frame_by_frame_reference(seed: int, max_gap: int) -> None:
    rng = np.random.default_rng(seed)
    rows = []
    for tid in range(1, 6):
        frames = np.sort(rng.choice(40, size=rng.integers(1, 25), replace=False)) + 1
        for f in frames:
            box = rng.uniform(0, 100, 2)
            rows.append([f, tid, *box, *(box + rng.uniform(5, 50, 2)), rng.uniform(), 0])
    arr = np.array(rows)
    arr[:, 7] = rng.uniform(size=len(arr)) < 0.6  # matched or coasted
    arr = arr[rng.permutation(len(arr))]
    got = fill_gaps(arr, max_gap)
    want = _reference(arr, max_gap)
    assert got.shape == (len(want), 7)
    assert len({(int(r[0]), int(r[1])) for r in got}) == len(got)
    for r in got:
        np.testing.assert_allclose(r, want[(int(r[0]), int(r[1]))], atol=1e-9)
    order = np.lexsort((got[:, 0], got[:, 1]))
    np.testing.assert_array_equal(order, np.arange(len(got)))


def test_coasted_boxes_between_detections_are_replaced_and_the_tail_kept() -> None:
    # matched at frames 1 and 4, coasted off course at 2, nothing at 3, coasted at 5 after.
    rows = np.array(
        [
            [1, 7, 0, 0, 10, 20, 0.9, 1],
            [2, 7, 50, 50, 60, 70, 0.5, 0],
            [4, 7, 30, 0, 40, 20, 0.6, 1],
            [5, 7, 40, 0, 50, 20, 0.6, 0],
        ]
    )
    got = fill_gaps(rows, 2)
    np.testing.assert_allclose(got[:, 0], [1, 2, 3, 4, 5])
    np.testing.assert_allclose(got[1, 2:7], [10, 0, 20, 20, 0.8])
    np.testing.assert_allclose(got[2, 2:7], [20, 0, 30, 20, 0.7])
    np.testing.assert_allclose(got[4], rows[3, :7])
    # a gap longer than max_gap keeps what the tracker reported
    np.testing.assert_allclose(fill_gaps(rows, 1), rows[:, :7])


def test_negative_max_gap_is_refused() -> None:
    with pytest.raises(ParameterError, match="max_gap"):
        fill_gaps(np.zeros((0, 8)), -1)
