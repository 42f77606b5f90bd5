"""densepeds.detect.split_batch: a batch split one part per CPU gives the outputs of one call."""

from __future__ import annotations

import os

import numpy as np
import pytest
from conftest import shared_path
from densepeds.detect import split_batch
from densepeds.detect.yoloseg import YoloSegDetector
from test_detect import video_frames


class _Echo:
    """A session whose outputs are its inputs doubled and their batch size, per call."""

    def __init__(self) -> None:
        self.sizes: list[int] = []

    def run(self, names: object, feed: dict[str, np.ndarray]) -> list[np.ndarray]:
        x = feed["x"]
        self.sizes.append(len(x))
        return [2 * x, np.full((len(x), 1), len(x))]


@pytest.mark.parametrize(
    ("items", "cpus", "sizes"),
    [(8, 2, [4, 4]), (7, 2, [3, 3, 1]), (5, 4, [1, 1, 1, 1, 1]), (3, 4, [3]), (3, 1, [3])],
)
def test_parts_are_equal_one_per_cpu_and_the_rest_runs_after(
    monkeypatch: pytest.MonkeyPatch, items: int, cpus: int, sizes: list[int]
) -> None:
    monkeypatch.setattr(split_batch.onnxutil, "available_cpus", lambda: cpus)
    session = _Echo()
    x = np.arange(items * 3, dtype=np.float32).reshape(items, 3)
    doubled, batch = split_batch.run_split(session, {"x": x})  # type: ignore[arg-type]
    assert np.array_equal(doubled, 2 * x)  # in order
    assert sorted(session.sizes) == sorted(sizes)
    assert session.sizes[-1] == sizes[-1]  # the rest last
    assert batch[:, 0].tolist() == [s for s in sizes for _ in range(s)]


def test_a_forked_child_makes_its_own_pool() -> None:
    parent = split_batch.cpu_pool()
    assert split_batch.cpu_pool() is parent
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: the pool works and is not the parent's
        try:
            out = split_batch.run_split(_Echo(), {"x": np.ones((4, 2), np.float32)})[0]
            ok = split_batch.cpu_pool() is not parent and float(out.sum()) == 16.0
            os.write(write, b"1" if ok else b"0")
        finally:
            os._exit(0)
    os.waitpid(pid, 0)
    assert os.read(read, 1) == b"1"


@pytest.mark.parametrize("dequantize", [True, False], ids=["float copy", "int8 as shipped"])
def test_detections_bitwise_the_same_split_or_in_one_call(dequantize: bool) -> None:
    yolo = shared_path("models", "yolov8n-seg-320-int8.onnx")
    video = shared_path("data", "MOT20-01-dev", "MOT20-01-raw.mp4")
    frames = video_frames(video, [1, 2, 3])
    split = YoloSegDetector(yolo, tiles=(3, 2), quantized=False, dequantize=dequantize)
    whole = YoloSegDetector(yolo, tiles=(3, 2), threads=2, quantized=False, dequantize=dequantize)
    assert split.session.get_session_options().intra_op_num_threads == 1
    for k in sorted(frames):
        a, b = split(frames[k]), whole(frames[k])
        assert split.last_views == 6 and len(a.boxes) > 10
        assert np.array_equal(a.boxes, b.boxes) and np.array_equal(a.scores, b.scores)
        assert a.masks is not None and b.masks is not None
        assert all(np.array_equal(m, n) for m, n in zip(a.masks, b.masks, strict=True))


def test_views_that_do_not_divide_evenly_run_as_one_call_on_every_cpu(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    yolo = shared_path("models", "yolov8n-seg-320-int8.onnx")
    monkeypatch.setattr(split_batch.onnxutil, "available_cpus", lambda: 2)
    det = YoloSegDetector(yolo, tiles="none", quantized=False)
    frame = np.full((240, 320, 3), 127, np.uint8)
    det(frame)
    assert det.last_views == 1 and det._wide is not None
    assert det._wide.get_session_options().intra_op_num_threads == 2
