"""Where the tracker's rows on nobody come from: every output row that covers no scored person,
classified, with what dropping each class would be worth.

    python benchmarks/fp_rows.py              # MOT20-01-dev/float and PETS09-S2L1-dev/float
    python benchmarks/fp_rows.py --cells 'MOT20*/float' --param coast_min_hits=3

Each cell is tracked as ``benchmarks/accuracy_grid.py`` tracks it (package defaults plus
``--param``). Rows are matched to the whole ground truth the way trackeval's MOTChallenge
preprocessing matches them (IoU >= 0.5, one-to-one per frame, every class and zero-marked boxes
included; ``densepeds.boxes.match_boxes``): a row matched to a distractor class (person on a
vehicle, static person, distractor, reflection; MOT20 also non-MOT vehicle) is removed before
scoring, which the script checks by scoring the rows without them. A row on nobody is one matched
to no scored person (class 1, flag not 0). Classes, in this order:

- ``coasted``: the track had no detection this frame (reported at its prediction);
- ``distractor``: matched to a distractor box (free: the scorer removes it);
- ``duplicate``: IoU >= 0.2 with a scored person whom another row of this frame covers;
- ``localised``: IoU 0.2-0.5 with a person no row covers (a real person, a box off them);
- ``unscored``: on an occluder or zero-marked box (IoU >= 0.5), not a person;
- ``clutter``: IoU < 0.2 with every scored person.

For each class: its rows, the detection score, the track's age and hits (matched rows so far, the
birth detection included) and the share of the track's rows on nobody, and for the localised and
duplicate rows the box against the person's (height and width ratios, top and bottom offsets in
the person's heights) and the person's visibility. Then the HOTA of the same rows with each class
dropped (an oracle bound, scored like the grid).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections import Counter, defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402
from id_errors import run_rows  # noqa: E402

Boxes = npt.NDArray[np.float64]
# MOTChallenge class ids: pedestrian, and the distractors trackeval removes rows on.
PEDESTRIAN = 1
DISTRACTORS = (2, 7, 8, 12)
MOT20_DISTRACTORS = (6,)
CLASSES = ("coasted", "distractor", "duplicate", "localised", "unscored", "clutter")
# IoU with a scored person below which a row is not taken for that person at all.
NEAR_IOU = 0.2


def load_full_gt(seq_dir: Path) -> dict[int, npt.NDArray[np.float64]]:
    """Per frame: every gt row ``id, x1, y1, x2, y2, flag, class, visibility`` (MOT15 gt: class
    1, visibility 1)."""
    from densepeds.motio import read_gt

    gt = read_gt(seq_dir / "gt" / "gt.txt")
    if gt.shape[1] >= 9 and np.all(np.isin(gt[:, 7], np.arange(1, 14))):
        cls, vis = gt[:, 7], gt[:, 8]
    else:
        cls, vis = np.full(len(gt), PEDESTRIAN), np.ones(len(gt))
    boxes = np.c_[gt[:, 2:4], gt[:, 2:4] + gt[:, 4:6]]
    table = np.c_[gt[:, 1], boxes, gt[:, 6], cls, vis]
    return {int(f): table[gt[:, 0] == f] for f in np.unique(gt[:, 0])}


def classify(
    rows: npt.NDArray[np.float64], gt: dict[int, npt.NDArray[np.float64]], mot20: bool
) -> tuple[list[str], npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """Per row: its class (``person`` for a row on a scored person, else one of CLASSES), the gt
    row index in its frame it is nearest to (-1 none) and that IoU with the nearest scored
    person."""
    from densepeds.boxes import iou_matrix, match_boxes

    distract = DISTRACTORS + (MOT20_DISTRACTORS if mot20 else ())
    kind = ["clutter"] * len(rows)
    near = np.full(len(rows), -1, np.int64)
    best = np.zeros(len(rows))
    for f in np.unique(rows[:, 0]).astype(int):
        ks = np.flatnonzero(rows[:, 0] == f)
        g = gt.get(f, np.zeros((0, 8)))
        scored = (g[:, 6] == PEDESTRIAN) & (g[:, 5] != 0)
        r, c = match_boxes(rows[ks, 2:6], g[:, 1:5], 0.5)
        on = dict(zip(ks[r].tolist(), c.tolist(), strict=True))
        held = {c for c in on.values() if scored[c]}
        iou = iou_matrix(rows[ks, 2:6], g[:, 1:5])
        iou_scored = np.where(scored[None, :], iou, 0.0)
        for i, k in enumerate(ks):
            if k in on and scored[on[k]]:
                kind[k], near[k], best[k] = "person", on[k], iou[i, on[k]]
                continue
            j = int(np.argmax(iou_scored[i])) if g.size else -1
            best[k] = iou_scored[i, j] if j >= 0 else 0.0
            near[k] = j if best[k] > 0 else -1
            if rows[k, 7] == 0:
                kind[k] = "coasted"
            elif k in on and g[on[k], 6] in distract:
                kind[k], near[k] = "distractor", on[k]
            elif best[k] >= NEAR_IOU and j in held:
                kind[k] = "duplicate"
            elif best[k] >= NEAR_IOU:
                kind[k] = "localised"
            elif k in on:
                kind[k], near[k] = "unscored", on[k]
    return kind, near, best


def track_history(rows: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.int64], ...]:
    """Per row: the track's age (frames since its first reported row, plus the birth frame) and
    hits (its matched rows until this one, plus the birth detection)."""
    age = np.zeros(len(rows), np.int64)
    hits = np.zeros(len(rows), np.int64)
    for i in np.unique(rows[:, 1]):
        ks = np.flatnonzero(rows[:, 1] == i)
        ks = ks[np.argsort(rows[ks, 0], kind="stable")]
        age[ks] = rows[ks, 0] - rows[ks[0], 0] + 2
        hits[ks] = np.cumsum(rows[ks, 7] > 0) + 1
    return age, hits


def _q(x: Sequence[float] | npt.NDArray[np.float64]) -> str:
    a = np.asarray(x, np.float64)
    a = a[np.isfinite(a)]
    if not len(a):
        return "-"
    lo, mid, hi = np.percentile(a, [25, 50, 75])
    return f"{mid:.2f} ({lo:.2f}-{hi:.2f})"


def report(cell: grid.Cell, params: dict[str, Any], cache: Path) -> None:
    data = grid.load_cell(cell, cache, quiet=True)
    config = grid.Config(params=params)
    rows = grid.track_cell(data, config)
    # The tracker's own record of which detection each row took (for its score).
    again = run_rows(data, params)
    if not np.array_equal(again[:, :6], rows[:, :6]):
        sys.exit(f"{cell.name}: the two runs differ")
    det_index = again[:, 6].astype(int)
    gt = load_full_gt(data.seq_dir)
    from densepeds.evaluate import detect_benchmark
    from densepeds.motio import read_gt

    mot20 = detect_benchmark(data.seq_dir.name, read_gt(data.seq_dir / "gt" / "gt.txt")) == "MOT20"
    kind, near, best = classify(rows, gt, mot20)
    kinds = np.array(kind)
    age, hits = track_history(rows)
    scores = np.array(
        [
            float(np.asarray(data.dets[int(r[0]) - 1].scores)[j]) if j >= 0 else np.nan
            for r, j in zip(rows, det_index, strict=True)
        ]
    )
    nobody = kinds != "person"
    share = np.zeros(len(rows))
    for i in np.unique(rows[:, 1]):
        m = rows[:, 1] == i
        share[m] = nobody[m].mean()
    p = dict(grid._pipeline(data, config).params)
    print(
        f"\n## {cell.name}: {len(rows)} rows, {int(np.sum(~nobody))} on a scored person, "
        f"{int(nobody.sum())} on nobody (det_threshold {p['det_threshold']}, "
        f"low_threshold {p['low_threshold']})"
    )
    print(
        "\n| class | rows | score | weak (< det_threshold) | age | hits | track's rows on nobody |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for k in CLASSES:
        m = kinds == k
        weak = np.mean(scores[m] < p["det_threshold"]) if m.any() and k != "coasted" else np.nan
        print(
            f"| {k} | {int(m.sum())} | {_q(scores[m])} | "
            f"{'-' if np.isnan(weak) else f'{weak:.0%}'} | {_q(age[m])} | {_q(hits[m])} | "
            f"{_q(share[m])} |"
        )
    by_track = Counter(int(i) for i in rows[nobody, 1])
    whole = sum(c for i, c in by_track.items() if share[rows[:, 1] == i][0] >= 0.8)
    print(
        f"\nrows on nobody in tracks with >= 80% of their rows on nobody: {whole}; "
        f"tracks holding rows on nobody: {len(by_track)}"
    )

    print(
        "\n| class | rows | IoU | height / person's | width / person's | top offset | "
        "bottom offset | person's visibility |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for k in ("duplicate", "localised", "person"):
        ks = np.flatnonzero(kinds == k)
        if not len(ks):
            continue
        geo = defaultdict(list)
        for i in ks:
            g = gt[int(rows[i, 0])][near[i]]
            b, pb = rows[i, 2:6], g[1:5]
            h, w = pb[3] - pb[1], pb[2] - pb[0]
            geo["h"].append((b[3] - b[1]) / h)
            geo["w"].append((b[2] - b[0]) / w)
            geo["top"].append((b[1] - pb[1]) / h)
            geo["bottom"].append((b[3] - pb[3]) / h)
            geo["vis"].append(g[7])
        print(
            f"| {k} | {len(ks)} | {_q(best[ks])} | {_q(geo['h'])} | {_q(geo['w'])} | "
            f"{_q(geo['top'])} | {_q(geo['bottom'])} | {_q(geo['vis'])} |"
        )
    dup = np.flatnonzero(kinds == "duplicate")
    if len(dup):
        younger = 0
        for i in dup:
            f = rows[:, 0] == rows[i, 0]
            other = np.flatnonzero(f & (kinds == "person"))
            holder = [o for o in other if near[o] == near[i]]
            if holder and age[holder[0]] > age[i]:
                younger += 1
        print(f"\nduplicate rows whose track is younger than the holder's: {younger}")

    print(
        "\n| rows (the same boxes) | HOTA | DetA | AssA | IDF1 | FP | HOTA, each row on a "
        "person under its id |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    variants: list[tuple[str, npt.NDArray[np.bool_]]] = [("as output", np.ones(len(rows), bool))]
    variants.append(("without distractor (scorer removes them)", kinds != "distractor"))
    for k in CLASSES:
        if k != "distractor" and (kinds == k).any():
            variants.append((f"without {k}", kinds != k))
    variants.append(("without all rows on nobody", ~nobody))
    perfect = rows.copy()
    on = ~nobody
    past = int(rows[:, 1].max(initial=0)) + 1
    gt_ids = np.array(
        [gt[int(r[0])][j, 0] if j >= 0 else -1 for r, j in zip(rows, near, strict=True)]
    )
    perfect[on, 1] = gt_ids[on] + past
    with tempfile.TemporaryDirectory() as tmp:
        for what, keep in variants:
            m = grid.score_cell(data, rows[keep], Path(tmp))
            ideal = grid.score_cell(data, perfect[keep], Path(tmp))
            print(
                f"| {what} | "
                + " | ".join(f"{m[k]:.2f}" for k in ("HOTA", "DetA", "AssA", "IDF1"))
                + f" | {m['FP']:.0f} | {ideal['HOTA']:.2f} |"
            )


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cells", nargs="+", default=["MOT20-01-dev/float", "PETS09-S2L1-dev/float"])
    ap.add_argument("--param", nargs="*", default=[], help="K=V tracker parameters")
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    args = ap.parse_args(argv)
    params = grid.parse_params(args.param)
    for cell in grid.select_cells(args.cells):
        report(cell, params, args.cache)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
