"""Overlapping tiles for crowds, and merging detections found in several tiles.

A 320 px model sees a 1080p crowd at a sixth of its size and misses most people; running it on
overlapping tiles (plus the whole frame, for people larger than a tile) recovers them. Merging
drops boxes cut by an interior tile edge when another view sees the person whole, then runs NMS.

``PeopleTiles`` (YoloSegDetector's "auto" tiles) chooses the tiles from the people themselves:
it fits person height against foot position (the perspective of a camera above the ground) on
the detections of recent frames and cuts each band of rows so that a person there spans a set
share of the network input: small, far people get small (magnified) tiles, near ones large.
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
# The detector settings of the people-following rule (the yoloseg "auto" tiles); a fixed grid
# reads full_scan_every too (SkipSchedule), and only where it is not 1.
PEOPLE_SETTINGS = ("person_share", "max_tiles", "max_scale", "full_scan_every")
# The people's tiles cost at most this many times the views of the frame's fixed grid
# (auto_grid): on small frames the people's share would otherwise ask for many magnified tiles.
GRID_MULTIPLE = 2


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
    """(columns, rows) from the user's spec: None/1/"none" = one pass, "auto" or "grid" (the
    fixed grid :func:`auto_grid` chooses), (c, r), "CxR". (YoloSegDetector starts its "auto"
    tiles from that grid, then follows the people; "grid" keeps it.)"""
    if tiles is None or tiles == 1 or tiles == "none":
        return 1, 1
    if tiles in ("auto", "grid"):
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
        "tiles must be None, 'auto', 'grid', 'none', 'CxR' or (columns, rows) with 1..16 each, "
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


# --- tiles that follow the people ------------------------------------------------------------


@dataclass(frozen=True)
class Perspective:
    """Person height (px) against foot row y (px): ``height(y) = a + b * y`` with b >= 0, y
    held inside [y_lo, y_hi]: the rows where feet were seen, extended upwards by two person
    heights (the farthest people are the ones a detector misses; beyond that, no guess)."""

    a: float
    b: float
    y_lo: float = -math.inf
    y_hi: float = math.inf

    def height(self, y: float) -> float:
        return max(self.a + self.b * min(max(y, self.y_lo), self.y_hi), 1.0)


def fit_perspective(boxes: FloatArray, min_people: int = 10) -> Perspective | None:
    """Least-squares line of box height on foot row, refit without outliers (boxes off the
    line by more than 2.5 median absolute deviations: parts of people, merged pairs); None with
    fewer than ``min_people`` boxes. A negative slope (nearer people smaller) is not a
    ground-plane view: the median height is used for every row instead."""
    if len(boxes) < min_people:
        return None
    foot = boxes[:, 3].astype(np.float64)
    h = (boxes[:, 3] - boxes[:, 1]).astype(np.float64)
    keep = np.ones(len(h), bool)
    b, a = 0.0, float(np.median(h))
    for _ in range(2):
        if np.ptp(foot[keep]) > 0:
            b, a = (float(v) for v in np.polyfit(foot[keep], h[keep], 1))
        resid = h - (a + b * foot)
        mad = float(np.median(np.abs(resid[keep]))) or 1.0
        keep = np.abs(resid) <= 2.5 * mad
        if keep.sum() < min_people:
            break
    lo, hi = (float(v) for v in np.percentile(foot, [5, 95]))
    if b < 0:
        return Perspective(float(np.median(h)), 0.0, lo, hi)
    # Two person heights above the farthest feet seen: y = lo - 2 * (a + b * y).
    lo = max((lo - 2 * a) / (1 + 2 * b), 0.0)
    return Perspective(a, b, lo, hi)


def people_tiles(
    width: int,
    height: int,
    input_size: int,
    perspective: Perspective,
    person_share: float,
    max_tiles: int,
    max_scale: float,
) -> list[Tile]:
    """Square tiles in bands of rows from the top (the last band cut at the frame's bottom). A
    band's side makes the smallest person whole in it (head at the band's top) span
    ``person_share`` of the input (magnified at most ``max_scale``, never larger than the
    frame); bands and columns overlap by the local person height so that everybody is whole in
    some tile. Where that needs more than ``max_tiles``
    tiles, people get a smaller share until it fits. An empty list: the whole frame in one
    view already gives people their share."""
    share = person_share
    while True:
        tiles = _people_tiles(width, height, input_size, perspective, share, max_scale)
        if len(tiles) <= max_tiles:
            return tiles
        share *= 0.9


def _people_tiles(
    width: int,
    height: int,
    input_size: int,
    persp: Perspective,
    share: float,
    max_scale: float,
) -> list[Tile]:
    smallest = input_size / max_scale
    largest = float(max(width, height))
    bands: list[tuple[int, int, int, float]] = []  # (y0, y1, tile width, overlap)
    y0 = 0.0
    while True:
        foot = y0
        for _ in range(3):  # the person whose head is at y0: feet at y0 + their height
            foot = y0 + persp.height(foot)
        side = min(max(persp.height(foot) / share, smallest), largest)
        if y0 == 0 and side >= height and side >= width:
            return []
        y1 = min(y0 + side, float(height))
        overlap = min(persp.height(y1), side / 2)
        bands.append((round(y0), round(y1), round(side), overlap))
        if y1 >= height:
            break
        y0 = y1 - overlap
    tiles = []
    for ty0, ty1, side, overlap in bands:
        if side >= width:
            xs = [(0, width)]
        else:
            cols = math.ceil((width - overlap) / (side - overlap))
            step = (width - side) / (cols - 1)
            xs = [(round(i * step), round(i * step) + side) for i in range(cols)]
            xs[-1] = (width - side, width)
        for tx0, tx1 in xs:
            interior = (tx0 > 0, ty0 > 0, tx1 < width, ty1 < height)
            tiles.append(Tile(tx0, ty0, tx1, ty1, interior))
    return tiles


def occupied_tiles(tiles: list[Tile], people: FloatArray, margin: float) -> list[int]:
    """Indices (ascending) of the ``tiles`` that show somebody in ``people`` (frame boxes)
    whole: the box, grown by ``margin`` of its height on every side (the way people may move
    before the next frame), crosses none of the tile's interior edges (the box alone where no
    tile holds the grown one). A person no tile shows whole keeps the tile that holds most of
    their box. Every person is thus whole in a kept tile wherever some tile shows them whole,
    with every view that does (overlapping views find more of a crowd than one alone); a tile
    left out shows nobody whole."""
    if not tiles or not len(people):
        return []
    return np.flatnonzero(showing(tiles, people, margin).any(axis=0)).tolist()


def showing(tiles: list[Tile], people: FloatArray, margin: float) -> npt.NDArray[np.bool_]:
    """[people, tiles]: the tiles ``occupied_tiles`` keeps for each person (see there)."""
    boxes = np.asarray(people, np.float64).reshape(-1, 4)
    h = np.maximum(boxes[:, 3] - boxes[:, 1], 1.0)
    grown = boxes + np.outer(h * margin, [-1.0, -1.0, 1.0, 1.0])
    edges = np.array([[t.x0, t.y0, t.x1, t.y1] for t in tiles], np.float64)
    inner = np.array([t.interior for t in tiles], bool)

    def whole(b: FloatArray) -> npt.NDArray[np.bool_]:  # [people, tiles]
        ok = np.ones((len(b), len(tiles)), bool)
        ok &= ~inner[:, 0] | (b[:, None, 0] >= edges[None, :, 0])
        ok &= ~inner[:, 1] | (b[:, None, 1] >= edges[None, :, 1])
        ok &= ~inner[:, 2] | (b[:, None, 2] <= edges[None, :, 2])
        ok &= ~inner[:, 3] | (b[:, None, 3] <= edges[None, :, 3])
        return ok

    shows = whole(grown)
    bare = ~shows.any(axis=1)
    shows[bare] = whole(boxes[bare])
    nobody = ~shows.any(axis=1)
    if nobody.any():
        inter = intersections(boxes[nobody], edges)
        shows[np.flatnonzero(nobody), np.argmax(inter, axis=1)] = True
    return shows


def sliding_windows(layout: list[Tile], people: FloatArray, margin: float) -> list[Tile] | None:
    """Windows the size of the layout's tiles, each placed anywhere in the frame the layout
    covers, such that every box of ``people`` grown by ``margin`` of its height (clipped to the
    frame) lies whole in one of them; None where the windows are not fewer than the tiles
    ``occupied_tiles`` keeps, or where a grown box fits no window it may go in. On a grid of
    one tile size (up to a pixel) a box may go in any window it fits; on a layout of several
    sizes (``people_tiles``' bands) only in one the size of a tile that shows it whole, so that
    people are seen at the scale the layout has for them. Greedy from the left: the leftmost
    box not yet held sets a window's left edge, and its size and top edge are those holding
    most of the boxes left."""
    if not layout or not len(people):
        return None
    width, height = max(t.x1 for t in layout), max(t.y1 for t in layout)
    # Tile sizes, those within a pixel of each other as one (the smallest).
    sizes: list[tuple[int, int]] = []
    size_of = []  # per tile, its entry in sizes
    for t in layout:
        tw, th = t.x1 - t.x0, t.y1 - t.y0
        near = [i for i, (sw, sh) in enumerate(sizes) if abs(sw - tw) <= 1 and abs(sh - th) <= 1]
        if not near:
            sizes.append((tw, th))
        k = near[0] if near else len(sizes) - 1
        sizes[k] = (min(sizes[k][0], tw), min(sizes[k][1], th))
        size_of.append(k)
    boxes = np.asarray(people, np.float64).reshape(-1, 4)
    h = np.maximum(boxes[:, 3] - boxes[:, 1], 1.0)
    grown = boxes + np.outer(h * margin, [-1.0, -1.0, 1.0, 1.0])
    np.clip(grown, 0, [width, height, width, height], out=grown)
    dims = np.array(sizes, np.float64)  # [sizes, 2]
    # fits[p, s]: the grown box fits a window of size s (and, with several sizes, a tile of
    # that size shows the person whole).
    fits = (grown[:, None, 2] - grown[:, None, 0] <= dims[None, :, 0]) & (
        grown[:, None, 3] - grown[:, None, 1] <= dims[None, :, 1]
    )
    if len(sizes) > 1:
        shows = showing(layout, boxes, margin)
        of_size = np.zeros((len(layout), len(sizes)), bool)
        of_size[np.arange(len(layout)), size_of] = True
        fits &= (shows.astype(np.int64) @ of_size) > 0
    if not fits.any(axis=1).all():
        return None
    windows: list[Tile] = []
    left = np.ones(len(grown), bool)
    while left.any():
        rest = np.flatnonzero(left)
        first = rest[np.argmin(grown[rest, 0])]
        best: tuple[int, int, float, npt.NDArray[np.intp]] | None = None  # count, size, top, held
        for k in np.flatnonzero(fits[first]).tolist():
            tw, th = sizes[k]
            x0 = min(grown[first, 0], width - tw)
            fit = rest[fits[rest, k]]
            col = fit[(grown[fit, 0] >= x0) & (grown[fit, 2] <= x0 + tw)]
            # Top edges that hold ``first``: each held box's own top, or first's bottom less th.
            tops = np.append(grown[col, 1], grown[first, 3] - th).clip(0, height - th)
            tops = tops[(tops <= grown[first, 1]) & (tops + th >= grown[first, 3])]
            held = (grown[None, col, 1] >= tops[:, None]) & (
                grown[None, col, 3] <= tops[:, None] + th
            )
            i = int(np.argmax(held.sum(axis=1)))
            if best is None or held[i].sum() > best[0]:
                best = (int(held[i].sum()), int(k), float(tops[i]), col[held[i]])
        assert best is not None
        _, k, top, taken = best
        left[taken] = False
        tw, th = sizes[k]
        x0i, y0i = math.floor(min(grown[first, 0], width - tw)), math.floor(top)
        x1i, y1i = min(width, x0i + tw), min(height, y0i + th)
        windows.append(Tile(x0i, y0i, x1i, y1i, (x0i > 0, y0i > 0, x1i < width, y1i < height)))
    if len(windows) >= len(occupied_tiles(layout, people, margin)):
        return None
    return windows


class SkipSchedule:
    """Which views of a fixed layout run each frame: all its tiles every ``full_scan_every``-th
    frame (a full scan, the first frame included), and on the frames between views of the
    people detected in the last ``full_scan_every`` frames, the last full scan's included
    (people grown by ``margin`` of their height): windows of the layout's tile sizes placed
    over them (``sliding_windows``) where that takes fewer views, else the tiles that show them
    whole (``occupied_tiles``); no view, so the whole frame in one, when nobody was detected.
    ``full_scan_every=1``: every frame a full scan.
    ``last_full`` says whether the last ``tiles`` call was one; ``observe`` feeds a frame's
    detections (a frame of another size, or another layout, starts with a full scan).
    """

    def __init__(self, full_scan_every: int, margin: float = 0.1) -> None:
        if full_scan_every < 1:
            raise ParameterError(f"full_scan_every must be >= 1, got {full_scan_every}")
        self.full_scan_every = full_scan_every
        self.margin = margin
        self._recent: list[FloatArray] = []
        self._layout: list[Tile] | None = None
        self._since_full = 0
        self.last_full = True

    def full_scan_due(self) -> bool:
        """Whether the next frame is a full scan whatever its layout."""
        return self._layout is None or self._since_full + 1 >= self.full_scan_every

    def tiles(self, layout: list[Tile]) -> list[Tile]:
        """The tiles of ``layout`` to run on the next frame."""
        if layout != self._layout or self.full_scan_due():
            self._layout = layout
            self._since_full = 0
            self.last_full = True
            return layout
        self._since_full += 1
        self.last_full = False
        if not layout:
            return []
        people = np.concatenate(self._recent) if self._recent else np.zeros((0, 4))
        windows = sliding_windows(layout, people, self.margin)
        if windows is not None:
            return windows
        return [layout[k] for k in occupied_tiles(layout, people, self.margin)]

    def observe(self, boxes: FloatArray) -> None:
        self._recent.append(np.asarray(boxes, np.float64).reshape(-1, 4))
        del self._recent[: -self.full_scan_every]

    def restart(self) -> None:
        """The next frame is a full scan (the people seen lately are kept)."""
        self._layout = None
        self._since_full = 0
        self.last_full = True

    def reset(self) -> None:
        self._recent.clear()
        self.restart()


class PeopleTiles:
    """Chooses each frame's tiles from the people detected in recent frames.

    ``tiles(width, height)`` gives the views for the next frame: ``auto_grid``'s tiles until
    ``min_people`` confident detections (score >= ``min_score``) have been seen, then
    ``people_tiles`` on the perspective fitted to those of the last ``window`` full scans, at
    most ``max_tiles`` and at most ``GRID_MULTIPLE`` times the grid's views. The layout is
    refitted on full scans only and kept until the next one; which views run on the frames
    between is ``SkipSchedule``'s rule (``full_scan_every``, ``margin``), so that
    people who enter or were missed are looked for at least every ``full_scan_every`` frames.
    ``last_full`` says whether the last ``tiles`` call was a full scan. ``observe`` feeds a
    frame's detections (a frame of another size starts over: another video).
    """

    def __init__(
        self,
        input_size: int,
        person_share: float,
        max_tiles: int,
        max_scale: float,
        full_scan_every: int,
        window: int = 25,
        min_score: float = 0.4,
        min_people: int = 10,
        margin: float = 0.1,
    ) -> None:
        self.schedule = SkipSchedule(full_scan_every, margin)  # full scans and the frames between
        self.input_size = input_size
        self.person_share = person_share
        self.max_tiles = max_tiles
        self.max_scale = max_scale
        self.full_scan_every = full_scan_every
        self.window = window
        self.min_score = min_score
        self.min_people = min_people
        self._seen: list[FloatArray] = []
        self._size = (0, 0)
        self._layout: list[Tile] = []  # the last full scan's tiles
        self.last_full = True
        self.perspective: Perspective | None = None

    def tiles(self, width: int, height: int) -> list[Tile]:
        cols, rows = auto_grid(width, height, self.input_size)
        if self.perspective is None or (width, height) != self._size:
            self.schedule.restart()  # the people's layout starts with a full scan
            self.last_full = True
            return make_tiles(width, height, cols, rows) if cols * rows > 1 else []
        if self.schedule.full_scan_due():
            # A full scan: the layout is refitted here only, and kept until the next one.
            self._layout = people_tiles(
                width,
                height,
                self.input_size,
                self.perspective,
                self.person_share,
                min(self.max_tiles, GRID_MULTIPLE * cols * rows),
                self.max_scale,
            )
        tiles = self.schedule.tiles(self._layout)
        self.last_full = self.schedule.last_full
        return tiles

    def observe(
        self, boxes: FloatArray, scores: npt.NDArray[np.floating], width: int, height: int
    ) -> None:
        if (width, height) != self._size:
            self.reset()
            self._size = (width, height)
        boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
        self.schedule.observe(boxes)
        if self.last_full:  # the people's sizes from full scans only: a steady layout
            self._seen.append(boxes[np.asarray(scores) >= self.min_score])
            del self._seen[: -self.window]
            self.perspective = fit_perspective(np.concatenate(self._seen), self.min_people)

    def reset(self) -> None:
        self._seen.clear()
        self.schedule.reset()
        self._size = (0, 0)
        self._layout = []
        self.last_full = True
        self.perspective = None
