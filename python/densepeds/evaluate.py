"""MOTChallenge evaluation (HOTA, CLEAR MOT, identity metrics) through the ``trackeval`` package.

trackeval expects its own folder layout; :func:`evaluate` builds it in a temporary directory
(links to the ground truth, a validated copy of each tracks file), runs trackeval's MOTChallenge
dataset with the rules of the sequence's benchmark, and keeps its console output quiet.

Rules: MOT16/17/20 gt has class and visibility columns: only class 1 (pedestrian) with a non-zero
flag is scored, and tracker boxes matched to distractor classes are removed before scoring
(MOT20 also counts non-MOT vehicles as distractors). MOT15 gt has no classes: every box whose
flag is not 0 is a pedestrian.

``frames="A:B"`` scores only frames A..B of the ground truth and the tracks (both renumbered from
1). Without it, tracks that cover fewer frames than the ground truth (e.g. from ``run --frames``)
are scored against the whole ground truth, and :attr:`EvalResult.warnings` says so.

trackeval is an optional dependency (``pip install 'densepeds[eval]'`` plus trackeval itself,
with metadata that requires the headless OpenCV instead of a second one:
:mod:`densepeds.install_trackeval`, :data:`INSTALL_HINT`).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from densepeds.errors import InputError, ParameterError
from densepeds.io import mot as motio

if TYPE_CHECKING:
    from densepeds.io.video import FrameRange

__all__ = ["METRICS", "EvalResult", "detect_benchmark", "evaluate", "format_results"]

# Reported metrics, in table order. Ratios are percentages (0-100); the rest are counts.
METRICS = ("HOTA", "DetA", "AssA", "MOTA", "MOTP", "IDF1", "MT", "ML", "FP", "FN", "IDSW")
COUNT_METRICS = frozenset(
    {"MT", "ML", "FP", "FN", "IDSW", "Frag", "GT_IDs", "IDs", "GT_Dets", "Dets"}
)
BENCHMARKS = ("MOT15", "MOT16", "MOT17", "MOT20")
# trackeval declares opencv-python (the GUI build) as a dependency but scores MOTChallenge boxes
# without it; installed with its dependencies it would sit beside our opencv-python-headless,
# both owning cv2. The eval extra holds what trackeval imports; trackeval goes in with --no-deps.
INSTALL_HINT = "pip install 'densepeds[eval]' && python -m densepeds.install_trackeval"
# Ground-truth frames outside the tracks' span beyond which evaluate() warns (a tracker may
# report nothing in a frame or two at the ends: tracks are confirmed on their 2nd match).
UNCOVERED_FRAMES_WARN = 2
COMBINED = "COMBINED"
_TRACKER = "tracker"


@dataclass
class EvalResult:
    """Metrics per sequence and over all sequences together (trackeval's combination)."""

    sequences: dict[str, dict[str, float]]
    combined: dict[str, float]
    benchmarks: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def rows(self) -> list[tuple[str, dict[str, float]]]:
        """(name, metrics) per sequence in input order, then the combined row."""
        return [*self.sequences.items(), (COMBINED, self.combined)]


def _has_mot17_classes(gt: np.ndarray) -> bool:
    """Whether columns 8 and 9 are MOTChallenge class ids (1-13) and visibilities (0-1)."""
    if gt.shape[1] < 9 or not len(gt):
        return False
    classes, vis = gt[:, 7], gt[:, 8]
    return bool(
        np.all(classes == np.round(classes))
        and np.all((classes >= 1) & (classes <= 13))
        and np.all((vis >= 0) & (vis <= 1))
    )


def detect_benchmark(seq_name: str, gt: np.ndarray) -> str:
    """MOT20/MOT17 rules where the gt has class columns, MOT15 rules where it does not."""
    upper = seq_name.upper()
    if "MOT20" in upper:
        return "MOT20"
    if "MOT16" in upper or "MOT17" in upper:
        return "MOT17"
    return "MOT17" if _has_mot17_classes(gt) else "MOT15"


@dataclass
class _Seq:
    name: str
    gt_file: Path
    length: int
    benchmark: str
    tracks: np.ndarray
    gt: np.ndarray | None = None  # the gt rows to score, where cut to a frame range
    warning: str | None = None


def _seq_name(gt_dir: Path) -> str:
    return gt_dir.resolve().name


def _tracks_file(
    tracks: Mapping[str, str | os.PathLike[str]] | str | os.PathLike[str],
    name: str,
    alias: str,
    single: bool,
) -> Path:
    if isinstance(tracks, Mapping):
        for key in (name, alias):
            if key in tracks:
                return Path(tracks[key])
        raise InputError(f"no tracks given for sequence {name} (keys: {', '.join(tracks)})")
    p = Path(tracks)
    if p.is_dir():
        for key in (name, alias):
            if (p / f"{key}.txt").is_file():
                return p / f"{key}.txt"
        raise InputError(f"{p}: no {name}.txt tracks file in this folder")
    if not single:
        raise InputError(
            f"{p}: a single tracks file given for several sequences; pass a folder "
            "of <sequence>.txt files or a mapping"
        )
    return p


def _load_sequence(
    gt_dir: Path, tracks_path: Path, benchmark: str, frames: FrameRange | None = None
) -> _Seq:
    gt_file = gt_dir / "gt" / "gt.txt"
    if not gt_file.is_file():
        raise InputError(f"{gt_dir}: no gt/gt.txt (is it a MOTChallenge sequence folder?)")
    gt = motio.read_gt(gt_file)
    tracks = motio.read_tracks(tracks_path)
    name = _seq_name(gt_dir)
    if (gt_dir / "seqinfo.ini").is_file():
        length = motio.read_seqinfo(gt_dir).length
    else:
        length = int(max(gt[:, 0].max(initial=0), tracks[:, 0].max(initial=0)))
    if len(gt) and gt[:, 0].max() > length:
        raise InputError(f"{gt_file}: frames go to {gt[:, 0].max():.0f}, past seqLength={length}")
    if len(tracks) and tracks[:, 0].max() > length:
        raise InputError(
            f"{tracks_path}: frames go to {tracks[:, 0].max():.0f} but sequence {name} has "
            f"{length} frames"
        )
    pairs = tracks[:, :2].astype(np.int64)
    uniq, counts = np.unique(pairs, axis=0, return_counts=True)
    if (counts > 1).any():
        f, i = uniq[np.argmax(counts > 1)]
        raise InputError(f"{tracks_path}: track id {i} appears twice in frame {f}")
    if benchmark == "auto":
        bench = detect_benchmark(name, gt)
    elif benchmark in BENCHMARKS:
        bench = "MOT17" if benchmark == "MOT16" else benchmark
    else:
        raise ParameterError(
            f"benchmark must be auto or one of {', '.join(BENCHMARKS)}, got {benchmark!r}"
        )
    if bench != "MOT15" and len(gt) and not _has_mot17_classes(gt):
        raise InputError(
            f"{gt_file}: {bench} rules need class and visibility columns (8th: class id 1-13, "
            "9th: visibility 0-1); for gt without classes use eval --benchmark MOT15 "
            "(benchmark='MOT15' in Python)"
        )
    if frames is not None:
        rng = frames.clip(length)
        assert rng.last is not None
        if rng.first > rng.last:
            raise ParameterError(
                f"frame range {rng.first}:{frames.last or ''} starts past the end of {name} "
                f"({length} frames)"
            )
        gt, tracks = _cut(gt, rng.first, rng.last), _cut(tracks, rng.first, rng.last)
        length = rng.last - rng.first + 1
        gt, tracks, length = _drop_empty_frames(gt, tracks, length)
        return _Seq(name, gt_file.resolve(), length, bench, tracks, gt)
    warning = _coverage(gt, tracks, name)
    kept_gt, tracks, kept = _drop_empty_frames(gt, tracks, length)
    if kept == length:
        return _Seq(name, gt_file.resolve(), length, bench, tracks, None, warning)
    return _Seq(name, gt_file.resolve(), kept, bench, tracks, kept_gt, warning)


def _drop_empty_frames(
    gt: np.ndarray, tracks: np.ndarray, length: int
) -> tuple[np.ndarray, np.ndarray, int]:
    """The rows renumbered over the frames that hold a gt or a tracks row, and their count.

    trackeval allocates per frame of the declared length (a seqLength of 2^31 - 1 or one row at
    frame 2e9 would need tens of GB); a frame with neither a gt nor a tracks row adds nothing to
    any metric (CLEAR skips it without breaking a trajectory, HOTA and Identity count nothing in
    it), so the evaluation runs over the frames the files hold and its memory follows them.
    """
    used = np.unique(np.concatenate([gt[:, 0], tracks[:, 0]])).astype(np.int64)
    if len(used) == length:
        return gt, tracks, length
    renumber = lambda rows: _renumbered(rows, used)  # noqa: E731
    return renumber(gt), renumber(tracks), max(len(used), 1)


def _renumbered(rows: np.ndarray, used: np.ndarray) -> np.ndarray:
    out = rows.copy()
    out[:, 0] = np.searchsorted(used, rows[:, 0].astype(np.int64)) + 1
    return out


def _cut(rows: np.ndarray, first: int, last: int) -> np.ndarray:
    """Rows of frames first..last, renumbered from 1."""
    kept = rows[(rows[:, 0] >= first) & (rows[:, 0] <= last)].copy()
    kept[:, 0] -= first - 1
    return kept


def _coverage(gt: np.ndarray, tracks: np.ndarray, name: str) -> str | None:
    """A warning where the ground truth has frames outside the span of the tracks."""
    gt_frames = np.unique(gt[:, 0]).astype(np.int64)
    if not len(gt_frames):
        return None
    if not len(tracks):
        return f"{name}: the tracks are empty; every ground-truth box is scored as missed"
    first, last = int(tracks[:, 0].min()), int(tracks[:, 0].max())
    outside = int(np.count_nonzero((gt_frames < first) | (gt_frames > last)))
    if outside <= UNCOVERED_FRAMES_WARN:
        return None
    return (
        f"{name}: the tracks cover frames {first}-{last} but the ground truth "
        f"{gt_frames[0]}-{gt_frames[-1]}; its {outside} frames outside the tracks are scored as "
        "missed (to score a partial run, pass its range: eval --frames A:B)"
    )


def _link_or_copy(src: Path, dst: Path) -> None:
    dst.parent.mkdir(parents=True, exist_ok=True)
    try:
        dst.symlink_to(src)
    except OSError:
        dst.write_bytes(src.read_bytes())


def _plain(metric: str, value: Any) -> float:
    """trackeval value -> a plain float: HOTA arrays averaged over IoU thresholds, ratios in %."""
    v = float(np.mean(value))
    return v if metric in COUNT_METRICS else 100.0 * v


def _flatten(res: Mapping[str, Mapping[str, Any]]) -> dict[str, float]:
    hota, clear, ident, count = res["HOTA"], res["CLEAR"], res["Identity"], res["Count"]
    out = {
        "HOTA": hota["HOTA"],
        "DetA": hota["DetA"],
        "AssA": hota["AssA"],
        "MOTA": clear["MOTA"],
        "MOTP": clear["MOTP"],
        "IDF1": ident["IDF1"],
        "IDP": ident["IDP"],
        "IDR": ident["IDR"],
        "MT": clear["MT"],
        "ML": clear["ML"],
        "FP": clear["CLR_FP"],
        "FN": clear["CLR_FN"],
        "IDSW": clear["IDSW"],
        "Frag": clear["Frag"],
        "GT_IDs": count["GT_IDs"],
        "IDs": count["IDs"],
    }
    return {k: _plain(k, v) for k, v in out.items()}


def evaluate(
    gt_dirs: Sequence[str | os.PathLike[str]],
    tracks: Mapping[str, str | os.PathLike[str]] | str | os.PathLike[str],
    *,
    benchmark: str = "auto",
    frames: str | FrameRange | None = None,
) -> EvalResult:
    """Score tracker output against MOTChallenge ground truth with trackeval.

    gt_dirs: sequence folders, each with gt/gt.txt (and seqinfo.ini for the length; without it the
        last frame of gt or tracks is used).
    tracks: {sequence name: tracks file}, a folder of ``<sequence>.txt``, or one file when there is
        one sequence. The sequence name is the folder's name.
    benchmark: "auto" (from the gt columns and the sequence name) or MOT15/MOT16/MOT17/MOT20.
    frames: ``"A:B"`` (1-based, inclusive; ``A:`` and ``:B`` too) to score only those frames of
        every sequence; None scores all, warning where the tracks cover fewer frames.
    """
    from densepeds.io.video import parse_frame_range

    rng = parse_frame_range(frames) if frames is not None else None
    try:
        import trackeval  # heavy import (scipy, pycocotools) only when evaluating
    except ImportError as err:
        raise InputError(
            f"evaluation needs trackeval ({err}); install it with: {INSTALL_HINT}"
        ) from err

    dirs = [Path(d) for d in gt_dirs]
    if not dirs:
        raise InputError("no ground-truth sequence folders given")
    seqs: list[_Seq] = []
    for d in dirs:
        if not d.is_dir():
            raise InputError(f"{d}: ground-truth sequence folder not found")
        alias = d.name
        if (d / "seqinfo.ini").is_file():
            alias = motio.read_seqinfo(d).name
        tpath = _tracks_file(tracks, _seq_name(d), alias, single=len(dirs) == 1)
        seqs.append(_load_sequence(d, tpath, benchmark, rng))
    names = [s.name for s in seqs]
    if len(set(names)) != len(names):
        raise InputError(f"sequence folders with the same name: {names}")

    metrics = [
        trackeval.metrics.HOTA({"PRINT_CONFIG": False}),
        trackeval.metrics.CLEAR({"PRINT_CONFIG": False}),
        trackeval.metrics.Identity({"PRINT_CONFIG": False}),
        trackeval.metrics.Count(),
    ]
    metric_names = [m.get_name() for m in metrics]
    per_seq: dict[str, dict[str, Any]] = {}
    log = io.StringIO()
    with (
        tempfile.TemporaryDirectory(prefix="densepeds-eval-") as tmp,
        contextlib.redirect_stdout(log),
        np.errstate(all="ignore"),
    ):
        root = Path(tmp)
        for s in seqs:
            gt_path = root / "gt" / s.name / "gt" / "gt.txt"
            if s.gt is None:
                _link_or_copy(s.gt_file, gt_path)
            else:
                gt_path.parent.mkdir(parents=True, exist_ok=True)
                gt_path.write_text(
                    "".join(",".join(f"{v:.17g}" for v in row) + "\n" for row in s.gt.tolist()),
                    encoding="utf-8",
                )
            motio.write_tracks(root / "trackers" / _TRACKER / "data" / f"{s.name}.txt", s.tracks)
        for bench in sorted({s.benchmark for s in seqs}):
            group = [s for s in seqs if s.benchmark == bench]
            config = {
                "GT_FOLDER": str(root / "gt"),
                "TRACKERS_FOLDER": str(root / "trackers"),
                "TRACKERS_TO_EVAL": [_TRACKER],
                "BENCHMARK": bench,
                "SKIP_SPLIT_FOL": True,
                "SEQ_INFO": {s.name: s.length for s in group},
                "PRINT_CONFIG": False,
            }
            try:
                dataset = trackeval.datasets.MotChallenge2DBox(config)
                for s in group:
                    per_seq[s.name] = trackeval.eval.eval_sequence(
                        s.name, dataset, _TRACKER, ["pedestrian"], metrics, metric_names
                    )["pedestrian"]
            except trackeval.utils.TrackEvalException as err:
                raise InputError(f"trackeval could not evaluate {bench} sequences: {err}") from err
        combined = {
            name: metric.combine_sequences({s: per_seq[s][name] for s in names})
            for metric, name in zip(metrics, metric_names, strict=True)
        }
    return EvalResult(
        sequences={s: _flatten(per_seq[s]) for s in names},
        combined=_flatten(combined),
        benchmarks={s.name: s.benchmark for s in seqs},
        warnings=[s.warning for s in seqs if s.warning],
    )


def _fmt_value(metric: str, value: float) -> str:
    return f"{value:.0f}" if metric in COUNT_METRICS else f"{value:.2f}"


def format_results(result: EvalResult, fmt: str = "md", metrics: Sequence[str] = METRICS) -> str:
    """The result as a Markdown table, CSV, or JSON (all metrics, full precision)."""
    rows = result.rows()
    if fmt == "json":
        return json.dumps(
            {
                "sequences": result.sequences,
                "combined": result.combined,
                "benchmarks": result.benchmarks,
            },
            indent=2,
        )
    unknown = [m for m in metrics if m not in result.combined]
    if unknown:
        raise ParameterError(f"unknown metrics {unknown}; known: {', '.join(result.combined)}")
    if fmt == "csv":
        lines = [",".join(["sequence", *metrics])]
        lines += [",".join([n, *(repr(float(r[m])) for m in metrics)]) for n, r in rows]
        return "\n".join(lines) + "\n"
    if fmt == "md":
        lines = ["| sequence | " + " | ".join(metrics) + " |", "|---|" + "---:|" * len(metrics)]
        for n, r in rows:
            name = f"**{n}**" if n == COMBINED else n
            lines.append(f"| {name} | " + " | ".join(_fmt_value(m, r[m]) for m in metrics) + " |")
        return "\n".join(lines) + "\n"
    raise ParameterError(f"format must be md, csv or json, got {fmt!r}")
