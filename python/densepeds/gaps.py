"""Offline gap filling: a track's boxes between two detections, interpolated after the run.

The tracker is online: each frame's output depends only on the frames up to it, so while a
person is hidden it reports the motion model's prediction (or nothing). Once a whole run is
done, a track that was matched to detections at frames ``a`` and ``b`` is known to have gone
from one box to the other; :func:`fill_gaps` replaces what the track reported between them
(coasted boxes, or no box) with the straight-line interpolation of the two boxes, where
``b - a - 1`` is at most ``max_gap`` frames. Rows before a track's first detection, after its
last, and in longer gaps are kept as reported. This is the usual offline step of trackers
scored on MOTChallenge; ``densepeds run --fill-gaps N`` applies it to the tracks file.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from densepeds.errors import ParameterError

__all__ = ["fill_gaps"]


def fill_gaps(rows: npt.ArrayLike, max_gap: int) -> npt.NDArray[np.float64]:
    """Rows with each track's gaps of up to ``max_gap`` frames between detections interpolated.

    ``rows``: [K, 8] (frame, id, x1, y1, x2, y2, score, matched), ``matched`` 1 where the track
    was matched to a detection in that frame, 0 where it coasted. Returns [K', 7] rows (frame,
    id, x1, y1, x2, y2, score) sorted by id then frame, for ``densepeds.io.mot.write_tracks``.
    An interpolated row's box and score are linear between the two detections' rows.
    ``max_gap`` 0 returns the rows as given (without the ``matched`` column).
    """
    arr = np.asarray(rows, dtype=np.float64).reshape(-1, 8)
    if max_gap < 0:
        raise ParameterError(f"max_gap must be >= 0, got {max_gap}")
    arr = arr[np.lexsort((arr[:, 0], arr[:, 1]))]
    if max_gap == 0 or len(arr) == 0:
        return arr[:, :7].copy()
    out: list[npt.NDArray[np.float64]] = []
    for track in np.split(arr, np.flatnonzero(np.diff(arr[:, 1])) + 1):
        out.append(_fill_track(track, max_gap))
    return np.concatenate(out)


def _fill_track(track: npt.NDArray[np.float64], max_gap: int) -> npt.NDArray[np.float64]:
    """One track's rows (sorted by frame) with its short gaps between detections filled."""
    anchors = track[track[:, 7] > 0]
    keep = np.ones(len(track), dtype=bool)
    filled: list[npt.NDArray[np.float64]] = []
    for a, b in zip(anchors[:-1], anchors[1:], strict=True):
        span = int(b[0] - a[0])
        if span < 2 or span - 1 > max_gap:
            continue
        keep &= ~((track[:, 0] > a[0]) & (track[:, 0] < b[0]))
        t = (np.arange(1, span) / span)[:, None]
        part = np.empty((span - 1, 7))
        part[:, 0] = a[0] + np.arange(1, span)
        part[:, 1] = a[1]
        part[:, 2:7] = a[2:7] + t * (b[2:7] - a[2:7])
        filled.append(part)
    rows = np.concatenate([track[keep, :7], *filled]) if filled else track[:, :7]
    return rows[np.argsort(rows[:, 0], kind="stable")]
