"""The detector's focus on the people the tracker lost (``YoloSegDetector(focus_scale=S)``),
measured live on the four video cells and chosen leave-one-out:

    OPENBLAS_NUM_THREADS=1 python benchmarks/focus_lost.py --write   # -> results/focus.md

Focus views close a loop (the tracker's lost people decide the next frame's views), so these
cells cannot come from the grid's cached detections: each is run frame by frame through
``densepeds.Pipeline.step`` on the video, exactly as ``densepeds run --detector yoloseg``
runs it (package defaults, only ``focus_scale`` varied), and scored by ``densepeds.evaluate``.
Runs are kept in ``out/cache/focus-*.npz``, keyed by the cell, the scale and the bytes of the
installed package (any code change misses the cache).

The scale is chosen leave-one-out: for each cell, the scale with the best mean HOTA on the other
three is scored on it. The closed loop makes each run one draw: other views give other detections
and other identities. So the float cells are also run at scale 0 and the default scale with the
detector's boxes moved by sub-pixel amounts (``NOISE_SEEDS``, as ``jitter_check.py`` moves the
det cells' boxes), and the spread over those seeds is reported beside the gain.

Recall per visibility bin (MOT20-01-dev only: its ground truth has visibility) compares the
tracker's output with the detector without focus views (scale 0), the baseline a tracker has to
beat, and with the detector's own detections at that scale.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import os
import platform
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402
import accuracy_tables as tables  # noqa: E402
import jitter_check  # noqa: E402
import realvideo  # noqa: E402

SCALES = (0.0, 1.5, 2.0, 2.5, 3.0, 3.5)
CELLS = tuple(grid.Cell(seq, src) for src in ("float", "int8") for seq in grid.VIDEOS)
COMMAND = "OPENBLAS_NUM_THREADS=1 python benchmarks/focus_lost.py --write"
SHOWN = ("HOTA", "IDF1", "MOTA", "FP", "FN", "IDSW")
RECALL_BIN = 1  # VISIBILITY_BINS index of 0.25-0.5, the bin issue 17's recall target names
NOISE_SEEDS = (1, 2, 3)  # sub-pixel moves of the detector's boxes; seed 0: none (the table's runs)
NOISE_CELLS = tuple(c for c in CELLS if c.source == "float")


@dataclass
class Run:
    """One cell tracked live at one scale."""

    rows: grid.Rows  # as accuracy_grid.Rows
    detected: list[npt.NDArray[np.float64]]  # every detection per frame (focus views included)
    fed: list[npt.NDArray[np.float64]]  # the boxes handed to the tracker per frame
    views: int  # detector views over the run
    seconds: float  # wall time of the run (frame reading included)


def code_stamp() -> str:
    """The installed package's bytes (Python files and the compiled core)."""
    import densepeds

    root = Path(densepeds.__file__).parent
    digest = hashlib.sha256()
    for p in sorted(root.rglob("*")):
        if p.suffix in (".py", ".so", ".pyd") and p.is_file():
            digest.update(p.relative_to(root).as_posix().encode())
            digest.update(p.read_bytes())
    return digest.hexdigest()[:12]


def _cache_file(cache: Path, cell: grid.Cell, scale: float, frames: str, seed: int) -> Path:
    key = realvideo.cache_key(cell.seq, frames, cell.detector_options)
    moved = f"-j{seed}" if seed else ""
    return cache / f"focus-{cell.seq}-{cell.source}-{key}-s{scale:g}{moved}-{code_stamp()}.npz"


class Jittered:
    """A detector whose boxes are moved by uniform [-SHIFT, SHIFT] px draws of ``seed``'s
    generator, a new draw per frame (masks as they are); everything else is the detector's."""

    def __init__(self, detector: Any, seed: int) -> None:
        self.detector = detector
        self.rng = np.random.default_rng(seed)

    def __call__(self, frame: npt.NDArray[np.uint8]) -> Any:
        dets = self.detector(frame)
        move = self.rng.uniform(-jitter_check.SHIFT, jitter_check.SHIFT, dets.boxes.shape)
        return dataclasses.replace(dets, boxes=(dets.boxes + move).astype(dets.boxes.dtype))

    def __getattr__(self, name: str) -> Any:
        return getattr(self.detector, name)


def _split(flat: npt.NDArray[np.float64], counts: npt.NDArray[np.int64]) -> list[np.ndarray]:
    return list(np.split(flat, np.cumsum(counts)[:-1])) if len(counts) else []


