"""The block table: each of the tracker's extensions switched off in turn on the dev grid, and
whether it earns its place by leave-one-out over the cells and leave-one-family-out.

    OPENBLAS_NUM_THREADS=1 python benchmarks/blocks.py          # -> benchmarks/results/blocks.md
    python benchmarks/blocks.py --blocks 'newborn re-ID' --cells '*/det'   # a quick look

Every block is scored by the dev grid of ``accuracy_grid.py`` (the same cells, inputs and
scoring) twice: at the package defaults (block as shipped) and with the block switched off on
every cell (its ``off`` overrides, on top of the defaults and the CNN preset). A block earns its
place when the choice made without a cell (on or off, by mean HOTA over the other cells) scores,
over the held-out cells, above the block switched off (leave-one-out), and the same holds with a
whole family of sequences held out at a time (leave-one-family-out); it is removed where neither
holds. A tie goes to off: a block is a cost to every user.

The families are read from each sequence's facts, once, here (``FAMILIES``): its frame rate
(``seqinfo.ini``), the people per frame and how fast their boxes change scale (a moving camera
walks or drives toward them) in its ground truth. Per-cell results are kept in ``out/blocks``
(keyed by the overrides and the built extension), so a second run only scores what changed.
"""

from __future__ import annotations

import argparse
import fnmatch
import hashlib
import json
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402

RESULTS = grid.REPO / "benchmarks" / "results"
COMMAND = "OPENBLAS_NUM_THREADS=1 python benchmarks/blocks.py"
Results = dict[str, dict[str, float]]  # cell name -> metrics


@dataclass(frozen=True)
class Block:
    what: str
    off: Mapping[str, Any]  # the overrides that switch it off on every cell


BLOCKS: dict[str, Block] = {
    "score calibration": Block(
        "the score cuts follow the detector's scores: a quantile floor, a ceiling for a "
        "detector scoring below the cuts, a smaller second-pass overlap for a detector that "
        "thresholds its own output",
        {"score_quantile_floor": 0.0, "score_quantile_ceiling": 0.0, "thresholded_low_iou": 1.0},
    ),
    "second pass": Block(
        "ByteTrack's low-score detections extend unmatched tracks", {"second_pass": False}
    ),
    "recovery": Block(
        "OC-SORT's re-match of lost tracks by their last observed box (off in the CNN preset)",
        {"recovery": False},
    ),
    "occlusion-aware coasting": Block(
        "an unmatched track covered by nearer people is reported up to `occluded_output` frames; "
        "one that left the image is deleted",
        {"occluded_output": 0},
    ),
    "adaptive lost reports": Block(
        "a lost track is reported only while lost tracks were re-found at their prediction at "
        "least as often as not (off in the CNN preset)",
        {"output_lost_adaptive": False},
    ),
    "young lost tracks hidden": Block(
        "a lost track is reported only after `coast_min_hits` matches", {"coast_min_hits": 0}
    ),
    "tentative tracks": Block(
        "a tentative track waits `tentative_max_age` frames for a weak detection",
        {"tentative_max_age": 0},
    ),
    "jitter smoothing": Block(
        "the matched centre leans on the prediction as much as the detector's measured jitter "
        "calls for (`jitter_floor`)",
        {"jitter_floor": 0.0},
    ),
    "position smoothing": Block(
        "the reported centre leans on the prediction (`position_smoothing`)",
        {"position_smoothing": 0.0},
    ),
    "lost-box aspect": Block(
        "a lost track keeps the width of a person seen whole (`coast_aspect`, "
        "`coast_aspect_quantile`, `coast_aspect_state`)",
        {"coast_aspect": False, "coast_aspect_quantile": 0.0, "coast_aspect_state": False},
    ),
    "amodal boxes": Block(
        "a box hidden below by a nearer one is completed from the fitted perspective (CNN preset)",
        {"amodal_boxes": False},
    ),
    "amodal widths": Block(
        "a matched box is reported at least as wide as a person seen whole (CNN preset)",
        {"amodal_width_quantile": 0.0},
    ),
    "appearance apart": Block(
        "a detection off the predicted box needs a closer appearance (CNN preset)",
        {"appearance_apart": 2.0},
    ),
    "newborn re-ID": Block(
        "a young track takes a lost one's id where their appearance agrees (`reid_newborn`)",
        {"reid_newborn": 0},
    ),
}


@dataclass(frozen=True)
class SceneFacts:
    seq: str
    fps: float
    people: float  # ground-truth people per frame (frames with any)
    scale_change: float  # mean |d ln(box height) / dt| per second over ground-truth tracks


