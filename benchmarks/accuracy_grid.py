"""Score a tracker configuration over the whole dev grid, from cached inputs.

    python benchmarks/accuracy_grid.py                          # package defaults, every cell
    python benchmarks/accuracy_grid.py --param max_age=90 --cnn-param output_lost=10
    python benchmarks/accuracy_grid.py --motion cv --features bbox --cells 'MOT20*'
    python benchmarks/accuracy_grid.py --tracker trackforge-deepsort   # a peer, same inputs
    python benchmarks/accuracy_grid.py --write                  # every table -> benchmarks/results/

The grid's cells are sequence x detection source:

- ``det``: motion only on each dev sequence's public ``det/det.txt`` (six sequences);
- ``frcnn``: motion only on the five MOT15 sequences' ``det/det-frcnn.txt``;
- ``float`` / ``int8``: the full pipeline on the two real videos (MOT20-01-dev frames 1-214,
  PETS09-S2L1-dev frames 1-397): the shared segmenter's detections (its float copy, or its int8
  graph as shipped: ``dequantize=False``) and OSNet embeddings per feature kind, computed once by
  ``benchmarks/realvideo.py``'s cache (``out/cache``) exactly as ``densepeds run`` computes them.

Optional sources, scored only where a ``--cells`` pattern names them and never in the grid's
mean: ``ortq`` (the int8 copy of ``densepeds models quantize``), ``grid`` and ``ortq-grid`` (the
float and int8 copies on the reference pipeline's fixed grid of tiles), and each of those with
``-scan4`` (``scan4`` for the float copy on the default tiles; ``scan2`` too): a full scan every
4th frame only (the detector's ``full_scan_every``). ``--fast-table FILE`` scores these beside
the defaults on both videos and writes their table (``results/fast.md``).

Every cell is tracked through ``densepeds.Pipeline.step`` (the code behind ``densepeds run``: a
det file keeps the tracker's own defaults, a CNN detector gets the pipeline's presets) and scored
with ``densepeds.evaluate``. ``--param`` overrides a default on every cell, ``--det-param`` on the
det-file cells only and ``--cnn-param`` on the video cells only. The summary figure is the mean
HOTA over the cells, each cell counted once.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers  # noqa: E402
import pipeline_speed  # noqa: E402
import realvideo  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SHARED = realvideo.SHARED
DET_SEQUENCES = (
    "MOT17-02-FRCNN",
    "TUD-Stadtmitte",
    "ETH-Sunnyday",
    "KITTI-17",
    "Venice-2",
    "PETS09-S2L1-dev",
)
FRCNN_SEQUENCES = ("TUD-Stadtmitte", "ETH-Sunnyday", "KITTI-17", "Venice-2", "PETS09-S2L1-dev")
VIDEOS = dict(realvideo.VIDEOS)  # sequence -> frame range
# Detection source -> det file (motion only) or the segmenter's options (full pipeline).
DET_FILES = {"det": "det.txt", "frcnn": "det-frcnn.txt"}
DETECTOR_OPTIONS: dict[str, dict[str, Any]] = {
    "float": {"quantized": False},
    "int8": {"dequantize": False, "quantized": False},
}
# Stands for the reference's fixed grid of tiles (``densepeds.detect.tiling.auto_grid`` for the
# video's frame size and the model's input), resolved per video by ``Cell.detector_options``.
REFERENCE_GRID = "reference-grid"
# Sources left out of the grid unless a --cells pattern names them (the fast settings): ``ortq``,
# the int8 copy made by `densepeds models quantize` (found in $DENSEPEDS_MODEL_DIR), on the default
# tiles; ``grid`` the float copy and ``ortq-grid`` the int8 copy on the reference's fixed grid;
# ``scanK`` (``ortq-scanK``) the float (int8) copy on the default tiles with ``full_scan_every=K``,
# ``grid-scanK`` (``ortq-grid-scanK``) on the reference's grid with ``full_scan_every=K``.
# All keep the package's tracker defaults and the yoloseg preset.
OPTIONAL_SOURCES: dict[str, dict[str, Any]] = {
    "ortq": {"quantized": True},
    "grid": {"quantized": False, "tiles": REFERENCE_GRID},
    "ortq-grid": {"quantized": True, "tiles": REFERENCE_GRID},
    "scan2": {"quantized": False, "full_scan_every": 2},
    "scan4": {"quantized": False, "full_scan_every": 4},
    "ortq-scan4": {"quantized": True, "full_scan_every": 4},
    "grid-scan4": {"quantized": False, "tiles": REFERENCE_GRID, "full_scan_every": 4},
    "ortq-grid-scan4": {"quantized": True, "tiles": REFERENCE_GRID, "full_scan_every": 4},
}
FEATURE_KINDS = ("segmented", "bbox", "masked_pool")
SHOWN = ("HOTA", "IDF1", "MOTA", "IDSW", "FP", "FN")
Rows = npt.NDArray[np.float64]  # [M, 8]: frame, id, x1, y1, x2, y2, score, matched (1/0)


@dataclass(frozen=True)
class Cell:
    seq: str
    source: str  # a DET_FILES key or a DETECTOR_OPTIONS key

    @property
    def name(self) -> str:
        return f"{self.seq}/{self.source}"

    @property
    def full_pipeline(self) -> bool:
        return self.source in DETECTOR_OPTIONS or self.source in OPTIONAL_SOURCES

    @property
    def detector_options(self) -> dict[str, Any]:
        options = dict({**DETECTOR_OPTIONS, **OPTIONAL_SOURCES}[self.source])
        if options.get("tiles") == REFERENCE_GRID:
            options["tiles"] = pipeline_speed.reference_tiles(SHARED / "data" / self.seq)
        return options


CELLS = (
    *(Cell(s, "det") for s in DET_SEQUENCES),
    *(Cell(s, "frcnn") for s in FRCNN_SEQUENCES),
    *(Cell(s, src) for src in DETECTOR_OPTIONS for s in VIDEOS),
)


@dataclass
class CellData:
    """One cell's inputs, frame by frame from the sequence's first frame."""

    cell: Cell
    seq_dir: Path
    fps: float
    size: tuple[int, int]  # (width, height) from seqinfo.ini, as `densepeds run` gives it
    dets: list[Any]  # densepeds.types.Detections per frame
    embeddings: dict[str, list[npt.NDArray[np.float32]]] = field(default_factory=dict)


@dataclass(frozen=True)
class Config:
    """One tracker configuration: ours (``tracker='densepeds'``) or a peer from peers.py."""

    motion: str = "frvo"
    features: str = "default"  # on the video cells; the det-file cells are motion only
    params: Mapping[str, Any] = field(default_factory=dict)  # every cell
    det_params: Mapping[str, Any] = field(default_factory=dict)  # det-file cells
    cnn_params: Mapping[str, Any] = field(default_factory=dict)  # video cells
    tracker: str = "densepeds"

    def label(self) -> str:
        if self.tracker != "densepeds":
            return self.tracker
        parts = [self.motion, self.features]
        for scope, p in (("", self.params), ("det:", self.det_params), ("cnn:", self.cnn_params)):
            parts += [f"{scope}{k}={v}" for k, v in p.items()]
        return " ".join(parts)

    def kind(self) -> str:
        """The appearance features of the video cells."""
        from densepeds.pipeline import default_features

        return default_features(has_images=True) if self.features == "default" else self.features

    def cell_params(self, cell: Cell) -> dict[str, Any]:
        scoped = self.cnn_params if cell.full_pipeline else self.det_params
        return {**self.params, **scoped}


def select_cells(patterns: Sequence[str] | None) -> list[Cell]:
    """The cells whose name (``SEQ/SOURCE``) matches any glob pattern (all without patterns)."""
    if not patterns:
        return list(CELLS)
    optional = [Cell(s, src) for src in OPTIONAL_SOURCES for s in VIDEOS]
    named = [c for c in optional if any(p.endswith(f"/{c.source}") for p in patterns)]
    cells = [c for c in (*CELLS, *named) if any(fnmatch.fnmatch(c.name, p) for p in patterns)]
    if not cells:
        sys.exit(f"no cell matches {list(patterns)}; cells: {', '.join(c.name for c in CELLS)}")
    return cells


def load_cell(
    cell: Cell, cache: Path, kinds: Sequence[str] = FEATURE_KINDS, quiet: bool = False
) -> CellData:
    """A cell's detections (and embeddings), computing a video's cache where it is missing."""
    from densepeds.io import mot as motio
    from densepeds.types import Detections

    seq_dir = SHARED / "data" / cell.seq
    if not seq_dir.is_dir():
        sys.exit(f"{seq_dir}: missing (the shared data beside the repo; set DENSEPEDS_SHARED)")
    info = motio.read_seqinfo(seq_dir)
    if cell.full_pipeline:
        video = realvideo.load_video(
            cell.seq, VIDEOS[cell.seq], kinds, cache, cell.detector_options, quiet
        )
        size = (info.width, info.height)
        return CellData(cell, seq_dir, info.fps, size, video.dets, video.embeddings)
    det_path = seq_dir / "det" / DET_FILES[cell.source]
    if not det_path.is_file():
        sys.exit(f"{det_path}: missing")
    by_frame = motio.read_detections(det_path)
    dets = [by_frame.get(f) or Detections.empty() for f in range(1, info.length + 1)]
    return CellData(cell, seq_dir, info.fps, (info.width, info.height), dets)


def load_grid(
    cells: Iterable[Cell], cache: Path, kinds: Sequence[str] = FEATURE_KINDS, quiet: bool = False
) -> list[CellData]:
    return [load_cell(c, cache, kinds, quiet) for c in cells]


def cell_pipeline(data: CellData, config: Config, tracker: Any = None) -> Any:
    from densepeds.pipeline import DETECTION_OPTIONS, Pipeline

    detector = "yoloseg" if data.cell.full_pipeline else None
    if tracker is not None:
        detection = {
            k: v for k, v in config.cell_params(data.cell).items() if k in DETECTION_OPTIONS
        }
        return Pipeline(detector, features="none", tracker=tracker, **detection)
    features = realvideo.kind_options(config.kind())[0] if data.cell.full_pipeline else "none"
    return Pipeline(
        detector, motion=config.motion, features=features, **config.cell_params(data.cell)
    )


def track_cell(data: CellData, config: Config) -> Rows:
    """Run one configuration on one cell; rows as in ``Rows``."""
    kind = config.kind() if data.cell.full_pipeline else "none"
    if config.tracker == "densepeds":
        pipe = cell_pipeline(data, config)
    else:
        name, fps = config.tracker, data.fps
        pipe = cell_pipeline(
            data, config, tracker=peers.PipelineTracker(lambda: peers.make_tracker(name, fps))
        )
    pipe.set_image_size(*data.size)
    out: list[Rows] = []
    for k, dets in enumerate(data.dets):
        emb = None if kind == "none" else data.embeddings[kind][k]
        tracks = pipe.step(None, dets, embeddings=emb)
        if len(tracks.ids):
            out.append(frame_rows(k + 1, tracks))
    return np.concatenate(out) if out else np.zeros((0, 8))


def frame_rows(frame: int, tracks: Any) -> Rows:
    """One frame's tracks (densepeds.Tracks) as ``Rows``."""
    matched = tracks.det_index >= 0
    return np.c_[np.full(len(tracks.ids), frame), tracks.ids, tracks.boxes, tracks.scores, matched]


