"""Tiny ONNX graphs with the published contracts of the downloadable models (names, shapes,
dtypes, pre-processing), built with onnx.helper: no real weights needed. Used by the tests and
by scripts/smoke-wheel.sh (which lays them out like the published hosts).

- ``zoo_maskrcnn``: the ONNX Model Zoo Mask R-CNN contract: input ``image`` float [3,H,W]
  (BGR 0-255 minus the mean, sides multiples of 32), outputs boxes [N,4], labels int64 [N],
  scores [N], masks [N,1,28,28], under the zoo file's numeric output names. Boxes are
  ``ZOO_BOXES`` in input pixels; a score loses the input's sides modulo 32 (an unpadded input
  drops every detection); masks are either a fixed blob or the input's channel 0 (BGR's blue,
  mean subtracted) over its top-left 28x28 pixels, divided by 255.
- ``youtu_reid``: OpenCV Zoo YoutuReID's contract: input [1,3,256,128] float (RGB, /255,
  ImageNet mean/std), output [1,768]: the per-channel mean of the input times ``youtu_weights()``
  through a Reshape to [1,-1] (so a rewritten dynamic batch breaks, as a fixed-batch export can).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

ZOO_BOXES = np.array(
    [[100, 200, 180, 420], [300, 150, 380, 400], [500, 100, 560, 300], [600, 300, 700, 600]],
    np.float32,
)
ZOO_LABELS = np.array([1, 1, 3, 1], np.int64)  # COCO (maskrcnn-benchmark ids): 1 person, 3 car
ZOO_SCORES = np.array([0.95, 0.9, 0.99, 0.3], np.float32)
ZOO_OUTPUT_NAMES = ("6568", "6570", "6572", "6887")  # boxes, labels, scores, masks
YOUTU_DIM = 768


def _const(name: str, value: np.ndarray) -> onnx.NodeProto:
    return helper.make_node("Constant", [], [name], value=numpy_helper.from_array(value, name))


def zoo_maskrcnn(path: Path, masks_from_image: bool = False) -> Path:
    boxes, labels, scores, masks = ZOO_OUTPUT_NAMES
    n = len(ZOO_BOXES)
    blob = np.zeros((28, 28), np.float32)
    blob[4:26, 8:20] = 0.9  # a person-like upright blob inside the box
    nodes = [
        _const("boxes_c", ZOO_BOXES),
        helper.make_node("Identity", ["boxes_c"], [boxes]),
        _const("labels_c", ZOO_LABELS),
        helper.make_node("Identity", ["labels_c"], [labels]),
        # scores = ZOO_SCORES - sum(H mod 32, W mod 32)
        helper.make_node("Shape", ["image"], ["shape"]),
        _const("one", np.array([1], np.int64)),
        _const("three", np.array([3], np.int64)),
        _const("zero", np.array([0], np.int64)),
        helper.make_node("Slice", ["shape", "one", "three", "zero"], ["hw"]),
        _const("stride", np.array([32], np.int64)),
        helper.make_node("Mod", ["hw", "stride"], ["rest"]),
        helper.make_node("ReduceSum", ["rest"], ["rest_sum"], keepdims=0),
        helper.make_node("Cast", ["rest_sum"], ["rest_f"], to=TensorProto.FLOAT),
        _const("scores_c", ZOO_SCORES),
        helper.make_node("Sub", ["scores_c", "rest_f"], [scores]),
    ]
    if masks_from_image:
        nodes += [
            _const("m_starts", np.array([0, 0, 0], np.int64)),
            _const("m_ends", np.array([1, 28, 28], np.int64)),
            helper.make_node("Slice", ["image", "m_starts", "m_ends"], ["patch"]),  # [1,28,28]
            _const("inv255", np.array(1 / 255, np.float32)),
            helper.make_node("Mul", ["patch", "inv255"], ["prob"]),
            helper.make_node("Unsqueeze", ["prob", "zero"], ["prob4"]),  # [1,1,28,28]
            helper.make_node("Concat", ["prob4"] * n, [masks], axis=0),
        ]
    else:
        nodes += [_const("masks_c", np.repeat(blob[None, None], n, axis=0))]
        nodes += [helper.make_node("Identity", ["masks_c"], [masks])]
    graph = helper.make_graph(
        nodes,
        "zoo_maskrcnn",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, [3, "height", "width"])],
        [
            helper.make_tensor_value_info(boxes, TensorProto.FLOAT, ["nbox", 4]),
            helper.make_tensor_value_info(labels, TensorProto.INT64, ["nbox"]),
            helper.make_tensor_value_info(scores, TensorProto.FLOAT, ["nbox"]),
            helper.make_tensor_value_info(masks, TensorProto.FLOAT, ["nbox", 1, 28, 28]),
        ],
    )
    return _save(graph, path)


def youtu_weights() -> np.ndarray:
    return np.random.default_rng(7).normal(size=(3, YOUTU_DIM)).astype(np.float32)


def youtu_reid(path: Path, variant: str = "published") -> Path:
    """``variant``: 'published' (batch 1, the Reshape's target a Constant node, which the
    dynamic-batch rewrite cannot see), 'initializer' (the target an initializer, which the
    rewrite patches) or 'ignores_batch' (claims any batch, averages over it: one row out)."""
    nodes = [helper.make_node("GlobalAveragePool", ["input"], ["pooled"])]  # [B,3,1,1]
    inits = [numpy_helper.from_array(youtu_weights(), "w")]
    target = np.array([1, -1], np.int64)
    if variant == "initializer":
        inits.append(numpy_helper.from_array(target, "target"))
    else:
        nodes.append(_const("target", target))
    pooled = "pooled"
    if variant == "ignores_batch":
        nodes.append(helper.make_node("ReduceMean", ["pooled"], ["mixed"], axes=[0], keepdims=1))
        pooled = "mixed"
    nodes += [
        helper.make_node("Reshape", [pooled, "target"], ["flat"]),
        helper.make_node("MatMul", ["flat", "w"], ["output"]),
    ]
    batch: int | str = "N" if variant == "ignores_batch" else 1
    graph = helper.make_graph(
        nodes,
        "youtu_reid",
        [helper.make_tensor_value_info("input", TensorProto.FLOAT, [batch, 3, 256, 128])],
        [helper.make_tensor_value_info("output", TensorProto.FLOAT, [1, YOUTU_DIM])],
        initializer=inits,
    )
    return _save(graph, path)


def youtu_reference(crop_rgb_256x128: np.ndarray) -> np.ndarray:
    """The embedding the YoutuReID stand-in gives for an RGB uint8 [256,128,3] crop, computed
    independently of densepeds (float64), unit length."""
    x = crop_rgb_256x128.astype(np.float64) / 255.0
    x = (x - np.array([0.485, 0.456, 0.406])) / np.array([0.229, 0.224, 0.225])
    row = x.mean(axis=(0, 1)) @ youtu_weights().astype(np.float64)
    return row / np.linalg.norm(row)


def _save(graph: onnx.GraphProto, path: Path) -> Path:
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path
