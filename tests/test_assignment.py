"""The Rust assignment solver and cost matrices against scipy and numpy."""

from __future__ import annotations

import numpy as np
import pytest
from densepeds import _core
from scipy.optimize import linear_sum_assignment as scipy_lsa


@pytest.mark.parametrize(
    ("n", "m"), [(1, 1), (3, 7), (7, 3), (20, 20), (64, 100), (100, 64), (500, 500), (300, 500)]
)
def test_linear_sum_assignment_matches_scipy(n: int, m: int) -> None:
    rng = np.random.default_rng(n * 1000 + m)
    for kind in ("uniform", "integer"):
        cost = rng.random((n, m)) if kind == "uniform" else rng.integers(0, 10, (n, m)) * 1.0
        rows, cols = _core.linear_sum_assignment(cost)
        ref_rows, ref_cols = scipy_lsa(cost)
        assert len(rows) == min(n, m)
        assert len(set(rows.tolist())) == len(rows) and len(set(cols.tolist())) == len(cols)
        assert np.all(np.diff(rows) > 0)
        total, ref_total = cost[rows, cols].sum(), cost[ref_rows, ref_cols].sum()
        np.testing.assert_allclose(total, ref_total, rtol=1e-12)


def test_forbidden_pairs_match_scipy() -> None:
    rng = np.random.default_rng(7)
    for _ in range(20):
        cost = rng.random((30, 40))
        cost[rng.random(cost.shape) < 0.6] = np.inf
        try:
            ref_rows, ref_cols = scipy_lsa(cost)
        except ValueError:
            with pytest.raises(ValueError, match="infeasible"):
                _core.linear_sum_assignment(cost)
            continue
        rows, cols = _core.linear_sum_assignment(cost)
        assert np.isfinite(cost[rows, cols]).all()
        np.testing.assert_allclose(cost[rows, cols].sum(), cost[ref_rows, ref_cols].sum())


def test_float32_input_and_bad_matrices() -> None:
    cost = np.array([[1.0, 2.0], [3.0, 10.0]], np.float32)
    rows, cols = _core.linear_sum_assignment(cost)
    assert rows.tolist() == [0, 1] and cols.tolist() == [1, 0]
    with pytest.raises(ValueError, match="NaN"):
        _core.linear_sum_assignment(np.array([[np.nan, 1.0]]))
    with pytest.raises(ValueError, match="shape"):
        _core.linear_sum_assignment(np.zeros(3))
    with pytest.raises(ValueError, match="dtype"):
        _core.linear_sum_assignment(np.zeros((2, 2), np.int64))  # type: ignore[arg-type]


def _random_boxes(rng: np.random.Generator, n: int) -> np.ndarray:
    xy = rng.random((n, 2)) * 100
    wh = rng.random((n, 2)) * 40
    return np.hstack([xy, xy + wh])


def _numpy_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    tl = np.maximum(a[:, None, :2], b[None, :, :2])
    br = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.clip(br - tl, 0, None).prod(-1)
    area_a = (a[:, 2:] - a[:, :2]).prod(-1)
    area_b = (b[:, 2:] - b[:, :2]).prod(-1)
    return inter / (area_a[:, None] + area_b[None, :] - inter)


def test_iou_matrix_matches_numpy() -> None:
    rng = np.random.default_rng(1)
    a, b = _random_boxes(rng, 50), _random_boxes(rng, 70)
    np.testing.assert_allclose(_core.iou_matrix(a, b), _numpy_iou(a, b), atol=1e-12)
    a32, b32 = a.astype(np.float32), b.astype(np.float32)
    want = _numpy_iou(a32.astype(np.float64), b32.astype(np.float64))
    np.testing.assert_allclose(_core.iou_matrix(a32, b32), want, atol=1e-12)
    with pytest.raises(ValueError, match="inverted"):
        _core.iou_matrix(np.array([[5.0, 0, 1, 1]]), b)


def test_cosine_distance_matrix_matches_numpy() -> None:
    rng = np.random.default_rng(2)
    a = rng.normal(size=(40, 128)).astype(np.float32)
    b = rng.normal(size=(60, 128)).astype(np.float32)
    an = a / np.linalg.norm(a, axis=1, keepdims=True)
    bn = b / np.linalg.norm(b, axis=1, keepdims=True)
    np.testing.assert_allclose(_core.cosine_distance_matrix(a, b), 1 - an @ bn.T, atol=1e-5)
    with pytest.raises(ValueError, match="shape"):
        _core.cosine_distance_matrix(a, b[:, :64])