def score_cell(data: CellData, rows: Rows, tmp: Path) -> dict[str, float]:
    from densepeds.evaluate import evaluate
    from densepeds.io.mot import write_tracks

    path = tmp / data.cell.source / f"{data.cell.seq}.txt"
    write_tracks(path, rows[:, :7])
    return evaluate([data.seq_dir], path).combined


def runs_on(config: Config, cell: Cell) -> bool:
    """Whether the configuration can track the cell (a peer that needs embeddings needs a video)."""
    return cell.full_pipeline or config.tracker not in peers.NEEDS_EMBEDDINGS


def score_grid(
    grid: Sequence[CellData],
    config: Config,
    keep_rows: dict[str, Rows] | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, dict[str, float]]:
    """Metrics per cell name for one configuration (tracks kept in ``keep_rows`` if given)."""
    out: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory(prefix="densepeds-grid-") as tmp:
        for data in grid:
            if not runs_on(config, data.cell):
                continue
            rows = track_cell(data, config)
            if keep_rows is not None:
                keep_rows[data.cell.name] = rows
            out[data.cell.name] = score_cell(data, rows, Path(tmp))
            if progress is not None:
                m = out[data.cell.name]
                progress(f"{data.cell.name}: HOTA {m['HOTA']:.2f} IDF1 {m['IDF1']:.2f}")
    return out


