"""One onnxruntime call split into one part per CPU, the parts run at once on one-thread sessions.

With idle threads sleeping (``onnxutil.session_options``), a session that spreads each layer of
a small network over several threads pays a wake-up per layer; for the detector's views and the
re-ID crops that costs more than it saves. Splitting the batch instead, one part per CPU, each
run start to end by one thread, keeps every CPU busy without those hand-overs
(``benchmarks/results/speed.md``). onnxruntime releases the GIL while it runs, and a session may
run on several threads at once.

Each item's output does not depend on the other items in its batch for the models this package
runs (convolutions, pooling and the like work image by image), so the split gives bitwise the
outputs of one call (``tests/test_split_batch.py`` checks both shipped models).
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


def parts_for(items: int) -> int:
    """How many parts a batch of ``items`` is split into: one per usable CPU, at most one per
    item (1: run as one call)."""
    return max(1, min(items, onnxutil.available_cpus()))


def run_split(
    session: ort.InferenceSession, feed: Mapping[str, np.ndarray], parts: int
) -> list[np.ndarray]:
    """``session.run(None, feed)`` with every input split along its first (batch) axis into
    ``parts`` near-equal parts, run at once on :func:`cpu_pool`; each output is the parts'
    outputs concatenated in order. ``session`` should run on one thread."""
    n = len(next(iter(feed.values())))
    parts = max(1, min(parts, n))
    if parts == 1:
        return list(session.run(None, dict(feed)))
    bounds = np.linspace(0, n, parts + 1).round().astype(int)

    def one(k: int) -> list[np.ndarray]:
        lo, hi = bounds[k], bounds[k + 1]
        return list(session.run(None, {name: v[lo:hi] for name, v in feed.items()}))

    results = list(cpu_pool().map(one, range(parts)))
    return [np.concatenate([r[i] for r in results]) for i in range(len(results[0]))]
