"""Where a peer covers ground-truth boxes that we do not (and the reverse), on one cell.

    python benchmarks/recall_gap.py --cell ETH-Sunnyday/det --peer motpy [--param K=V ...]

Both trackers get the cell's cached inputs (``accuracy_grid.track_cell``). Per frame, each
tracker's boxes are matched one-to-one to the ground truth at IoU 0.5 (``boxes.match_boxes``).
A ground-truth box one tracker covers and the other does not is put in a class by what the
detector gave for it in that frame (the detection matched to it at IoU 0.5, by score band) and by
what the other tracker reported there: a box fed by that detection that misses the person
(shifted), a box near it (IoU > 0), or nothing. Rows on no ground-truth box (false positives) are
counted per tracker as matched to a detection or coasted. Per HOTA alpha (IoU threshold), the
detection recall and precision of both trackers (one-to-one per frame) are printed too.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402
import coast_errors  # noqa: E402
from densepeds.boxes import iou_matrix, match_boxes  # noqa: E402

Boxes = npt.NDArray[np.float64]
ALPHAS = (0.05, 0.2, 0.35, 0.5, 0.65, 0.8, 0.95)
SCORE_BANDS = (0.05, 0.3)  # below the first: under the second pass; below the second: weak


def _by_frame(rows: grid.Rows) -> dict[int, grid.Rows]:
    frames = rows[:, 0].astype(int)
    return {int(f): rows[frames == f] for f in np.unique(frames)}


def covered(rows_f: grid.Rows | None, gt_boxes: Boxes, alpha: float = 0.5) -> npt.NDArray[np.bool_]:
    """Which ground-truth boxes a frame's rows cover at IoU ``alpha`` (one-to-one)."""
    out = np.zeros(len(gt_boxes), bool)
    if rows_f is not None and len(rows_f):
        g, _ = match_boxes(gt_boxes, rows_f[:, 2:6], alpha)
        out[g] = True
    return out


def band(score: float) -> str:
    if score < SCORE_BANDS[0]:
        return "det<0.05"
    return "det weak" if score < SCORE_BANDS[1] else "det confident"


def other_side(
    rows_f: grid.Rows | None, free: npt.NDArray[np.bool_], gt_box: Boxes, det_box: Boxes | None
) -> str:
    """What a tracker reported at a ground-truth box it does not cover (``free``: its rows on no
    ground-truth box)."""
    if rows_f is None or not len(rows_f):
        return "nothing"
    if det_box is not None:
        fed = iou_matrix(det_box[None], rows_f[:, 2:6])[0] >= 0.8
        if np.any(fed & (rows_f[:, 7] > 0)):
            return "matched, off the person"
    near = np.where(free, iou_matrix(gt_box[None], rows_f[:, 2:6])[0], 0.0)
    if np.any(near > 0):
        k = int(np.argmax(near))
        return "coasted near" if rows_f[k, 7] == 0 else "matched near"
    return "nothing"


def free_rows(rows_f: grid.Rows | None, gt_boxes: Boxes) -> npt.NDArray[np.bool_]:
    if rows_f is None:
        return np.zeros(0, bool)
    free = np.ones(len(rows_f), bool)
    free[match_boxes(gt_boxes, rows_f[:, 2:6], 0.5)[1]] = False
    return free


@dataclass
class Tally:
    """Per tracker: ground-truth boxes it covers and the other does not, by class; and per HOTA
    alpha, (boxes covered, ground-truth boxes, rows)."""

    classes: dict[str, Counter[str]]
    per_alpha: dict[str, npt.NDArray[np.float64]]


