"""Where the tracker's coasted boxes (lost tracks reported at their prediction) go wrong.

    python benchmarks/coast_errors.py             # MOT20-01-dev/float and PETS09-S2L1-dev/float
    python benchmarks/coast_errors.py --cells 'MOT20*/float' --param coast_aspect_quantile=0

Each cell is tracked with the package defaults (plus ``--param``) exactly as
``benchmarks/accuracy_grid.py`` tracks it. Every output row matched to a detection is labelled with
a ground-truth person (IoU >= 0.5, one-to-one per frame); a coasted row (no detection this frame)
inherits the person of its track's last matched row. Per frames lost, the script prints how often
the coasted box lands on that person, its centre offset and height error (in the person's box
heights), the person's visibility, and the same figures for boxes computed offline from the
output: the last matched box held still, moved with the track's own velocity, moved with the mean
velocity of the matched neighbours, and moved with the neighbour that covered it. Each alternative
is then substituted for the coasted rows and scored (HOTA), and coasted rows are dropped by
oracle rules (person gone, person hidden) to bound what not reporting them is worth.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections import defaultdict
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402
from accuracy_tables import match_pairs  # noqa: E402

Boxes = npt.NDArray[np.float64]
LOST_BINS = ((1, 1), (2, 3), (4, 5), (6, 10), (11, 10**9))
# Neighbours whose centre lies within this many of the lost track's box heights give the flow.
FLOW_RADIUS = 1.5
# Frames of the track's matched history its own velocity is measured over.
OWN_WINDOW = 5


def _centre(b: Boxes) -> Boxes:
    return np.c_[(b[..., 0] + b[..., 2]) / 2, (b[..., 1] + b[..., 3]) / 2]


def _iou(a: Boxes, b: Boxes) -> float:
    from densepeds.boxes import iou_matrix

    return float(iou_matrix(a, b)[0, 0])


def _shift(b: Boxes, d: Boxes) -> Boxes:
    return np.array([b[0] + d[0], b[1] + d[1], b[2] + d[0], b[3] + d[1]])


def _recentre(size_of: Boxes, c: Boxes) -> Boxes:
    w, h = size_of[2] - size_of[0], size_of[3] - size_of[1]
    return np.array([c[0] - w / 2, c[1] - h / 2, c[0] + w / 2, c[1] + h / 2])


def load_gt(seq_dir: Path) -> dict[int, tuple[npt.NDArray[np.int64], Boxes, Boxes]]:
    """Per frame: pedestrian ids, boxes (x1 y1 x2 y2) and visibility (1 where not annotated)."""
    from densepeds.motio import read_gt

    gt = read_gt(seq_dir / "gt" / "gt.txt")
    mot17 = gt.shape[1] >= 9 and np.all(np.isin(gt[:, 7], np.arange(1, 13)))
    if mot17:
        gt = gt[(gt[:, 7] == 1) & (gt[:, 6] != 0)]
        vis = gt[:, 8]
    else:
        vis = np.ones(len(gt))
    out = {}
    for f in np.unique(gt[:, 0]).astype(int):
        m = gt[:, 0] == f
        g = gt[m]
        out[f] = (g[:, 1].astype(np.int64), np.c_[g[:, 2:4], g[:, 2:4] + g[:, 4:6]], vis[m])
    return out


def alternatives(rows: grid.Rows) -> dict[str, Boxes]:
    """For every row, the box each offline rule would report (the row's own box where matched)."""
    n = len(rows)
    frames = rows[:, 0].astype(int)
    ids = rows[:, 1].astype(int)
    matched = rows[:, 7] > 0
    by_frame: dict[int, npt.NDArray[np.int64]] = defaultdict(lambda: np.zeros(0, np.int64))
    for f in np.unique(frames):
        by_frame[int(f)] = np.flatnonzero(frames == f)
    # Per frame: matched rows' displacement since the previous frame where matched there too.
    disp: dict[int, tuple[Boxes, Boxes]] = {}
    pos: dict[tuple[int, int], int] = {(int(frames[k]), int(ids[k])): k for k in range(n)}
    for f, ks in by_frame.items():
        cs, ds = [], []
        for k in ks:
            prev = pos.get((f - 1, int(ids[k])))
            if matched[k] and prev is not None and matched[prev]:
                cs.append(_centre(rows[k, 2:6][None])[0])
                ds.append(_centre(rows[k, 2:6][None])[0] - _centre(rows[prev, 2:6][None])[0])
        disp[f] = (np.array(cs).reshape(-1, 2), np.array(ds).reshape(-1, 2))

    out = {name: rows[:, 2:6].copy() for name in ("hold", "own", "flow", "cover")}
    track_rows: dict[int, list[int]] = defaultdict(list)
    for k in np.lexsort((frames, ids)):
        track_rows[int(ids[k])].append(int(k))
    for tid, ks in track_rows.items():
        last_match: int | None = None
        cur: dict[str, Boxes] = {}
        cover_id: int | None = None
        for k in ks:
            if matched[k]:
                last_match = k
                continue
            if last_match is None:
                continue
            f = int(frames[k])
            lost = f - int(frames[last_match])
            last_box = rows[last_match, 2:6]
            size = rows[k, 2:6]  # the reported size, so that the alternatives move the centre only
            if lost == 1 or (f - 1, tid) not in pos:
                cur = {name: last_box.copy() for name in out}
                # Own velocity over the last OWN_WINDOW matched frames.
                hist = [j for j in ks if matched[j] and frames[j] <= frames[last_match]]
                hist = [j for j in hist if frames[last_match] - frames[j] <= OWN_WINDOW]
                j0 = hist[0]
                dt = frames[last_match] - frames[j0]
                own_v = (
                    (_centre(last_box[None])[0] - _centre(rows[j0, 2:6][None])[0]) / dt
                    if dt > 0
                    else np.zeros(2)
                )
                # The covering neighbour: the other row at the last matched frame overlapping the
                # last box most, with a lower foot (nearer the camera).
                best, cover_id = 0.0, None
                for j in by_frame[int(frames[last_match])]:
                    if ids[j] == tid or rows[j, 5] <= last_box[3] - 0.05 * (
                        last_box[3] - last_box[1]
                    ):
                        continue
                    o = _iou(last_box, rows[j, 2:6])
                    if o > best:
                        best, cover_id = o, int(ids[j])
            cur["own"] = _shift(cur["own"], own_v)
            cs, ds = disp.get(f, (np.zeros((0, 2)), np.zeros((0, 2))))
            c = _centre(cur["flow"][None])[0]
            h = last_box[3] - last_box[1]
            near = np.hypot(*(cs - c).T) <= FLOW_RADIUS * h if len(cs) else np.zeros(0, bool)
            cur["flow"] = _shift(cur["flow"], ds[near].mean(0) if near.any() else own_v)
            moved = None
            if cover_id is not None:
                a, b = pos.get((f, cover_id)), pos.get((f - 1, cover_id))
                if a is not None and b is not None:
                    moved = _centre(rows[a, 2:6][None])[0] - _centre(rows[b, 2:6][None])[0]
            cur["cover"] = _shift(cur["cover"], moved if moved is not None else own_v)
            for name in out:
                base = last_box if name == "hold" else cur[name]
                out[name][k] = _recentre(size, _centre(base[None])[0])
    return out


def label_rows(
    rows: grid.Rows, gt: dict[int, tuple[npt.NDArray[np.int64], Boxes, Boxes]]
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Per row: the gt person it covers (-1: none) and its track's person (last matched row's)."""
    n = len(rows)
    on = np.full(n, -1, np.int64)
    frames = rows[:, 0].astype(int)
    for f in np.unique(frames):
        ks = np.flatnonzero(frames == f)
        if int(f) not in gt:
            continue
        gid, gb, _ = gt[int(f)]
        for i, j in match_pairs(gb, rows[ks, 2:6]):
            on[ks[j]] = gid[i]
    person = np.full(n, -1, np.int64)
    last: dict[int, int] = {}
    for k in np.lexsort((frames, rows[:, 1])):
        tid = int(rows[k, 1])
        if rows[k, 7] > 0:
            last[tid] = int(on[k])
        person[k] = on[k] if rows[k, 7] > 0 else last.get(tid, -1)
    return on, person


def score(data: grid.CellData, rows: grid.Rows) -> dict[str, float]:
    with tempfile.TemporaryDirectory(prefix="coast-") as tmp:
        return grid.score_cell(data, rows, Path(tmp))


def unlabelled(data: grid.CellData, rows: grid.Rows, person: npt.NDArray[np.int64]) -> None:
    """Coasted rows whose track's last matched box is on no pedestrian: that box's best overlap
    with any ground-truth box (every class), and the coasted box's size against that box."""
    from densepeds.motio import read_gt

    gt = read_gt(data.seq_dir / "gt" / "gt.txt")
    frames = rows[:, 0].astype(int)
    last: dict[int, int] = {}
    best: list[float] = []
    size: list[tuple[float, float]] = []
    for k in np.lexsort((frames, rows[:, 1])):
        tid = int(rows[k, 1])
        if rows[k, 7] > 0:
            last[tid] = int(k)
            continue
        j = last.get(tid)
        if j is None or person[k] >= 0:
            continue
        g = gt[gt[:, 0] == frames[j]]
        if not len(g):
            continue
        boxes = np.c_[g[:, 2:4], g[:, 2:4] + g[:, 4:6]]
        ious = [_iou(rows[j, 2:6], b) for b in boxes]
        i = int(np.argmax(ious))
        best.append(ious[i])
        now = gt[(gt[:, 0] == frames[k]) & (gt[:, 1] == g[i, 1])]
        if 0.3 <= ious[i] < 0.5 and len(now):
            w, h = now[0, 4], now[0, 5]
            size.append(((rows[k, 4] - rows[k, 2]) / w, (rows[k, 5] - rows[k, 3]) / h))
    if not best:
        return
    b = np.array(best)
    bins = " ".join(
        f"{lo}-{hi}: {int(((b >= lo) & (b < hi)).sum())}"
        for lo, hi in ((0, 0.3), (0.3, 0.5), (0.5, 1.01))
    )
    print(f"coasted rows of tracks last matched on no pedestrian: {len(b)}; that box's IoU {bins}")
    if size:
        r = np.median(np.array(size), 0)
        print(f"  at IoU 0.3-0.5, coasted box / the person's: width {r[0]:.2f}, height {r[1]:.2f}")


def _scores(m: dict[str, float]) -> str:
    return f"{m['HOTA']:.2f} / {m['IDF1']:.2f} / {m['MOTA']:.2f}"


def report(data: grid.CellData, rows: grid.Rows) -> None:
    gt = load_gt(data.seq_dir)
    on, person = label_rows(rows, gt)
    coast = np.flatnonzero(rows[:, 7] == 0)
    alts = {"tracker": rows[:, 2:6], **alternatives(rows)}
    frames = rows[:, 0].astype(int)
    # Frames lost per coasted row.
    last: dict[int, int] = {}
    lost = np.zeros(len(rows), int)
    for k in np.lexsort((frames, rows[:, 1])):
        if rows[k, 7] > 0:
            last[int(rows[k, 1])] = frames[k]
        else:
            lost[k] = frames[k] - last.get(int(rows[k, 1]), frames[k])
    print(f"\n## {data.cell.name}: {len(rows)} rows, {len(coast)} coasted")
    # The person's box and visibility for each coasted row.
    gbox = np.full((len(rows), 4), np.nan)
    gvis = np.full(len(rows), np.nan)
    for k in coast:
        f, g = int(frames[k]), person[k]
        if g < 0 or f not in gt:
            continue
        gid, gb, vis = gt[f]
        m = np.flatnonzero(gid == g)
        if len(m):
            gbox[k], gvis[k] = gb[m[0]], vis[m[0]]
    print(
        "lost | rows | no person | person gone | on any gt (tracker) | vis median | "
        + " | ".join(f"{n}: on person, |dc|/h, dh/h" for n in alts)
    )
    for lo, hi in LOST_BINS:
        ks = coast[(lost[coast] >= lo) & (lost[coast] <= hi)]
        if not len(ks):
            continue
        nop = int((person[ks] < 0).sum())
        has = ks[~np.isnan(gvis[ks])]
        gone = int(((person[ks] >= 0) & np.isnan(gvis[ks])).sum())
        parts = []
        for _name, b in alts.items():
            if not len(has):
                parts.append("-")
                continue
            hit = np.mean([_iou(b[k], gbox[k]) >= 0.5 for k in has])
            gh = gbox[has, 3] - gbox[has, 1]
            dc = np.hypot(*(_centre(b[has]) - _centre(gbox[has])).T) / gh
            dh = ((b[has, 3] - b[has, 1]) - gh) / gh
            parts.append(f"{hit:.2f}, {np.median(dc):.2f}, {np.median(dh):+.2f}")
        print(
            f"{lo}-{hi if hi < 10**9 else 'inf'} | {len(ks)} | {nop} | {gone} | "
            f"{np.mean(on[ks] >= 0):.2f} | {np.nanmedian(gvis[ks]) if len(has) else np.nan:.2f} | "
            + " | ".join(parts)
        )
    unlabelled(data, rows, person)
    # Visibility of the person under coasted rows that hit it vs those that miss it.
    has = coast[~np.isnan(gvis[coast])]
    hit = np.array([_iou(rows[k, 2:6], gbox[k]) >= 0.5 for k in has])
    if len(has):
        for lo, hi in ((0, 0.05), (0.05, 0.25), (0.25, 0.5), (0.5, 1.01)):
            m = (gvis[has] >= lo) & (gvis[has] < hi)
            print(
                f"person visibility {lo}-{hi}: {int(m.sum())} coasted rows, "
                f"on the person {hit[m].mean() if m.any() else float('nan'):.2f}, "
                f"on any gt {np.mean(on[has[m]] >= 0) if m.any() else float('nan'):.2f}"
            )
    base = score(data, rows)
    print(f"scores (HOTA / IDF1 / MOTA): tracker {_scores(base)}")
    for name, b in alts.items():
        if name == "tracker":
            continue
        r = rows.copy()
        r[coast, 2:6] = b[coast]
        s = score(data, r)
        print(f"  substituted {name}: {_scores(s)}")
    drops: dict[str, Callable[[int], bool]] = {
        "no coasted rows": lambda k: True,
        "person gone": lambda k: person[k] >= 0 and np.isnan(gvis[k]),
        "person vis < 0.05": lambda k: gvis[k] < 0.05,
        "person vis < 0.15": lambda k: gvis[k] < 0.15,
        "rows on no gt (oracle FP)": lambda k: on[k] < 0,
    }
    for name, rule in drops.items():
        keep = np.ones(len(rows), bool)
        keep[[k for k in coast if rule(k)]] = False
        s = score(data, rows[keep])
        print(f"  dropped {name} ({int((~keep).sum())}): {_scores(s)}")


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", nargs="*", default=["MOT20-01-dev/float", "PETS09-S2L1-dev/float"])
    ap.add_argument("--param", action="append", default=[], metavar="K=V")
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    args = ap.parse_args(argv)
    config = grid.Config(params=grid.parse_params(args.param))
    for cell in grid.select_cells(args.cells):
        data = grid.load_cell(cell, args.cache, quiet=True)
        report(data, grid.track_cell(data, config))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
