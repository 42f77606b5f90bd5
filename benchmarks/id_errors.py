"""Where the tracker's identities break: every change of id on a ground-truth person, classified.

    python benchmarks/id_errors.py            # MOT20-01-dev/float and PETS09-S2L1-dev/float
    python benchmarks/id_errors.py --cells 'MOT20*/float' --param appearance_threshold=0.3

Each cell is tracked as ``benchmarks/accuracy_grid.py`` tracks it (package defaults plus
``--param``), and a second time with every live confirmed track reported (``output_lost`` huge,
``coast_min_hits`` 0, ``output_lost_adaptive`` off: reporting only, the associations are the
same, which the script checks), so that a lost track's prediction is known in every frame.
Output rows are labelled with the ground-truth person they cover (IoU >= 0.5, one-to-one per
frame, ``densepeds.boxes.match_boxes``). For each person, its rows in frame order give a run of
predicted ids; each change of id is one event, classified by the history of the id that takes
over:

- ``new``: fragmentation, a track born on the person (its earlier matched rows, if any, cover
  no other person). Detailed at the new track's first detection (the frame before its first
  reported row): frames since the old id was last matched, whether the old track was alive,
  matched elsewhere or deleted, its predicted box's IoU with and centre distance to the new
  detection (in box heights), the new detection's cosine distance to the old track's gallery
  (rebuilt from its matched embeddings as the tracker summarises them) and to the nearest other
  lost track's, and why the old track did not take the detection;
- ``switch``: a track matched in the previous frame on another person jumped to this one;
- ``coast``: a track that was lost (unmatched) after another person took this one over.
  Both are detailed by the person's visibility and neighbours (people within one box height),
  the overlap of the taking track's last matched box with its new one, whether its matched
  detections changed person (a detection switch) or only its reported box did, and the taken
  detection's cosine distance to the taking track's gallery and to the person's earlier id's;
- ``back``: the person's earlier id came back (the run in between was another id's).

Rows lost: the person's rows not under its most frequent id (what IDF1 counts), each run
attributed to the event that began it (the first run to the event that ended it).

Bounds on the same boxes (scored like the grid): the rows as output; every row on a person given
that person's id (association made perfect, the boxes unchanged); and that with the rows on
nobody dropped as well (no false positives either). What stays between the last and 100 is the
boxes: people never output, and localisation.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402
from coast_errors import load_gt  # noqa: E402

Boxes = npt.NDArray[np.float64]
# Reporting-only settings that make every live confirmed track appear in the output.
REPORT_ALL = {"output_lost": 10**6, "coast_min_hits": 0, "output_lost_adaptive": False}
# Embeddings per gallery row and rows kept, as crates/assoc/src/track.rs summarises a gallery.
GALLERY_ROWS = 8
BOUND_METRICS = ("HOTA", "DetA", "AssA", "IDF1")


@dataclass
class Track:
    """One id's rows: frame -> (box, detection index or -1)."""

    rows: dict[int, tuple[Boxes, int]] = field(default_factory=dict)
    person: dict[int, int] = field(default_factory=dict)  # frame -> gt id of a matched row


@dataclass
class Event:
    person: int
    frame: int  # first frame under the new id
    old: int
    new: int
    kind: str
    rows_lost: int = 0
    info: dict[str, Any] = field(default_factory=dict)


def run_rows(data: grid.CellData, params: dict[str, Any]) -> npt.NDArray[np.float64]:
    """Rows ``frame, id, x1, y1, x2, y2, det_index`` (-1 unmatched), tracked as accuracy_grid
    tracks a cell."""
    config = grid.Config(params=params)
    kind = config.kind() if data.cell.full_pipeline else "none"
    pipe = grid.cell_pipeline(data, config)
    pipe.set_image_size(*data.size)
    out = []
    for k, dets in enumerate(data.dets):
        emb = None if kind == "none" else data.embeddings[kind][k]
        t = pipe.step(None, dets, embeddings=emb)
        for i in range(len(t.ids)):
            out.append([k + 1, t.ids[i], *t.boxes[i], t.det_index[i]])
    return np.array(out, dtype=np.float64).reshape(-1, 7)


