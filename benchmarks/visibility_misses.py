"""Why the tracker misses the people it misses at one visibility band, on the MOT20 video cells.

    python benchmarks/visibility_misses.py     # MOT20-01-dev/float and /int8, visibility .25-.5
    python benchmarks/visibility_misses.py --band 0 0.25 --param occluded_output=20

Each cell is tracked with the package defaults (plus ``--param``) from its cached detections and
embeddings, exactly as ``benchmarks/accuracy_grid.py`` tracks it (the detector alone: no focus
views, which need a live run; ``focus_lost.py`` measures those). Per frame the ground-truth
pedestrians are matched one-to-one to the tracker's output at IoU >= 0.5, as the recall per
visibility of ``accuracy-visibility.md``; every pedestrian in the band left unmatched is put in
the first class that fits (``CLASSES``):

- the boxes fed to the tracker held one on the person (IoU >= 0.5, one-to-one per frame);
- a fed box lies within the person's box (``PART_INSIDE`` of its area) without reaching IoU 0.5
  (a part of the person) and a reported track was matched to it, its box off the person; or no
  reported track was matched to it (split by the detection's score against the tracker's
  ``det_threshold``: below it only the second pass can take it);
- no such detection: what became of the track that last covered the person (reported on
  another person, reported on nobody, or not reported), or nobody covered them before.

The last classes have nothing a tracker can match in the frame; the first ones are what a better
tracker (or box completion) could still turn into hits.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402

PART_INSIDE = 0.8  # share of a detection's area inside the person's box that makes it a part
CLASSES = (
    "a fed detection on the person (IoU >= 0.5)",
    "a part detected, matched to a track whose box misses the person",
    "a part detected at >= det_threshold, matched to no reported track",
    "a part detected below det_threshold, matched to no reported track",
    "nothing detected; the person's last track reported on another person",
    "nothing detected; the person's last track reported on nobody",
    "nothing detected; the person's last track not reported",
    "nothing detected; never covered before",
)


@dataclass
class Frame:
    """One frame: the pedestrians, what the tracker was fed and what it reported."""

    gt: npt.NDArray[np.float64]  # [G, 4] x1, y1, x2, y2
    gt_ids: npt.NDArray[np.int64]  # [G]
    fed: npt.NDArray[np.float64]  # [F, 4] the boxes handed to the tracker
    fed_scores: npt.NDArray[np.float64]  # [F]
    out: npt.NDArray[np.float64]  # [T, 4] the reported boxes
    out_ids: npt.NDArray[np.int64]  # [T]
    out_fed: npt.NDArray[np.int64]  # [T] the fed box each reported track was matched to, or -1
    visibility: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))  # [G]


def inside_share(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> np.ndarray:
    """[len(a), len(b)]: the share of each ``b`` box's area that lies inside each ``a`` box."""
    x1 = np.maximum(a[:, None, 0], b[None, :, 0])
    y1 = np.maximum(a[:, None, 1], b[None, :, 1])
    x2 = np.minimum(a[:, None, 2], b[None, :, 2])
    y2 = np.minimum(a[:, None, 3], b[None, :, 3])
    inter = np.clip(x2 - x1, 0, None) * np.clip(y2 - y1, 0, None)
    area = np.maximum((b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1]), 1e-9)
    return inter / area[None, :]


def classify(
    frame: Frame, in_band: npt.NDArray[np.bool_], last_track: dict[int, int], det_threshold: float
) -> list[int]:
    """The ``CLASSES`` index of every pedestrian in ``in_band`` the output misses, in order;
    ``last_track`` (person id -> id of the track that last covered them) is read, then updated
    with this frame's hits."""
    from densepeds.boxes import iou_matrix, match_boxes

    rows, cols = match_boxes(frame.gt, frame.out)
    hit = dict(zip(rows.tolist(), cols.tolist(), strict=True))
    on_person = set(cols.tolist())
    fed_rows, fed_cols = match_boxes(frame.gt, frame.fed)
    fed_hit = set(fed_rows.tolist())
    free = np.ones(len(frame.fed), bool)
    free[fed_cols] = False
    iou = iou_matrix(frame.gt, frame.fed) if len(frame.fed) else np.zeros((len(frame.gt), 0))
    share = inside_share(frame.gt, frame.fed)
    out: list[int] = []
    for i in np.flatnonzero(in_band):
        if i in hit:
            continue
        if i in fed_hit:
            out.append(0)
            continue
        parts = np.flatnonzero(free & (share[i] >= PART_INSIDE) & (iou[i] > 0))
        if len(parts):
            j = parts[np.argmax(iou[i, parts])]
            if (frame.out_fed == j).any():
                out.append(1)
            else:
                out.append(2 if frame.fed_scores[j] >= det_threshold else 3)
            continue
        track = last_track.get(int(frame.gt_ids[i]))
        at = np.flatnonzero(frame.out_ids == track) if track is not None else []
        if track is None:
            out.append(7)
        elif not len(at):
            out.append(6)
        else:
            out.append(4 if int(at[0]) in on_person else 5)
    for i, t in hit.items():
        last_track[int(frame.gt_ids[i])] = int(frame.out_ids[t])
    return out


