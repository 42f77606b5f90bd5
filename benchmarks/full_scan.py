"""How often the detector runs every tile (``YoloSegDetector(full_scan_every=K)``), measured
live with the package's defaults (focus views included) on the four video cells and chosen
leave-one-out:

    OPENBLAS_NUM_THREADS=1 python benchmarks/full_scan.py --write   # -> results/full-scan.md

Between full scans the detector runs only views of the people found lately (fewer views, less
time); people who enter or were missed are looked for at least every K frames. Like the focus
views (``focus_lost.py``), whose runner this uses, the loop is closed (the tracker's lost people
add views), so each cell is run frame by frame through ``densepeds.Pipeline.step`` as
``densepeds run --detector yoloseg`` runs it, package defaults but ``full_scan_every``, and
scored by ``densepeds.evaluate``. ``--noise`` adds the float cells at K = 1 and the K chosen on
all four with the detector's boxes moved by sub-pixel draws (``focus_lost.NOISE_SEEDS``), so that
a difference can be read against a cell's own spread.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402
import accuracy_tables as tables  # noqa: E402
import focus_lost  # noqa: E402

PERIODS = (1, 2, 4, 8)
COMMAND = "OPENBLAS_NUM_THREADS=1 python benchmarks/full_scan.py --noise --write"
SHOWN = ("HOTA", "IDF1", "MOTA", "FP", "FN", "IDSW")


@dataclass(frozen=True)
class ScanCell(grid.Cell):
    """A video cell whose detector runs every tile only every ``every``-th frame."""

    every: int = 1

    @property
    def detector_options(self) -> dict[str, Any]:
        return {**super().detector_options, "full_scan_every": self.every}


def cells(every: int) -> list[ScanCell]:
    return [ScanCell(c.seq, c.source, every) for c in focus_lost.CELLS]


def default_period() -> int:
    from densepeds.detect.yoloseg import YoloSegDetector

    return int(YoloSegDetector.__init__.__kwdefaults__["full_scan_every"])  # type: ignore[index]


def score(
    cell: ScanCell, cache: Path, tmp: Path, seed: int = 0
) -> tuple[dict[str, float], focus_lost.Run]:
    run = focus_lost.run_cell(cell, focus_lost.default_scale(), cache, seed=seed)
    metrics = grid.score_cell(focus_lost.cell_data(cell, run), run.rows, tmp)
    extra = f" seed {seed}" if seed else ""
    print(
        f"{cell.name} full scan every {cell.every}{extra}: HOTA {metrics['HOTA']:.2f} "
        f"({run.seconds / len(run.detected):.2f} s a frame)",
        file=sys.stderr,
    )
    return metrics, run


def report(
    scored: Mapping[tuple[str, int], tuple[dict[str, float], focus_lost.Run]],
    periods: Sequence[int],
    noise: Mapping[tuple[str, int, int], float],
) -> list[str]:
    default = default_period()
    cpu = platform.processor() or platform.machine()
    names = [c.name for c in focus_lost.CELLS]
    lines = [
        "# How often the detector runs every tile",
        "",
        "`YoloSegDetector(full_scan_every=K)`: all the tiles on every K-th frame only; between, "
        "only views of the people found in the last K frames (`densepeds.detect.tiling."
        "SkipSchedule`), plus the focus views on the people the tracker lost (package default "
        f"`focus_scale={focus_lost.default_scale():g}`). Each cell run live through "
        "`densepeds.Pipeline.step` on the video (as `densepeds run --detector yoloseg`), package "
        "defaults but `full_scan_every`; scored by `densepeds.evaluate`. Cells: MOT20-01-dev "
        "frames 1-214 and PETS09-S2L1-dev frames 1-397, the shared segmenter's float copy "
        "(`/float`) and its int8 graph as shipped (`/int8`), on the tiles that follow the people.",
        "",
        f"Regenerate with `{COMMAND}`. Package default: `full_scan_every={default}`. Machine: "
        f"{os.cpu_count()} CPUs ({cpu}), Python {platform.python_version()}.",
        "",
        "| cell | K | " + " | ".join(SHOWN) + " | views a frame |",
        "|---|---:|" + "---:|" * (len(SHOWN) + 1),
    ]
    for name in names:
        for k in periods:
            m, run = scored[(name, k)]
            vals = " | ".join(grid.fmt_metric(key, m[key]) for key in SHOWN)
            frames = len(run.detected)
            lines.append(f"| {name} | {k} | {vals} | {run.views / frames:.1f} |")
    results = {f"full_scan_every={k}": {n: scored[(n, k)][0] for n in names} for k in periods}
    lines += focus_lost.loo_lines(
        results, "full_scan_every=1", "K", "every tile every frame (K = 1)", "K = 1"
    )
    if noise:
        seeds = (0, *focus_lost.NOISE_SEEDS)
        compared = sorted({k for _, k, _ in noise})
        lines += [
            "",
            "Noise: the float cells again with every box the detector gives moved by its own "
            "uniform draw in [-0.5, 0.5] px (seeds "
            f"{', '.join(map(str, focus_lost.NOISE_SEEDS))}; seed 0 is the table above), at "
            f"K = {' and '.join(map(str, compared))} (HOTA).",
            "",
            "| cell | K | " + " | ".join(f"seed {s}" for s in seeds) + " | mean | sd |",
            "|---|---:|" + "---:|" * (len(seeds) + 2),
        ]
        for name in names:
            for k in compared:
                if (name, k, seeds[1]) not in noise:
                    continue
                hota = np.array([noise[(name, k, s)] for s in seeds])
                lines.append(
                    f"| {name} | {k} | "
                    + " | ".join(f"{v:.2f}" for v in hota)
                    + f" | {hota.mean():.2f} | {hota.std():.2f} |"
                )
    lines += [
        "",
        "`views a frame`: the detector's views (tiles, windows and focus views) over the run's "
        "frames; the detector's time grows with them (`benchmarks/pipeline_speed.py` times "
        "settings against the reference, `results/speed.md`).",
    ]
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    ap.add_argument("--periods", type=int, nargs="+", default=list(PERIODS))
    ap.add_argument("--noise", action="store_true", help="also the float cells' noise runs")
    ap.add_argument("--write", action="store_true", help="write benchmarks/results/full-scan.md")
    args = ap.parse_args(argv)
    periods = sorted({1, default_period(), *args.periods})
    scored: dict[tuple[str, int], tuple[dict[str, float], focus_lost.Run]] = {}
    noise: dict[tuple[str, int, int], float] = {}
    with tempfile.TemporaryDirectory(prefix="densepeds-scan-") as tmp:
        for k in periods:
            for cell in cells(k):
                scored[(cell.name, k)] = score(cell, args.cache, Path(tmp))
        if args.noise:
            means = {
                k: np.mean([scored[(c.name, k)][0]["HOTA"] for c in focus_lost.CELLS])
                for k in periods
            }
            best = max(periods, key=lambda k: means[k])
            for k in sorted({1, best}):
                for cell in cells(k):
                    if cell.source != "float":
                        continue
                    name = cell.name
                    noise[(name, k, 0)] = scored[(name, k)][0]["HOTA"]
                    for seed in focus_lost.NOISE_SEEDS:
                        noise[(name, k, seed)] = score(cell, args.cache, Path(tmp), seed)[0]["HOTA"]
    lines = report(scored, periods, noise)
    if args.write:
        tables.write_table(tables.RESULTS, "full-scan.md", lines)
    else:
        print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