def scene_facts(seq_dir: Path) -> SceneFacts:
    """A sequence's facts from its ``seqinfo.ini`` and ``gt/gt.txt`` (nine columns, MOT16-20:
    the pedestrians that count, flag 1 and class 1; ten, MOT15: every row)."""
    from densepeds.io import mot as motio

    info = motio.read_seqinfo(seq_dir)
    g = np.loadtxt(seq_dir / "gt" / "gt.txt", delimiter=",", ndmin=2)
    if g.shape[1] == 9:
        g = g[(g[:, 6] == 1) & (g[:, 7] == 1)]
    per_frame = np.bincount(g[:, 0].astype(int))
    rates: list[float] = []
    for tid in np.unique(g[:, 1]):
        t = g[g[:, 1] == tid]
        t = t[np.argsort(t[:, 0])]
        step = np.diff(t[:, 0]) == 1
        rates += list(np.abs(np.diff(np.log(t[:, 5])))[step] * info.fps)
    return SceneFacts(
        seq_dir.name,
        float(info.fps),
        float(per_frame[per_frame > 0].mean()),
        float(np.mean(rates)) if rates else 0.0,
    )


DENSE_PEOPLE = 10.0  # people per frame
MOVING_SCALE = 0.08  # |d ln h / dt| per second: a camera walking or driving toward the people
LOW_FPS = 15.0
FAMILIES: dict[str, Callable[[SceneFacts], bool]] = {
    f"dense crowd (>= {DENSE_PEOPLE:.0f} people per frame)": lambda f: f.people >= DENSE_PEOPLE,
    f"moving camera (boxes change scale >= {MOVING_SCALE} per second)": (
        lambda f: f.scale_change >= MOVING_SCALE
    ),
    f"low frame rate (< {LOW_FPS:.0f} fps)": lambda f: f.fps < LOW_FPS,
    "static camera, few people": (
        lambda f: f.people < DENSE_PEOPLE and f.scale_change < MOVING_SCALE
    ),
}


def families(cells: Sequence[str], facts: Mapping[str, SceneFacts]) -> dict[str, list[str]]:
    """The cells of each family (a cell belongs to its sequence's families)."""
    out = {}
    for name, rule in FAMILIES.items():
        out[name] = [c for c in cells if rule(facts[c.split("/")[0]])]
    return out


@dataclass(frozen=True)
class Verdict:
    mean_on: float
    mean_off: float
    wins: int  # cells where on beats off
    loo: float  # mean over cells of the choice made without the cell, minus off there
    loo_on: int  # leave-one-out folds that chose on
    lofo: dict[str, tuple[bool, float]]  # family -> (chose on without it, gain on it vs off)

    @property
    def verdict(self) -> str:
        """``earns its place`` (above off under both), ``removed`` (no better under either) or
        ``kept, not confirmed across families`` (better under one only)."""
        lofo = sum(g for _, g in self.lofo.values())
        if self.loo > 0 and lofo > 0:
            return "earns its place"
        if self.loo <= 0 and lofo <= 0:
            return "removed"
        return "kept, not confirmed across families"


def judge(on: Results, off: Results, fams: Mapping[str, Sequence[str]]) -> Verdict:
    """Leave-one-out and leave-one-family-out choice between a block on and off (HOTA)."""
    cells = [c for c in on if c in off]
    a = np.array([on[c]["HOTA"] for c in cells])
    b = np.array([off[c]["HOTA"] for c in cells])
    held, chose_on = [], 0
    for k in range(len(cells)):
        rest = np.arange(len(cells)) != k
        pick_on = bool(a[rest].mean() > b[rest].mean())
        chose_on += pick_on
        held.append((a[k] if pick_on else b[k]) - b[k])
    lofo = {}
    for fam, members in fams.items():
        inside = np.array([c in members for c in cells])
        if not inside.any() or inside.all():
            continue
        pick_on = bool(a[~inside].mean() > b[~inside].mean())
        lofo[fam] = (pick_on, float((a[inside] - b[inside]).mean()) if pick_on else 0.0)
    return Verdict(
        float(a.mean()), float(b.mean()), int((a > b).sum()), float(np.mean(held)), chose_on, lofo
    )


def _stamp() -> str:
    """The built extension's digest: cached results are reused only for the same tracker."""
    import densepeds._core as core

    return hashlib.sha256(Path(core.__file__).read_bytes()).hexdigest()[:16]


