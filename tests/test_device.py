"""Where the models run (``device``: auto, cpu, cuda), tested on a CPU-only onnxruntime.

A GPU is faked by making ``onnxruntime.get_available_providers()`` list CUDA (and TensorRT):
the providers each session asks for are recorded, and the CPU build of onnxruntime then runs it
on the CPU, which is the "installed but unusable" case a GPU-less machine with the ``gpu`` extra
meets. A session that reports a GPU provider (a subclass) checks that a frame's views and crops
go to it in one call, with the CPU's outputs.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import onnxruntime as ort
import pytest
from conftest import shared_path
from densepeds.detect import onnxutil
from densepeds.detect.yoloseg import YoloSegDetector
from densepeds.errors import ParameterError
from densepeds.pipeline import Pipeline
from densepeds.reid import ReID

CPU, CUDA, TRT = "CPUExecutionProvider", "CUDAExecutionProvider", "TensorrtExecutionProvider"


def fake_available(
    monkeypatch: pytest.MonkeyPatch, names: list[str], tensorrt: bool = True
) -> None:
    """onnxruntime lists ``names``; TensorRT's library is found where ``tensorrt``."""
    monkeypatch.setattr(ort, "get_available_providers", lambda: list(names))
    monkeypatch.setattr(onnxutil, "tensorrt_installed", lambda: tensorrt)
    monkeypatch.setattr(onnxutil, "_preload_gpu_libraries", lambda: None)


@pytest.mark.parametrize(
    ("available", "device", "expected"),
    [
        ([CPU], "cpu", [CPU]),
        ([CPU], "auto", [CPU]),
        ([CUDA, CPU], "cpu", [CPU]),
        ([CUDA, CPU], "auto", [CUDA, CPU]),
        ([CUDA, CPU], "cuda", [CUDA, CPU]),
        ([TRT, CUDA, CPU], "auto", [TRT, CUDA, CPU]),
        ([CPU, CUDA, TRT], "cuda", [TRT, CUDA, CPU]),  # best first, whatever the listing's order
        ([TRT, CPU], "auto", [CPU]),  # TensorRT's provider needs CUDA's
        (["AzureExecutionProvider", CPU], "auto", [CPU]),
        ([CPU], "openvino", [CPU]),  # OpenVINO's sessions are not onnxruntime's
    ],
)
def test_providers_follow_the_device_and_what_is_installed(
    monkeypatch: pytest.MonkeyPatch, available: list[str], device: str, expected: list[str]
) -> None:
    fake_available(monkeypatch, available)
    assert onnxutil.providers(device) == expected
    fake_available(monkeypatch, available, tensorrt=False)  # listed, but not installed
    assert onnxutil.providers(device) == [p for p in expected if p != TRT]


def test_cuda_without_a_cuda_provider_is_one_clear_line(monkeypatch: pytest.MonkeyPatch) -> None:
    fake_available(monkeypatch, [CPU])
    with pytest.raises(ParameterError, match="no CUDA provider") as err:
        onnxutil.providers("cuda")
    assert "\n" not in str(err.value) and "densepeds[gpu]" in str(err.value)
    with pytest.raises(ParameterError, match="device must be one of auto, cpu, cuda"):
        onnxutil.providers("gpu")
    with pytest.raises(ParameterError, match="device 'gpu'"):
        Pipeline(device="gpu")


