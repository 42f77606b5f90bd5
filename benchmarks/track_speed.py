"""Per-frame time of Tracker.update: ours (each motion model, motion only) vs peer trackers.

Inputs, identical for every tracker: MOT17-02-FRCNN's public detections (about 30 people a
frame) and synthetic crowds of 80 and 200 people (walking in four crossing streams, box jitter,
10% missed detections). Each tracker is called once per frame through the adapters in peers.py
(NumPy in, NumPy out, conversions included); the figures are the median and p95 over frames.
The trackers take turns, one whole run of an input each, `--repeat` times, so that all see the
same machine load (printed before and after); ours step their motion model on `--threads`
threads (default 1, the calling thread). The last column of each input is the median over
trackforge ByteTrack's median on the same input.

With ``--write FILE`` it also times the update with appearance embeddings as the crowd grows
(``appearance_speed.py``: the CNN preset, one thread) and writes both tables, with the command,
machine and load, to FILE (``benchmarks/results/tracker.md``).

    python benchmarks/track_speed.py                 # all trackers, all inputs
    python benchmarks/track_speed.py --frames 200 --repeat 3
    python benchmarks/track_speed.py --repeat 3 --write benchmarks/results/tracker.md
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import appearance_speed  # noqa: E402
import peers  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
Frames = list[tuple[np.ndarray, np.ndarray]]
TRACKERS = (
    *(f"densepeds-{m}" for m in peers.MOTIONS),
    "trackforge-bytetrack",
    "trackforge-ocsort",
    "roboflow-bytetrack",
)


def synthetic_crowd(n_people: int, n_frames: int, seed: int = 0) -> Frames:
    """Four streams crossing a 1920x1080 view; people re-enter on the opposite side."""
    rng = np.random.default_rng(seed)
    size = np.array([1920.0, 1080.0])
    pos = rng.random((n_people, 2)) * size
    heading = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]], float)[np.arange(n_people) % 4]
    vel = heading * rng.uniform(2, 5, (n_people, 1)) + rng.normal(0, 0.5, (n_people, 2))
    half = np.array([20.0, 50.0]) * rng.uniform(0.8, 1.2, (n_people, 1))
    frames: Frames = []
    for _ in range(n_frames):
        pos = (pos + vel) % size
        seen = rng.random(n_people) > 0.1
        c = pos[seen] + rng.normal(0, 1.0, (seen.sum(), 2))
        h = half[seen]
        boxes = np.hstack([c - h, c + h]).astype(np.float32)
        frames.append((boxes, rng.uniform(0.3, 1.0, len(boxes)).astype(np.float32)))
    return frames


def mot_frames(seq: Path) -> Frames:
    from densepeds.io import mot as motio

    info = motio.read_seqinfo(seq)
    dets = motio.read_detections(seq / "det" / "det.txt")
    empty = (np.zeros((0, 4), np.float32), np.zeros(0, np.float32))
    return [
        (dets[f].boxes, dets[f].scores) if f in dets else empty for f in range(1, info.length + 1)
    ]


def run_once(name: str, frames: Frames, fps: float, params: dict[str, object]) -> list[float]:
    """Milliseconds per update call over one run of a fresh tracker."""
    tracker = peers.make_tracker(name, fps, params if name.startswith("densepeds-") else None)
    times = []
    for boxes, scores in frames:
        t0 = time.perf_counter()
        tracker.update(boxes, scores)
        times.append((time.perf_counter() - t0) * 1e3)
    return times


def load() -> str:
    return "load average " + " / ".join(f"{x:.2f}" for x in os.getloadavg())


def update_table(args: argparse.Namespace) -> list[str]:
    """Time every tracker on every input; the lines of the Markdown report (also printed)."""
    inputs: dict[str, tuple[Frames, float]] = {}
    seq = args.data / "MOT17-02-FRCNN"
    if (seq / "det" / "det.txt").is_file():
        inputs["MOT17-02 det (~30/frame)"] = (mot_frames(seq), 30.0)
    else:
        print(f"skipping MOT17-02: no {seq / 'det' / 'det.txt'}", file=sys.stderr)
    for n in (80, 200):
        inputs[f"synthetic {n} people"] = (synthetic_crowd(n, args.frames, seed=n), 30.0)

    lines = [
        f"Python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} cores",
        ", ".join(f"{k} {v}" for k, v in peers.versions().items()),
        f"repeat={args.repeat}, threads={args.threads}; before: {load()}",
    ]
    print(*lines, sep="\n", flush=True)
    params: dict[str, object] = {"threads": args.threads}
    times: dict[tuple[str, str], list[float]] = {(n, k): [] for n in args.trackers for k in inputs}
    for key, (frames, fps) in inputs.items():
        for _ in range(args.repeat):
            for name in args.trackers:
                times[name, key] += run_once(name, frames, fps, params)
    lines += [f"after: {load()}", ""]
    ref = "trackforge-bytetrack"
    lines.append(
        "| tracker | " + " | ".join(f"{k} median / p95 ms | / ByteTrack" for k in inputs) + " |"
    )
    lines.append("|---|" + "---:|---:|" * len(inputs))
    for name in args.trackers:
        cells = []
        for key in inputs:
            t = np.array(times[name, key])
            ratio = "-"
            if (ref, key) in times:
                ratio = f"{np.median(t) / np.median(times[ref, key]):.2f}"
            cells.append(f"{np.median(t):.3f} / {np.percentile(t, 95):.3f} | {ratio}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    print(*lines[3:], sep="\n", flush=True)
    return lines


def appearance_table(frames: int) -> list[str]:
    """``appearance_speed.py``'s table at its default crowd sizes (printed as it goes)."""
    lines = [
        f"load average before: {os.getloadavg()[0]:.1f}",
        "| people | detections/frame | update ms, median | p95 | CPU ms, median |",
        "|---:|---:|---:|---:|---:|",
    ]
    print(*lines, sep="\n", flush=True)
    for people in appearance_speed.PEOPLE:
        med, p95, cpu, dets = appearance_speed.time_updates(people, frames, appearance_speed.DIM)
        lines.append(f"| {people} | {dets} | {med:.1f} | {p95:.1f} | {cpu:.1f} |")
        print(lines[-1], flush=True)
    lines.append(f"load average after: {os.getloadavg()[0]:.1f}")
    return lines


