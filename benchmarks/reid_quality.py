"""How well the re-ID embeddings tell a person from the people near them, on both videos' gt.

    OPENBLAS_NUM_THREADS=1 python benchmarks/reid_quality.py \
        --write benchmarks/results/reid-quality.md

The detections and embeddings are those the tracker gets on the float video cells (the shared
segmenter's float copy, cached by ``benchmarks/realvideo.py`` in ``out/cache``). Each frame's
detections are matched one-to-one to the ground truth (IoU >= 0.5, Hungarian); the rest are left
out. For a gap of ``k`` frames, every person matched in frames ``t`` and ``t + k`` gives a probe
(their embedding at ``t + k``), its *positive* (their own embedding at ``t``) and its *nearby
negatives*: the other people matched at ``t`` whose box centre lies within ``NEAR`` of the
person's box heights of theirs at ``t`` (the people a tracker can confuse them with). Columns:

- ``AUC``: the probability that a probe's nearby negative is farther from it (cosine distance)
  than its positive, over all (probe, nearby negative) pairs of the video and gap (ties count
  half);
- ``wrong``: of the probes with at least one nearby negative, the share whose nearest
  embedding at ``t`` is a nearby other person, not themselves;
- ``wrong (gallery)``: the same with each person at ``t`` represented by their embeddings in
  frames ``t - GALLERY + 1 .. t`` and the distance to the nearest of them (as the tracker's
  gallery does).

Lower ``wrong`` and higher ``AUC`` are better. Where the gt has a visibility column (MOT20) the
measures are also given with the probes cut by their visibility at ``t + k``. Kinds are those
of ``realvideo.kind_options`` (a feature kind with optional ``+flip`` / ``+ctxF``).

``--time N`` also times each kind's ``ReID.embed`` (the call ``densepeds run`` makes) on the
first N frames of each video, the kinds interleaved frame by frame, and prints the machine's
load. ``--track`` also tracks each kind on the four video cells (``accuracy_grid.py --cells
'*/float' '*/int8' --features KIND``) and gives their HOTA at the package defaults and averaged
over nearby appearance thresholds (``THRESHOLDS``).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import realvideo  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
GAPS = (1, 10, 30)
NEAR = 1.5  # nearby: box centres within this many of the person's box heights
GALLERY = 10  # frames of a person's past embeddings in the gallery measure
MIN_IOU = 0.5
SOURCE = {"quantized": False}  # the float video cells' detections
KINDS = ("segmented", "bbox", "masked_pool")
COMMAND = (
    "OPENBLAS_NUM_THREADS=1 python benchmarks/reid_quality.py "
    "--write benchmarks/results/reid-quality.md"
)


@dataclass
class Matched:
    """Per frame: gt ids, box centres and heights, and row indices into the frame's detections;
    the gt's visibility where it has one (MOT17/20 layout)."""

    ids: list[npt.NDArray[np.int64]]
    centres: list[npt.NDArray[np.float64]]
    heights: list[npt.NDArray[np.float64]]
    rows: list[npt.NDArray[np.intp]]
    visibility: list[npt.NDArray[np.float64]] | None = None


def match_gt(video: realvideo.CachedVideo) -> Matched:
    """Each frame's detections matched to its ground-truth people (IoU >= MIN_IOU)."""
    from densepeds.boxes import match_boxes
    from densepeds.motio import read_gt

    gt = read_gt(video.seq_dir / "gt" / "gt.txt")
    has_visibility = gt.shape[1] >= 9 and bool(np.all(gt[:, 7] >= 0))
    if has_visibility:  # MOT17/20 layout: flag, class, visibility
        gt = gt[(gt[:, 6] == 1) & (gt[:, 7] == 1)]
    out = Matched([], [], [], [], [] if has_visibility else None)
    for k, dets in enumerate(video.dets):
        g = gt[gt[:, 0] == video.first + k]
        boxes = np.c_[g[:, 2:4], g[:, 2:4] + g[:, 4:6]]
        ids = np.zeros(0, np.int64)
        rows = np.zeros(0, np.intp)
        if len(g) and len(dets):
            r, c = match_boxes(boxes, dets.boxes, MIN_IOU)
            ids, rows = g[r, 1].astype(np.int64), c
            boxes, g = boxes[r], g[r]
        else:
            boxes, g = np.zeros((0, 4)), g[:0]
        if out.visibility is not None:
            out.visibility.append(g[:, 8].astype(np.float64))
        out.ids.append(ids)
        out.rows.append(rows)
        out.centres.append((boxes[:, :2] + boxes[:, 2:]) / 2)
        out.heights.append(boxes[:, 3] - boxes[:, 1])
    return out