class _Spy:
    """Records the providers every session is made with; the real onnxruntime makes it."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, cls: Any = ort.InferenceSession) -> None:
        self.asked: list[list[str]] = []
        real = cls

        def make(*args: Any, **kwargs: Any) -> Any:
            wanted = kwargs.get("providers") or []
            self.asked.append([p[0] if isinstance(p, tuple) else p for p in wanted])
            with warnings.catch_warnings():  # the CPU build warns of a provider it lacks
                warnings.simplefilter("ignore")
                return real(*args, **kwargs)

        monkeypatch.setattr(ort, "InferenceSession", make)


@pytest.fixture
def models() -> tuple[Path, Path]:
    return (
        shared_path("models", "yolov8n-seg-320-int8.onnx"),
        shared_path("models", "osnet_x0_25_msmt17.onnx"),
    )


def test_auto_with_an_unusable_gpu_warns_and_runs_on_the_cpu(
    monkeypatch: pytest.MonkeyPatch, models: tuple[Path, Path]
) -> None:
    detector_file, reid_file = models
    fake_available(monkeypatch, [TRT, CUDA, CPU])
    spy = _Spy(monkeypatch)
    with pytest.warns(onnxutil.DeviceWarning, match="device auto runs on the CPU") as record:
        det = YoloSegDetector(detector_file, device="auto")
        reid = ReID(reid_file, device="auto")
    # Asked for the GPU once per model; later sessions (the detector's on every CPU, the pooled
    # copy) go straight to the CPU that the first one found, without warning again.
    assert spy.asked[0] == [TRT, CUDA, CPU]
    assert [p for p in spy.asked if p != [CPU]] == [[TRT, CUDA, CPU]] * 2
    assert len(record) == 2 and all("\n" not in str(w.message) for w in record)
    assert det.device == "cpu" and reid.device == "cpu"
    assert det.session.get_providers() == [CPU]
    reid._pooled_session()
    assert spy.asked[-1] == [CPU]


def test_cuda_with_an_unusable_gpu_is_an_error(
    monkeypatch: pytest.MonkeyPatch, models: tuple[Path, Path]
) -> None:
    fake_available(monkeypatch, [CUDA, CPU])
    _Spy(monkeypatch)
    with pytest.raises(ParameterError, match="device cuda: onnxruntime lists CUDA") as err:
        ReID(models[1], device="cuda")
    assert "\n" not in str(err.value)


def test_pipeline_gives_its_device_to_the_models_it_loads(
    monkeypatch: pytest.MonkeyPatch, models: tuple[Path, Path]
) -> None:
    fake_available(monkeypatch, [CUDA, CPU])
    spy = _Spy(monkeypatch)
    pipe = Pipeline("yoloseg", device="cpu", detector_model=models[0], reid=models[1])
    pipe.detector()
    pipe.reid()
    assert spy.asked and all(p == [CPU] for p in spy.asked)
    spy.asked.clear()
    gpu = Pipeline("yoloseg", device="cuda", detector_model=models[0], reid=models[1])
    with pytest.raises(ParameterError, match="device cuda"):
        gpu.detector()
    assert spy.asked == [[CUDA, CPU]]


class _GpuLike(ort.InferenceSession):
    """A CPU session that reports the CUDA provider first and counts its calls' batch sizes."""

    calls: list[int] = []  # noqa: RUF012 (shared by the sessions a test makes)

    def get_providers(self) -> list[str]:
        return [CUDA, CPU]

    def run(self, names: Any, feed: Any, options: Any = None) -> Any:
        type(self).calls.append(len(next(iter(feed.values()))))
        return super().run(names, feed, options)


def test_on_a_gpu_a_frames_views_and_crops_go_in_one_call(
    monkeypatch: pytest.MonkeyPatch, models: tuple[Path, Path]
) -> None:
    detector_file, reid_file = models
    rng = np.random.default_rng(3)
    capture = cv2.VideoCapture(str(shared_path("data", "PETS09-S2L1-dev", "vtest.avi")))
    ok, image = capture.read()
    capture.release()
    assert ok
    frame = np.asarray(image, np.uint8)
    cpu_det = YoloSegDetector(detector_file, tiles="3x2", device="cpu")
    cpu_reid = ReID(reid_file, device="cpu")
    crops = [rng.integers(0, 256, (120, 50, 3), np.uint8) for _ in range(9)]
    expected_dets, expected_rows = cpu_det(frame), cpu_reid.embed_crops(crops)
    assert len(expected_dets) > 3

    fake_available(monkeypatch, [CUDA, CPU])
    _Spy(monkeypatch, _GpuLike)
    _GpuLike.calls = []
    det = YoloSegDetector(detector_file, tiles="3x2", device="cuda")
    reid = ReID(reid_file, device="cuda")
    assert det.device == "cuda" and reid.device == "cuda"
    assert det.views_per_call() > 6
    det(frame)  # the first frame fits the model's input to the grid's tiles: a new session
    _GpuLike.calls = []
    got = det(frame)
    assert _GpuLike.calls == [6]  # the 3x2 grid's views in one call, not split over the CPUs
    _GpuLike.calls = []
    rows = reid.embed_crops(crops)
    assert _GpuLike.calls == [9]
    np.testing.assert_array_equal(got.boxes, expected_dets.boxes)
    np.testing.assert_allclose(rows, expected_rows, atol=1e-5)


# --- a batch worker's share of the CPUs -------------------------------------------------------