def mean_metric(result: Mapping[str, Mapping[str, float]], metric: str = "HOTA") -> float:
    return float(np.mean([m[metric] for m in result.values()]))


def fmt_metric(metric: str, v: float) -> str:
    return f"{v:.0f}" if metric in ("IDSW", "FP", "FN", "MT", "ML", "IDs") else f"{v:.2f}"


def cell_table(result: Mapping[str, Mapping[str, float]], shown: Sequence[str] = SHOWN) -> str:
    lines = ["| cell | " + " | ".join(shown) + " |", "|---|" + "---:|" * len(shown)]
    for name, m in result.items():
        lines.append(f"| {name} | " + " | ".join(fmt_metric(k, m[k]) for k in shown) + " |")
    means = " | ".join(
        fmt_metric(k, float(np.mean([m[k] for m in result.values()]))) for k in shown
    )
    lines.append(f"| mean of {len(result)} cells | {means} |")
    return "\n".join(lines) + "\n"


# The fast settings' table (``--fast-table``): each source on both videos, package defaults.
FAST_SOURCES = {
    "float": "defaults: float copy, tiles that follow the people",
    "grid": "float copy on the reference's grid",
    "ortq": "int8 copy, tiles that follow the people",
    "ortq-grid": "int8 copy on the reference's grid",
    "scan4": "float copy, tiles that follow the people, a full scan every 4th frame",
    "ortq-scan4": "int8 copy, tiles that follow the people, a full scan every 4th frame",
    "grid-scan4": "float copy on the reference's grid, a full scan every 4th frame",
    "ortq-grid-scan4": "int8 copy on the reference's grid, a full scan every 4th frame",
}
FAST_COMMAND = (
    "DENSEPEDS_MODEL_DIR=out/models:../shared/models OPENBLAS_NUM_THREADS=1 \\\n"
    "        python benchmarks/accuracy_grid.py --fast-table benchmarks/results/fast.md"
)


