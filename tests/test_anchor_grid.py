"""A YOLO head's anchor grid follows a new input size (densepeds.detect.anchor_grid), and the
detector runs a fixed grid's tiles at an input of their shape (YoloSegDetector fit_input)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import onnx
import pytest
from conftest import shared_path
from densepeds.boxes import iou_matrix
from densepeds.detect import onnxutil
from densepeds.detect.yoloseg import YoloSegDetector, fitted_input
from densepeds.errors import ModelError
from onnx import TensorProto, helper, numpy_helper


def toy_head(height: int, width: int, unit: str, nhwc: bool) -> onnx.ModelProto:
    """A fixed-size model with a YOLO-style head built for ``height`` x ``width``: per level
    (strides 8, 16, 32) a strided convolution gives 4 distances a cell, flattened by constant
    Reshapes and decoded against constant anchor centres and strides in ``unit``. Written
    cell by cell here, independently of the package's code."""
    centres, scales = [], []
    for s in (8, 16, 32):
        for row in range(height // s):
            for col in range(width // s):
                if unit == "cell":
                    centres.append((col + 0.5, row + 0.5))  # strides come as [1, A]
                elif unit == "pixel":
                    centres.append(((col + 0.5) * s, (row + 0.5) * s))
                    scales.append((s, s, s, s))
                else:
                    centres.append(((col + 0.5) * s / width, (row + 0.5) * s / height))
                    scales.append((s / width, s / height, s / width, s / height))
    rng = np.random.default_rng(0)
    nodes, inits = [], []
    image = "image"
    if nhwc:
        nodes.append(helper.make_node("Transpose", ["image"], ["nchw"], perm=[0, 3, 1, 2]))
        image = "nchw"
    levels = []
    for s in (8, 16, 32):
        w = numpy_helper.from_array(rng.normal(0, 0.01, (4, 3, s, s)).astype(np.float32), f"w{s}")
        shape = numpy_helper.from_array(
            np.array([1, 4, (height // s) * (width // s)], np.int64), f"shape{s}"
        )
        inits += [w, shape]
        nodes.append(helper.make_node("Conv", [image, f"w{s}"], [f"c{s}"], strides=[s, s]))
        nodes.append(helper.make_node("Reshape", [f"c{s}", f"shape{s}"], [f"r{s}"]))
        levels.append(f"r{s}")
    nodes.append(helper.make_node("Concat", levels, ["dist"], axis=2))
    centre = np.array(centres, np.float32).T[None]  # [1, 2, A]
    if unit == "cell":
        stride = np.concatenate(
            [np.full((height // s) * (width // s), s, np.float32) for s in (8, 16, 32)]
        )[None]  # [1, A] in pixels
        inits += [
            numpy_helper.from_array(centre, "anchors"),
            numpy_helper.from_array(stride, "strides"),
        ]
        nodes.append(helper.make_node("Slice", ["dist", "z", "two", "one"], ["lt"]))
        nodes.append(helper.make_node("Add", ["anchors", "lt"], ["moved"]))
        nodes.append(helper.make_node("Mul", ["moved", "strides"], ["boxes"]))
        inits += [
            numpy_helper.from_array(np.array([0], np.int64), "z"),
            numpy_helper.from_array(np.array([2], np.int64), "two"),
            numpy_helper.from_array(np.array([1], np.int64), "one"),
        ]
    else:
        scale = np.array(scales, np.float32).T[None]  # [1, 4, A]
        inits += [
            numpy_helper.from_array(centre, "anchors"),
            numpy_helper.from_array(scale, "norm"),
        ]
        nodes.append(helper.make_node("Mul", ["dist", "norm"], ["scaled"]))
        nodes.append(helper.make_node("Concat", ["anchors", "anchors"], ["both"], axis=1))
        nodes.append(helper.make_node("Add", ["scaled", "both"], ["boxes"]))
    in_shape = [1, height, width, 3] if nhwc else [1, 3, height, width]
    graph = helper.make_graph(
        nodes,
        "toy",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, in_shape)],
        [helper.make_tensor_value_info("boxes", TensorProto.FLOAT, None)],
        inits,
    )
    return helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])


def run(model: onnx.ModelProto, image: np.ndarray) -> np.ndarray:
    session = onnxutil.make_session(model, 1)
    return np.asarray(session.run(None, {"image": image})[0])


@pytest.mark.parametrize("unit", ["cell", "pixel", "fraction"])
@pytest.mark.parametrize("nhwc", [False, True])
def test_a_resized_head_equals_the_head_built_at_that_size(unit: str, nhwc: bool) -> None:
    resized = onnxutil.with_input_size(toy_head(320, 320, unit, nhwc), 256, 320)
    reference = toy_head(256, 320, unit, nhwc)
    shape = (1, 256, 320, 3) if nhwc else (1, 3, 256, 320)
    image = np.random.default_rng(1).random(shape, np.float32)
    got, want = run(resized, image), run(reference, image)
    assert got.shape == want.shape == (1, 4 if unit != "cell" else 2, 32 * 40 + 16 * 20 + 8 * 10)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)


def test_an_anchor_sized_constant_in_no_known_form_is_an_error() -> None:
    model = toy_head(320, 320, "pixel", False)
    for init in model.graph.initializer:
        if init.name == "anchors":
            noise = np.random.default_rng(2).random((1, 2, 2100), np.float32) * 300
            init.CopyFrom(numpy_helper.from_array(noise, "anchors"))
    with pytest.raises(ModelError, match="anchor"):
        onnxutil.with_input_size(model, 256, 320)
    with pytest.raises(ModelError, match="multiple of 32"):
        onnxutil.with_input_size(toy_head(320, 320, "pixel", False), 250, 320)


def test_fitted_input_keeps_the_scale_and_rounds_up_to_whole_cells() -> None:
    assert fitted_input(384, 288, 320, 320) == (256, 320)  # a 2x2 grid of a 4:3 frame
    assert fitted_input(640, 540, 320, 320) == (288, 320)  # a 3x2 grid of a 1080p frame
    assert fitted_input(288, 384, 320, 320) == (320, 256)  # portrait
    assert fitted_input(300, 300, 320, 320) == (320, 320)
    assert fitted_input(1920, 1080, 640, 640) == (384, 640)
    for tw, th in [(384, 288), (640, 540), (100, 37), (37, 100), (1000, 999)]:
        h, w = fitted_input(tw, th, 320, 320)
        assert min(w / tw, h / th) == pytest.approx(min(320 / tw, 320 / th))
        assert h % 32 == 0 and w % 32 == 0 and h <= 320 and w <= 320


def pets_frame() -> np.ndarray:
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    capture = cv2.VideoCapture(str(video))
    ok, frame = capture.read()
    capture.release()
    assert ok
    return np.asarray(frame)


def test_a_fixed_grid_runs_the_tiles_shape_and_finds_the_same_people() -> None:
    model = shared_path("models", "yolov8n-seg-320-int8.onnx")
    frame = pets_frame()
    fitted = YoloSegDetector(model, tiles="2x2", threads=1, quantized=False, focus_scale=0)
    square = YoloSegDetector(
        model, tiles="2x2", threads=1, quantized=False, focus_scale=0, fit_input=False
    )
    a, b = fitted(frame), square(frame)
    assert (fitted.input_h, fitted.input_w) == (256, 320)
    assert (square.input_h, square.input_w) == (320, 320)
    assert len(a.boxes) == len(b.boxes) >= 4
    # The same people, placed within a pixel or so (the square model's anchors are rounded).
    assert np.all(iou_matrix(a.boxes, b.boxes).max(axis=1) > 0.8)
    assert a.masks is not None and all(m.any() for m in a.masks)
    # Focus views take the input's shape: their longer side focus_scale times the height.
    fitted.focus_scale = 2.0
    fitted.focus(np.array([[300.0, 100.0, 340.0, 200.0]]))
    (view,) = fitted.focus_views(frame.shape[1], frame.shape[0])
    t = view.tile
    assert (t.x1 - t.x0, t.y1 - t.y0) == (200, 160)
    assert view.scale == pytest.approx(320 / 200)


def test_people_tiles_and_unrebuildable_models_keep_the_models_own_size() -> None:
    model = shared_path("models", "yolov8n-seg-320-int8.onnx")
    frame = pets_frame()
    people = YoloSegDetector(model, threads=1, quantized=False, focus_scale=0)
    people(frame)
    assert (people.input_h, people.input_w) == (320, 320)
    # The graph as shipped stores its anchors as int8 constants: not rebuilt, run as it is.
    shipped = YoloSegDetector(
        Path(model), tiles="2x2", threads=1, quantized=False, dequantize=False, focus_scale=0
    )
    assert len(shipped(frame).boxes) >= 4
    assert (shipped.input_h, shipped.input_w) == (320, 320)


def test_the_fitted_input_finds_as_many_people_on_a_real_video() -> None:
    """PETS09-S2L1 frames 41-64 on the 2x2 grid, every tile every frame and with a full scan
    every 4th: the fitted input finds about as many ground-truth people as the model's own."""
    from test_detect import pets09_gt_boxes, read_gt, recall, video_frames

    gt = read_gt(shared_path("data", "PETS09-S2L1-dev", "gt", "gt.txt"))
    frames = video_frames(shared_path("data", "PETS09-S2L1-dev", "vtest.avi"), list(range(41, 65)))
    model = shared_path("models", "yolov8n-seg-320-int8.onnx")
    for every in (1, 4):
        found = {}
        for fit in (True, False):
            det = YoloSegDetector(
                model,
                tiles="2x2",
                threads=2,
                quantized=False,
                focus_scale=0,
                full_scan_every=every,
                fit_input=fit,
            )
            found[fit] = sum(recall(det(f), pets09_gt_boxes(gt, k))[0] for k, f in frames.items())
        print(f"full scan every {every}: found {found}")
        assert found[True] >= 0.95 * found[False] and found[False] > 100


def test_a_detector_without_a_known_anchor_grid_runs_its_own_size(tmp_path: Path) -> None:
    """A model whose boxes do not come from a known anchor grid (here: constant outputs) could
    be resized by onnxruntime but its boxes would be wrong: it runs at its own size."""
    from test_detect import tiny_yoloseg

    model = tiny_yoloseg(tmp_path / "tiny.onnx")
    with pytest.raises(ModelError, match="no anchor grid"):
        onnxutil.with_input_size(onnxutil.load_model(model), 32, 64, anchors=True)
    assert onnxutil.with_input_size(onnxutil.load_model(model), 32, 64)  # not asked: resized
    det = YoloSegDetector(model, tiles="2x2", threads=1, focus_scale=0)
    found = det(np.zeros((96, 128, 3), np.uint8))
    assert (det.input_h, det.input_w) == (64, 64) and len(found.boxes) > 0
