"""densepeds.boxes.match_boxes against a brute-force search over every one-to-one matching."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from densepeds.boxes import iou_matrix, match_boxes


def _brute_best(iou: np.ndarray, min_iou: float) -> float:
    """Largest total IoU over one-to-one matchings that use only pairs at or above min_iou."""
    n, m = iou.shape
    best = 0.0
    for k in range(min(n, m) + 1):
        for rows in itertools.combinations(range(n), k):
            for cols in itertools.permutations(range(m), k):
                if all(iou[r, c] >= min_iou for r, c in zip(rows, cols, strict=True)):
                    best = max(best, sum(iou[r, c] for r, c in zip(rows, cols, strict=True)))
    return best


def _boxes(rng: np.random.Generator, n: int) -> np.ndarray:
    xy = rng.uniform(0, 30, (n, 2))
    wh = rng.uniform(10, 25, (n, 2))
    return np.c_[xy, xy + wh]


@pytest.mark.parametrize("seed", range(40))
def test_match_boxes_is_the_best_valid_matching(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b = _boxes(rng, int(rng.integers(0, 5))), _boxes(rng, int(rng.integers(0, 5)))
    min_iou = float(rng.choice([0.1, 0.3, 0.5]))
    rows, cols = match_boxes(a, b, min_iou)
    iou = iou_matrix(a, b)
    assert len(set(rows.tolist())) == len(rows) and len(set(cols.tolist())) == len(cols)
    assert np.all(np.diff(rows) > 0)
    assert np.all(iou[rows, cols] >= min_iou)
    total = float(iou[rows, cols].sum()) if len(rows) else 0.0
    assert total == pytest.approx(_brute_best(iou, min_iou) if iou.size else 0.0)


def test_a_pair_under_the_threshold_does_not_displace_a_valid_one() -> None:
    # a0-b0 overlap at 0.55; the crossed pairs a0-b1 and a1-b0 at 0.45 each sum to more, so an
    # assignment on raw IoU takes them and then keeps no pair at all.
    a = np.array([[0.0, 0.0, 10.0, 10.0], [6.69, 0.0, 16.69, 10.0]])
    b = np.array([[2.9, 0.0, 12.9, 10.0], [-3.79, 0.0, 6.21, 10.0]])
    iou = iou_matrix(a, b)
    assert iou[0, 0] == pytest.approx(0.55, abs=0.01)
    assert iou[0, 1] == pytest.approx(0.45, abs=0.01) and iou[1, 0] == pytest.approx(0.45, abs=0.01)
    rows, cols = match_boxes(a, b, 0.5)
    assert rows.tolist() == [0] and cols.tolist() == [0]
