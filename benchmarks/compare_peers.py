"""Accuracy and per-frame update time of DensePeds (motion only) against established trackers.

Every tracker gets identical input per frame: the sequence's public det.txt boxes (x1, y1, x2, y2)
and scores. Score convention, the same for all trackers and the same as the CLI's det.txt input
(``motio.read_detections``' default, see ``motio.score_scale``): a det file whose scores already lie
in [0, 1] (MOT17) is used as is; otherwise (MOT15: e.g. -0.7 .. 138.9) its scores are min-max
rescaled per file to [0, 1]. No detection is dropped before tracking.
Tracker output is written in MOTChallenge format and scored with densepeds.evaluate (trackeval).
The update time is the median (and p95) wall time of one update call per frame, including the
adapter's conversion from/to NumPy arrays (see peers.py).

    python benchmarks/compare_peers.py                       # all trackers, 6 dev sequences
    python benchmarks/compare_peers.py --param xi=30 --motion frvo cv --trackers densepeds
    python benchmarks/compare_peers.py --sweep xi=10,30 --sweep lambda_iou=0.2,0.3  # ours only
"""

from __future__ import annotations

import argparse
import itertools
import platform
import shlex
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers  # noqa: E402
from accuracy_grid import DET_SEQUENCES as DEV_SEQUENCES  # noqa: E402
from accuracy_grid import parse_params, parse_value  # noqa: E402
from densepeds import motio  # noqa: E402
from densepeds.evaluate import evaluate  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SHOWN = ("HOTA", "IDF1", "MOTA", "IDSW")


@dataclass
class Sequence:
    path: Path
    info: motio.SeqInfo
    frames: list[tuple[np.ndarray, np.ndarray]]  # per frame 1..length: boxes [N,4], scores [N]
    score_note: str


def load_sequence(path: Path) -> Sequence:
    """Frames of boxes and scores, read with motio's default score mapping (the CLI's too)."""
    info = motio.read_seqinfo(path)
    det_path = path / "det" / "det.txt"
    dets = motio.read_detections(det_path)
    raw = motio.read_detections(det_path, normalize="none")  # only to describe the mapping
    raw_scores = np.concatenate([d.scores for d in raw.values()]) if raw else np.zeros(0)
    scale = motio.score_scale(raw_scores)
    if not len(raw_scores):
        note = "no detections"
    elif scale is None:
        note = f"as is ({raw_scores.min():.3g}..{raw_scores.max():.3g})"
    else:
        note = f"min-max rescaled from {scale[0]:.3g}..{scale[1]:.3g}"
    empty = (np.zeros((0, 4), np.float32), np.zeros(0, np.float32))
    frames = [
        (dets[f].boxes, dets[f].scores) if f in dets else empty for f in range(1, info.length + 1)
    ]
    return Sequence(path, info, frames, note)


def run_tracker(
    name: str, seq: Sequence, out: Path, params: dict[str, object] | None
) -> list[float]:
    """Track one sequence, write its MOT file, return the update time per frame in ms."""
    tracker = peers.make_tracker(name, seq.info.fps, params)
    rows: list[np.ndarray] = []
    times = []
    for f, (boxes, scores) in enumerate(seq.frames, start=1):
        t0 = time.perf_counter()
        ids, tboxes, tscores = tracker.update(boxes, scores)
        times.append((time.perf_counter() - t0) * 1e3)
        if len(ids):
            rows.append(np.c_[np.full(len(ids), f), ids, tboxes, tscores])
    motio.write_tracks(out, np.concatenate(rows) if rows else np.zeros((0, 7)))
    return times