@dataclass(frozen=True)
class Quality:
    probes: int  # probes with at least one nearby negative
    pairs: int  # (positive, nearby negative) pairs
    auc: float
    wrong: float
    wrong_gallery: float
    pos_q95: float  # 95th percentile of the positives' distance
    neg_q05: float  # 5th percentile of the nearby negatives' distance


def quality(
    matched: Matched,
    emb: Sequence[npt.NDArray[np.float32]],
    gap: int,
    gallery: int = GALLERY,
    probe: Sequence[npt.NDArray[np.bool_]] | None = None,
) -> Quality:
    """The measures of the module docstring for one video, kind and gap; ``probe`` (per frame,
    one flag per matched person) keeps only the flagged people as probes."""
    frames = len(matched.ids)
    person = [e[r].astype(np.float64) for e, r in zip(emb, matched.rows, strict=True)]
    pos_all: list[float] = []
    neg_all: list[npt.NDArray[np.float64]] = []
    wrong = wrong_gal = probes = 0
    for t in range(frames - gap):
        a_ids, b_ids = matched.ids[t], matched.ids[t + gap]
        if not len(a_ids) or not len(b_ids):
            continue
        dist = 1.0 - person[t + gap] @ person[t].T  # [probe at t+k, person at t]
        where = {int(p): i for i, p in enumerate(a_ids)}
        near = (
            np.linalg.norm(matched.centres[t][:, None] - matched.centres[t][None], axis=2)
            <= NEAR * matched.heights[t][:, None]
        )
        # Gallery distances: nearest over each person's embeddings in frames t-gallery+1..t.
        gal = np.full((len(b_ids), len(a_ids)), np.inf)
        for s in range(max(0, t - gallery + 1), t + 1):
            idx = [where.get(int(p), -1) for p in matched.ids[s]]
            keep = [i for i, j in enumerate(idx) if j >= 0]
            if keep:
                d = 1.0 - person[t + gap] @ person[s][keep].T
                cols = np.asarray([idx[i] for i in keep])
                gal[:, cols] = np.minimum(gal[:, cols], d)
        for i, p in enumerate(b_ids):
            j = where.get(int(p))
            if j is None or (probe is not None and not probe[t + gap][i]):
                continue
            others = np.flatnonzero(near[j])
            others = others[others != j]
            if not len(others):
                continue
            probes += 1
            pos_all.append(dist[i, j])
            neg_all.append(dist[i, others])
            wrong += int(dist[i, others].min() < dist[i, j])
            wrong_gal += int(gal[i, others].min() < gal[i, j])
    neg = np.concatenate(neg_all) if neg_all else np.zeros(0)
    pos = np.asarray(pos_all)
    # Each probe's positive is paired with its own negatives only: AUC over those pairs.
    paired = [d[:, None] > p for p, d in zip(pos, neg_all, strict=True)]
    ties = [d[:, None] == p for p, d in zip(pos, neg_all, strict=True)]
    n_pairs = len(neg)
    a = (
        float((sum(x.sum() for x in paired) + 0.5 * sum(x.sum() for x in ties)) / n_pairs)
        if n_pairs
        else float("nan")
    )
    q95 = float(np.percentile(pos, 95)) if len(pos) else float("nan")
    q05 = float(np.percentile(neg, 5)) if len(neg) else float("nan")
    return Quality(probes, n_pairs, a, wrong / max(probes, 1), wrong_gal / max(probes, 1), q95, q05)


def frame_scale(video: realvideo.CachedVideo, emb: Sequence[npt.NDArray[np.float32]]) -> float:
    """Median cosine distance between nearby detections of one frame (no gt: all detections)."""
    out: list[npt.NDArray[np.float64]] = []
    for dets, e in zip(video.dets, emb, strict=True):
        if len(e) < 2:
            continue
        b = dets.boxes.astype(np.float64)
        c = (b[:, :2] + b[:, 2:]) / 2
        near = np.linalg.norm(c[:, None] - c[None], axis=2) <= NEAR * (b[:, 3] - b[:, 1])[:, None]
        np.fill_diagonal(near, False)
        out.append((1.0 - e.astype(np.float64) @ e.astype(np.float64).T)[near])
    return float(np.median(np.concatenate(out))) if out else float("nan")