def _ort_version() -> str:
    import onnxruntime

    return str(onnxruntime.__version__)


def fast_table(cache: Path, quiet: bool = False) -> list[str]:
    """HOTA / IDF1 per video for the fast settings (``FAST_SOURCES``), package defaults."""
    from densepeds.errors import DensePedsError

    config = Config()
    cells = [Cell(seq, src) for src in FAST_SOURCES for seq in VIDEOS]
    try:
        grid = load_grid(cells, cache, (config.kind(),), quiet)
    except DensePedsError as exc:
        sys.exit(f"error: {exc}")
    log = None if quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    result = score_grid(grid, config, progress=log)
    metrics = ("HOTA", "DetA", "AssA", "IDF1")
    head = " | ".join(f"{seq.split('-dev')[0]} {m}" for seq in VIDEOS for m in metrics)
    lines = [
        "# The fast settings' accuracy: grid tiles, the int8 copy and skipped tiles",
        "",
        "Written by this command (do not edit; rerun it):",
        "",
        f"    {FAST_COMMAND}",
        "",
        f"The full pipeline on MOT20-01-dev frames {VIDEOS['MOT20-01-dev']} and PETS09-S2L1-dev "
        f"frames {VIDEOS['PETS09-S2L1-dev']}: the shared segmenter's detections with each setting "
        f"below, OSNet x0.25 embeddings ({config.kind()}), the package's tracker defaults and the "
        "yoloseg preset, tracked through `densepeds.Pipeline.step` and scored with "
        "`densepeds.evaluate` (detections and embeddings cached in `out/cache` by "
        "`benchmarks/realvideo.py`). The int8 copy is the one `densepeds models quantize` makes "
        "(`benchmarks/results/int8.md`); the reference's grid is "
        "`densepeds.detect.tiling.auto_grid` for the frame size ("
        + ", ".join(f"{c.seq} {c.detector_options['tiles']}" for c in cells if c.source == "grid")
        + "); on it the detector runs its input cut to the tiles' shape (`YoloSegDetector`'s "
        "default `fit_input`: the same scale, less padding; the people-following tiles are "
        "square and run the model's own). `a full scan every 4th frame` is the detector's "
        "`full_scan_every=4`: all the "
        "tiles every 4th frame, between only views of the people found in the last 4 frames: "
        "windows of the tiles' sizes placed over them, or the tiles that show them whole, "
        "whichever are fewer (`densepeds.detect.tiling.SkipSchedule`). These cells are not part of "
        "the 15-cell dev grid or its mean "
        f"(`accuracy.md`). onnxruntime {_ort_version()}. Speed of the same settings: `speed.md`.",
        "",
        f"| setting | {head} |",
        "|---|" + "---:|" * (len(metrics) * len(VIDEOS)),
    ]
    for src, what in FAST_SOURCES.items():
        vals = [result[f"{seq}/{src}"][m] for seq in VIDEOS for m in metrics]
        lines.append(f"| {what} (`/{src}`) | " + " | ".join(f"{v:.2f}" for v in vals) + " |")
    lines += ["", "Change against the defaults (HOTA):", ""]
    for src, what in list(FAST_SOURCES.items())[1:]:
        deltas = ", ".join(
            f"{seq} {result[f'{seq}/{src}']['HOTA'] - result[f'{seq}/float']['HOTA']:+.2f}"
            for seq in VIDEOS
        )
        lines.append(f"- {what}: {deltas}")
    lines += ["", "Change against the same setting run on every tile every frame (HOTA):", ""]
    for src, every in _every_frame_sources(list(FAST_SOURCES)).items():
        deltas = ", ".join(
            f"{seq} {result[f'{seq}/{src}']['HOTA'] - result[f'{seq}/{every}']['HOTA']:+.2f}"
            for seq in VIDEOS
        )
        lines.append(f"- {FAST_SOURCES[src]}: {deltas}")
    return lines


