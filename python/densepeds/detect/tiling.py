"""Overlapping tiles for crowds, and merging detections found in several tiles.

A 320 px model sees a 1080p crowd at a sixth of its size and misses most people; running it on
overlapping tiles (plus the whole frame, for people larger than a tile) recovers them. Merging
drops boxes cut by an interior tile edge when another view sees the person whole, then runs NMS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from densepeds.boxes import box_area, intersections, iou_matrix
from densepeds.errors import ParameterError

FloatArray = npt.NDArray[np.float64]
TilesSpec = str | int | tuple[int, int] | None

OVERLAP = 0.2  # fraction of a tile shared with each neighbour
CUT_MARGIN = 3.0  # px (frame scale): a box this close to an interior tile edge is "cut"


@dataclass(frozen=True)
class Tile:
    """A frame region [x0, x1) x [y0, y1); ``interior`` flags edges (left, top, right, bottom)
    that lie inside the frame, where a box touching them is cut."""

    x0: int
    y0: int
    x1: int
    y1: int
    interior: tuple[bool, bool, bool, bool]


def parse_grid(tiles: TilesSpec, width: int, height: int, input_size: int) -> tuple[int, int]:
    """(columns, rows) from the user's spec: None/1/"none" = one pass, "auto", (c, r), "CxR"."""
    if tiles is None or tiles == 1 or tiles == "none":
        return 1, 1
    if tiles == "auto":
        return auto_grid(width, height, input_size)
    if isinstance(tiles, str) and "x" in tiles:
        parts = tiles.lower().split("x")
        if len(parts) == 2 and all(p.strip().isdigit() for p in parts):
            tiles = (int(parts[0]), int(parts[1]))
    if (
        isinstance(tiles, tuple)
        and len(tiles) == 2
        and all(isinstance(v, int) and 1 <= v <= 16 for v in tiles)
    ):
        return tiles[0], tiles[1]
    raise ParameterError(
        "tiles must be None, 'auto', 'none', 'CxR' or (columns, rows) with 1..16 each, "
        f"got {tiles!r}"
    )


def auto_grid(width: int, height: int, input_size: int) -> tuple[int, int]:
    """Tiles about 1.25x the model input (so people keep roughly their size), at most 3x2.

    960x540 at 320 px gives 3x2; 1920x1080 also 3x2 (people there are large enough to be
    downscaled ~2x: 4x3 found no more on MOT17-02 at twice the cost); frames barely above the
    input size get a single pass.
    """
    target = 1.25 * input_size
    cols = min(3, max(1, math.ceil(width / target)))
    rows = min(2, max(1, math.ceil(height / target)))
    return cols, rows


def make_tiles(width: int, height: int, cols: int, rows: int) -> list[Tile]:
    """Overlapping tiles covering the frame, ``cols`` x ``rows``, row-major."""
    xs = _spans(width, cols)
    ys = _spans(height, rows)
    tiles = []
    for j, (y0, y1) in enumerate(ys):
        for i, (x0, x1) in enumerate(xs):
            interior = (i > 0, j > 0, i < cols - 1, j < rows - 1)
            tiles.append(Tile(x0, y0, x1, y1, interior))
    return tiles


def _spans(length: int, count: int) -> list[tuple[int, int]]:
    if count == 1:
        return [(0, length)]
    size = length / (count - (count - 1) * OVERLAP)
    step = size * (1 - OVERLAP)
    return [(round(k * step), min(length, round(k * step + size))) for k in range(count)]


def cut_flags(boxes: FloatArray, tile: Tile) -> npt.NDArray[np.bool_]:
    """Boxes (frame coordinates) touching an interior edge of ``tile``."""
    left, top, right, bottom = tile.interior
    cut = np.zeros(len(boxes), bool)
    if left:
        cut |= boxes[:, 0] <= tile.x0 + CUT_MARGIN
    if top:
        cut |= boxes[:, 1] <= tile.y0 + CUT_MARGIN
    if right:
        cut |= boxes[:, 2] >= tile.x1 - CUT_MARGIN
    if bottom:
        cut |= boxes[:, 3] >= tile.y1 - CUT_MARGIN
    return cut


def nms(boxes: FloatArray, scores: npt.NDArray[np.floating], iou_threshold: float) -> np.ndarray:
    """Greedy class-agnostic NMS; indices kept, best first."""
    order = np.argsort(-scores, kind="stable")
    if len(order) == 0:
        return order
    iou = iou_matrix(boxes[order], boxes[order])
    suppressed = np.zeros(len(order), bool)
    keep = []
    for k in range(len(order)):
        if suppressed[k]:
            continue
        keep.append(k)
        suppressed |= iou[k] > iou_threshold
    return order[np.array(keep, dtype=np.intp)]


def merge_views(
    boxes: FloatArray,
    scores: npt.NDArray[np.floating],
    view: npt.NDArray[np.intp],
    cut: npt.NDArray[np.bool_],
    iou_threshold: float,
    contained: float = 0.7,
) -> np.ndarray:
    """Indices of detections kept after merging views (tiles and/or the whole frame).

    A box cut by a tile edge is dropped when a whole box from another view covers at least
    ``contained`` of it; the rest go through NMS where whole boxes win over cut ones.
    """
    alive = np.ones(len(boxes), bool)
    cut_idx = np.flatnonzero(cut)
    whole_idx = np.flatnonzero(~cut)
    if len(cut_idx) and len(whole_idx):
        inter = intersections(boxes[cut_idx], boxes[whole_idx])
        covered = inter / np.maximum(box_area(boxes[cut_idx]), 1e-9)[:, None] >= contained
        covered &= view[cut_idx][:, None] != view[whole_idx][None, :]
        alive[cut_idx[covered.any(axis=1)]] = False
    idx = np.flatnonzero(alive)
    # Whole boxes rank above cut ones at equal footing; score breaks ties within each group.
    priority = scores[idx].astype(np.float64) - np.where(cut[idx], 1e6, 0.0)
    return idx[nms(boxes[idx], priority, iou_threshold)]
