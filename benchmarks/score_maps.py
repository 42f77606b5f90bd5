"""Accuracy when the detector's scores change scale: dev cells (by default the motion-only ones)
with every detection's score passed through a monotone map (boxes unchanged), ours and the peers.

    python benchmarks/score_maps.py                                   # print the table
    python benchmarks/score_maps.py --write benchmarks/results/score-maps.md
    python benchmarks/score_maps.py --trackers densepeds motpy --maps x0.3 cube
    python benchmarks/score_maps.py --ours score_quantile_ceiling=0 --ours max_age=30
    python benchmarks/score_maps.py --cells '*/float' '*/int8'        # the video cells

A detector other than the ones the defaults were chosen on may score the same boxes lower,
higher or with another spread. Each map below stands for such a detector: the cells' boxes, and
the order of their scores, stay as they are. Cells: by default the grid's motion-only cells
(``accuracy_grid.py``: ``*/det`` and ``*/frcnn``; ``--cells`` takes its patterns), read from the
same cache (a video cell's scores are those the detector kept above its floor), tracked through
``densepeds.Pipeline.step`` and scored with ``densepeds.evaluate``. The figure per map and
tracker is the mean HOTA over the cells, with the lowest cell. ``--ours KEY=VALUE`` adds a
column: our tracker with that parameter changed (by default the score ceiling off, the rule
before it).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402
import peers  # noqa: E402

Scores = npt.NDArray[np.float64]
# name -> (what it stands for, the map of the scores s in [0, 1] as the cells hold them).
MAPS: dict[str, tuple[str, Callable[[Scores], Scores]]] = {
    "identity": ("s (the scores as given)", lambda s: s),
    "cube": ("s^3 (fewer confident scores)", lambda s: s**3),
    "sqrt": ("sqrt(s) (more confident scores)", np.sqrt),
    "x0.3": ("0.3 s (every score below 0.3)", lambda s: 0.3 * s),
    "half+": ("0.5 + 0.5 s (every score above 0.5)", lambda s: 0.5 + 0.5 * s),
}
CELLS = ("*/det", "*/frcnn")
# Our tracker with one parameter changed, beside its defaults (the score ceiling off by default).
OURS_VARIANTS = ("score_quantile_ceiling=0",)
# Ours and the peers that track from boxes and scores alone (peers.py), in the table's order.
TRACKERS = (
    "densepeds",
    *(p for p in peers.PEERS if p not in peers.APPEARANCE and p != "iou-baseline"),
)


def mapped(data: grid.CellData, f: Callable[[Scores], Scores]) -> grid.CellData:
    """The cell with every detection's score passed through ``f`` (float32 as the cache's)."""
    dets = [
        dataclasses.replace(d, scores=f(np.asarray(d.scores, np.float64)).astype(np.float32))
        for d in data.dets
    ]
    return dataclasses.replace(data, dets=dets)


def hota_per_cell(
    datas: Sequence[grid.CellData], config: grid.Config, f: Callable[[Scores], Scores], tmp: Path
) -> list[float]:
    out = []
    for data in datas:
        d = mapped(data, f)
        rows = grid.track_cell(d, config)
        out.append(grid.score_cell(d, rows, tmp)["HOTA"])
    return out


def markdown(
    results: dict[str, dict[str, list[float]]],
    patterns: Sequence[str],
    cells: Sequence[str],
    elapsed: float,
    load: tuple[float, float, float],
) -> list[str]:
    trackers = list(next(iter(results.values())))
    vers = ", ".join(f"{k} {v}" for k, v in peers.versions().items())
    lines = [
        "# Accuracy under a change of score scale",
        "",
        "Written by `python benchmarks/score_maps.py --write benchmarks/results/score-maps.md`.",
        "Every detection's score on the dev cells (`"
        + "`, `".join(patterns)
        + f"`: {len(cells)} cells) is passed through a monotone map, the boxes unchanged, and "
        "every tracker runs with its package defaults (a `densepeds KEY=VALUE` column: ours with "
        "that one parameter changed). Mean HOTA over the cells (lowest cell in brackets); the "
        "best figure per map in bold.",
        "",
        f"Versions: {vers}. Machine: {platform.machine()}, {os.cpu_count()} cores; load average "
        f"{load[0]:.2f} {load[1]:.2f} {load[2]:.2f} at the start; {elapsed:.0f} s.",
        "",
        "| map of the score s | " + " | ".join(trackers) + " |",
        "|---|" + "---:|" * len(trackers),
    ]
    for name, per in results.items():
        means = {t: float(np.mean(v)) for t, v in per.items()}
        best = max(means.values())
        cells_txt = []
        for t in trackers:
            txt = f"{means[t]:.2f} ({min(per[t]):.1f})"
            cells_txt.append(f"**{txt}**" if means[t] == best else txt)
        lines.append(f"| {MAPS[name][0]} | " + " | ".join(cells_txt) + " |")
    lines += [
        "",
        "## HOTA per cell",
        "",
        "| map | tracker | " + " | ".join(cells) + " |",
        "|---|---|" + "---:|" * len(cells),
    ]
    for name, per in results.items():
        for t, v in per.items():
            lines.append(f"| {name} | {t} | " + " | ".join(f"{h:.2f}" for h in v) + " |")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    ap.add_argument("--cells", nargs="+", default=list(CELLS), help="accuracy_grid cell patterns")
    ap.add_argument("--maps", nargs="+", choices=list(MAPS), default=list(MAPS))
    ap.add_argument("--trackers", nargs="+", default=list(TRACKERS))
    ap.add_argument(
        "--ours",
        action="append",
        help="KEY=VALUE: a column for our tracker with this parameter "
        f"(default: {' '.join(OURS_VARIANTS)})",
    )
    ap.add_argument("--write", type=Path, help="write the Markdown table here")
    args = ap.parse_args(argv)
    unknown = [t for t in args.trackers if t != "densepeds" and t not in peers.PEERS]
    if unknown:
        ap.error(f"unknown tracker {unknown[0]!r}; known: densepeds, {', '.join(peers.PEERS)}")
    configs = {
        t: grid.Config(tracker=t) for t in args.trackers if t == "densepeds" or t in peers.PEERS
    }
    if "densepeds" in args.trackers:
        for item in OURS_VARIANTS if args.ours is None else args.ours:
            configs[f"densepeds {item}"] = grid.Config(params=grid.parse_params([item]))
        # Ours first, then its variants, then the peers as asked.
        order = ["densepeds", *(k for k in configs if k.startswith("densepeds "))]
        configs = {k: configs[k] for k in [*order, *(k for k in configs if k not in order)]}
    load = os.getloadavg()
    start = time.perf_counter()
    cells = grid.select_cells(args.cells)
    datas = [grid.load_cell(c, args.cache, quiet=True) for c in cells]
    results: dict[str, dict[str, list[float]]] = {}
    with tempfile.TemporaryDirectory(prefix="densepeds-maps-") as tmp:
        for name in args.maps:
            results[name] = {}
            for tracker, config in configs.items():
                hs = hota_per_cell(datas, config, MAPS[name][1], Path(tmp))
                results[name][tracker] = hs
                print(f"{name:9s} {tracker:22s} mean {np.mean(hs):6.2f} min {min(hs):6.2f}")
    lines = markdown(
        results, args.cells, [c.name for c in cells], time.perf_counter() - start, load
    )
    print("\n".join(lines))
    if args.write:
        args.write.write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
