"""Every accuracy table of the dev grid, regenerated into ``benchmarks/results/`` by one command:

    OPENBLAS_NUM_THREADS=1 python benchmarks/accuracy_grid.py --write

(which runs this script: ``python benchmarks/accuracy_tables.py [--cache DIR] [--results DIR]
[--cells GLOB...] [--tables NAME...] [--quiet]``)

- ``accuracy.md``: the package defaults on every cell beside every peer on the same inputs;
- ``accuracy-loo.md``: defaults chosen leave-one-out from a small stated candidate set;
- ``accuracy-visibility.md``: recall per ground-truth visibility bin (MOT20-01-dev), detector
  against tracker, and the false positives that coasting adds;
- ``accuracy-claims.md``: the method's claims (FRVO vs RVO/SF/CV; segmented vs bbox /
  masked_pool) over the grid with a sign test and a bootstrap over cells;
- ``accuracy-scene.md``: the masking ablation on the built-in scene, exact and noisy masks;
- ``realvideo.md``: ``realvideo.py``'s full-pipeline ablation on the two real videos.

Figures are computed on every run; nothing here holds a result.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402
import peers  # noqa: E402
import realvideo  # noqa: E402

RESULTS = grid.REPO / "benchmarks" / "results"
COMMAND = "OPENBLAS_NUM_THREADS=1 python benchmarks/accuracy_grid.py --write"
# Leave-one-out candidates: each overrides the package defaults on every cell (on top of the
# tracker's own defaults on det files and the CNN preset on the videos). A candidate naming a
# parameter that the installed tracker does not have is left out, and the tables say so.
CANDIDATES: dict[str, dict[str, Any]] = {
    "package defaults": {},
    "max_age 30": {"max_age": 30},
    "coast_aspect off": {"coast_aspect": False},
    "coast_aspect_state off": {"coast_aspect_state": False},
    "coast_aspect_state on": {"coast_aspect_state": True},
    "max_age 60": {"max_age": 60},
    "n_init 3": {"n_init": 3},
    "output_lost 0": {"output_lost": 0},
    "output_lost 10": {"output_lost": 10},
    "output_lost_adaptive": {"output_lost_adaptive": True},
    "occluded_output 0": {"occluded_output": 0},
    "occluded_output 5": {"occluded_output": 5},
    "occluded_output 60": {"occluded_output": 60},
    "score_quantile_floor 0": {"score_quantile_floor": 0.0},
    "score_quantile_floor 0.3": {"score_quantile_floor": 0.3},
    "amodal_boxes": {"amodal_boxes": True},
    "position_smoothing 0": {"position_smoothing": 0.0},
    "position_smoothing 0.5": {"position_smoothing": 0.5},
    "jitter_floor 0": {"jitter_floor": 0.0},
    "jitter_floor 0.05": {"jitter_floor": 0.05},
    "jitter_floor 0.07": {"jitter_floor": 0.07},
    "appearance_apart off": {"appearance_apart": 2.0},
    "appearance_apart 0.15": {"appearance_apart": 0.15},
    "appearance_apart 0.22": {"appearance_apart": 0.22},
    "score_quantile_ceiling 0": {"score_quantile_ceiling": 0.0},
    "score_quantile_ceiling 0.5": {"score_quantile_ceiling": 0.5},
    "score_quantile_ceiling 0.9": {"score_quantile_ceiling": 0.9},
    "thresholded_low_iou off": {"thresholded_low_iou": 1.0},
    "thresholded_low_iou 0.25": {"thresholded_low_iou": 0.25},
    "thresholded_low_iou 0.4": {"thresholded_low_iou": 0.4},
    "tentative_max_age 0": {"tentative_max_age": 0},
    "tentative_max_age 1": {"tentative_max_age": 1},
    "tentative_max_age 3": {"tentative_max_age": 3},
    "coast_aspect_quantile off": {"coast_aspect_quantile": 0.0},
    "coast_aspect_quantile 0.75": {"coast_aspect_quantile": 0.75},
    "coast_aspect_quantile 0.9": {"coast_aspect_quantile": 0.9},
    "coast_aspect_quantile 0.95": {"coast_aspect_quantile": 0.95},
    "coast_min_hits 0": {"coast_min_hits": 0},
    "coast_min_hits 4": {"coast_min_hits": 4},
    "coast_min_hits 8": {"coast_min_hits": 8},
    "coast_min_hits 11": {"coast_min_hits": 11},
    "reid_newborn off": {"reid_newborn": 0},
    "reid_newborn 3": {"reid_newborn": 3},
    "reid_newborn 5": {"reid_newborn": 5},
    "amodal_width_quantile off": {"amodal_width_quantile": 0.0},
    "amodal_width_quantile 0.6": {"amodal_width_quantile": 0.6},
    "amodal_width_quantile 0.75": {"amodal_width_quantile": 0.75},
    "amodal_width_quantile 0.85": {"amodal_width_quantile": 0.85},
}
# What the package defaults were chosen on: update this where a default is tuned again.
TUNED_ON = {
    "det": "the six `/det` cells together, motion only (the score reading, "
    "`score_quantile_floor`, `max_age`, `output_lost_adaptive`, `position_smoothing`, "
    "`jitter_floor` and `coast_aspect` on all 15 cells by leave-one-out, "
    "the `/frcnn` and `/int8` ones included; `score_quantile_ceiling` by the same leave-one-out "
    "and by the 11 motion-only cells under monotone score maps (`decisions.md`); "
    "`thresholded_low_iou`, `tentative_max_age` and `coast_min_hits` by the "
    "same leave-one-out)",
    "cnn": "the two `/float` videos together (the score reading as above; "
    "`appearance_apart` on all 15 cells by leave-one-out; "
    "`coast_aspect_state` on the two `/float` videos, checked by leave-one-out; "
    "`coast_aspect_quantile` on the two `/float` videos, checked by leave-one-out; "
    "`tentative_max_age` 0 on the two `/float` videos; `amodal_width_quantile` on the "
    "four video cells, checked by leave-one-out; `reid_newborn`, which acts only with "
    "embeddings, on the four video cells and checked by leave-one-out)",
}
UNTUNED = (
    "every `/frcnn` and `/int8` cell for all but the score reading, `score_quantile_ceiling`, "
    "`max_age`, `output_lost_adaptive`, `position_smoothing`, `jitter_floor`, `coast_aspect`, "
    "`appearance_apart`, `thresholded_low_iou`, `tentative_max_age`, "
    "`coast_min_hits`; the `/int8` cells for all but `reid_newborn`"
)
MOTION_ROWS = ("frvo", "rvo", "sf", "cv")
FEATURE_ROWS = ("segmented", "bbox", "masked_pool", "none")
VISIBILITY_BINS = ((0.0, 0.25), (0.25, 0.5), (0.5, 0.75), (0.75, 1.01))
VISIBILITY_CELLS = ("MOT20-01-dev/float", "MOT20-01-dev/int8")
# Frames since a coasted box's track was last matched: bins (first, last) of the precision table.
LOST_BINS = ((1, 1), (2, 3), (4, 5), (6, 10), (11, 20), (21, 10**9))
# MOTChallenge's MOT20 distractor classes: a box on one is neither a hit nor a false positive.
DISTRACTOR_CLASSES = (2, 6, 7, 8, 12)
BOOTSTRAP = 10_000
Results = dict[str, dict[str, float]]  # cell name -> metrics


def _log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _group(name: str) -> str:
    return name.split("/")[1]


def _header(title: str, what: str) -> list[str]:
    from densepeds.presets import PRESETS
    from densepeds.tracking import Tracker

    vers = ", ".join(f"{k} {v}" for k, v in peers.versions().items())
    own = {k: v for k, v in Tracker().params.items() if k != "threads"}
    return [
        f"# {title}",
        "",
        what,
        "",
        f"Regenerate every accuracy table with `{COMMAND}` (about 12 minutes on 2 cores once "
        "`out/cache` holds the videos' detections and embeddings; `realvideo.py` computes them "
        "on first use).",
        "",
        "Cells: motion only on each dev sequence's public `det/det.txt` (`/det`) and the five "
        "MOT15 sequences' `det/det-frcnn.txt` (`/frcnn`), scores mapped into [0, 1] by "
        "`densepeds.io.mot.read_detections`; the full pipeline on MOT20-01-dev frames 1-214 and "
        "PETS09-S2L1-dev frames 1-397 with the shared segmenter's float copy (`/float`) and "
        "its int8 graph as shipped (`/int8`, `dequantize=False`), OSNet x0.25 embeddings of "
        "every detection, cached. Every cell is tracked through `densepeds.Pipeline.step` and "
        "scored by `densepeds.evaluate` (trackeval, MOTChallenge rules). The cached detections "
        "are the detector's alone: the package's closer look at the people the tracker lost "
        "(`YoloSegDetector(focus_scale)`, on by default) needs a live run, and is measured on "
        "the four video cells in `results/decisions.md`.",
        "",
        "Package defaults: on det files the tracker's own defaults, chosen on "
        f"{TUNED_ON['det']} (leave-one-out check in `results/accuracy-loo.md`): `{own}`. "
        "On the videos the CNN presets, "
        f"chosen on {TUNED_ON['cnn']} (`results/realvideo.md`): "
        f"`{PRESETS['yoloseg'].describe()}`. Cells no default was "
        f"chosen on: {UNTUNED}.",
        "",
        f"Packages: {vers}; Python {platform.python_version()}.",
        "",
    ]


def write_table(out: Path, name: str, lines: Sequence[str]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    path = out / name
    tmp = path.with_suffix(".md.tmp")
    tmp.write_text("\n".join(lines).rstrip() + "\n", encoding="utf-8")
    tmp.replace(path)
    _log(f"wrote {path}")


def _run(
    data: Sequence[grid.CellData],
    config: grid.Config,
    keep_rows: dict[str, grid.Rows] | None = None,
) -> Results:
    t0 = time.perf_counter()
    res = grid.score_grid(data, config, keep_rows)
    _log(
        f"{config.label()}: mean HOTA {grid.mean_metric(res):.2f} over {len(res)} cells "
        f"({time.perf_counter() - t0:.0f} s)"
    )
    return res


# --- peers on equal inputs ---


def peers_table(ours: Results, peer_results: Mapping[str, Results]) -> list[str]:
    cells = list(ours)
    lines = [
        "## Ours (package defaults) against the best peer per cell",
        "",
        "| cell | ours HOTA | ours IDF1 | best peer | its HOTA | its IDF1 | ours - best HOTA |",
        "|---|---:|---:|---|---:|---:|---:|",
    ]
    for c in cells:
        ran = {p: r[c] for p, r in peer_results.items() if c in r}
        best = max(ran, key=lambda p: ran[p]["HOTA"])
        o, b = ours[c], ran[best]
        lines.append(
            f"| {c} | {o['HOTA']:.2f} | {o['IDF1']:.2f} | {best} | {b['HOTA']:.2f} | "
            f"{b['IDF1']:.2f} | {o['HOTA'] - b['HOTA']:+.2f} |"
        )
    lines += ["", "Mean HOTA per detection source (a peer's mean over the cells it ran on):", ""]
    groups = list(dict.fromkeys(_group(c) for c in cells))
    lines += [
        "| tracker | " + " | ".join(groups) + " | all cells |",
        "|---|" + "---:|" * (len(groups) + 1),
    ]
    for name, res in {"densepeds (defaults)": ours, **peer_results}.items():
        vals = []
        for g in [*groups, None]:
            v = [m["HOTA"] for c, m in res.items() if g is None or _group(c) == g]
            vals.append(f"{np.mean(v):.2f}" if v else "-")
        lines.append(f"| {name} | " + " | ".join(vals) + " |")
    for metric in ("HOTA", "IDF1"):
        lines += ["", f"## {metric} of every tracker on every cell", ""]
        names = ["densepeds", *peer_results]
        lines += ["| cell | " + " | ".join(names) + " |", "|---|" + "---:|" * len(names)]
        for c in cells:
            row = [
                ours[c][metric],
                *(r[c][metric] if c in r else np.nan for r in peer_results.values()),
            ]
            top = np.nanmax(row)
            cellv = [
                "-" if np.isnan(v) else (f"**{v:.2f}**" if v == top else f"{v:.2f}") for v in row
            ]
            lines.append(f"| {c} | " + " | ".join(cellv) + " |")
    return lines


# --- leave-one-out defaults ---


@dataclass
class LeaveOneOut:
    cell: str
    chosen: str  # candidate best on the other cells
    held_out: float  # its HOTA on this cell
    tuned: str  # candidate best on all cells
    tuned_value: float


def leave_one_out(results: Mapping[str, Results], metric: str = "HOTA") -> list[LeaveOneOut]:
    """For every cell: the candidate with the best mean ``metric`` over the other cells, and its
    figure on the left-out cell, beside the candidate best on all cells (ties: first listed)."""
    names = list(results)
    cells = list(next(iter(results.values())))
    table = np.array([[results[n][c][metric] for c in cells] for n in names])
    tuned = int(np.argmax(table.mean(1)))
    out = []
    for j, c in enumerate(cells):
        others = np.delete(table, j, axis=1).mean(1)
        k = int(np.argmax(others))
        out.append(
            LeaveOneOut(c, names[k], float(table[k, j]), names[tuned], float(table[tuned, j]))
        )
    return out


def loo_table(results: Mapping[str, Results], skipped: Sequence[str]) -> list[str]:
    loo = leave_one_out(results)
    lines = [
        "Candidates (each overrides the package defaults on every cell): "
        + "; ".join(f"`{n}` {CANDIDATES[n] or '(none)'}" for n in results)
        + ".",
        "",
    ]
    if skipped:
        lines += [
            "Left out (a parameter the installed tracker does not have): "
            + ", ".join(f"`{s}`" for s in skipped)
            + ".",
            "",
        ]
    lines += [
        f"Tuned on all {len(loo)} cells: `{loo[0].tuned}` (best mean HOTA). Leave-one-out: "
        "for each cell, the candidate best on the other cells, and its HOTA on the cell.",
        "",
        "| cell | chosen without the cell | its HOTA there (held out) | tuned (all cells) HOTA "
        "| held out - tuned |",
        "|---|---|---:|---:|---:|",
    ]
    for r in loo:
        lines.append(
            f"| {r.cell} | {r.chosen} | {r.held_out:.2f} | {r.tuned_value:.2f} | "
            f"{r.held_out - r.tuned_value:+.2f} |"
        )
    held, tuned = np.mean([r.held_out for r in loo]), np.mean([r.tuned_value for r in loo])
    lines += [
        f"| mean | | {held:.2f} | {tuned:.2f} | {held - tuned:+.2f} |",
        "",
        "## HOTA of every candidate on every cell",
        "",
        "| candidate | " + " | ".join(next(iter(results.values()))) + " | mean |",
        "|---|" + "---:|" * (len(next(iter(results.values()))) + 1),
    ]
    for name, res in results.items():
        vals = [f"{m['HOTA']:.2f}" for m in res.values()]
        lines.append(f"| {name} | " + " | ".join(vals) + f" | {grid.mean_metric(res):.2f} |")
    return lines


# --- recall per visibility bin ---


def match_pairs(
    a: npt.NDArray[np.float64], b: npt.NDArray[np.float64], thr: float = 0.5
) -> list[tuple[int, int]]:
    """Pairs (i, j) of the one-to-one matching of boxes a to b at IoU >= thr (densepeds.boxes)."""
    from densepeds.boxes import match_boxes

    rows, cols = match_boxes(a, b, thr)
    return [(int(r), int(c)) for r, c in zip(rows, cols, strict=True)]


@dataclass
class VisibilityRecall:
    gt: list[int]  # pedestrians per bin
    found: dict[str, list[int]]  # source -> matched pedestrians per bin
    coasting_rows: int  # output rows not matched to a detection this frame
    coasting_fp: int  # of those, on no ground-truth box (pedestrian or distractor)
    output_fp: int  # all output rows on no ground-truth box
    coast_by_lost: list[tuple[int, int]]  # per LOST_BINS: (coasting rows, of those on a gt box)


def visibility_recall(
    data: grid.CellData, fed: Sequence[npt.NDArray[np.float64]], rows: grid.Rows
) -> VisibilityRecall:
    """Recall per ``VISIBILITY_BINS`` (IoU >= 0.5, one-to-one per frame) of the detector's boxes,
    the boxes the tracker was fed (after the pipeline's filtering) and the tracker's output."""
    from densepeds.io.mot import read_gt

    gt = read_gt(data.seq_dir / "gt" / "gt.txt")
    counts = [0] * len(VISIBILITY_BINS)
    found = {s: [0] * len(VISIBILITY_BINS) for s in ("detector", "fed to the tracker", "tracker")}
    coasting = coasting_fp = output_fp = 0
    by_lost = [[0, 0] for _ in LOST_BINS]
    last_matched: dict[int, int] = {}  # track id -> last frame it was matched
    for k in range(1, len(data.dets) + 1):
        g = gt[gt[:, 0] == k]
        ped = g[(g[:, 7] == 1) & (g[:, 6] != 0)]
        scored = g[(g[:, 7] == 1) & (g[:, 6] != 0) | np.isin(g[:, 7], DISTRACTOR_CLASSES)]
        boxes = np.c_[ped[:, 2:4], ped[:, 2:4] + ped[:, 4:6]]
        bins = np.digitize(ped[:, 8], [b[1] for b in VISIBILITY_BINS[:-1]])
        for b in bins:
            counts[b] += 1
        out = rows[rows[:, 0] == k]
        sources = {
            "detector": data.dets[k - 1].boxes.astype(np.float64),
            "fed to the tracker": fed[k - 1],
            "tracker": out[:, 2:6],
        }
        for name, det in sources.items():
            for i, _ in match_pairs(boxes, det):
                found[name][bins[i]] += 1
        hit = np.zeros(len(out), bool)
        all_gt = np.c_[scored[:, 2:4], scored[:, 2:4] + scored[:, 4:6]]
        for _, j in match_pairs(all_gt, out[:, 2:6]):
            hit[j] = True
        coast = out[:, 7] == 0
        coasting += int(coast.sum())
        coasting_fp += int((coast & ~hit).sum())
        output_fp += int((~hit).sum())
        for row, on_gt in zip(out, hit, strict=True):
            tid = int(row[1])
            if row[7]:
                last_matched[tid] = k
                continue
            lost = k - last_matched.get(tid, k)
            for b, (lo, hi) in enumerate(LOST_BINS):
                if lo <= lost <= hi:
                    by_lost[b][0] += 1
                    by_lost[b][1] += int(on_gt)
    return VisibilityRecall(
        counts, found, coasting, coasting_fp, output_fp, [(n, h) for n, h in by_lost]
    )


def fed_boxes(data: grid.CellData, config: grid.Config) -> list[npt.NDArray[np.float64]]:
    """The boxes the pipeline hands its tracker on each frame of a video cell."""
    pipe = grid.cell_pipeline(data, config)
    return [d.boxes[pipe._kept(d)].astype(np.float64) for d in data.dets]


def visibility_table(found: Mapping[str, VisibilityRecall]) -> list[str]:
    head = " | ".join(f"{lo:g}-{min(hi, 1.0):g}" for lo, hi in VISIBILITY_BINS)
    lines = [
        "Recall (%) of the ground-truth pedestrians per visibility bin (MOT20 gt column 9), "
        "matched one-to-one per frame at IoU >= 0.5. `detector`: every cached detection; `fed "
        "to the tracker`: after the pipeline's score floor, height floor and duplicate "
        "suppression; `tracker`: the tracker's output. Coasting rows: output boxes the tracker "
        "reported without a detection in that frame; FP: output boxes on no ground-truth box "
        "(pedestrians and MOT20 distractor classes).",
        "",
        f"| cell | tracker | boxes | {head} |",
        "|---|---|---|" + "---:|" * len(VISIBILITY_BINS),
    ]
    for key, r in found.items():
        cell, who = key.split(" :: ")
        lines.append(f"| {cell} | {who} | pedestrians | " + " | ".join(str(n) for n in r.gt) + " |")
        for src, hits in r.found.items():
            vals = " | ".join(f"{100 * h / max(n, 1):.1f}" for h, n in zip(hits, r.gt, strict=True))
            lines.append(f"| {cell} | {who} | {src} | {vals} |")
    lines += [
        "",
        "| cell | tracker | output FP | coasting rows | coasting rows that are FP |",
        "|---|---|---:|---:|---:|",
    ]
    for key, r in found.items():
        cell, who = key.split(" :: ")
        coast = f"{r.coasting_rows} | {r.coasting_fp}" if who == "densepeds" else "- | -"
        lines.append(f"| {cell} | {who} | {r.output_fp} | {coast} |")
    lost_head = " | ".join(
        f"{lo}" if lo == hi else f"{lo}+" if hi > 10**6 else f"{lo}-{hi}" for lo, hi in LOST_BINS
    )
    lines += [
        "",
        "Coasted boxes by frames since the track's last match: rows, and the share (%) on a "
        "ground-truth box (IoU >= 0.5, one-to-one with the frame's other output boxes).",
        "",
        f"| cell | {lost_head} |",
        "|---|" + "---:|" * len(LOST_BINS),
    ]
    for key, r in found.items():
        cell, who = key.split(" :: ")
        if who != "densepeds":
            continue
        vals = " | ".join(f"{n}: {100 * h / n:.0f}" if n else "0: -" for n, h in r.coast_by_lost)
        lines.append(f"| {cell} | {vals} |")
    return lines


# --- the method's claims ---

# Every side of a comparison gets the same treatment: scored at the package defaults, and over a
# band of settings of its most sensitive parameters, from which it is (a) picked leave-one-out
# (the setting best on the other cells, scored on the left-out cell: ``held_out``) and (b)
# averaged (``band_mean``). Motion: the preferred velocity's window, which every model follows,
# and each model's own parameter, each at these multiples of its default (CV has no parameter of
# its own).
BAND_FACTORS = (0.25, 0.5, 1.0, 2.0)
MOTION_BANDS: dict[str, tuple[str, ...]] = {
    "frvo": ("pref_window", "time_horizon"),
    "rvo": ("pref_window", "time_horizon"),
    "sf": ("pref_window", "sf_relaxation_time"),
    "cv": ("pref_window",),
}
# Appearance: the CNN preset's appearance_threshold plus these offsets (appearance_apart moved by
# the same offset times the preset's ratio of the two), for every feature kind alike.
THRESHOLD_OFFSETS = tuple(round(0.01 * k, 2) for k in range(-6, 7))
ALPHA = 0.05  # the sign test's level for a verdict
VERDICT_RULE = (
    "A comparison's verdict: `the first is better` (or `worse`) where the bootstrap interval "
    f"lies above (below) 0 and the sign test gives p < {ALPHA}; `leans to the first` (`second`) "
    "where only the interval does; `not separated` otherwise. Over n cells with no ties the "
    "sign test cannot go below p = 2 / 2^n: with four cells (0.125) no verdict above `leans` "
    "is possible, and the bootstrap resamples only four values."
)
CLAIM_HEAD = (
    "| comparison | treatment | cells | wins / ties / losses | sign test p | mean HOTA diff "
    "| 95% interval | verdict |"
)
TREATMENTS = (
    ("defaults", "package defaults"),
    ("held_out", "each its own setting, leave-one-out"),
    ("band_mean", "each averaged over its band"),
)


@dataclass
class Side:
    """One side of a claim: its figures at the package defaults and over its band of settings
    (setting label -> results; empty where it has none)."""

    defaults: Results
    band: dict[str, Results]

    def treated(self, how: str) -> Results | None:
        if how == "defaults":
            return self.defaults
        if not self.band:
            return None
        return held_out(self.band)[0] if how == "held_out" else band_mean(self.band)


def held_out(band: Mapping[str, Results]) -> tuple[Results, dict[str, str]]:
    """Per cell, the HOTA of the setting best (mean HOTA) on the other cells, and that setting."""
    picks = leave_one_out(band)
    return {r.cell: {"HOTA": r.held_out} for r in picks}, {r.cell: r.chosen for r in picks}


def band_mean(band: Mapping[str, Results]) -> Results:
    """Per cell, the mean HOTA over the band's settings."""
    cells = list(next(iter(band.values())))
    return {c: {"HOTA": float(np.mean([r[c]["HOTA"] for r in band.values()]))} for c in cells}


def motion_band(model: str) -> dict[str, dict[str, Any]]:
    """Setting label -> tracker parameters: ``MOTION_BANDS[model]`` at ``BAND_FACTORS`` times the
    defaults, every combination."""
    from itertools import product

    from densepeds.tracking import Tracker

    defaults = Tracker().params
    names = MOTION_BANDS[model]
    out = {}
    for factors in product(BAND_FACTORS, repeat=len(names)):
        params = {
            n: type(defaults[n])(f * defaults[n]) for n, f in zip(names, factors, strict=True)
        }
        out[" ".join(f"{n}={v}" for n, v in params.items())] = params
    return out


def threshold_band() -> dict[str, dict[str, Any]]:
    """Setting label -> CNN parameters: the preset's appearance_threshold plus
    ``THRESHOLD_OFFSETS``, appearance_apart at the preset's ratio."""
    from densepeds.presets import PRESETS

    preset = PRESETS["yoloseg"].tracker
    thr, apart = float(preset["appearance_threshold"]), float(preset["appearance_apart"])
    return {
        f"{thr + off:.2f}": {
            "appearance_threshold": round(thr + off, 4),
            "appearance_apart": round(apart + off * apart / thr, 4),
        }
        for off in THRESHOLD_OFFSETS
    }


def paired(
    a: Results, b: Results, rng: np.random.Generator
) -> tuple[int, int, int, float, float, float, float]:
    """Wins, ties, losses of a over b (HOTA per cell), the sign test's two-sided p, the mean
    difference and a 95% bootstrap interval of it over cells."""
    from scipy.stats import binomtest

    d = np.array([a[c]["HOTA"] - b[c]["HOTA"] for c in a])
    wins, losses = int((d > 0.005).sum()), int((d < -0.005).sum())
    ties = len(d) - wins - losses
    p = binomtest(wins, wins + losses, 0.5).pvalue if wins + losses else 1.0
    means = d[rng.integers(0, len(d), (BOOTSTRAP, len(d)))].mean(1)
    lo, hi = np.percentile(means, [2.5, 97.5])
    return wins, ties, losses, float(p), float(d.mean()), float(lo), float(hi)


def verdict(p: float, lo: float, hi: float) -> str:
    """The verdict of ``VERDICT_RULE`` from the sign test's p and the bootstrap interval."""
    if lo > 0:
        return "the first is better" if p < ALPHA else "leans to the first"
    if hi < 0:
        return "the first is worse" if p < ALPHA else "leans to the second"
    return "not separated"


def _claim_line(
    label: str, treatment: str, a: Results, b: Results, rng: np.random.Generator
) -> str:
    w, t, l_, p, mean, lo, hi = paired(a, b, rng)
    return (
        f"| {label} | {treatment} | {len(a)} | {w} / {t} / {l_} | {p:.3f} | {mean:+.2f} | "
        f"[{lo:+.2f}, {hi:+.2f}] | {verdict(p, lo, hi)} |"
    )


def _claim_rows(first: str, sides: Mapping[str, Side], rng: np.random.Generator) -> list[str]:
    lines = []
    for other, side in sides.items():
        if other == first:
            continue
        for how, words in TREATMENTS:
            a, b = sides[first].treated(how), side.treated(how)
            if a is not None and b is not None:
                lines.append(_claim_line(f"{first} vs {other}", words, a, b, rng))
    return lines


def _band_tables(title: str, sides: Mapping[str, Side], what: str) -> list[str]:
    banded = {k: s for k, s in sides.items() if s.band}
    cells = list(next(iter(banded.values())).defaults)
    picks = {k: held_out(s.band) for k, s in banded.items()}
    means = {k: band_mean(s.band) for k, s in banded.items()}
    lines = [
        "",
        f"### {title}: leave-one-out pick and band mean per cell",
        "",
        f"{what} Each entry: the HOTA, on the cell, of the setting best on the other cells "
        "(that setting in brackets), and the mean HOTA over the band.",
        "",
        "| cell | " + " | ".join(f"{k} held out | {k} band mean" for k in banded) + " |",
        "|---|" + "---:|---:|" * len(banded),
    ]
    for c in cells:
        vals = [
            f"{picks[k][0][c]['HOTA']:.2f} ({picks[k][1][c]}) | {means[k][c]['HOTA']:.2f}"
            for k in banded
        ]
        lines.append(f"| {c} | " + " | ".join(vals) + " |")
    lines += ["", f"### {title}: mean HOTA over the cells of every setting", ""]
    labels = [list(s.band) for s in banded.values()]
    if all(ls == labels[0] for ls in labels):  # one band for every side: a side per row
        lines += [
            "| side | " + " | ".join(labels[0]) + " |",
            "|---|" + "---:|" * len(labels[0]),
        ]
        for k, s in banded.items():
            vals = " | ".join(f"{grid.mean_metric(r):.2f}" for r in s.band.values())
            lines.append(f"| {k} | {vals} |")
        return lines
    lines += ["| side | setting | mean HOTA |", "|---|---|---:|"]
    for k, s in banded.items():
        for label, res in s.band.items():
            lines.append(f"| {k} | {label} | {grid.mean_metric(res):.2f} |")
    return lines


def claims_table(
    motions: Mapping[str, Side],
    features: Mapping[str, Side],
) -> list[str]:
    """``motions`` / ``features``: each side, the method's first (FRVO, segmented)."""
    rng = np.random.default_rng(0)
    motion_what = (
        "Bands: "
        + "; ".join(f"{m}: {', '.join(p)}" for m, p in MOTION_BANDS.items())
        + f", each at {', '.join(f'{f:g}' for f in BAND_FACTORS)} times its default, every "
        "combination."
    )
    feature_what = (
        "Band: the CNN preset's appearance_threshold "
        f"{THRESHOLD_OFFSETS[0]:+.2f} to {THRESHOLD_OFFSETS[-1]:+.2f} in steps of 0.01, "
        "appearance_apart moved in the preset's ratio; `none` has no threshold."
    )
    lines = [
        "HOTA differences per cell, paired. Sign test: two-sided binomial test on the cells "
        "where the two differ by more than 0.005; interval: 95% percentile bootstrap "
        f"({BOOTSTRAP} resamples of the cells) of the mean difference. {VERDICT_RULE}",
        "",
        "Each side gets the same treatment: at the package defaults (tuned with FRVO and "
        "segmented boxes, which favours them); at its own setting from a band of its most "
        "sensitive parameters, picked for each cell on the other cells (leave-one-out, so no "
        "cell scores the setting picked on it); and averaged over that band. "
        f"{motion_what} {feature_what}",
        "",
        "## Motion model (every cell; video cells with the default features)",
        "",
        CLAIM_HEAD,
        "|---|---|---:|---|---:|---:|---|---|",
        *_claim_rows("frvo", motions, rng),
    ]
    lines += [
        "",
        "## Appearance features (video cells, FRVO)",
        "",
        CLAIM_HEAD,
        "|---|---|---:|---|---:|---:|---|---|",
        *_claim_rows("segmented", features, rng),
    ]
    groups: list[tuple[str, Mapping[str, Results]]] = [
        ("motion model, package defaults", {k: s.defaults for k, s in motions.items()}),
        ("features, package defaults", {k: s.defaults for k, s in features.items()}),
    ]
    for title, group in groups:
        cells = list(next(iter(group.values())))
        lines += [
            "",
            f"### HOTA per cell ({title})",
            "",
            "| cell | " + " | ".join(group) + " |",
            "|---|" + "---:|" * len(group),
        ]
        for c in cells:
            lines.append(
                f"| {c} | " + " | ".join(f"{r[c]['HOTA']:.2f}" for r in group.values()) + " |"
            )
    lines += _band_tables("Motion model", motions, motion_what)
    lines += _band_tables("Features", features, feature_what)
    return lines


# --- the built-in scene ---

SCENE_MASKS: dict[str, dict[str, int]] = {
    "exact": {},
    "dilated 3 px": {"mask_dilate": 3},
    "eroded 2 px": {"mask_dilate": -2},
    "shifted up to 4 px": {"mask_shift": 4},
    "dilated 3 px + shifted 4 px": {"mask_dilate": 3, "mask_shift": 4},
}
SCENE_KINDS = ("segmented", "masked_pool", "bbox", "none")


def scene_ablation(seed: int = 0, frames: int = 150) -> dict[str, dict[str, dict[str, float]]]:
    """Metrics per mask setting and features (FRVO, the tracker's defaults) on the scene."""
    import tempfile

    from densepeds.evaluate import evaluate
    from densepeds.io.mot import write_tracks
    from densepeds.pipeline import Pipeline, track_rows
    from densepeds.scene import make_scene

    out: dict[str, dict[str, dict[str, float]]] = {}
    with tempfile.TemporaryDirectory(prefix="densepeds-scene-") as tmp:
        for label, noise in SCENE_MASKS.items():
            scene = make_scene(seed=seed, frames=frames, **noise)
            seq = scene.write(Path(tmp) / label.replace(" ", "_"), images=False)
            emb = scene.embedder()
            images = dict(scene.frames())
            out[label] = {}
            for kind in SCENE_KINDS:
                pipe = Pipeline(None, motion="frvo", features=kind)
                rows: list[tuple[float, ...]] = []
                for k in range(1, scene.length + 1):
                    d = scene.detections.get(k)
                    if d is None:
                        continue
                    image = images[k]
                    assert image is not None
                    e = None if kind == "none" else emb.embed(image, d, kind)
                    rows += track_rows(k, pipe.step(None, d, embeddings=e))
                path = Path(tmp) / f"{label}-{kind}.txt"
                write_tracks(path, rows)
                out[label][kind] = evaluate([seq], path).combined
            _log(f"scene, {label} masks: done")
    return out


def scene_table(res: Mapping[str, Mapping[str, Mapping[str, float]]]) -> list[str]:
    lines = [
        "The built-in scene (`densepeds.scene.make_scene(seed=0, frames=150)`), its stand-in "
        "detector's boxes and masks, its colour-histogram embedder, FRVO with the tracker's "
        "defaults. With exact masks a mask holds only the person's own visible pixels, so "
        "masking beats the plain box by construction; the noisy rows make the masks grow, "
        "shrink or slide (`SceneConfig.mask_dilate`, `mask_shift`) as a real segmenter's do. "
        "The histogram embedder is not OSNet: these rows test the pipeline's plumbing of the "
        "masking, not the method's claim (that is `accuracy-claims.md`).",
        "",
        "| masks | " + " | ".join(f"{k} HOTA / IDF1" for k in SCENE_KINDS) + " |",
        "|---|" + "---:|" * len(SCENE_KINDS),
    ]
    for label, by_kind in res.items():
        vals = [f"{by_kind[k]['HOTA']:.1f} / {by_kind[k]['IDF1']:.1f}" for k in SCENE_KINDS]
        lines.append(f"| {label} | " + " | ".join(vals) + " |")
    return lines


# --- everything ---


def _known(params: Mapping[str, Any]) -> bool:
    from densepeds.tracking import Tracker

    names = set(Tracker().params)
    return all(k in names for k in params)


TABLES = ("peers", "loo", "visibility", "claims", "scene", "realvideo")


def _peer_results(data: Sequence[grid.CellData], ours: grid.Config) -> dict[str, Results]:
    return {name: _run(data, replace(ours, tracker=name)) for name in peers.PEERS}


def write_all(
    cache: Path,
    quiet: bool = False,
    out: Path = RESULTS,
    cells: Sequence[grid.Cell] = grid.CELLS,
    tables: Sequence[str] = TABLES,
) -> int:
    """Compute and write the ``tables`` (``cells``: a subset for a quick look; ``out``: where;
    ``realvideo.md`` only for the whole grid into ``RESULTS``)."""
    t0 = time.perf_counter()
    unknown = sorted(set(tables) - set(TABLES))
    if unknown:
        sys.exit(f"unknown tables {unknown}: expected some of {', '.join(TABLES)}")
    data = grid.load_grid(cells, cache, grid.FEATURE_KINDS, quiet)
    ours = grid.Config()
    rows: dict[str, grid.Rows] = {}
    default = _run(data, ours, rows)
    peer_results: dict[str, Results] = {}

    if "peers" in tables:
        peer_results = _peer_results(data, ours)
        write_table(
            out,
            "accuracy.md",
            _header(
                "Accuracy on the dev grid: DensePeds against established trackers on equal inputs",
                "Every tracker gets the same boxes and scores per frame (on the videos, the "
                "boxes the pipeline hands its own tracker, with the same OSNet embeddings, "
                f"which the peers that use appearance take: {', '.join(peers.APPEARANCE)}). "
                "Peers run with their package defaults (the sequence's frame rate where a peer "
                f"asks for it); {', '.join(peers.NEEDS_EMBEDDINGS)} need embeddings and run on "
                "the video cells only.",
            )
            + peers_table(default, peer_results),
        )

    if "loo" in tables:
        usable = {n: p for n, p in CANDIDATES.items() if _known(p)}
        skipped = [n for n in CANDIDATES if n not in usable]
        cand_results = {"package defaults": default}
        for name, params in usable.items():
            if params:
                cand_results[name] = _run(data, replace(ours, params=params))
        write_table(
            out,
            "accuracy-loo.md",
            _header(
                "Leave-one-out defaults on the dev grid",
                "How much of each cell's figure comes from having tuned on it: a small set of "
                "candidate settings is scored on every cell; for each cell the candidate best "
                "on the other cells is chosen and its figure on the left-out cell reported.",
            )
            + loo_table(cand_results, skipped),
        )

    by_name = {d.cell.name: d for d in data}
    vis_cells = [by_name[c] for c in VISIBILITY_CELLS if c in by_name]
    if "visibility" in tables and vis_cells:
        if not peer_results:
            peer_results = _peer_results(vis_cells, ours)
        found: dict[str, VisibilityRecall] = {}
        for d in vis_cells:
            cell = d.cell.name
            fed = fed_boxes(d, ours)
            found[f"{cell} :: densepeds"] = visibility_recall(d, fed, rows[cell])
            best = max(peer_results, key=lambda p: peer_results[p].get(cell, {}).get("HOTA", -1))
            peer_rows: dict[str, grid.Rows] = {}
            grid.score_grid([d], replace(ours, tracker=best), peer_rows)
            found[f"{cell} :: {best}"] = visibility_recall(d, fed, peer_rows[cell])
        write_table(
            out,
            "accuracy-visibility.md",
            _header(
                "Who is found at each visibility: detector against tracker (MOT20-01-dev)",
                "Our tracker with the package defaults and the peer best on the cell by HOTA "
                "(peers do not say which detection a track took, so their coasting is not "
                "counted).",
            )
            + visibility_table(found),
        )

    if "claims" in tables:
        motions = {}
        for m in MOTION_ROWS:
            band = {
                label: _run(data, replace(ours, motion=m, params=params))
                for label, params in motion_band(m).items()
            }
            base = default if m == "frvo" else _run(data, replace(ours, motion=m))
            motions[m] = Side(base, band)
        videos = [d for d in data if d.cell.full_pipeline]
        features = {}
        for f in FEATURE_ROWS:
            band = (
                {
                    label: _run(videos, replace(ours, features=f, cnn_params=params))
                    for label, params in threshold_band().items()
                }
                if f != "none"
                else {}
            )
            base = _run(videos, replace(ours, features=f))
            features[f] = Side(base, band)
        write_table(
            out,
            "accuracy-claims.md",
            _header(
                "The method's claims on the dev grid: FRVO and segmented boxes",
                "FRVO against RVO, social forces (SF) and constant velocity (CV); the method's "
                "segmented boxes (white fill outside the mask) against the plain box (`bbox`), "
                "mask-weighted pooling (`masked_pool`) and no appearance (`none`); every other "
                "setting at the package defaults.",
            )
            + claims_table(motions, features),
        )

    if "scene" in tables:
        write_table(
            out,
            "accuracy-scene.md",
            ["# The masking ablation on the built-in scene, exact and noisy masks", ""]
            + scene_table(scene_ablation()),
        )
    whole = out == RESULTS and len(cells) == len(grid.CELLS)
    if "realvideo" in tables and whole:
        realvideo.main(["--cache", str(cache), "--quiet", "--write", str(out / "realvideo.md")])
    _log(f"tables {', '.join(tables)} in {time.perf_counter() - t0:.0f} s")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``accuracy_grid.py --write``: every table, or ``--tables`` of them."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    ap.add_argument("--results", type=Path, help="write here instead (a quick look)")
    ap.add_argument("--cells", nargs="+", help="glob patterns over SEQ/SOURCE (default: all)")
    ap.add_argument("--tables", nargs="+", help=f"only these ({' '.join(TABLES)})")
    ap.add_argument("--quiet", "-q", action="store_true")
    args = ap.parse_args(argv)
    return write_all(
        args.cache,
        quiet=args.quiet,
        out=args.results or RESULTS,
        cells=grid.select_cells(args.cells),
        tables=args.tables or TABLES,
    )


if __name__ == "__main__":
    sys.exit(main())
