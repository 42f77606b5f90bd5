"""The maskrcnn backend, end to end on a tiny model of torchvision's export contract."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
import pytest
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
