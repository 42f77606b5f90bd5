"""Pairwise geometry of boxes ``(x1, y1, x2, y2)``: areas, intersections and IoU.

IoU comes from the Rust core (``densepeds._core.iou_matrix``, the tracker's own), so every stage
measures overlap the same way.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from densepeds import _core
from densepeds.errors import InputError

FloatArray = npt.NDArray[np.float64]


def as_boxes(boxes: npt.ArrayLike) -> FloatArray:
    return np.ascontiguousarray(np.asarray(boxes, np.float64).reshape(-1, 4))


def box_area(boxes: npt.ArrayLike) -> FloatArray:
    b = as_boxes(boxes)
    return np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None)


def intersections(a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
    """Pairwise intersection areas [len(a), len(b)]."""
    a, b = as_boxes(a), as_boxes(b)
    w = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    h = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    return np.clip(w, 0, None) * np.clip(h, 0, None)


def iou_matrix(a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
    """Pairwise IoU [len(a), len(b)]; 0 where the union is empty. Boxes must be finite with
    x2 >= x1 and y2 >= y1 (else InputError)."""
    try:
        return _core.iou_matrix(as_boxes(a), as_boxes(b))
    except ValueError as exc:
        raise InputError(str(exc)) from exc


def match_boxes(
    a: npt.ArrayLike, b: npt.ArrayLike, min_iou: float = 0.5
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """One-to-one matching of boxes ``a`` to boxes ``b``: the pairs ``(rows, cols)`` with IoU at
    least ``min_iou`` of the assignment with the largest total IoU over such pairs (pairs under
    ``min_iou`` count as nothing, so they never displace a valid pair). Rows are ascending."""
    iou = iou_matrix(a, b)
    if iou.size == 0:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    rows, cols = _core.linear_sum_assignment(-np.where(iou >= min_iou, iou, 0.0))
    rows, cols = np.asarray(rows, np.intp), np.asarray(cols, np.intp)
    keep = iou[rows, cols] >= min_iou
    order = np.argsort(rows[keep], kind="stable")
    return rows[keep][order], cols[keep][order]
