"""Re-ID's onnxruntime thread choice: small batches on one thread, larger ones on every CPU,
with bitwise the same embeddings either way."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import shared_path
from densepeds import reid as reid_module
from densepeds.reid import ONE_THREAD_CROPS, ReID
from test_reid import fixed_batch_mars_like


def _crops(count: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [
        rng.integers(0, 256, (int(rng.integers(40, 200)), int(rng.integers(20, 90)), 3), np.uint8)
        for _ in range(count)
    ]


def test_small_batches_run_on_one_thread_and_larger_ones_on_every_cpu(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(reid_module.onnxutil, "available_cpus", lambda: 2)
    reid = ReID(fixed_batch_mars_like(tmp_path / "m.onnx"), batch_size=64)
    threads = reid.session.get_session_options().intra_op_num_threads
    assert threads == 1
    reid.embed_crops(_crops(ONE_THREAD_CROPS, 1))
    assert reid._wide is None  # nothing made for larger batches until one comes
    reid.embed_crops(_crops(ONE_THREAD_CROPS + 1, 2))
    assert reid._wide is not None
    assert reid._wide.get_session_options().intra_op_num_threads == 2
    # Threads given: one session for every batch.
    fixed = ReID(fixed_batch_mars_like(tmp_path / "m2.onnx"), threads=2, batch_size=64)
    fixed.embed_crops(_crops(ONE_THREAD_CROPS + 5, 3))
    assert fixed._wide is None
    assert fixed.session.get_session_options().intra_op_num_threads == 2


@pytest.mark.parametrize("count", [1, 5, ONE_THREAD_CROPS, ONE_THREAD_CROPS + 1, 24])
def test_osnet_embeddings_bitwise_the_same_on_one_thread_or_two(count: int) -> None:
    model = shared_path("models", "osnet_x0_25_msmt17.onnx")
    crops = _crops(count, count)
    default = ReID(model).embed_crops(crops)
    one = ReID(model, threads=1).embed_crops(crops)
    two = ReID(model, threads=2).embed_crops(crops)
    assert default.shape == (count, 512) and np.isfinite(default).all()
    assert np.array_equal(default, one) and np.array_equal(default, two)