def label(rows: npt.NDArray[np.float64], gt: dict[Any, Any]) -> npt.NDArray[np.int64]:
    """The gt id each row covers (IoU >= 0.5, one-to-one per frame), -1 for none."""
    from densepeds.boxes import match_boxes

    out = np.full(len(rows), -1, np.int64)
    for f in np.unique(rows[:, 0]).astype(int):
        if f not in gt:
            continue
        ks = np.flatnonzero(rows[:, 0] == f)
        ids, boxes, _ = gt[f]
        r, c = match_boxes(rows[ks, 2:6], boxes, 0.5)
        out[ks[r]] = ids[c]
    return out


def relabelled(
    rows: npt.NDArray[np.float64], people: npt.NDArray[np.int64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The rows (``frame, id, x1, y1, x2, y2, score``) with every row on a person under that
    person's id (rows on nobody keep their track's id, moved past every person's), and the same
    without the rows on nobody."""
    out = np.c_[rows[:, :6], np.ones(len(rows))]
    on = people >= 0
    past = int(people.max(initial=0)) + 1
    out[on, 1] = people[on]
    out[~on, 1] = rows[~on, 1] + past
    return out, out[on]


def tracks_of(rows: npt.NDArray[np.float64], people: npt.NDArray[np.int64]) -> dict[int, Track]:
    tracks: dict[int, Track] = defaultdict(Track)
    for r, p in zip(rows, people, strict=True):
        t = tracks[int(r[1])]
        t.rows[int(r[0])] = (r[2:6], int(r[6]))
        if r[6] >= 0 and p >= 0:
            t.person[int(r[0])] = int(p)
    return tracks


def gallery(emb: list[npt.NDArray[np.float32]], t: Track, before: int, capacity: int) -> Boxes:
    """The track's gallery rows at frame ``before`` (its matched embeddings until then, in blocks
    of ``ceil(capacity / 8)``, the last 8 block means, normalised)."""
    vs = [emb[f - 1][j] for f, (_, j) in sorted(t.rows.items()) if f < before and j >= 0]
    if not vs:
        return np.zeros((0, 1))
    block = -(-capacity // GALLERY_ROWS)
    keep = -(-capacity // block)
    blocks = [np.sum(vs[i : i + block], axis=0) for i in range(0, len(vs), block)][-keep:]
    g = np.array(blocks, dtype=np.float64)
    return g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-12)


def cos_dist(g: Boxes, e: npt.NDArray[np.float32]) -> float:
    if len(g) == 0:
        return float("nan")
    u = np.asarray(e, np.float64)
    u = u / max(float(np.linalg.norm(u)), 1e-12)
    return float(max(0.0, 1.0 - np.max(g @ u)))


def _centre(b: Boxes) -> Boxes:
    return np.array([(b[0] + b[2]) / 2, (b[1] + b[3]) / 2])


def _iou(a: Boxes, b: Boxes) -> float:
    from densepeds.boxes import iou_matrix

    return float(iou_matrix(a[None], b[None])[0, 0])


def events_of(
    rows: npt.NDArray[np.float64], people: npt.NDArray[np.int64], tracks: dict[int, Track]
) -> list[Event]:
    """Every change of id on a person, classified, with the rows it cost."""
    by_person: dict[int, list[tuple[int, int]]] = defaultdict(list)
    for r, p in zip(rows, people, strict=True):
        if p >= 0:
            by_person[int(p)].append((int(r[0]), int(r[1])))
    events: list[Event] = []
    for person, seq in by_person.items():
        seq.sort()
        runs: list[list[tuple[int, int]]] = []
        for f, i in seq:
            if runs and runs[-1][-1][1] == i:
                runs[-1].append((f, i))
            else:
                runs.append([(f, i)])
        dominant = Counter(i for _, i in seq).most_common(1)[0][0]
        mine: list[Event] = []
        for a, b in zip(runs, runs[1:], strict=False):
            old, new, f2 = a[-1][1], b[0][1], b[0][0]
            before = {f: q for f, q in tracks[new].person.items() if f < f2}
            if not before or all(q == person for q in before.values()):
                kind = "back" if before or any(i == new for _, i in seq if _ < f2) else "new"
            elif before[max(before)] == person:
                kind = "back"
            else:
                last = max(f for f, (_, j) in tracks[new].rows.items() if f < f2 and j >= 0)
                kind = "switch" if last == f2 - 1 else "coast"
            mine.append(Event(person, f2, old, new, kind))
        for k, run in enumerate(runs):
            if run[0][1] == dominant or not mine:
                continue
            ev = mine[k - 1] if k > 0 else mine[0]
            ev.rows_lost += len(run)
        events += mine
    return events


def detail_new(
    ev: Event,
    tracks: dict[int, Track],
    data: grid.CellData,
    emb: list[npt.NDArray[np.float32]] | None,
    params: dict[str, Any],
) -> None:
    """Fills ``ev.info`` for a fragmentation: the old track at the new track's first detection."""
    new, old = tracks[ev.new], tracks[ev.old]
    b0 = min(new.rows)
    fb = b0 - 1  # the birth frame (n_init 2, a tentative track ends at its first miss)
    dets = data.dets[fb - 1] if fb >= 1 else None
    box0 = new.rows[b0][0]
    if dets is None or len(dets.boxes) == 0:
        return
    from densepeds.boxes import iou_matrix

    ious = iou_matrix(np.asarray(dets.boxes), box0[None])[:, 0]
    j = int(np.argmax(ious))
    det = np.asarray(dets.boxes)[j]
    h = det[3] - det[1]
    last_match = max((f for f, (_, d) in old.rows.items() if f < fb and d >= 0), default=-1)
    info: dict[str, Any] = {"gap": fb - last_match, "score": float(np.asarray(dets.scores)[j])}
    if fb in old.rows:
        pbox, pj = old.rows[fb]
        info["old"] = "matched elsewhere" if pj >= 0 else "lost"
        info["iou"] = _iou(pbox, det)
        info["dist"] = float(np.linalg.norm(_centre(pbox) - _centre(det)) / h)
    else:
        info["old"] = "deleted"
    if emb is not None:
        e = emb[fb - 1][j]
        cap = int(params["gallery_size"])
        info["app"] = cos_dist(gallery(emb, old, fb, cap), e)
        others = [
            cos_dist(gallery(emb, t, fb, cap), e)
            for tid, t in tracks.items()
            if tid not in (ev.old, ev.new) and fb in t.rows and t.rows[fb][1] < 0
        ]
        info["app_other"] = min(others, default=float("nan"))
    ev.info = info


def why(info: dict[str, Any], p: dict[str, Any]) -> str:
    """Why the old track did not take the new track's first detection."""
    if "old" not in info:
        return "no detection"
    if info["old"] != "lost":
        return info["old"]
    app, iou = info.get("app", float("nan")), info["iou"]
    if info["dist"] > p["gate_radius"]:
        return "outside the gate (gate_radius box heights)"
    limit = (
        p["appearance_threshold"]
        if iou > 0
        else min(p["appearance_threshold"], p["appearance_apart"])
    )
    if app <= limit:
        return "appearance within limit (lost the assignment)"
    if iou >= p["iou_threshold"]:
        return "overlaps the prediction (lost the assignment)"
    return "unlike and off the prediction"


def label_dets(boxes: Any, g: Any) -> npt.NDArray[np.int64]:
    """The gt id each detection covers (IoU >= 0.5, one-to-one), -1 for none."""
    from densepeds.boxes import match_boxes

    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    out = np.full(len(b), -1, np.int64)
    if g is not None and len(b):
        r, c = match_boxes(b, g[1], 0.5)
        out[r] = g[0][c]
    return out


def detail_switch(
    ev: Event,
    tracks: dict[int, Track],
    det_people: list[npt.NDArray[np.int64]],
    gt: dict[Any, Any],
    emb: list[npt.NDArray[np.float32]] | None,
    capacity: int,
) -> None:
    """Fills ``ev.info`` for an id that took over a person: whether the detections it matched
    changed person (a real switch) or only its reported box moved onto another person."""
    t = tracks[ev.new]
    ids, boxes, v = gt[ev.frame]
    me = boxes[ids == ev.person][0]
    h = me[3] - me[1]
    near = np.hypot(*(_centre(boxes.T) - _centre(me)[:, None])) <= h
    info: dict[str, Any] = {"vis": float(v[ids == ev.person][0]), "neighbours": int(near.sum()) - 1}
    f2 = ev.frame
    prev = [f for f, (_, j) in t.rows.items() if f < f2 and j >= 0]
    j2 = t.rows[f2][1] if f2 in t.rows else -1
    info["gap"] = f2 - max(prev) if prev else -1
    if j2 < 0 or not prev:
        info["how"] = "reported box moved (unmatched)"
    else:
        fp = max(prev)
        was = det_people[fp - 1][t.rows[fp][1]]
        now = det_people[f2 - 1][j2]
        if now == ev.person and was >= 0 and was != ev.person:
            gone = was not in det_people[f2 - 1]
            info["how"] = "detection switch" + (
                " (own person undetected)" if gone else " (own person detected)"
            )
        elif now != ev.person:
            info["how"] = "reported box moved (detection not on the person)"
        else:
            info["how"] = "from an unlabelled detection"
        # The overlap term: the taking track's last matched box against the taken detection.
        info["iou"] = _iou(t.rows[fp][0], t.rows[f2][0])
        if emb is not None:
            e = emb[f2 - 1][j2]
            info["app_new"] = cos_dist(gallery(emb, t, f2, capacity), e)
            info["app_old"] = cos_dist(gallery(emb, tracks[ev.old], f2, capacity), e)
    ev.info = info


def _median(x: Sequence[float]) -> float:
    a = np.asarray(x, np.float64)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if len(a) else float("nan")


def rows_by_owner(
    rows: npt.NDArray[np.float64], people: npt.NDArray[np.int64]
) -> Counter[tuple[str, str]]:
    """The rows on a person not under its most frequent id, by whose track holds them: a
    fragment (another track whose own most frequent person is this one), another person's track,
    or a mixed track (no person holds half its rows); and whether the row was matched or coasted."""
    ids = rows[:, 1].astype(int)
    on = people >= 0
    dominant_id = {
        int(q): Counter(ids[people == q].tolist()).most_common(1)[0][0]
        for q in np.unique(people[on])
    }
    owner: dict[int, int] = {}
    for i in np.unique(ids):
        mine = people[(ids == i) & on]
        q, c = Counter(mine.tolist()).most_common(1)[0] if len(mine) else (-1, 0)
        owner[int(i)] = q if 2 * c >= np.sum(ids == i) else -1
    out: Counter[tuple[str, str]] = Counter()
    for k in np.flatnonzero(on):
        q, i = int(people[k]), int(ids[k])
        if dominant_id[q] == i:
            continue
        who = "fragment" if owner[i] == q else "mixed" if owner[i] < 0 else "another person's"
        out[(who, "matched" if rows[k, 6] >= 0 else "coasted")] += 1
    return out


def newborn_candidates(
    tracks: dict[int, Track],
    people_of: dict[int, int],
    emb: list[npt.NDArray[np.float32]],
    hits: int,
    capacity: int,
) -> list[tuple[float, float, bool, int]]:
    """For every track with at least ``hits`` matches, born after the first frame: the cosine
    distance of the mean of its first ``hits`` embeddings to the nearest gallery among the tracks
    lost since before its birth and still alive then, the margin to the second nearest, whether
    the nearest is the same person (most frequent gt id of the matched rows), and the newborn's
    rows on that person."""
    out = []
    for b, tb in tracks.items():
        fs = sorted(f for f, (_, j) in tb.rows.items() if j >= 0)
        born = min(tb.rows) - 1  # the first reported row is the second match (n_init 2)
        if len(fs) < hits or born <= 1:
            continue
        fk = fs[hits - 1]
        v = np.sum([emb[f - 1][tb.rows[f][1]] for f in fs[:hits]], axis=0)
        dists = []
        for a, ta in tracks.items():
            if a == b or fk not in ta.rows or ta.rows[fk][1] >= 0:
                continue
            last = max((f for f, (_, j) in ta.rows.items() if j >= 0 and f <= fk), default=-1)
            if 0 <= last < born:
                dists.append((cos_dist(gallery(emb, ta, last + 1, capacity), v), a))
        if not dists:
            continue
        dists.sort()
        d, a = dists[0]
        second = dists[1][0] if len(dists) > 1 else float("inf")
        same = people_of.get(a, -1) == people_of.get(b, -2)
        out.append((d, second - d, same, len(tb.person)))
    return out


def report(cell: grid.Cell, params: dict[str, Any], cache: Path, hits: int) -> None:
    data = grid.load_cell(cell, cache, quiet=True)
    gt = load_gt(data.seq_dir)
    rows = run_rows(data, params)
    every = run_rows(data, {**params, **REPORT_ALL})
    matched = {(int(r[0]), int(r[1]), int(r[6])) for r in rows if r[6] >= 0}
    matched_all = {(int(r[0]), int(r[1]), int(r[6])) for r in every if r[6] >= 0}
    if matched != matched_all:
        sys.exit(f"{cell.name}: reporting every track changed the associations")
    kind = grid.Config(params=params).kind()
    emb = data.embeddings.get(kind) if data.cell.full_pipeline else None
    p = dict(grid.cell_pipeline(data, grid.Config(params=params)).params)
    people = label(rows, gt)
    tracks = tracks_of(every, label(every, gt))
    events = events_of(rows, people, tracks)
    n_rows = int(np.sum(people >= 0))
    print(f"\n## {cell.name}: {len(rows)} rows, {n_rows} on a person, {len(events)} changes of id")
    print("\n| class | events | rows lost |")
    print("|---|---:|---:|")
    for k in ("new", "switch", "coast", "back"):
        ev = [e for e in events if e.kind == k]
        print(f"| {k} | {len(ev)} | {sum(e.rows_lost for e in ev)} |")

    print("\n| rows (the same boxes) | HOTA | DetA | AssA | IDF1 |")
    print("|---|---:|---:|---:|---:|")
    perfect, no_fp = relabelled(rows, people)
    as_output = np.c_[rows[:, :6], np.ones(len(rows))]
    with tempfile.TemporaryDirectory() as tmp:
        for what, r in (
            ("as output", as_output),
            ("each on a person under its id", perfect),
            ("and none on nobody", no_fp),
        ):
            m = grid.score_cell(data, r, Path(tmp))
            print(f"| {what} | " + " | ".join(f"{m[k]:.2f}" for k in BOUND_METRICS) + " |")

    owners = rows_by_owner(rows, people)
    print(f"\nrows on a person not under its most frequent id: {sum(owners.values())}")
    print("| held by | matched | coasted |")
    print("|---|---:|---:|")
    for who in ("fragment", "another person's", "mixed"):
        print(f"| {who} track | {owners[(who, 'matched')]} | {owners[(who, 'coasted')]} |")

    frag = [e for e in events if e.kind == "new"]
    for e in frag:
        detail_new(e, tracks, data, emb, p)
    reasons: Counter[str] = Counter()
    lost: Counter[str] = Counter()
    for e in frag:
        reasons[why(e.info, p)] += 1
        lost[why(e.info, p)] += e.rows_lost
    print("\nnew: why the old track did not take the new track's first detection")
    for r, c in reasons.most_common():
        print(f"  {r}: {c} events, {lost[r]} rows lost")
    live = [e for e in frag if e.info.get("old") == "lost"]
    if live:
        gaps = [e.info["gap"] for e in live]
        app = np.array([e.info.get("app", np.nan) for e in live])
        other = np.array([e.info.get("app_other", np.nan) for e in live])
        print(
            f"  old track lost and alive: {len(live)}; frames since its last match median "
            f"{_median(gaps):.0f}; its prediction to the new detection: IoU median "
            f"{_median([e.info['iou'] for e in live]):.2f}, centre distance median "
            f"{_median([e.info['dist'] for e in live]):.2f} box heights"
        )
        if np.isfinite(app).any():
            nearer = np.mean(app < np.nan_to_num(other, nan=np.inf))
            print(
                f"  cosine distance to the old gallery median {_median(app):.3f} "
                f"(<= appearance_threshold {p['appearance_threshold']}: "
                f"{np.mean(app <= p['appearance_threshold']):.0%}); to the nearest other lost "
                f"track's median {_median(other):.3f}; the old track the nearer: {nearer:.0%}"
            )

    det_people = [label_dets(d.boxes, gt.get(k + 1)) for k, d in enumerate(data.dets)]
    for k in ("switch", "coast"):
        ev = [e for e in events if e.kind == k]
        if not ev:
            continue
        for e in ev:
            detail_switch(e, tracks, det_people, gt, emb, int(p["gallery_size"]))
        moved = _median([e.info.get("iou", np.nan) for e in ev])
        print(
            f"\n{k}: the person taken over: visibility median "
            f"{_median([e.info['vis'] for e in ev]):.2f}, people within one box height median "
            f"{_median([e.info['neighbours'] for e in ev]):.0f}; the taking track's last matched "
            f"box against its new box: IoU median {moved:.2f}"
        )
        for h, c in Counter(e.info["how"] for e in ev).most_common():
            sel = [e for e in ev if e.info["how"] == h]
            print(
                f"  {h}: {c} events, {sum(e.rows_lost for e in sel)} rows lost; frames since the "
                f"taking track's last match median {_median([e.info['gap'] for e in sel]):.0f}; "
                "cosine distance of the detection to its gallery median "
                f"{_median([e.info.get('app_new', np.nan) for e in sel]):.3f}, to the person's "
                f"earlier id's {_median([e.info.get('app_old', np.nan) for e in sel]):.3f}"
            )

    if emb is None:
        return
    people_of = {
        i: Counter(t.person.values()).most_common(1)[0][0] for i, t in tracks.items() if t.person
    }
    cands = newborn_candidates(tracks, people_of, emb, hits, int(p["gallery_size"]))
    print(
        f"\nnewborn tracks against the tracks lost before their birth (mean of the first {hits} "
        f"embeddings): {len(cands)} with a lost track alive, the nearest the same person in "
        f"{sum(c[2] for c in cands)}"
    )
    print("| distance <= | margin >= | nearest | of them right | rows right | rows wrong |")
    print("|---:|---:|---:|---:|---:|---:|")
    for d_max in (0.15, 0.2, 0.25):
        for margin in (0.0, 0.05, 0.1):
            sel = [c for c in cands if c[0] <= d_max and c[1] >= margin]
            right = [c for c in sel if c[2]]
            print(
                f"| {d_max} | {margin} | {len(sel)} | {len(right)} | "
                f"{sum(c[3] for c in right)} | {sum(c[3] for c in sel if not c[2])} |"
            )


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cells", nargs="+", default=["MOT20-01-dev/float", "PETS09-S2L1-dev/float"])
    ap.add_argument("--param", nargs="*", default=[], help="K=V tracker parameters")
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    ap.add_argument(
        "--hits", type=int, default=3, help="embeddings of a newborn track compared (default 3)"
    )
    args = ap.parse_args(argv)
    params = grid.parse_params(args.param)
    for cell in grid.select_cells(args.cells):
        report(cell, params, args.cache, args.hits)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
