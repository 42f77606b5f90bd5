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