def embed_cost(
    video: realvideo.CachedVideo, frames: str, kinds: Sequence[str], count: int
) -> dict[str, float]:
    """Milliseconds per frame of ``ReID.embed`` per kind over the first ``count`` frames."""
    import time

    from densepeds.reid import ReID

    models = {}
    for kind in kinds:
        features, options = realvideo.kind_options(kind)
        models[kind] = (features, ReID(**options))
    spent = dict.fromkeys(kinds, 0.0)
    for k, (_, image) in enumerate(realvideo.read_frames(video.seq_dir, frames)):
        if k >= count:
            break
        for kind, (features, reid) in models.items():
            t0 = time.perf_counter()
            reid.embed(image, video.dets[k], features=features)
            spent[kind] += time.perf_counter() - t0
    n = min(count, len(video.dets))
    return {kind: 1000 * t / max(n, 1) for kind, t in spent.items()}


# The tracked figure is also averaged over appearance thresholds near the preset's (apart at the
# preset's ratio): one id event moves a cell's HOTA by ~0.5, and a threshold's step by more.
THRESHOLDS = (0.22, 0.23, 0.24, 0.25, 0.26, 0.27, 0.28, 0.29, 0.30)


def tracked(cache: Path, kinds: Sequence[str]) -> list[str]:
    """HOTA of each kind on the four video cells: at the package defaults, and the mean (and
    its spread) over ``THRESHOLDS``."""
    import accuracy_grid
    from densepeds.presets import PRESETS

    preset = PRESETS["yoloseg"].tracker
    ratio = float(preset["appearance_apart"]) / float(preset["appearance_threshold"])
    cells = accuracy_grid.select_cells(["*/float", "*/int8"])
    grid = accuracy_grid.load_grid(cells, cache, kinds, quiet=True)
    lines = [
        "Tracked with each kind (`accuracy_grid.py --cells '*/float' '*/int8' --features "
        "KIND`), HOTA at the package defaults, and the four cells' mean HOTA averaged over "
        f"appearance_threshold {THRESHOLDS[0]}-{THRESHOLDS[-1]} in steps of 0.01 "
        f"(appearance_apart {ratio:.2f} of it, the preset's ratio) with its standard deviation "
        "over those thresholds:",
        "",
        "| kind | " + " | ".join(c.name for c in cells) + " | mean | mean over thresholds | sd |",
        "|---|" + "---:|" * (len(cells) + 3),
    ]
    for kind in kinds:
        result = accuracy_grid.score_grid(grid, accuracy_grid.Config(features=kind))
        values = [result[c.name]["HOTA"] for c in cells]
        means = []
        for th in THRESHOLDS:
            params = {"appearance_threshold": th, "appearance_apart": round(ratio * th, 4)}
            config = accuracy_grid.Config(features=kind, cnn_params=params)
            means.append(accuracy_grid.mean_metric(accuracy_grid.score_grid(grid, config)))
        lines.append(
            f"| {kind} | "
            + " | ".join(f"{v:.2f}" for v in values)
            + f" | {accuracy_grid.mean_metric(result):.2f} | {np.mean(means):.2f} | "
            f"{np.std(means):.2f} |"
        )
    return [*lines, ""]


VISIBILITY_BINS = ((0.0, 0.5), (0.5, 1.0))


def visibility_rows(
    matched: Matched, emb: Sequence[npt.NDArray[np.float32]], kind: str
) -> list[str]:
    """Table rows of the measures with the probes cut by their gt visibility at ``t + k``."""
    assert matched.visibility is not None
    lines = []
    for lo, hi in VISIBILITY_BINS:
        flags = [(v >= lo) & ((v < hi) | (hi >= 1.0)) for v in matched.visibility]
        cells = []
        for k in GAPS:
            q = quality(matched, emb, k, probe=flags)
            cells += [f"{q.auc:.4f}", f"{100 * q.wrong:.2f}%", f"{100 * q.wrong_gallery:.2f}%"]
        n = quality(matched, emb, GAPS[0], probe=flags).probes
        lines.append(f"| {kind} | {lo}-{hi} | " + " | ".join(cells) + f" | {n} |")
    return lines