def run_cell(
    cell: grid.Cell, scale: float, cache: Path, frames: str | None = None, seed: int = 0
) -> Run:
    """Track ``cell`` live with the detector's ``focus_scale`` at ``scale`` (cached), on its
    video's dev frames or ``frames`` ("A:B"); ``seed`` > 0 moves the detector's boxes
    (``Jittered``)."""
    from densepeds.io.mot import read_seqinfo
    from densepeds.pipeline import Pipeline

    frames = frames or grid.VIDEOS[cell.seq]
    path = _cache_file(cache, cell, scale, frames, seed)
    if path.is_file():
        z = np.load(path)
        return Run(
            z["rows"],
            _split(z["detected"], z["detected_counts"]),
            _split(z["fed"], z["fed_counts"]),
            int(z["views"]),
            float(z["seconds"]),
        )
    seq_dir = grid.SHARED / "data" / cell.seq
    pipe = Pipeline("yoloseg", detector_options={**cell.detector_options, "focus_scale": scale})
    info = read_seqinfo(seq_dir)
    pipe.set_image_size(info.width, info.height)
    detector = pipe.detector()
    if seed:
        pipe._detector = Jittered(detector, seed)
    rows: list[grid.Rows] = []
    detected: list[npt.NDArray[np.float64]] = []
    fed: list[npt.NDArray[np.float64]] = []
    views = 0
    t0 = time.perf_counter()
    for k, (_, image) in enumerate(realvideo.read_frames(seq_dir, frames)):
        tracks = pipe.step(image)
        views += detector.last_views
        raw = pipe._frame_detections
        detected.append(raw.boxes.astype(np.float64))
        fed.append(raw.boxes[pipe._kept(raw)].astype(np.float64))
        rows.append(grid.frame_rows(k + 1, tracks))
    seconds = time.perf_counter() - t0
    run = Run(np.concatenate(rows) if rows else np.zeros((0, 8)), detected, fed, views, seconds)
    cache.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(
        tmp,
        rows=run.rows,
        detected=np.concatenate(detected).reshape(-1, 4),
        detected_counts=[len(d) for d in detected],
        fed=np.concatenate(fed).reshape(-1, 4),
        fed_counts=[len(d) for d in fed],
        views=views,
        seconds=seconds,
    )
    os.replace(tmp, path)
    return run


def cell_data(cell: grid.Cell, run: Run) -> grid.CellData:
    """The run's detections as a grid cell (for the grid's scorer and recall counts)."""
    from densepeds.io.mot import read_seqinfo
    from densepeds.types import Detections

    seq_dir = grid.SHARED / "data" / cell.seq
    info = read_seqinfo(seq_dir)
    dets = [Detections(b.astype(np.float32), np.ones(len(b), np.float32)) for b in run.detected]
    return grid.CellData(cell, seq_dir, info.fps, (info.width, info.height), dets)


@dataclass
class Scored:
    metrics: dict[str, float]
    frames: int
    run: Run


def score_all(cache: Path, scales: Sequence[float]) -> dict[tuple[str, float], Scored]:
    out: dict[tuple[str, float], Scored] = {}
    with tempfile.TemporaryDirectory(prefix="densepeds-focus-") as tmp:
        for cell in CELLS:
            for scale in scales:
                t0 = time.perf_counter()
                run = run_cell(cell, scale, cache)
                data = cell_data(cell, run)
                m = grid.score_cell(data, run.rows, Path(tmp))
                out[(cell.name, scale)] = Scored(m, len(run.detected), run)
                print(
                    f"{cell.name} focus {scale:g}: HOTA {m['HOTA']:.2f} IDF1 {m['IDF1']:.2f} "
                    f"({run.seconds / len(run.detected):.2f} s a frame when run; "
                    f"{time.perf_counter() - t0:.0f} s now)",
                    file=sys.stderr,
                )
    return out


def noise_all(cache: Path, scales: Sequence[float]) -> dict[tuple[str, float, int], Scored]:
    """The float cells at ``scales`` with the detector's boxes moved by each of NOISE_SEEDS."""
    out: dict[tuple[str, float, int], Scored] = {}
    with tempfile.TemporaryDirectory(prefix="densepeds-focus-") as tmp:
        for cell in NOISE_CELLS:
            for scale in scales:
                for seed in NOISE_SEEDS:
                    run = run_cell(cell, scale, cache, seed=seed)
                    m = grid.score_cell(cell_data(cell, run), run.rows, Path(tmp))
                    out[(cell.name, scale, seed)] = Scored(m, len(run.detected), run)
                    print(
                        f"{cell.name} focus {scale:g} seed {seed}: HOTA {m['HOTA']:.2f}",
                        file=sys.stderr,
                    )
    return out


def recall_ratio(cell: grid.Cell, run: Run, base: Run) -> float:
    """Tracker recall of ``run`` at visibility RECALL_BIN over the detector's of ``base``."""
    ours = tables.visibility_recall(cell_data(cell, run), run.fed, run.rows)
    theirs = tables.visibility_recall(cell_data(cell, base), base.fed, base.rows)
    return ours.found["tracker"][RECALL_BIN] / max(theirs.found["detector"][RECALL_BIN], 1)


