"""Re-ID's onnxruntime threads: by default each batch is split into one part per CPU, each part
run on one thread, all at once (crops left over after); the embeddings are bitwise those of one
call on any thread count."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import shared_path
from densepeds import reid as reid_module
from densepeds.reid import ReID
from test_reid import fixed_batch_mars_like


def _crops(count: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [
        rng.integers(0, 256, (int(rng.integers(40, 200)), int(rng.integers(20, 90)), 3), np.uint8)
        for _ in range(count)
    ]


class _Recording:
    """Wraps a session: records each call's batch size and the thread that ran it."""

    def __init__(self, session: Any) -> None:
        self.session = session
        self.calls: list[tuple[int, int]] = []
        self.lock = threading.Lock()

    def run(self, names: Any, feed: dict[str, np.ndarray]) -> Any:
        with self.lock:
            self.calls.append((len(next(iter(feed.values()))), threading.get_ident()))
        return self.session.run(names, feed)


def test_default_splits_each_batch_one_part_per_cpu_on_one_thread_sessions(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(reid_module.onnxutil, "available_cpus", lambda: 2)
    reid = ReID(fixed_batch_mars_like(tmp_path / "m.onnx"), batch_size=64)
    assert reid.session.get_session_options().intra_op_num_threads == 1
    rec = _Recording(reid.session)
    reid.session = rec  # type: ignore[assignment]
    crops = _crops(9, 2)
    split = reid.embed_crops(crops)
    me = threading.get_ident()
    # Two parts of 4 at once on the pool's threads, the crop left over after, on this thread.
    assert sorted((n, t == me) for n, t in rec.calls) == [(1, True), (4, False), (4, False)]
    rec.calls.clear()
    reid.embed_crops(crops[:1])  # one crop: one call on the calling thread
    assert rec.calls == [(1, me)]
    # Threads given: one call per batch on that many threads, the same rows.
    fixed = ReID(fixed_batch_mars_like(tmp_path / "m2.onnx"), threads=2, batch_size=64)
    assert fixed.session.get_session_options().intra_op_num_threads == 2
    rec2 = _Recording(fixed.session)
    fixed.session = rec2  # type: ignore[assignment]
    assert np.array_equal(fixed.embed_crops(crops), split)
    assert [n for n, _ in rec2.calls] == [9]


@pytest.mark.parametrize("count", [1, 2, 5, 9, 24, 40])
def test_osnet_embeddings_bitwise_the_same_split_or_on_one_thread_or_two(count: int) -> None:
    model = shared_path("models", "osnet_x0_25_msmt17.onnx")
    crops = _crops(count, count)
    default = ReID(model).embed_crops(crops)
    one = ReID(model, threads=1).embed_crops(crops)
    two = ReID(model, threads=2).embed_crops(crops)
    assert default.shape == (count, 512) and np.isfinite(default).all()
    assert np.array_equal(default, one) and np.array_equal(default, two)


def test_masked_pool_embeddings_bitwise_the_same_split_or_in_one_call() -> None:
    model = shared_path("models", "osnet_x0_25_msmt17.onnx")
    crops = _crops(7, 11)
    rng = np.random.default_rng(3)
    masks = [rng.random(c.shape[:2]) > 0.4 for c in crops]
    default = ReID(model).embed_crops(crops, masks)
    two = ReID(model, threads=2).embed_crops(crops, masks)
    assert np.isfinite(default).all() and np.array_equal(default, two)


@pytest.mark.parametrize("pooled", [False, True])
def test_a_crowd_is_embedded_a_few_crops_per_thread_at_a_time_with_the_same_embeddings(
    monkeypatch: pytest.MonkeyPatch, pooled: bool
) -> None:
    """CROPS_PER_THREAD bounds each call (memory stays bounded in a crowd); the embeddings are
    those of one call on every crop."""
    model = shared_path("models", "osnet_x0_25_msmt17.onnx")
    crops = _crops(37, 5)
    rng = np.random.default_rng(4)
    masks = [rng.random(c.shape[:2]) > 0.4 for c in crops] if pooled else None
    monkeypatch.setattr(reid_module, "CROPS_PER_THREAD", 1000)
    whole = ReID(model, threads=2).embed_crops(crops, masks)
    monkeypatch.setattr(reid_module, "CROPS_PER_THREAD", 3)
    small = ReID(model, threads=2)
    session = small._pooled_session()[0] if pooled else small.session
    recording = _Recording(session)
    if pooled:
        small._pooled = (recording, small._pooled[1])  # type: ignore[assignment, index]
    else:
        small.session = recording  # type: ignore[assignment]
    got = small.embed_crops(crops, masks)
    sizes = [n for n, _ in recording.calls]
    assert sum(sizes) == 37 and max(sizes) == 6  # 3 crops on each of 2 threads at most
    assert np.array_equal(got, whole)