def table(
    results: dict[tuple[str, str, int], Quality],
    scales: dict[tuple[str, str], float],
    kinds: Sequence[str],
) -> list[str]:
    lines = []
    for seq, _ in realvideo.VIDEOS:
        lines += [
            f"**{seq}**",
            "",
            "| kind | "
            + " | ".join(f"AUC k={k} | wrong k={k} | wrong (gallery) k={k}" for k in GAPS)
            + " | probes k=1 |",
            "|---|" + "---:|" * (3 * len(GAPS) + 1),
        ]
        for kind in kinds:
            cells = []
            for k in GAPS:
                q = results[(seq, kind, k)]
                cells += [f"{q.auc:.4f}", f"{100 * q.wrong:.2f}%", f"{100 * q.wrong_gallery:.2f}%"]
            cells.append(str(results[(seq, kind, GAPS[0])].probes))
            lines.append(f"| {kind} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += [
        "Distances (cosine): the positives' 95th percentile and the nearby negatives' 5th at "
        "each gap, and `scale`, the median distance between nearby detections of one frame "
        "(all detections, no gt):",
        "",
        "| video | kind | "
        + " | ".join(f"pos q95 k={k} | neg q05 k={k}" for k in GAPS)
        + " | scale |",
        "|---|---|" + "---:|" * (2 * len(GAPS) + 1),
    ]
    for seq, _ in realvideo.VIDEOS:
        for kind in kinds:
            cells = []
            for k in GAPS:
                q = results[(seq, kind, k)]
                cells += [f"{q.pos_q95:.3f}", f"{q.neg_q05:.3f}"]
            cells.append(f"{scales[(seq, kind)]:.3f}")
            lines.append(f"| {seq} | {kind} | " + " | ".join(cells) + " |")
    lines.append("")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--cache", type=Path, default=REPO / "out" / "cache")
    ap.add_argument("--kinds", default=",".join(KINDS), help="embedding kinds, comma-separated")
    ap.add_argument("--write", type=Path, help="also write the table to this markdown file")
    ap.add_argument("--time", type=int, default=0, metavar="N", help="time re-ID on N frames")
    ap.add_argument("--track", action="store_true", help="track each kind on the video cells")
    ap.add_argument("--quiet", "-q", action="store_true")
    args = ap.parse_args(argv)
    kinds = args.kinds.split(",")
    costs: dict[str, dict[str, float]] = {}
    scales: dict[tuple[str, str], float] = {}
    by_visibility: list[str] = []
    results: dict[tuple[str, str, int], Quality] = {}
    for seq, frames in realvideo.VIDEOS:
        video = realvideo.load_video(seq, frames, kinds, args.cache, SOURCE, args.quiet)
        matched = match_gt(video)
        for kind in kinds:
            for k in GAPS:
                results[(seq, kind, k)] = quality(matched, video.embeddings[kind], k)
            scales[(seq, kind)] = frame_scale(video, video.embeddings[kind])
            if matched.visibility is not None:
                if not by_visibility:
                    by_visibility += [
                        f"{seq}, the probes cut by their gt visibility at `t + k`:",
                        "",
                        "| kind | visibility | "
                        + " | ".join(
                            f"AUC k={k} | wrong k={k} | wrong (gallery) k={k}" for k in GAPS
                        )
                        + " | probes k=1 |",
                        "|---|---|" + "---:|" * (3 * len(GAPS) + 1),
                    ]
                by_visibility += visibility_rows(matched, video.embeddings[kind], kind)
        if args.time:
            costs[seq] = embed_cost(video, frames, kinds, args.time)
    lines = table(results, scales, kinds)
    if by_visibility:
        lines += [*by_visibility, ""]
    if args.track:
        lines += tracked(args.cache, kinds)
    if costs:
        crops = {
            seq: np.mean([len(d) for d in v.dets[: args.time]])
            for seq, v in (
                (s, realvideo.load_video(s, f, [], args.cache, SOURCE, True))
                for s, f in realvideo.VIDEOS
            )
        }
        lines += [
            f"Re-ID cost, ms per frame (`ReID.embed`, first {args.time} frames, kinds "
            f"interleaved; load {' / '.join(f'{x:.1f}' for x in os.getloadavg())}, "
            f"{os.cpu_count()} cores):",
            "",
            "| kind | " + " | ".join(f"{seq} ({crops[seq]:.0f} crops)" for seq in costs) + " |",
            "|---|" + "---:|" * len(costs),
        ]
        for kind in kinds:
            lines.append(
                f"| {kind} | " + " | ".join(f"{costs[seq][kind]:.1f}" for seq in costs) + " |"
            )
        lines.append("")
    print("\n".join(lines))
    if args.write:
        head = [
            "# Re-ID quality: the same person against the people near them",
            "",
            "Written by this command (do not edit; rerun it):",
            "",
            f"    {COMMAND}"
            + ("" if args.kinds == ",".join(KINDS) else f" --kinds {args.kinds}")
            + (f" --time {args.time}" if args.time else "")
            + (" --track" if args.track else ""),
            "",
            f"Detections of the float video cells matched to gt (IoU >= {MIN_IOU}); nearby: box "
            f"centres within {NEAR} box heights; gallery: the last {GALLERY} frames. "
            "Definitions: `benchmarks/reid_quality.py`.",
            "",
        ]
        args.write.write_text("\n".join(head + lines) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
