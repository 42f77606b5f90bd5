"""Mask IoU against box IoU: which tells a person's next detection from a neighbour's better.

    python benchmarks/mask_overlap.py                 # the four video cells
    python benchmarks/mask_overlap.py --cells 'MOT20*/float'

Each video cell's cached detections (``benchmarks/accuracy_grid.py``'s cache), filtered as the
pipeline filters them before tracking (score floor, duplicate suppression), are labelled with the
ground-truth person they cover (IoU >= 0.5, one-to-one per frame, ``densepeds.boxes.match_boxes``).
Every pair of labelled detections in consecutive frames whose boxes overlap (IoU above
``--min-iou``) is a candidate match of the kind the tracker's IoU stage weighs: the same person
(a true continuation) or a neighbour (a steal). For each pair the script measures the box IoU and
the mask IoU (both masks on the frame's pixel grid), each as found and with the earlier detection
moved by its person's ground-truth motion (a perfect prediction). It prints, per measure:

- how well it ranks same-person pairs above neighbour pairs (AUC, the Mann-Whitney statistic);
- for every detection with its true continuation and at least one neighbour among its
  candidates, how often the continuation has the largest overlap, and the cases where box IoU
  and mask IoU disagree;
- for overlapping detections of the same frame (box IoU above ``--min-iou``), the median ratio of
  their mask IoU to their box IoU (below 1 where masks separate people whose boxes overlap).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402
from coast_errors import load_gt  # noqa: E402

Boxes = npt.NDArray[np.float64]
Mask = npt.NDArray[np.bool_]
Gt = dict[int, tuple[npt.NDArray[np.int64], Boxes, npt.NDArray[np.float64]]]  # load_gt
MEASURES = ("box IoU", "mask IoU", "box IoU, moved", "mask IoU, moved")


def mask_iou(
    mask_a: Mask,
    box_a: Sequence[int],
    mask_b: Mask,
    box_b: Sequence[int],
    shift: tuple[int, int] = (0, 0),
) -> float:
    """IoU of two box-local masks (``mask`` covering the integer region ``box`` = x0 y0 x1 y1, as
    ``densepeds.Detections`` holds them), mask a moved by ``shift`` = (dx, dy) pixels."""
    ax0, ay0 = int(box_a[0]) + shift[0], int(box_a[1]) + shift[1]
    bx0, by0 = int(box_b[0]), int(box_b[1])
    x0, y0 = max(ax0, bx0), max(ay0, by0)
    x1 = min(ax0 + mask_a.shape[1], bx0 + mask_b.shape[1])
    y1 = min(ay0 + mask_a.shape[0], by0 + mask_b.shape[0])
    inter = 0
    if x1 > x0 and y1 > y0:
        inter = int(
            np.count_nonzero(
                mask_a[y0 - ay0 : y1 - ay0, x0 - ax0 : x1 - ax0]
                & mask_b[y0 - by0 : y1 - by0, x0 - bx0 : x1 - bx0]
            )
        )
    union = int(np.count_nonzero(mask_a)) + int(np.count_nonzero(mask_b)) - inter
    return inter / union if union else 0.0


@dataclass
class Pairs:
    """Candidate pairs (earlier detection, later detection) of consecutive frames."""

    same: npt.NDArray[np.bool_]  # the same person
    values: npt.NDArray[np.float64]  # [P, len(MEASURES)]
    group: npt.NDArray[np.int64]  # one number per earlier detection


def label(
    boxes: Boxes, gt_frame: tuple[npt.NDArray[np.int64], Boxes, npt.NDArray[np.float64]] | None
) -> npt.NDArray[np.int64]:
    """The ground-truth id each box covers (-1 for none)."""
    from densepeds.boxes import match_boxes

    out = np.full(len(boxes), -1, np.int64)
    if gt_frame is None or not len(boxes):
        return out
    ids, gt_boxes, _ = gt_frame
    rows, cols = match_boxes(boxes, gt_boxes)
    out[rows] = ids[cols]
    return out


def _centres(b: Boxes) -> Boxes:
    return np.c_[(b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2]


def motion(gt: Gt, frame: int) -> dict[int, npt.NDArray[np.float64]]:
    """Each person's centre displacement from ``frame`` to ``frame + 1`` (ground truth)."""
    if frame not in gt or frame + 1 not in gt:
        return {}
    ids0, b0, _ = gt[frame]
    ids1, b1, _ = gt[frame + 1]
    c0, c1 = _centres(b0), _centres(b1)
    where = {int(p): k for k, p in enumerate(ids1)}
    return {int(p): c1[where[int(p)]] - c0[k] for k, p in enumerate(ids0) if int(p) in where}


