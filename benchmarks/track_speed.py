"""Per-frame time of Tracker.update: ours (each motion model, motion only) vs peer trackers.

Inputs, identical for every tracker: MOT17-02-FRCNN's public detections (about 30 people a
frame) and synthetic crowds of 80 and 200 people (walking in four crossing streams, box jitter,
10% missed detections). Each tracker is called once per frame through the adapters in peers.py
(NumPy in, NumPy out, conversions included); the figures are the median and p95 over frames.
The trackers take turns, one whole run of an input each, `--repeat` times, so that all see the
same machine load (printed before and after); ours step their motion model on `--threads`
threads (default 1, the calling thread). The last column of each input is the median over
trackforge ByteTrack's median on the same input.

    python benchmarks/track_speed.py                 # all trackers, all inputs
    python benchmarks/track_speed.py --frames 200 --repeat 3
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
    from densepeds import motio

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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    ap.add_argument("--frames", type=int, default=300, help="frames of each synthetic crowd")
    ap.add_argument("--repeat", type=int, default=3, help="runs per tracker and input")
    ap.add_argument("--trackers", nargs="+", default=list(TRACKERS))
    ap.add_argument("--threads", type=int, default=1, help="our motion model's threads")
    args = ap.parse_args(argv)

    inputs: dict[str, tuple[Frames, float]] = {}
    seq = args.data / "MOT17-02-FRCNN"
    if (seq / "det" / "det.txt").is_file():
        inputs["MOT17-02 det (~30/frame)"] = (mot_frames(seq), 30.0)
    else:
        print(f"skipping MOT17-02: no {seq / 'det' / 'det.txt'}", file=sys.stderr)
    for n in (80, 200):
        inputs[f"synthetic {n} people"] = (synthetic_crowd(n, args.frames, seed=n), 30.0)

    print(f"Python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} cores")
    print(", ".join(f"{k} {v}" for k, v in peers.versions().items()))
    print(f"repeat={args.repeat}, threads={args.threads}; before: {load()}")
    params: dict[str, object] = {"threads": args.threads}
    times: dict[tuple[str, str], list[float]] = {(n, k): [] for n in args.trackers for k in inputs}
    for key, (frames, fps) in inputs.items():
        for _ in range(args.repeat):
            for name in args.trackers:
                times[name, key] += run_once(name, frames, fps, params)
    print(f"after: {load()}")
    print()
    ref = "trackforge-bytetrack"
    print("| tracker | " + " | ".join(f"{k} median / p95 ms | / ByteTrack" for k in inputs) + " |")
    print("|---|" + "---:|---:|" * len(inputs))
    for name in args.trackers:
        cells = []
        for key in inputs:
            t = np.array(times[name, key])
            ratio = "-"
            if (ref, key) in times:
                ratio = f"{np.median(t) / np.median(times[ref, key]):.2f}"
            cells.append(f"{np.median(t):.3f} / {np.percentile(t, 95):.3f} | {ratio}")
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
