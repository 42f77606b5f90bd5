"""Tracker update time with appearance embeddings, on one thread, as the crowd grows.

    python benchmarks/appearance_speed.py [--people 200,800,1670] [--frames 30] [--dim 512]

Inputs: synthetic crowds (people walking in random directions on a 1920x1080 view, box jitter,
10% missed detections) where each person has a fixed random unit embedding
plus per-frame noise (cosine distance about 0.1 to their own mean, about 1 to others). The
tracker runs with the CNN preset (``densepeds.presets``' ``yoloseg``: gallery of 100
embeddings, appearance within one box height) and ``threads=1``. Frames after the first
``gallery_size`` are timed (the galleries are full by then); prints the median and p95 of
``Tracker.update`` (conversions included) per frame, the calling thread's CPU time (steadier than
wall time on a shared machine), and the load average.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np
from densepeds.presets import get_preset
from densepeds.tracking import Tracker

NOISE = 0.015  # per-value noise on a unit 512-d embedding: cosine ~0.1 to the person's mean
PEOPLE = (200, 800, 1670)  # about 180, 720 and 1,500 detections a frame
DIM = 512  # OSNet's embedding size


def crowd_with_embeddings(
    people: int, frames: int, dim: int, seed: int = 0
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Frames of (boxes, scores, embeddings): people walking across a 1920x1080 view at 1-4
    px/frame in random directions (wrapping at the edges), 10% missed each frame."""
    rng = np.random.default_rng(seed)
    size = np.array([1920.0, 1080.0])
    identity = rng.normal(size=(people, dim)).astype(np.float32)
    identity /= np.linalg.norm(identity, axis=1, keepdims=True)
    pos = rng.random((people, 2)) * size
    angle = rng.uniform(0, 2 * np.pi, people)
    vel = np.stack([np.cos(angle), np.sin(angle)], 1) * rng.uniform(1, 4, (people, 1))
    half = np.array([20.0, 50.0]) * rng.uniform(0.8, 1.2, (people, 1))
    out = []
    for _ in range(frames):
        pos = (pos + vel) % size
        seen = np.flatnonzero(rng.random(people) > 0.1)
        c = pos[seen] + rng.normal(0, 1.0, (len(seen), 2))
        boxes = np.hstack([c - half[seen], c + half[seen]])
        scores = rng.uniform(0.3, 1.0, len(seen))
        emb = identity[seen] + rng.normal(0, NOISE, (len(seen), dim)).astype(np.float32)
        out.append((boxes, scores, emb))
    return out


def time_updates(people: int, frames: int, dim: int) -> tuple[float, float, float, int]:
    """(median wall ms, p95 wall ms, median CPU ms of this thread, detections a frame)."""
    params = {**get_preset("yoloseg").tracker, "threads": 1}
    warm = int(params["gallery_size"])
    data = crowd_with_embeddings(people, warm + frames, dim)
    tracker = Tracker(**params)
    wall, cpu = [], []
    for k, (boxes, scores, emb) in enumerate(data):
        start, start_cpu = time.perf_counter(), time.thread_time()
        tracker.update(boxes, scores, emb)
        if k >= warm:
            wall.append(time.perf_counter() - start)
            cpu.append(time.thread_time() - start_cpu)
    dets = int(np.mean([len(d[0]) for d in data]))
    return 1000 * np.median(wall), 1000 * np.percentile(wall, 95), 1000 * np.median(cpu), dets


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--people", default=",".join(map(str, PEOPLE)), help="crowd sizes")
    ap.add_argument("--frames", type=int, default=30, help="timed frames after the warm-up")
    ap.add_argument("--dim", type=int, default=DIM)
    args = ap.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    print("| people | detections/frame | update ms, median | p95 | CPU ms, median |")
    print("|---:|---:|---:|---:|---:|")
    for people in (int(p) for p in args.people.split(",")):
        med, p95, cpu, dets = time_updates(people, args.frames, args.dim)
        print(f"| {people} | {dets} | {med:.1f} | {p95:.1f} | {cpu:.1f} |", flush=True)
    print(
        f"{args.dim}-d embeddings, CNN preset, threads=1; load average after: "
        f"{os.getloadavg()[0]:.1f}; {platform.processor() or platform.machine()}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