def tally(
    gt: Mapping[int, tuple[Any, Boxes, Any]],
    dets: Sequence[Any],
    rows: Mapping[str, grid.Rows],
    hidden: grid.Rows | None = None,
) -> Tally:
    """Compare ``ours`` with the one other tracker in ``rows`` (frame-by-frame rows as in
    ``accuracy_grid.Rows``) over ground truth ``gt`` (``coast_errors.load_gt``) and the frames'
    detections ``dets`` (``dets[f - 1]`` with ``boxes`` and ``scores``). ``hidden``: our rows
    with every live confirmed track reported (the same tracking), which marks the boxes a lost
    track of ours covered without being reported."""
    (peer_name,) = [name for name in rows if name != "ours"]
    by_frame = {name: _by_frame(r) for name, r in rows.items()}
    live = _by_frame(hidden) if hidden is not None else {}
    out = Tally(
        {name: Counter() for name in rows}, {name: np.zeros((len(ALPHAS), 3)) for name in rows}
    )
    for f, (_, gt_boxes, _) in sorted(gt.items()):
        d = dets[f - 1]
        det_boxes = np.asarray(d.boxes, np.float64).reshape(-1, 4)
        det_of = np.full(len(gt_boxes), -1)
        if len(det_boxes):
            g, j = match_boxes(gt_boxes, det_boxes, 0.5)
            det_of[g] = j
        cov = {name: covered(r.get(f), gt_boxes) for name, r in by_frame.items()}
        for name, r in by_frame.items():
            rf = r.get(f)
            for a, alpha in enumerate(ALPHAS):
                n_rows = 0 if rf is None else len(rf)
                out.per_alpha[name][a] += (
                    covered(rf, gt_boxes, alpha).sum(),
                    len(gt_boxes),
                    n_rows,
                )
        for k in range(len(gt_boxes)):
            j = int(det_of[k])
            det_class = "no det" if j < 0 else band(float(d.scores[j]))
            for name, loser in (("ours", peer_name), (peer_name, "ours")):
                if cov[name][k] and not cov[loser][k]:
                    det_box = None if j < 0 else det_boxes[j]
                    rf = by_frame[loser].get(f)
                    what = other_side(rf, free_rows(rf, gt_boxes), gt_boxes[k], det_box)
                    if loser == "ours" and covered(live.get(f), gt_boxes)[k]:
                        what += " (a live track unreported covers it)"
                    out.classes[name][f"{det_class}: {loser} {what}"] += 1
    return out


def report(data: grid.CellData, rows: Mapping[str, grid.Rows], hidden: grid.Rows) -> None:
    gt = coast_errors.load_gt(data.seq_dir)
    t = tally(gt, data.dets, rows, hidden)
    for name, pa in t.per_alpha.items():
        print(f"\n{name}: HOTA alpha  DetRe  DetPr")
        for a, alpha in enumerate(ALPHAS):
            tp, n_gt, n_out = pa[a]
            print(f"  {alpha:.2f}  {100 * tp / n_gt:5.1f}  {100 * tp / max(n_out, 1):5.1f}")
    for name, c in t.classes.items():
        print(f"\ngt boxes {name} covers and the other does not ({sum(c.values())}):")
        for k, v in c.most_common():
            print(f"  {v:5d}  {k}")
    for name, r in rows.items():
        fp: Counter[str] = Counter()
        for f, rf in _by_frame(r).items():
            hit = np.zeros(len(rf), bool)
            if f in gt:
                hit[match_boxes(gt[f][1], rf[:, 2:6], 0.5)[1]] = True
            for k in np.flatnonzero(~hit):
                fp["matched" if rf[k, 7] > 0 else "not matched this frame"] += 1
        print(f"{name}: rows {len(r)}, on no gt box: {dict(fp)}")


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--cell", default="ETH-Sunnyday/det")
    ap.add_argument("--peer", default="motpy")
    ap.add_argument("--param", action="append", default=[], help="KEY=VALUE for ours")
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    args = ap.parse_args(argv)
    (cell,) = grid.select_cells([args.cell])
    data = grid.load_cell(cell, args.cache, quiet=True)
    ours = grid.track_cell(data, grid.Config(params=grid.parse_params(args.param)))
    every = {"output_lost": 10**6, "output_lost_adaptive": False, "coast_min_hits": 0}
    ours_all = grid.track_cell(data, grid.Config(params={**grid.parse_params(args.param), **every}))
    peer = grid.track_cell(data, grid.Config(tracker=args.peer))
    report(data, {"ours": ours, args.peer: peer}, ours_all)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