def report(args: argparse.Namespace, update: list[str], appearance: list[str]) -> str:
    command = f"python benchmarks/track_speed.py --repeat {args.repeat} --write {args.write}"
    return "\n".join(
        [
            "# Tracker update time: ours against peer trackers",
            "",
            "Written by this command (do not edit; rerun it):",
            "",
            f"    {command}",
            "",
            "## Motion only",
            "",
            "Each tracker is called once per frame through `benchmarks/peers.py`'s adapters (NumPy"
            " in and out, conversions included), a fresh tracker per run; the trackers take turns,"
            f" one whole run of an input each, {args.repeat} times; median / p95 over all frames of"
            " the runs, and the median over trackforge ByteTrack's on the same input. Ours step"
            f" their motion model on {args.threads} thread(s). Inputs: MOT17-02's public detections"
            f" and synthetic crowds (four crossing streams on a 1920x1080 view, {args.frames}"
            " frames, 10% missed detections).",
            "",
            "```",
            *update[:4],
            "```",
            "",
            *update[5:],
            "",
            "## With appearance embeddings",
            "",
            "`Tracker.update` with the CNN preset (gallery of 100 embeddings summarised in at most"
            f" 8 rows, appearance within one box height) on one thread, {appearance_speed.DIM}-d"
            " embeddings, synthetic crowds of people walking in random directions on a 1920x1080"
            f" view, 10% missed; {args.appearance_frames} frames timed after the galleries fill."
            " The CPU column is the calling thread's time, steadier than wall time on a shared"
            " machine.",
            "",
            *appearance[1:-1],
            "",
            f"Load average before / after: {appearance[0].split(': ')[1]} /"
            f" {appearance[-1].split(': ')[1]}; {platform.processor() or platform.machine()}.",
            "",
        ]
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    ap.add_argument("--frames", type=int, default=300, help="frames of each synthetic crowd")
    ap.add_argument("--repeat", type=int, default=3, help="runs per tracker and input")
    ap.add_argument("--trackers", nargs="+", default=list(TRACKERS))
    ap.add_argument("--threads", type=int, default=1, help="our motion model's threads")
    ap.add_argument("--write", type=Path, help="also time with embeddings and write the report")
    ap.add_argument("--appearance-frames", type=int, default=10, help="with --write")
    args = ap.parse_args(argv)
    if args.write and set(args.trackers) != set(TRACKERS):
        ap.error("--write times every tracker (leave out --trackers)")
    update = update_table(args)
    if args.write:
        appearance = appearance_table(args.appearance_frames)
        args.write.write_text(report(args, update, appearance))
        print(f"wrote {args.write}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