def _every_frame_sources(sources: Sequence[str]) -> dict[str, str]:
    """For each source that skips tiles (``full_scan_every`` > 1), the source among ``sources``
    with the same options but a full scan every frame."""
    options = {**DETECTOR_OPTIONS, **OPTIONAL_SOURCES}
    out = {}
    for src in sources:
        opts = dict(options[src])
        if opts.pop("full_scan_every", 1) == 1:
            continue
        for other in sources:
            if other != src and options[other] == opts:
                out[src] = other
    return out


def parse_value(text: str) -> Any:
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def parse_params(items: Sequence[str]) -> dict[str, Any]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            sys.exit(f"a parameter is KEY=VALUE, got {item!r}")
        out[key] = parse_value(value)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--cache", type=Path, default=REPO / "out" / "cache")
    ap.add_argument("--cells", nargs="+", help="glob patterns over SEQ/SOURCE (default: all)")
    ap.add_argument("--tracker", default="densepeds", help=f"densepeds or {', '.join(peers.PEERS)}")
    ap.add_argument("--motion", default="frvo", choices=peers.MOTIONS)
    ap.add_argument("--features", default="default", help="video cells' appearance features")
    ap.add_argument("--param", action="append", default=[], help="KEY=VALUE on every cell")
    ap.add_argument("--det-param", action="append", default=[], help="KEY=VALUE, det-file cells")
    ap.add_argument("--cnn-param", action="append", default=[], help="KEY=VALUE, video cells")
    ap.add_argument("--json", type=Path, help="also write the per-cell metrics here")
    ap.add_argument("--write", action="store_true", help="regenerate every table (see module doc)")
    ap.add_argument("--results", type=Path, help="with --write: write here instead (a quick look)")
    ap.add_argument(
        "--tables",
        nargs="+",
        help="with --write: only these (peers loo visibility claims scene realvideo)",
    )
    ap.add_argument(
        "--fast-table",
        type=Path,
        metavar="FILE",
        help="score the fast settings (grid tiles, int8 copy) on the videos; write their table",
    )
    ap.add_argument("--quiet", "-q", action="store_true")
    args = ap.parse_args(argv)
    if args.fast_table:
        text = "\n".join(fast_table(args.cache, args.quiet)) + "\n"
        args.fast_table.write_text(text, encoding="utf-8")
        print(text)
        return 0
    if args.write:
        # accuracy_tables.py builds the tables from this module's grid: its own command.
        command = [sys.executable, str(Path(__file__).with_name("accuracy_tables.py"))]
        command += ["--cache", str(args.cache), *(["--quiet"] if args.quiet else [])]
        command += ["--results", str(args.results)] if args.results else []
        command += ["--cells", *args.cells] if args.cells else []
        command += ["--tables", *args.tables] if args.tables else []
        return subprocess.call(command)
    config = Config(
        motion=args.motion,
        features=args.features,
        params=parse_params(args.param),
        det_params=parse_params(args.det_param),
        cnn_params=parse_params(args.cnn_param),
        tracker=args.tracker,
    )
    cells = select_cells(args.cells)
    t0 = time.perf_counter()
    kinds = sorted({*FEATURE_KINDS, config.kind()} - {"none"})
    grid = load_grid(cells, args.cache, kinds, args.quiet)
    t1 = time.perf_counter()
    log = None if args.quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    result = score_grid(grid, config, progress=log)
    print(f"{config.label()}: mean HOTA {mean_metric(result):.2f} over {len(result)} cells")
    print(cell_table(result))
    print(
        f"(loaded in {t1 - t0:.1f} s, tracked and scored in {time.perf_counter() - t1:.1f} s)",
        file=sys.stderr,
    )
    if args.json:
        args.json.write_text(json.dumps({"config": config.label(), "cells": result}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
