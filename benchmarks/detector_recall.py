"""Detector recall per ground-truth visibility, for tile choices, on the two real videos.

    OPENBLAS_NUM_THREADS=1 python benchmarks/detector_recall.py \\
        --tiles auto auto:full_scan_every=4 3x2 4x2 [--every 3] [--int8] [--option person_share=0.3]

Runs the shared segmenter (float copy, or ``--int8``: the graph as shipped) on every
``--every``-th frame of MOT20-01-dev (frames 1-214) and PETS09-S2L1-dev (1-397); a tile rule
that follows the people sees only those frames, and its ``full_scan_every`` counts them
(``--every 1`` measures the rule as ``densepeds run`` runs it). It keeps what the pipeline's
detection filter keeps (the yoloseg preset), matches the kept boxes one-to-one to the
ground truth at IoU >= 0.5 and prints, per tile choice and video: recall per visibility bin
(MOT20's gt column 9; PETS09 has none), unmatched detections per frame, views (tiles) per frame
and detector milliseconds per frame (wall clock, with the machine load: compare rows of one run).
A tile choice may carry detector options of its own after a colon (``auto:KEY=VALUE,...``);
``--option`` applies to every choice.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid  # noqa: E402
import realvideo  # noqa: E402

BINS = (0.0, 0.25, 0.5, 0.75, 1.01)


def run(seq: str, frames: str, every: int, options: dict[str, Any]) -> dict[str, float]:
    from densepeds.boxes import match_boxes
    from densepeds.pipeline import Pipeline

    seq_dir = realvideo.SHARED / "data" / seq
    last = int(frames.split(":")[1])
    gt = np.loadtxt(seq_dir / "gt" / "gt.txt", delimiter=",", ndmin=2)
    gt = gt[gt[:, 0] <= last]
    if seq.startswith("MOT20"):  # pedestrians, considered (MOT20 rules)
        gt = gt[(gt[:, 6] == 1) & (gt[:, 7] == 1)]
        vis = gt[:, 8]
    else:
        vis = np.ones(len(gt))
    pipe = Pipeline("yoloseg", detector_options=options, features="none")
    det = pipe.detector()
    total = np.zeros(len(BINS) - 1)
    found = np.zeros(len(BINS) - 1)
    unmatched = views = seconds = 0.0
    count = 0
    for k, (frame_no, image) in enumerate(realvideo.read_frames(seq_dir, frames)):
        if k % every:
            continue
        t0 = time.perf_counter()
        dets = det(image)
        seconds += time.perf_counter() - t0
        views += det.last_views
        kept = dets.boxes[pipe._kept(dets)].astype(np.float64)
        sel = gt[:, 0] == frame_no
        g = gt[sel]
        boxes = np.c_[g[:, 2:4], g[:, 2:4] + g[:, 4:6]]
        hit = np.zeros(len(g), bool)
        if len(g) and len(kept):
            hit[match_boxes(boxes, kept, 0.5)[0]] = True
        unmatched += len(kept) - hit.sum()
        b = np.clip(np.digitize(vis[sel], BINS) - 1, 0, len(BINS) - 2)
        np.add.at(total, b, 1)
        np.add.at(found, b, hit)
        count += 1
    out = {
        f"{BINS[i]:.2f}-{min(BINS[i + 1], 1):.2f}": 100 * found[i] / total[i]
        for i in range(len(total))
        if total[i]
    }
    out["all"] = 100 * found.sum() / total.sum()
    out["unmatched/frame"] = unmatched / count
    out["views/frame"] = views / count
    out["ms/frame"] = 1000 * seconds / count
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--tiles", nargs="+", default=["auto"])
    ap.add_argument("--every", type=int, default=3)
    ap.add_argument("--int8", action="store_true")
    ap.add_argument("--videos", nargs="+", default=[s for s, _ in realvideo.VIDEOS])
    ap.add_argument("--option", action="append", default=[], help="KEY=VALUE for the detector")
    ap.add_argument("--write", type=Path, help="also write a Markdown table here")
    args = ap.parse_args(argv)
    # The float copy or the graph as shipped, never an int8 copy found in the model folders
    # (``densepeds models quantize``) unless an --option asks for it.
    base = {"quantized": False, **accuracy_grid.parse_params(args.option)}
    if args.int8:
        base["dequantize"] = False
    load = f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
    print(load, flush=True)
    rows = []
    for tiles in args.tiles:
        for seq, frames in realvideo.VIDEOS:
            if seq not in args.videos:
                continue
            r = run(seq, frames, args.every, {**base, **choice_options(tiles)})
            cells = " ".join(f"{k} {v:.1f}" for k, v in r.items())
            print(f"{tiles} {seq}: {cells}", flush=True)
            rows.append((tiles, seq, r))
    if args.write:
        args.write.write_text(markdown(rows, args, load), encoding="utf-8")
    return 0


def choice_options(choice: str) -> dict[str, Any]:
    """Detector options of a tile choice: ``TILES[:KEY=VALUE,...]``."""
    tiles, _, extra = choice.partition(":")
    return {"tiles": tiles, **accuracy_grid.parse_params([p for p in extra.split(",") if p])}


def markdown(rows: Sequence[tuple[str, str, dict[str, float]]], args: Any, load: str) -> str:
    graph = "int8 graph as shipped" if args.int8 else "float copy"
    keys = [f"{BINS[i]:.2f}-{min(BINS[i + 1], 1):.2f}" for i in range(len(BINS) - 1)]
    keys += ["all", "unmatched/frame", "views/frame", "ms/frame"]
    opts = "".join(f" --option {o}" for o in args.option)
    frames = "every frame" if args.every == 1 else f"every {args.every}th frame"
    lines = [
        f"# Detector recall per tile choice ({graph})",
        "",
        "Recall (%) of ground-truth pedestrians per visibility bin after the pipeline's "
        "detection filter (one-to-one, IoU >= 0.5), unmatched detections, views (tiles) and "
        f"detector milliseconds per frame, {frames}; {load}. A choice's own detector options "
        "follow its colon (`auto:full_scan_every=K`: the people's whole layout every K-th frame, "
        "between only views of the people found in the last K frames: windows of the tiles' "
        "sizes placed over them, or the tiles that show them whole, whichever are fewer; "
        "`densepeds.detect.tiling.SkipSchedule`). Regenerate with:",
        "",
        "    OPENBLAS_NUM_THREADS=1 python benchmarks/detector_recall.py --tiles "
        + " ".join(args.tiles)
        + f" --every {args.every}"
        + (" --int8" if args.int8 else "")
        + opts
        + f" --write {args.write}",
        "",
        "| tiles | video | " + " | ".join(keys) + " |",
        "|---|---|" + "---:|" * len(keys),
    ]
    for tiles, seq, r in rows:
        cells = " | ".join(f"{r[k]:.1f}" if k in r else "-" for k in keys)
        lines.append(f"| {tiles} | {seq} | {cells} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
