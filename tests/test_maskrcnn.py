"""The maskrcnn backend, end to end on a tiny model of torchvision's export contract."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
import pytest
from contract_models import zoo_maskrcnn
from densepeds.detect import make_detector
from densepeds.errors import ModelError, ParameterError
from onnx import TensorProto, helper, numpy_helper

BOXES = np.array([[10, 10, 40, 50], [50, 5, 70, 45], [0, 0, 5, 5], [60, 40, 90, 75]], np.float32)
LABELS = np.array([1, 1, 3, 1], np.int64)  # COCO: 1 person, 3 car
SCORES = np.array([0.9, 0.3, 0.95, 0.7], np.float32)


def tiny_maskrcnn(path: Path) -> Path:
    """Constant boxes/labels/scores; every mask is the image's red channel (probabilities)."""
    nodes = [
        helper.make_node("Constant", [], ["boxes"], value=numpy_helper.from_array(BOXES)),
        helper.make_node("Constant", [], ["labels"], value=numpy_helper.from_array(LABELS)),
        helper.make_node("Constant", [], ["scores"], value=numpy_helper.from_array(SCORES)),
        helper.make_node("Constant", [], ["zero"], value=numpy_helper.from_array(np.array([0]))),
        helper.make_node("Gather", ["image", "zero"], ["red"], axis=0),  # [1, H, W]
        helper.make_node("Unsqueeze", ["red", "zero"], ["red4"]),  # [1, 1, H, W]
        helper.make_node("Concat", ["red4"] * len(BOXES), ["masks"], axis=0),
    ]
    graph = helper.make_graph(
        nodes,
        "tiny_maskrcnn",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, [3, "H", "W"])],
        [
            helper.make_tensor_value_info("boxes", TensorProto.FLOAT, ["N", 4]),
            helper.make_tensor_value_info("labels", TensorProto.INT64, ["N"]),
            helper.make_tensor_value_info("scores", TensorProto.FLOAT, ["N"]),
            helper.make_tensor_value_info("masks", TensorProto.FLOAT, ["N", 1, "H", "W"]),
        ],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def scene() -> np.ndarray:
    rng = np.random.default_rng(3)
    frame = np.empty((80, 100, 3), np.uint8)
    frame[..., 0] = rng.integers(200, 256, (80, 100))  # blue high: catches a channel swap
    frame[..., 1] = rng.integers(0, 256, (80, 100))
    frame[..., 2] = rng.integers(0, 100, (80, 100))  # red low (prob < 0.5) ...
    frame[20:40, 15:30, 2] = 255  # ... except the "person"
    frame[50:60, 70:80, 2] = 200
    return frame


def test_maskrcnn_contract_end_to_end(tmp_path: Path) -> None:
    detector = make_detector("maskrcnn", tiny_maskrcnn(tmp_path / "m.onnx"), threads=1)
    frame = scene()
    dets = detector(frame)
    # Person label only, score >= 0.5 (default), clipped to the frame.
    assert np.allclose(dets.boxes, [[10, 10, 40, 50], [60, 40, 90, 75]])
    assert np.allclose(dets.scores, [0.9, 0.7])
    assert dets.masks is not None and dets.mask_boxes is not None
    assert dets.mask_boxes.tolist() == [[10, 10, 40, 50], [60, 40, 90, 75]]
    for mask, (x0, y0, x1, y1) in zip(dets.masks, dets.mask_boxes, strict=True):
        expected = frame[y0:y1, x0:x1, 2] / 255.0 > 0.5
        assert mask.shape == (y1 - y0, x1 - x0)
        assert np.array_equal(mask, expected)
    assert dets.masks[0].sum() == 20 * 15 and dets.masks[1].sum() == 100


def test_maskrcnn_with_tiles_keeps_people(tmp_path: Path) -> None:
    detector = make_detector(
        "maskrcnn", tiny_maskrcnn(tmp_path / "m.onnx"), tiles=(2, 1), score_threshold=0.2
    )
    dets = detector(np.zeros((200, 300, 3), np.uint8))
    # Each tile reports the constant boxes in its own coordinates; all land inside the frame.
    assert len(dets) >= 3
    assert (dets.boxes[:, 2] <= 300).all() and (dets.boxes[:, 0] >= 0).all()