def scored(
    data: Sequence[grid.CellData], params: Mapping[str, Any], store: Path, stamp: str
) -> Results:
    """The grid's metrics with ``params`` on every cell, from ``store`` where already scored."""
    key = hashlib.sha256(json.dumps(dict(params), sort_keys=True).encode()).hexdigest()[:12]
    path = store / f"{key}.json"
    kept: dict[str, Any] = json.loads(path.read_text()) if path.is_file() else {}
    res: Results = kept.get("cells", {}) if kept.get("stamp") == stamp else {}
    todo = [d for d in data if d.cell.name not in res]
    if todo:
        res.update(grid.score_grid(todo, grid.Config(params=dict(params)), progress=_log))
        store.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"stamp": stamp, "params": dict(params), "cells": res}))
    return {d.cell.name: res[d.cell.name] for d in data}


def _log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def table(
    base: Results,
    offs: Mapping[str, Results],
    facts: Mapping[str, SceneFacts],
) -> list[str]:
    cells = list(base)
    fams = families(cells, facts)
    lines = [
        "# The block table: each extension on and off, leave-one-out and leave-one-family-out",
        "",
        "Written by this command (do not edit; rerun it):",
        "",
        f"    {COMMAND}",
        "",
        f"The dev grid of `accuracy_grid.py` ({len(cells)} cells: "
        + ", ".join(f"`{c}`" for c in cells)
        + "), each block switched off on every cell against the package defaults (the block as "
        "shipped; the CNN preset on the video cells). HOTA. `LOO`: for each cell, on or off as "
        "the other cells choose, minus off on that cell, averaged over the cells. `LOFO`: for "
        "each family, on or off as the cells outside it choose, minus off, averaged over its "
        "cells (`off`: the cells outside it chose off). A block earns its place where both are "
        "above 0 (LOFO summed over the families); it is removed where neither is (a tie goes "
        "to off); a block better under one only is kept and said to be not confirmed across "
        "families (it helps where it was tuned, mostly the two videos' CNN preset).",
        "",
        "Families, from each sequence's facts (`seqinfo.ini`; people per frame and the rate at "
        "which their boxes change scale, in its ground truth):",
        "",
        "| sequence | fps | people per frame | scale change per second | families |",
        "|---|---:|---:|---:|---|",
    ]
    for seq, f in facts.items():
        names = [n.split(" (")[0] for n, rule in FAMILIES.items() if rule(f)]
        lines.append(
            f"| {seq} | {f.fps:.0f} | {f.people:.1f} | {f.scale_change:.3f} | {', '.join(names)} |"
        )
    short = [n.split(" (")[0] for n in fams]
    lines += [
        "",
        f"Package defaults: mean HOTA {grid.mean_metric(base):.2f} over {len(base)} cells.",
        "",
        "| block | off | mean on | mean off | cells on > off | LOO | LOO folds on | "
        + " | ".join(f"LOFO {s}" for s in short)
        + " | verdict |",
        "|---|---|---:|---:|---:|---:|---:|" + "---:|" * len(short) + "---|",
    ]
    for name, res in offs.items():
        v = judge(base, res, fams)
        lofo = [
            (f"{v.lofo[f][1]:+.2f}" if v.lofo[f][0] else "off") if f in v.lofo else "-"
            for f in fams
        ]
        off = ", ".join(f"{k}={val}" for k, val in BLOCKS[name].off.items())
        lines.append(
            f"| {name} | `{off}` | {v.mean_on:.2f} | {v.mean_off:.2f} | {v.wins}/{len(cells)} | "
            f"{v.loo:+.2f} | {v.loo_on}/{len(cells)} | " + " | ".join(lofo) + f" | {v.verdict} |"
        )
    lines += ["", "What each block does:", ""]
    lines += [f"- {name}: {BLOCKS[name].what}." for name in offs]
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    ap.add_argument("--store", type=Path, default=grid.REPO / "out" / "blocks")
    ap.add_argument("--cells", nargs="+", help="glob patterns over SEQ/SOURCE (default: all)")
    ap.add_argument("--blocks", nargs="+", help="glob patterns over block names (default: all)")
    ap.add_argument("--out", type=Path, default=RESULTS / "blocks.md")
    args = ap.parse_args(argv)
    from densepeds.tracking import Tracker

    known = set(Tracker().params)
    names = [
        b
        for b in BLOCKS
        if (not args.blocks or any(fnmatch.fnmatch(b, p) for p in args.blocks))
        and set(BLOCKS[b].off) <= known
    ]
    cells = grid.select_cells(args.cells)
    data = grid.load_grid(cells, args.cache, (grid.Config().kind(),))
    stamp = _stamp()
    base = scored(data, {}, args.store, stamp)
    offs = {b: scored(data, BLOCKS[b].off, args.store, stamp) for b in names}
    facts = {s: scene_facts(grid.SHARED / "data" / s) for s in dict.fromkeys(c.seq for c in cells)}
    text = "\n".join(table(base, offs, facts)) + "\n"
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