def evaluate_tracker(
    name: str, seqs: list[Sequence], workdir: Path, params: dict[str, object] | None = None
) -> dict[str, dict[str, float]]:
    """Metrics per sequence (and COMBINED) plus timing for one tracker configuration."""
    tdir = workdir / name
    timing = {}
    for seq in seqs:
        times = run_tracker(name, seq, tdir / f"{seq.path.name}.txt", params)
        timing[seq.path.name] = (float(np.median(times)), float(np.percentile(times, 95)))
    result = evaluate([s.path for s in seqs], tdir)
    table = {}
    for seq_name, metrics in result.rows():
        m = dict(metrics)
        if seq_name in timing:
            m["ms_median"], m["ms_p95"] = timing[seq_name]
        table[seq_name] = m
    return table


def results_table(results: dict[str, dict[str, dict[str, float]]], seq_names: list[str]) -> str:
    """One row per (sequence, tracker): HOTA, IDF1, MOTA, IDSW, FP, FN, update time."""
    lines = [
        "| sequence | tracker | HOTA | IDF1 | MOTA | IDSW | FP | FN | update ms (median / p95) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for seq_name in [*seq_names, "COMBINED"]:
        best = {k: max(r[seq_name][k] for r in results.values()) for k in ("HOTA", "IDF1")}
        for tracker, r in results.items():
            m = r[seq_name]
            cells = [
                f"**{m[k]:.2f}**" if m[k] == best[k] else f"{m[k]:.2f}" for k in ("HOTA", "IDF1")
            ]
            timing = f"{m['ms_median']:.3f} / {m['ms_p95']:.3f}" if "ms_median" in m else "-"
            lines.append(
                f"| {seq_name} | {tracker} | {cells[0]} | {cells[1]} | {m['MOTA']:.2f} | "
                f"{m['IDSW']:.0f} | {m['FP']:.0f} | {m['FN']:.0f} | {timing} |"
            )
    return "\n".join(lines) + "\n"


def summary_table(
    results: dict[str, dict[str, dict[str, float]]], seq_names: list[str], metric: str
) -> str:
    short = [s.split("-")[0] + "-" + s.split("-")[1] if "-" in s else s for s in seq_names]
    lines = [
        f"| {metric} | " + " | ".join([*short, "combined"]) + " |",
        "|---|" + "---:|" * (len(seq_names) + 1),
    ]
    for tracker, r in results.items():
        vals = [f"{r[s][metric]:.2f}" for s in [*seq_names, "COMBINED"]]
        lines.append(f"| {tracker} | " + " | ".join(vals) + " |")
    return "\n".join(lines) + "\n"


def write_markdown(
    path: Path,
    results: dict[str, dict[str, dict[str, float]]],
    seqs: list[Sequence],
    command: str,
    notes: list[str],
) -> None:
    seq_names = [s.path.name for s in seqs]
    vers = ", ".join(f"{k} {v}" for k, v in peers.versions().items())
    parts = [
        "# Accuracy: DensePeds (motion only) vs established trackers on public detections\n",
        f"Command (from the repository root): `{command}`\n",
        f"Packages: {vers}; Python {platform.python_version()}.\n",
        "Input: each sequence's public `det/det.txt`, identical for every tracker. Scores: a file "
        "whose scores lie in [0, 1] is used as is, otherwise it is min-max rescaled per file to "
        "[0, 1] (" + "; ".join(f"{s.path.name}: {s.score_note}" for s in seqs) + "). "
        "Peers run with their package defaults (Roboflow ByteTrack gets the sequence frame rate). "
        "Metrics by `densepeds.evaluate` (trackeval, MOTChallenge rules: MOT17 for MOT17-02, "
        "MOT15 for the others). Update time: median / p95 ms per frame of the tracker's update "
        "call including the adapter's NumPy conversion, on this machine, in the same run.\n",
        *[n + "\n" for n in notes],
        "## HOTA\n",
        summary_table(results, seq_names, "HOTA"),
        "\n## IDF1\n",
        summary_table(results, seq_names, "IDF1"),
        "\n## All figures\n",
        results_table(results, seq_names),
    ]
    motio_tmp = path.with_suffix(".md.tmp")
    motio_tmp.parent.mkdir(parents=True, exist_ok=True)
    motio_tmp.write_text("\n".join(parts))
    motio_tmp.replace(path)


def run_sweep(args: argparse.Namespace, seqs: list[Sequence], workdir: Path) -> None:
    grid_keys, grid_values = [], []
    for item in args.sweep:
        key, _, values = item.partition("=")
        grid_keys.append(key)
        grid_values.append([parse_value(v) for v in values.split(",")])
    base = parse_params(args.param)
    seq_names = [s.path.name for s in seqs]
    header = (
        "| motion | params | "
        + " | ".join(f"{s.split('-')[0]} HOTA/IDF1" for s in seq_names)
        + " | combined HOTA/IDF1 |"
    )
    print(header)
    print("|---|---|" + "---:|" * (len(seq_names) + 1))
    for motion in args.motion:
        for combo in itertools.product(*grid_values):
            params = {**base, **dict(zip(grid_keys, combo, strict=True))}
            name = f"densepeds-{motion}"
            try:
                r = evaluate_tracker(name, seqs, workdir / "sweep", params)
            except Exception as err:  # report a rejected combination and go on with the grid
                print(f"| {motion} | {params} | failed: {err} |", flush=True)
                continue
            cells = [f"{r[s]['HOTA']:.2f}/{r[s]['IDF1']:.2f}" for s in [*seq_names, "COMBINED"]]
            print(f"| {motion} | {params} | " + " | ".join(cells) + " |", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    ap.add_argument("--sequences", nargs="+", default=list(DEV_SEQUENCES))
    ap.add_argument(
        "--trackers",
        nargs="+",
        default=[*(p for p in peers.PEERS if p not in peers.NEEDS_EMBEDDINGS), "densepeds"],
        help=f"any of {', '.join(peers.PEERS)} (except {', '.join(peers.NEEDS_EMBEDDINGS)}: "
        "these need embeddings), densepeds (= each --motion)",
    )
    ap.add_argument("--motion", nargs="+", default=list(peers.MOTIONS), choices=peers.MOTIONS)
    ap.add_argument("--param", action="append", default=[], help="key=value for our Tracker")
    ap.add_argument("--sweep", action="append", default=[], help="key=v1,v2: grid over ours")
    ap.add_argument("--tracks-dir", type=Path, help="keep the tracker outputs here")
    ap.add_argument("--out", type=Path, help="write the Markdown report here")
    args = ap.parse_args(argv)

    missing = [s for s in args.sequences if not (args.data / s / "det" / "det.txt").is_file()]
    if missing:
        print(f"no det/det.txt under {args.data} for: {', '.join(missing)}", file=sys.stderr)
        return 2
    seqs = [load_sequence(args.data / s) for s in args.sequences]
    notes = []
    workdir_ctx = tempfile.TemporaryDirectory(prefix="densepeds-peers-")
    workdir = args.tracks_dir or Path(workdir_ctx.name)
    with workdir_ctx:
        if args.sweep:
            run_sweep(args, seqs, workdir)
            return 0
        names = [t for t in args.trackers if t != "densepeds"]
        if "densepeds" in args.trackers:
            why_not = peers.densepeds_available()
            if why_not is None:
                names += [f"densepeds-{m}" for m in args.motion]
            else:
                notes.append(f"DensePeds not run: {why_not}.")
                print(f"skipping densepeds: {why_not}", file=sys.stderr)
        params = parse_params(args.param)
        if params:
            notes.append(f"DensePeds parameters: {params}.")
        results = {}
        for name in names:
            t0 = time.perf_counter()
            results[name] = evaluate_tracker(name, seqs, workdir, params)
            print(f"{name}: done in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
        seq_names = [s.path.name for s in seqs]
        print(summary_table(results, seq_names, "HOTA"))
        print(summary_table(results, seq_names, "IDF1"))
        print(results_table(results, seq_names))
        if args.out:
            command = "python benchmarks/compare_peers.py " + shlex.join(
                argv if argv is not None else sys.argv[1:]
            )
            write_markdown(args.out, results, seqs, command.strip(), notes)
            print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