def test_maskrcnn_rejects_wrong_contract(tmp_path: Path) -> None:
    graph = helper.make_graph(
        [helper.make_node("Identity", ["x"], ["y"])],
        "wrong",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 3, 8, 8])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 3, 8, 8])],
    )
    path = tmp_path / "wrong.onnx"
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)]), str(path))
    with pytest.raises(ModelError, match="Mask R-CNN"):
        make_detector("maskrcnn", path)


@pytest.mark.parametrize("option", [{"score_threshold": 1.5}, {"iou_threshold": 0.0}])
def test_maskrcnn_rejects_bad_thresholds(tmp_path: Path, option: dict[str, float]) -> None:
    with pytest.raises(ParameterError):
        make_detector("maskrcnn", tiny_maskrcnn(tmp_path / "m.onnx"), **option)


# --- the ONNX Model Zoo contract (MaskRCNN-12 / MaskRCNN-12-int8) ------------------------------


def zoo_reference_input(frame: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The zoo README's pre-processing written out independently: short side 800 (long side at
    most 1333), BGR float minus the mean, CHW, zero-padded to multiples of 32."""
    import math

    import cv2

    h, w = frame.shape[:2]
    scale = min(800 / min(h, w), 1333 / max(h, w))
    nw, nh = int(round(w * scale)), int(round(h * scale))
    img = cv2.resize(frame, (nw, nh)).astype(np.float32) if (nw, nh) != (w, h) else frame
    img = np.asarray(img, np.float32) - np.array([102.9801, 115.9465, 122.7717], np.float32)
    out = np.zeros((3, math.ceil(nh / 32) * 32, math.ceil(nw / 32) * 32), np.float32)
    out[:, :nh, :nw] = img.transpose(2, 0, 1)
    return out, nw / w, nh / h


@pytest.mark.parametrize("size", [(576, 768), (800, 1000), (400, 300), (600, 2400)])
def test_zoo_input_matches_the_readme(tmp_path: Path, size: tuple[int, int]) -> None:
    detector = make_detector("maskrcnn", zoo_maskrcnn(tmp_path / "z.onnx"), threads=1)
    assert detector.contract == "zoo"  # type: ignore[attr-defined]
    frame = np.random.default_rng(1).integers(0, 256, (*size, 3), np.uint8)
    got, scale = detector.zoo_input(frame)  # type: ignore[attr-defined]
    want, sx, sy = zoo_reference_input(frame)
    assert got.shape == want.shape and got.shape[1] % 32 == 0 and got.shape[2] % 32 == 0
    assert np.allclose(got, want, atol=1e-3)
    assert np.allclose(scale, [sx, sy, sx, sy])


def test_zoo_contract_end_to_end(tmp_path: Path) -> None:
    """Boxes come back in frame pixels (input pixels / scale), people only, above the score
    threshold; masks are the 28x28 probabilities resized into each box."""
    from contract_models import ZOO_BOXES

    detector = make_detector("maskrcnn", zoo_maskrcnn(tmp_path / "z.onnx"), threads=1)
    frame = np.zeros((576, 768, 3), np.uint8)
    dets = detector(frame)
    sx, sy = 1067 / 768, 800 / 576
    want = ZOO_BOXES[[0, 1]] / np.array([sx, sy, sx, sy], np.float32)
    assert np.allclose(dets.boxes, want, atol=1e-3)
    assert np.allclose(dets.scores, [0.95, 0.9])  # the 0.3 person and the car are dropped
    assert dets.masks is not None and dets.mask_boxes is not None
    for mask, (x0, y0, x1, y1) in zip(dets.masks, dets.mask_boxes, strict=True):
        assert mask.shape == (y1 - y0, x1 - x0)
        # The blob covers rows 4-26 and columns 8-20 of the 28x28 grid.
        assert mask[mask.shape[0] // 2, mask.shape[1] // 2]
        assert not mask[mask.shape[0] // 2, 1] and not mask[1, mask.shape[1] // 2]
        assert abs(mask.mean() - (22 * 12) / (28 * 28)) < 0.05


def test_zoo_channels_and_mean(tmp_path: Path) -> None:
    """Masks from the input's channel 0 / 255: blue 255 minus the mean 102.98 passes 0.5, blue
    200 does not (nor would it pass with RGB order or without the mean)."""
    detector = make_detector("maskrcnn", zoo_maskrcnn(tmp_path / "z.onnx", True), threads=1)
    frame = np.zeros((800, 1000, 3), np.uint8)  # scale 1: the input's top-left is the frame's
    frame[..., 0] = 200
    frame[:14, :14, 0] = 255
    frame[..., 2] = 255  # red high: a channel swap would fill every mask
    dets = detector(frame)
    assert len(dets) == 2 and dets.masks is not None
    for mask in dets.masks:
        h, w = mask.shape
        assert mask[: h // 2 - 2, : w // 2 - 2].all() and not mask[h // 2 + 2 :, :].any()


def test_contract_from_the_graph(tmp_path: Path) -> None:
    assert make_detector("maskrcnn", tiny_maskrcnn(tmp_path / "t.onnx")).contract == "torchvision"  # type: ignore[attr-defined]
    assert make_detector("maskrcnn", zoo_maskrcnn(tmp_path / "z.onnx")).contract == "zoo"  # type: ignore[attr-defined]
    # Without output shapes in the graph, one blank image decides.
    for builder, want in ((tiny_maskrcnn, "torchvision"), (zoo_maskrcnn, "zoo")):
        path = builder(tmp_path / f"{want}.onnx")
        model = onnx.load(str(path))
        for out in model.graph.output:
            del out.type.tensor_type.shape.dim[:]
            for _ in range({"boxes": 2, "6568": 2, "masks": 4, "6887": 4}.get(out.name, 1)):
                out.type.tensor_type.shape.dim.add()
        onnx.save(model, str(path))
        assert make_detector("maskrcnn", path).contract == want  # type: ignore[attr-defined]


def test_densepeds_run_with_the_fetched_contracts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`densepeds run` on real frames with only the default set's files present (stand-ins with
    the published contracts): it picks Mask R-CNN and YoutuReID by itself."""
    from conftest import shared_path
    from contract_models import ZOO_BOXES, youtu_reid
    from densepeds.cli import main
    from densepeds.models.files import ENV_VAR

    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    models = tmp_path / "models"
    models.mkdir()
    zoo_maskrcnn(models / "MaskRCNN-12-int8.onnx")
    youtu_reid(models / "person_reid_youtu_2021nov_int8.onnx")
    monkeypatch.setenv(ENV_VAR, str(models))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    out = tmp_path / "tracks.txt"
    rc = main(["run", str(video), "--frames", "1:5", "--out", str(out), "-q"])
    _, err = capsys.readouterr()
    assert rc == 0, err
    rows = np.loadtxt(out, delimiter=",", ndmin=2)
    assert set(rows[:, 0].astype(int)) >= {3, 4, 5} and set(rows[:, 1].astype(int)) == {1, 2}
    sx, sy = 1067 / 768, 800 / 576
    want = ZOO_BOXES[[0, 1]] / np.array([sx, sy, sx, sy])
    want[:, 2:] -= want[:, :2]  # MOT rows: left, top, width, height
    for frame in (3, 4, 5):
        got = rows[rows[:, 0] == frame][:, 2:6]
        assert np.allclose(np.sort(got, axis=0), np.sort(want, axis=0), atol=0.5)


def test_contract_rules() -> None:
    from densepeds.detect.maskrcnn import _contract_from_graph

    assert _contract_from_graph((3, "height", "width"), ("nbox", 1, 28, 28)) == "zoo"
    assert _contract_from_graph((3, 800, 1088), ("nbox", 1, 28, 28)) == "zoo"
    assert _contract_from_graph((3, "H", "W"), ("N", 1, "H", "W")) == "torchvision"
    assert _contract_from_graph((3, 540, 960), ("N", 1, 540, 960)) == "torchvision"
    assert _contract_from_graph((3, "H", "W"), ("N", 1, None, None)) is None
    assert _contract_from_graph((3, "H", "W"), ("N", 1, "a", "b")) is None