@pytest.mark.parametrize(
    ("cpus", "inputs", "workers", "threads", "expected"),
    [
        (2, 4, None, None, (2, 1)),  # every CPU a worker of its own
        (2, 1, None, None, (1, 2)),  # one input: one worker on both CPUs, as `run`
        (2, 4, 1, None, (1, 2)),  # --workers 1: the worker gets every CPU
        (16, 3, None, None, (3, 5)),
        (2, 4, None, 2, (1, 2)),
        (8, 100, None, None, (8, 1)),
        (2, 4, 3, None, (3, 1)),  # more workers than CPUs asked for: one thread each
    ],
)
def test_default_workers_and_threads_fill_the_cpus(
    cpus: int, inputs: int, workers: int | None, threads: int | None, expected: tuple[int, int]
) -> None:
    from densepeds.batch import worker_shape

    assert worker_shape(cpus, inputs, workers, threads) == expected


def test_a_worker_sizes_its_sessions_for_its_cpus(
    monkeypatch: pytest.MonkeyPatch, models: tuple[Path, Path]
) -> None:
    from densepeds.batch import worker as batch_worker
    from densepeds.detect import split_batch

    monkeypatch.setattr(onnxutil, "_cpu_limit", None)
    monkeypatch.setattr(batch_worker, "_LOADED", {})
    monkeypatch.setattr(os, "sched_getaffinity", lambda _pid: {0, 1, 2, 3}, raising=False)
    assert onnxutil.available_cpus() == 4
    batch_worker.use_cpus(2)
    assert onnxutil.available_cpus() == 2
    assert onnxutil.session_options(None).intra_op_num_threads == 2
    # The worker's models split their batches over its 2 CPUs, as `run` does on a 2-CPU machine.
    reid = batch_worker.WorkerModels({}, 2).reid(str(models[1]))
    assert reid.threads is None
    parts: list[int] = []
    real = split_batch.run_split

    def counting(session: Any, feed: Any) -> Any:
        out = real(session, feed)
        parts.append(onnxutil.available_cpus())
        return out

    monkeypatch.setattr(split_batch, "run_split", counting)
    reid.embed_crops([np.zeros((100, 40, 3), np.uint8)] * 6)
    assert parts == [2]
    with pytest.raises(ParameterError):
        onnxutil.limit_cpus(0)


def test_batch_workers_ask_ray_for_a_share_of_the_gpus() -> None:
    from densepeds.batch.on_ray import gpu_share

    assert gpu_share("cpu", 2, 4) == 0.0
    assert gpu_share("auto", 0, 4) == 0.0  # no GPU in the cluster: the CPUs
    assert gpu_share("auto", 1, 4) == 0.25  # four workers share one GPU
    assert gpu_share("cuda", 4, 2) == 1.0  # at most a whole GPU each
    with pytest.raises(ParameterError, match="device cuda: the Ray cluster has no GPU"):
        gpu_share("cuda", 0, 2)


def test_batch_device_reaches_the_workers_models(
    monkeypatch: pytest.MonkeyPatch, models: tuple[Path, Path]
) -> None:
    from densepeds.batch import run
    from densepeds.batch import worker as batch_worker

    monkeypatch.setattr(batch_worker, "_LOADED", {})
    fake_available(monkeypatch, [CUDA, CPU])
    spy = _Spy(monkeypatch)
    reid = batch_worker.WorkerModels({}, 1, "cpu").reid(str(models[1]))
    assert reid.device == "cpu" and spy.asked and all(p == [CPU] for p in spy.asked)
    with pytest.raises(ParameterError, match="device must be one of"):
        run(["x.mp4"], "out", device="gpu")


def test_gpu_libraries_load_before_a_gpu_session_only(
    monkeypatch: pytest.MonkeyPatch, models: tuple[Path, Path]
) -> None:
    fake_available(monkeypatch, [CUDA, CPU])
    _Spy(monkeypatch)
    loads: list[int] = []
    monkeypatch.setattr(onnxutil, "_preload_gpu_libraries", lambda: loads.append(1))
    onnxutil.make_session(models[1], 1, device="cpu")
    assert loads == []
    with pytest.warns(onnxutil.DeviceWarning):
        onnxutil.make_session(models[1], 1, device="auto")
    assert loads == [1]


def test_run_device_cuda_without_a_gpu_is_one_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from densepeds.cli import main

    fake_available(monkeypatch, [CPU])  # as onnxruntime's CPU build, whatever is installed here
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    out = tmp_path / "t.txt"
    rc = main(["run", str(video), "--frames", "1:2", "-q", "--device", "cuda", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "device cuda" in err[0] and "densepeds[gpu]" in err[0]
    assert not out.exists()
    assert (
        main(["run", str(video), "--frames", "1:2", "-q", "--device", "cpu", "--out", str(out)])
        == 0
    )
