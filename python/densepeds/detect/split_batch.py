"""One onnxruntime call split into one part per CPU, the parts run at once on one-thread sessions.

With idle threads sleeping (``onnxutil.session_options``), a session that spreads each layer of
a small network over several threads pays a wake-up per layer. Splitting the batch instead, one
part per CPU, each run start to end by one thread, keeps every CPU busy without those
hand-overs (``benchmarks/results/speed.md`` times the whole pipeline). Items left over when the
batch does not divide evenly (fewer than the CPUs) run after, in one call. The detector, whose
layers are large enough to share, splits only a batch of views that divides evenly and runs any
other as one call on every CPU. onnxruntime releases the GIL while it runs, and a session may
run on several threads at once.

Each item's output does not depend on the other items in its batch for the models this package
runs (convolutions, pooling and the like work image by image), so the split gives bitwise the
outputs of one call (``tests/test_split_batch.py`` checks the segmenter, as shipped and as its
float copy, ``tests/test_reid_threads.py`` OSNet).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import onnxruntime as ort

from densepeds.detect import onnxutil

_pool: tuple[int, ThreadPoolExecutor] | None = None  # (the process that made it, the pool)


def cpu_pool() -> ThreadPoolExecutor:
    """One worker thread per usable CPU, made on first use in this process (a forked child, whose
    parent's threads did not come along, makes its own)."""
    global _pool
    if _pool is None or _pool[0] != os.getpid():
        _pool = (os.getpid(), ThreadPoolExecutor(onnxutil.available_cpus(), "densepeds-ort"))
    return _pool[1]


def run_split(session: ort.InferenceSession, feed: Mapping[str, np.ndarray]) -> list[np.ndarray]:
    """``session.run(None, feed)`` with every input split along its first (batch) axis: the
    largest multiple of the usable CPUs among the items in one equal part per CPU, run at once on
    :func:`cpu_pool` (``session`` should run on one thread), then the items left over (fewer than
    the CPUs) in one call on the calling thread. Each output is the parts' outputs concatenated
    in order."""
    n = len(next(iter(feed.values())))
    cpus = onnxutil.available_cpus()
    per = n // cpus

    def part(lo: int, hi: int) -> list[np.ndarray]:
        return list(session.run(None, {name: v[lo:hi] for name, v in feed.items()}))

    if cpus == 1 or per == 0:
        return part(0, n)
    futures = [cpu_pool().submit(part, k * per, (k + 1) * per) for k in range(cpus)]
    results = [f.result() for f in futures]
    if per * cpus < n:
        results.append(part(per * cpus, n))
    return [np.concatenate([r[i] for r in results]) for i in range(len(results[0]))]