def noise_lines(
    scored: Mapping[tuple[str, float], Scored],
    noise: Mapping[tuple[str, float, int], Scored],
    default: float,
) -> list[str]:
    """Per float cell: HOTA (and on MOT20 the recall ratio) per seed, without focus views and at
    the default scale, with the gain per seed."""
    seeds = (0, *NOISE_SEEDS)
    lo, hi = tables.VISIBILITY_BINS[RECALL_BIN]
    lines = [
        "Noise: the float cells again with every box the detector gives moved by its own uniform "
        f"draw in [-{jitter_check.SHIFT:g}, {jitter_check.SHIFT:g}] px (seeds "
        f"{', '.join(map(str, NOISE_SEEDS))}; seed 0 is the table above), without focus views "
        f"and at the default scale {default:g}. `recall x`: the tracker's recall at visibility "
        f"{lo:g}-{hi:g} over the detector's without focus views in the same seed.",
        "",
        "| cell | figure | " + " | ".join(f"seed {k}" for k in seeds) + " | mean | sd |",
        "|---|---|" + "---:|" * (len(seeds) + 2),
    ]

    def run_of(cell: grid.Cell, scale: float, seed: int) -> Scored:
        return scored[(cell.name, scale)] if seed == 0 else noise[(cell.name, scale, seed)]

    for cell in NOISE_CELLS:
        rows: dict[str, list[float]] = {}
        for scale in (0.0, default):
            rows[f"HOTA at {scale:g}"] = [run_of(cell, scale, k).metrics["HOTA"] for k in seeds]
        rows["HOTA gain"] = [b - a for a, b in zip(*rows.values(), strict=True)]
        if cell.seq.startswith("MOT20"):
            rows[f"recall x at {default:g}"] = [
                recall_ratio(cell, run_of(cell, default, k).run, run_of(cell, 0.0, k).run)
                for k in seeds
            ]
        for name, vals in rows.items():
            a = np.array(vals)
            lines.append(
                f"| {cell.name} | {name} | "
                + " | ".join(f"{v:+.2f}" if "gain" in name else f"{v:.2f}" for v in a)
                + f" | {a.mean():.2f} | {a.std():.2f} |"
            )
    return lines


def by_scale(
    scored: Mapping[tuple[str, float], Scored], scales: Sequence[float]
) -> dict[str, dict[str, dict[str, float]]]:
    """The runs as accuracy_tables' Results per candidate ``focus_scale=S``."""
    return {
        f"focus_scale={s:g}": {c.name: scored[(c.name, s)].metrics for c in CELLS} for s in scales
    }


def default_scale() -> float:
    from densepeds.detect.yoloseg import YoloSegDetector

    return float(YoloSegDetector.__init__.__kwdefaults__["focus_scale"])  # type: ignore[index]


def report(
    scored: Mapping[tuple[str, float], Scored],
    scales: Sequence[float],
    noise: Mapping[tuple[str, float, int], Scored] | None = None,
) -> list[str]:
    default = default_scale()
    cpu = platform.processor() or platform.machine()
    lines = [
        "# The detector's focus on the people the tracker lost",
        "",
        "`YoloSegDetector(focus_scale=S)`: on each frame one more detector view per person the "
        "tracker reported without a detection on the last frame, a square S times their height "
        "centred on them (S = 0: no focus views). Each cell run live through "
        "`densepeds.Pipeline.step` on the video (as `densepeds run --detector yoloseg`), "
        "package defaults but `focus_scale`; scored by `densepeds.evaluate`. Cells: MOT20-01-dev "
        "frames 1-214 and PETS09-S2L1-dev frames 1-397, the shared segmenter's float copy "
        "(`/float`) and its int8 graph as shipped (`/int8`).",
        "",
        f"Regenerate with `{COMMAND}` (about 80 minutes on 2 cores without `out/cache`). "
        f"Package default: `focus_scale={default:g}`. Machine: {os.cpu_count()} CPUs ({cpu}), "
        f"Python {platform.python_version()}.",
        "",
        "| cell | focus_scale | " + " | ".join(SHOWN) + " | views a frame |",
        "|---|---:|" + "---:|" * (len(SHOWN) + 1),
    ]
    for cell in CELLS:
        for s in scales:
            r = scored[(cell.name, s)]
            vals = " | ".join(grid.fmt_metric(k, r.metrics[k]) for k in SHOWN)
            lines.append(f"| {cell.name} | {s:g} | {vals} | {r.run.views / r.frames:.1f} |")
    results = by_scale(scored, scales)
    lines += loo_lines(results, "focus_scale=0", "scale", "no focus views", "scale 0")
    lines += [""]
    lines += recall_lines(scored, scales)
    if noise:
        lines += ["", *noise_lines(scored, noise, default)]
    lines += [
        "",
        "`views a frame`: the detector's views (tiles and focus views) over the run's frames; "
        "the detector's time grows with them. `benchmarks/pipeline_speed.py` times the pipeline "
        "with and without focus views against the reference (`results/speed.md`).",
    ]
    return lines


