"""OpenVINO runs the pipeline's models with onnxruntime's outputs (benchmarks/runtime_speed.py
times the two): the segmenter's float copy on a real view and OSNet on real crops, each raw
output within float rounding of onnxruntime's. Skipped where OpenVINO is not installed."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO, shared_path
from densepeds.detect import onnxutil
from densepeds.reid import ReID

sys.path.insert(0, str(REPO / "benchmarks"))
import runtime_speed  # noqa: E402


@pytest.fixture(autouse=True)
def _needs_openvino() -> None:
    pytest.importorskip("openvino")
    runtime_speed.FRAME = shared_path("data", "MOT20-01-dev", "MOT20-01-raw.mp4")


def _agree(model: Path, feed: dict[str, np.ndarray], atol: float) -> None:
    ort_out = runtime_speed.ort_runner(model, feed, 1, None)()
    ov_out = runtime_speed.ov_runner(model, feed, 1)()
    assert len(ov_out) == len(ort_out)
    for a, b in zip(ov_out, ort_out, strict=True):
        assert a.shape == b.shape
        assert np.abs(b).max() > 0  # a real output, not a blank
        np.testing.assert_allclose(a, b, rtol=0, atol=atol)


def test_the_segmenters_float_copy_agrees(tmp_path: Path) -> None:
    shipped = shared_path("models", "yolov8n-seg-320-int8.onnx")
    floated = tmp_path / "float.onnx"
    floated.write_bytes(onnxutil.dequantized(onnxutil.load_model(shipped)).SerializeToString())
    name = onnxutil.make_session(floated, 1, device="cpu").get_inputs()[0].name
    view = runtime_speed.detector_view(runtime_speed.first_frame())
    _agree(floated, {name: view}, 1e-4)


def test_osnet_agrees_on_a_batch_of_crops() -> None:
    reid = ReID(shared_path("models", "osnet_x0_25_msmt17.onnx"), device="cpu")
    crops = runtime_speed.reid_crops(runtime_speed.first_frame(), reid)
    assert len(crops) == runtime_speed.CROPS
    _agree(reid.path, {reid.input_name: crops}, 1e-4)


def test_device_openvino_detects_and_embeds_as_onnxruntime() -> None:
    """The package's own models on OpenVINO (``device="openvino"``): the same detections on a
    real frame (boxes within a hundredth of a pixel) and the same embeddings."""
    from densepeds.detect.yoloseg import YoloSegDetector

    detector = shared_path("models", "yolov8n-seg-320-int8.onnx")
    frame = runtime_speed.first_frame()
    cpu, ov = (YoloSegDetector(detector, device=d) for d in ("cpu", "openvino"))
    assert (cpu.device, ov.device) == ("cpu", "openvino")
    expected, got = cpu(frame), ov(frame)
    assert len(expected) > 10 and len(got) == len(expected)
    np.testing.assert_allclose(got.boxes, expected.boxes, atol=1e-2)
    np.testing.assert_allclose(got.scores, expected.scores, atol=1e-4)
    reid_file = shared_path("models", "osnet_x0_25_msmt17.onnx")
    cpu_reid, ov_reid = (ReID(reid_file, device=d) for d in ("cpu", "openvino"))
    crops = [frame[y : y + 150, x : x + 60] for y in (0, 200) for x in range(0, 900, 100)]
    np.testing.assert_allclose(
        ov_reid.embed_crops(crops), cpu_reid.embed_crops(crops), rtol=0, atol=1e-4
    )


def test_device_openvino_without_openvino_is_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "openvino", None)  # import fails
    from densepeds.errors import ParameterError

    with pytest.raises(ParameterError, match=r"pip install 'densepeds\[openvino\]'"):
        ReID(shared_path("models", "osnet_x0_25_msmt17.onnx"), device="openvino")


def test_openvino_leaves_the_threads_signal_stack_as_it_was() -> None:
    """OpenVINO gives the thread that compiles a model an alternate signal stack of its own and
    frees it with the model; a Ctrl-C handled afterwards would run on freed memory (a crash of
    the whole process), so the session puts the thread's own back."""
    import ctypes
    import gc

    def stack() -> tuple[int, int, int]:
        st = onnxutil._StackT()
        assert ctypes.CDLL(None).sigaltstack(None, ctypes.byref(st)) == 0
        return (st.sp or 0, st.flags, st.size)

    before = stack()
    reid = ReID(shared_path("models", "osnet_x0_25_msmt17.onnx"), device="openvino")
    reid.embed_crops([np.zeros((100, 40, 3), np.uint8)])
    assert stack() == before
    del reid
    gc.collect()
    assert stack() == before