def cell_frames(data: grid.CellData, config: grid.Config) -> tuple[list[Frame], float]:
    """The cell tracked as ``accuracy_grid.track_cell`` does, frame by frame, with the boxes fed
    and the tracker's ``det_threshold``."""
    from densepeds.motio import read_gt

    gt = read_gt(data.seq_dir / "gt" / "gt.txt")
    pipe = grid.cell_pipeline(data, config)
    kind = config.kind() if data.cell.full_pipeline else None
    frames = []
    for k, dets in enumerate(data.dets, 1):
        emb = None if kind is None else data.embeddings[kind][k - 1]
        tracks = pipe.step(None, dets, embeddings=emb)
        kept = pipe._kept(dets)
        back = np.full(len(dets), -1)
        back[kept] = np.arange(len(kept))
        matched = tracks.det_index >= 0
        out_fed = np.full(len(tracks.det_index), -1)
        out_fed[matched] = back[tracks.det_index[matched]]  # safe on a frame without detections
        g = gt[gt[:, 0] == k]
        ped = g[(g[:, 7] == 1) & (g[:, 6] != 0)]
        frames.append(
            Frame(
                np.c_[ped[:, 2:4], ped[:, 2:4] + ped[:, 4:6]],
                ped[:, 1].astype(np.int64),
                dets.boxes[kept].astype(np.float64),
                dets.scores[kept].astype(np.float64),
                np.asarray(tracks.boxes, np.float64).reshape(-1, 4),
                np.asarray(tracks.ids, np.int64),
                out_fed.astype(np.int64),
                ped[:, 8].astype(np.float64),
            )
        )
    return frames, float(pipe.params["det_threshold"])


def report(data: grid.CellData, config: grid.Config, band: tuple[float, float]) -> list[str]:
    frames, det_threshold = cell_frames(data, config)
    counts: Counter[int] = Counter()
    total = 0
    last: dict[int, int] = {}
    for frame in frames:
        in_band = (frame.visibility >= band[0]) & (frame.visibility < band[1])
        total += int(in_band.sum())
        counts.update(classify(frame, in_band, last, det_threshold))
    missed = sum(counts.values())
    lines = [
        f"## {data.cell.name}: visibility {band[0]:g}-{band[1]:g}, {total} pedestrian boxes, "
        f"{missed} missed (tracker recall {100 * (total - missed) / max(total, 1):.1f}%)",
        "",
        "| why missed | boxes | share of the missed |",
        "|---|---:|---:|",
    ]
    for c, name in enumerate(CLASSES):
        lines.append(f"| {name} | {counts[c]} | {100 * counts[c] / max(missed, 1):.1f}% |")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", nargs="*", default=["MOT20-01-dev/float", "MOT20-01-dev/int8"])
    ap.add_argument("--band", nargs=2, type=float, default=(0.25, 0.5), metavar=("LO", "HI"))
    ap.add_argument("--param", action="append", default=[], metavar="K=V")
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    args = ap.parse_args(argv)
    config = grid.Config(params=grid.parse_params(args.param))
    for cell in grid.select_cells(args.cells):
        if not cell.seq.startswith("MOT20"):
            sys.exit(f"{cell.name}: only MOT20's ground truth has visibility")
        data = grid.load_cell(cell, args.cache, quiet=True)
        lo, hi = args.band
        print("\n".join(report(data, config, (lo, hi))) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