def loo_lines(
    results: Mapping[str, tables.Results], base: str, what: str, base_text: str, base_label: str
) -> list[str]:
    """Mean HOTA per candidate (``results``' keys) over the four cells, then each cell scored at
    the candidate best on the other three, beside the one best on all four and ``base``."""
    loo = tables.leave_one_out(results)
    first = results[base]
    lines = [
        "",
        "Mean HOTA over the four cells: "
        + ", ".join(f"{n}: {grid.mean_metric(r):.2f}" for n, r in results.items())
        + f"; best on all four: `{loo[0].tuned}`.",
        "",
        f"Leave-one-out: each cell scored at the {what} best on the other three (mean HOTA), "
        f"beside the {what} best on all four and {base_text}.",
        "",
        "| left out | chosen on the others | its HOTA there (held out) | tuned (all cells) "
        f"| {base_label} | held out - {base_label} |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for r in loo:
        own = first[r.cell]["HOTA"]
        lines.append(
            f"| {r.cell} | {r.chosen} | {r.held_out:.2f} | {r.tuned_value:.2f} | {own:.2f} "
            f"| {r.held_out - own:+.2f} |"
        )
    held = float(np.mean([r.held_out for r in loo]))
    tuned = float(np.mean([r.tuned_value for r in loo]))
    own_mean = grid.mean_metric(first)
    lines.append(f"| mean | | {held:.2f} | {tuned:.2f} | {own_mean:.2f} | {held - own_mean:+.2f} |")
    return lines


def recall_lines(scored: Mapping[tuple[str, float], Scored], scales: Sequence[float]) -> list[str]:
    head = " | ".join(f"{lo:g}-{min(hi, 1.0):g}" for lo, hi in tables.VISIBILITY_BINS)
    lo, hi = tables.VISIBILITY_BINS[RECALL_BIN]
    lines = [
        "Recall (%) of the ground-truth pedestrians per visibility bin (MOT20 gt column 9), "
        "matched one-to-one per frame at IoU >= 0.5 (as in `accuracy-visibility.md`). "
        "`detector`: every detection of the run (focus views included); `tracker`: the "
        "tracker's output. The last column divides the tracker's recall at visibility "
        f"{lo:g}-{hi:g} by the detector's without focus views (scale 0).",
        "",
        f"| cell | focus_scale | boxes | {head} | tracker / detector at scale 0 |",
        "|---|---:|---|" + "---:|" * (len(tables.VISIBILITY_BINS) + 1),
    ]
    for cell in CELLS:
        if not cell.seq.startswith("MOT20"):
            continue
        found = {}
        for s in scales:
            r = scored[(cell.name, s)]
            found[s] = tables.visibility_recall(cell_data(cell, r.run), r.run.fed, r.run.rows)
        gt = found[scales[0]].gt
        base = found[0.0].found["detector"][RECALL_BIN] / max(gt[RECALL_BIN], 1)
        lines.append(f"| {cell.name} | | pedestrians | " + " | ".join(map(str, gt)) + " | |")
        for s in scales:
            for src in ("detector", "tracker"):
                hits = found[s].found[src]
                vals = " | ".join(
                    f"{100 * h / max(n, 1):.1f}" for h, n in zip(hits, gt, strict=True)
                )
                ratio = hits[RECALL_BIN] / max(gt[RECALL_BIN], 1) / max(base, 1e-9)
                tail = f"{ratio:.2f}x" if src == "tracker" else ""
                lines.append(f"| {cell.name} | {s:g} | {src} | {vals} | {tail} |")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    ap.add_argument("--scales", type=float, nargs="+", default=list(SCALES))
    ap.add_argument("--write", action="store_true", help="write benchmarks/results/focus.md")
    ap.add_argument(
        "--no-noise", action="store_true", help="skip the runs with moved boxes (NOISE_SEEDS)"
    )
    args = ap.parse_args(argv)
    scales = sorted(set([0.0, default_scale(), *args.scales]))
    scored = score_all(args.cache, scales)
    noise = None if args.no_noise else noise_all(args.cache, (0.0, default_scale()))
    lines = report(scored, scales, noise)
    if args.write:
        tables.write_table(tables.RESULTS, "focus.md", lines)
    else:
        print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