def collect(dets: Sequence[Any], gt: Gt, min_iou: float) -> Pairs:
    """The candidate pairs of a cell (``dets`` per frame from frame 1, masks required)."""
    from densepeds.boxes import iou_matrix

    labels = [label(d.boxes.astype(np.float64), gt.get(k + 1)) for k, d in enumerate(dets)]
    same, values, group = [], [], []
    n_groups = 0
    for k in range(len(dets) - 1):
        da, db = dets[k], dets[k + 1]
        if not len(da) or not len(db):
            continue
        ba, bb = da.boxes.astype(np.float64), db.boxes.astype(np.float64)
        overlap = iou_matrix(ba, bb)
        moves = motion(gt, k + 1)
        for i in np.flatnonzero(labels[k] >= 0):
            n_groups += 1
            move = moves.get(int(labels[k][i]), np.zeros(2))
            shift = (int(round(move[0])), int(round(move[1])))
            moved = iou_matrix((ba[i] + np.r_[move, move])[None], bb)[0]
            for j in np.flatnonzero((labels[k + 1] >= 0) & (overlap[i] > min_iou)):
                ma, mb = da.masks[i], db.masks[j]
                a, b = da.mask_boxes[i], db.mask_boxes[j]
                same.append(labels[k][i] == labels[k + 1][j])
                values.append(
                    (overlap[i, j], mask_iou(ma, a, mb, b), moved[j], mask_iou(ma, a, mb, b, shift))
                )
                group.append(n_groups)
    return Pairs(
        np.array(same, bool),
        np.array(values, np.float64).reshape(-1, len(MEASURES)),
        np.array(group, np.int64),
    )


def auc(pos: npt.NDArray[np.float64], neg: npt.NDArray[np.float64]) -> float:
    """P(a positive scores above a negative), ties counting half."""
    from scipy.stats import mannwhitneyu

    if not len(pos) or not len(neg):
        return float("nan")
    return float(mannwhitneyu(pos, neg).statistic) / (len(pos) * len(neg))


def ranked_first(pairs: Pairs) -> npt.NDArray[np.bool_]:
    """[G, len(MEASURES)]: per contested group (its true continuation and >= 1 neighbour among
    its candidates), whether each measure puts the continuation first."""
    out = []
    for g in np.unique(pairs.group):
        sel = pairs.group == g
        same = pairs.same[sel]
        if same.sum() == 1 and (~same).any():
            out.append(same[np.argmax(pairs.values[sel], axis=0)])
    return np.array(out, bool).reshape(-1, len(MEASURES))


def same_frame_ratio(dets: Sequence[Any], min_iou: float) -> tuple[int, float]:
    """(pairs, median mask IoU / box IoU) over overlapping detections of the same frame."""
    from densepeds.boxes import iou_matrix

    ratios = []
    for d in dets:
        overlap = iou_matrix(d.boxes.astype(np.float64), d.boxes.astype(np.float64))
        for i, j in zip(*np.nonzero(np.triu(overlap > min_iou, 1)), strict=True):
            m = mask_iou(d.masks[i], d.mask_boxes[i], d.masks[j], d.mask_boxes[j])
            ratios.append(m / overlap[i, j])
    return len(ratios), float(np.median(ratios)) if ratios else float("nan")


def report(name: str, dets: Sequence[Any], gt: Gt, min_iou: float) -> None:
    pairs = collect(dets, gt, min_iou)
    print(f"\n## {name}: {pairs.same.sum()} same-person pairs, {(~pairs.same).sum()} neighbour")
    print("\n| measure | same: median | neighbour: median | AUC | continuation first |")
    print("|---|---:|---:|---:|---:|")
    first = ranked_first(pairs)
    for k, measure in enumerate(MEASURES):
        s, o = pairs.values[pairs.same, k], pairs.values[~pairs.same, k]
        print(
            f"| {measure} | {np.median(s):.3f} | {np.median(o):.3f} | {auc(s, o):.3f} "
            f"| {first[:, k].sum()}/{len(first)} |"
        )
    for box, mask in ((0, 1), (2, 3)):
        only_box = int((first[:, box] & ~first[:, mask]).sum())
        only_mask = int((~first[:, box] & first[:, mask]).sum())
        print(
            f"{MEASURES[box]} vs {MEASURES[mask]}: only the box right {only_box}, "
            f"only the mask right {only_mask}, neither {int((~first[:, [box, mask]]).all(1).sum())}"
        )
    n, ratio = same_frame_ratio(dets, min_iou)
    print(f"overlapping detections of one frame: {n} pairs, mask IoU / box IoU median {ratio:.3f}")


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--cells", nargs="+", default=["*/float", "*/int8"])
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    ap.add_argument("--min-iou", type=float, default=0.3, help="box IoU of a candidate pair")
    args = ap.parse_args(argv)
    cells = [c for c in grid.select_cells(args.cells) if c.full_pipeline]
    if not cells:
        sys.exit("no video cell (with masks) among the cells named")
    for cell in cells:
        data = grid.load_cell(cell, args.cache, kinds=(), quiet=True)
        pipe = grid.cell_pipeline(data, grid.Config(features="none"))
        dets = [d.subset(pipe._kept(d)) for d in data.dets]
        report(cell.name, dets, load_gt(data.seq_dir), args.min_iou)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
