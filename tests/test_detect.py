"""Detectors: tiling and merging, the dynamic-batch rewrite, and recall on real crowd frames."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import onnx
import pytest
from conftest import REPO, shared_path
from densepeds.boxes import intersections, iou_matrix
from densepeds.detect import make_detector
from densepeds.detect.onnxutil import dequantized, load_model, make_session, with_dynamic_batch
from densepeds.detect.precomputed import PrecomputedDetector
from densepeds.detect.tiling import (
    GRID_MULTIPLE,
    PeopleTiles,
    Perspective,
    SkipSchedule,
    Tile,
    auto_grid,
    fit_perspective,
    make_tiles,
    merge_views,
    nms,
    occupied_tiles,
    parse_grid,
    people_tiles,
    showing,
    sliding_windows,
)
from densepeds.detect.yoloseg import YoloSegDetector
from densepeds.errors import InputError, ModelError, ParameterError
from densepeds.io.mot import read_gt
from densepeds.types import Detections
from onnx import TensorProto, helper, numpy_helper
from scipy.optimize import linear_sum_assignment

YOLO = "yolov8n-seg-320-int8.onnx"


# --- tiling and merging (no data needed) -------------------------------------------------------
def test_auto_grid_and_tiles_cover_the_frame() -> None:
    assert auto_grid(960, 540, 320) == (3, 2)
    assert auto_grid(1920, 1080, 320) == (3, 2)
    assert auto_grid(768, 576, 320) == (2, 2)
    assert auto_grid(320, 240, 320) == (1, 1)
    tiles = make_tiles(960, 540, 3, 2)
    covered = np.zeros((540, 960), int)
    for t in tiles:
        covered[t.y0 : t.y1, t.x0 : t.x1] += 1
    assert covered.min() >= 1 and covered.max() >= 2  # all covered, with overlaps
    assert tiles[0].interior == (False, False, True, True)
    assert tiles[4].interior == (True, True, True, False)


def test_parse_grid() -> None:
    assert parse_grid("4x3", 100, 100, 320) == (4, 3)
    assert parse_grid((2, 1), 100, 100, 320) == (2, 1)
    assert parse_grid(None, 100, 100, 320) == (1, 1)
    for bad in ("lots", (0, 2), (2, 2, 2), 7):
        with pytest.raises(ParameterError):
            parse_grid(bad, 100, 100, 320)  # type: ignore[arg-type]


def brute_force_nms(boxes: np.ndarray, scores: np.ndarray, thr: float) -> list[int]:
    order = sorted(range(len(boxes)), key=lambda i: -scores[i])
    keep: list[int] = []
    for i in order:
        ok = True
        for k in keep:
            a, b = boxes[i], boxes[k]
            iw = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
            ih = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
            inter = iw * ih
            union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
            if inter / union > thr:
                ok = False
                break
        if ok:
            keep.append(i)
    return keep


@pytest.mark.parametrize("seed", range(5))
def test_nms_matches_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 100, (60, 2))
    boxes = np.c_[xy, xy + rng.uniform(5, 40, (60, 2))]
    scores = rng.random(60)
    assert nms(boxes, scores, 0.4).tolist() == brute_force_nms(boxes, scores, 0.4)


def test_box_intersections_and_iou_match_brute_force() -> None:
    rng = np.random.default_rng(7)
    xy = rng.uniform(0, 50, (12, 2))
    a = np.c_[xy, xy + rng.uniform(0, 30, (12, 2))]
    b = a[::-1] + 3.0
    for i in range(len(a)):
        for j in range(len(b)):
            iw = max(0.0, min(a[i, 2], b[j, 2]) - max(a[i, 0], b[j, 0]))
            ih = max(0.0, min(a[i, 3], b[j, 3]) - max(a[i, 1], b[j, 1]))
            area_a = (a[i, 2] - a[i, 0]) * (a[i, 3] - a[i, 1])
            area_b = (b[j, 2] - b[j, 0]) * (b[j, 3] - b[j, 1])
            assert intersections(a, b)[i, j] == pytest.approx(iw * ih, abs=1e-9)
            want = iw * ih / (area_a + area_b - iw * ih)
            assert iou_matrix(a, b)[i, j] == pytest.approx(want, abs=1e-12)
    assert iou_matrix(np.zeros((0, 4)), b).shape == (0, len(b))
    with pytest.raises(InputError, match="inverted"):
        iou_matrix(np.array([[5.0, 0, 1, 1]]), b)


def test_merge_drops_cut_box_seen_whole_elsewhere() -> None:
    boxes = np.array(
        [
            [90, 10, 100, 60],  # cut by tile 0's right edge (x=100)
            [80, 10, 110, 60],  # the same person whole in tile 1
            [20, 10, 40, 60],  # someone else, whole
            [60, 10, 70, 60],  # cut, but no other view sees it: kept
        ],
        float,
    )
    scores = np.array([0.95, 0.5, 0.8, 0.6])
    view = np.array([0, 1, 0, 0])
    cut = np.array([True, False, False, True])
    keep = merge_views(boxes, scores, view, cut, 0.6)
    assert sorted(keep.tolist()) == [1, 2, 3]
    # The same pair within one view is left to NMS (IoU 1/3 < 0.6: both kept).
    assert sorted(merge_views(boxes[:2], scores[:2], np.array([0, 0]), cut[:2], 0.6)) == [0, 1]


# --- real model and data -----------------------------------------------------------------------
def recall(dets: Detections, gt: np.ndarray) -> tuple[int, int]:
    """Ground-truth boxes matched one-to-one at IoU >= 0.5."""
    if len(gt) == 0 or len(dets) == 0:
        return 0, len(gt)
    iou = iou_matrix(gt, dets.boxes.astype(np.float64))
    rows, cols = linear_sum_assignment(-iou)
    return int((iou[rows, cols] >= 0.5).sum()), len(gt)


def visible_gt(gt: np.ndarray, frame: int) -> np.ndarray:
    """MOT17/20 pedestrians (flag 1, class 1) with visibility >= 0.5, as x1 y1 x2 y2."""
    sel = gt[(gt[:, 0] == frame) & (gt[:, 6] == 1) & (gt[:, 7] == 1) & (gt[:, 8] >= 0.5)]
    return np.c_[sel[:, 2:4], sel[:, 2:4] + sel[:, 4:6]]


def video_frames(path: Path, wanted: list[int]) -> dict[int, np.ndarray]:
    """Frames by 1-based number, read sequentially (seeking is not exact for every codec)."""
    cap = cv2.VideoCapture(str(path))
    out: dict[int, np.ndarray] = {}
    number = 0
    while len(out) < len(wanted):
        ok, frame = cap.read()
        if not ok:
            raise AssertionError(f"{path} ended at frame {number}")
        number += 1
        if number in wanted:
            out[number] = frame
    cap.release()
    return out


@pytest.fixture(scope="module")
def yolo() -> YoloSegDetector:
    det = make_detector("yoloseg", shared_path("models", YOLO), threads=2)
    assert isinstance(det, YoloSegDetector)
    return det


@pytest.fixture(scope="module")
def mot20_frames() -> dict[int, np.ndarray]:
    return video_frames(
        shared_path("data", "MOT20-01-dev", "MOT20-01-raw.mp4"), [1, 50, 100, 150, 200]
    )


def assert_masks_inside_boxes(dets: Detections, width: int, height: int) -> None:
    assert dets.masks is not None and dets.mask_boxes is not None
    for box, mask, mb in zip(dets.boxes, dets.masks, dets.mask_boxes, strict=True):
        x0, y0, x1, y1 = mb
        assert 0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height
        assert mask.shape == (y1 - y0, x1 - x0) and mask.dtype == bool
        # The mask's region is the box rounded outwards: every mask pixel lies in the box.
        assert x0 >= np.floor(box[0]) and x1 <= np.ceil(box[2])
        assert y0 >= np.floor(box[1]) and y1 <= np.ceil(box[3])
    areas = [m.mean() for m in dets.masks]
    assert np.median(areas) > 0.2  # people, not empty masks


def test_dynamic_batch_copy_matches_per_tile_calls() -> None:
    path = shared_path("models", YOLO)
    model = load_model(path)
    fixed = make_session(model, 2)
    batched = make_session(with_dynamic_batch(model), 2)
    rng = np.random.default_rng(0)
    x = rng.random((3, 320, 320, 3), dtype=np.float32)
    name = fixed.get_inputs()[0].name
    together = batched.run(None, {name: x})
    for i in range(3):
        alone = fixed.run(None, {name: x[i : i + 1]})
        for a, b in zip(alone, together, strict=True):
            np.testing.assert_allclose(a[0], b[i], rtol=1e-5, atol=1e-5)


def test_batched_views_equal_per_view_calls(yolo: YoloSegDetector, mot20_frames) -> None:
    frame = mot20_frames[100]
    yolo.tiles = "3x2"  # the same views in both calls ("auto" follows the first call's people)
    try:
        one_call = yolo(frame)
        yolo.batch_views = False
        per_view = yolo(frame)
    finally:
        yolo.batch_views = True
        yolo.tiles = "auto"
    np.testing.assert_allclose(one_call.boxes, per_view.boxes, atol=1e-3)
    assert one_call.masks is not None and per_view.masks is not None
    assert all(np.array_equal(a, b) for a, b in zip(one_call.masks, per_view.masks, strict=True))


def test_mot17_tiled_recall_and_masks(yolo: YoloSegDetector) -> None:
    frames_dir = shared_path("data", "MOT17-02-FRCNN", "frames")
    gt = read_gt(shared_path("data", "MOT17-02-FRCNN", "gt", "gt.txt"))
    found = total = 0
    for k in range(1, 5):
        frame = cv2.imread(str(frames_dir / f"{k:06d}.jpg"))
        dets = yolo(frame)
        assert_masks_inside_boxes(dets, frame.shape[1], frame.shape[0])
        a, b = recall(dets, visible_gt(gt, k))
        found, total = found + a, total + b
    print(f"MOT17-02 tiled recall {found}/{total}")
    assert total > 30 and found / total >= 0.6


def test_mot20_tiled_recall_beats_one_pass(yolo: YoloSegDetector, mot20_frames) -> None:
    gt = read_gt(shared_path("data", "MOT20-01-dev", "gt", "gt.txt"))
    tiled = one_pass = total = 0
    for k, frame in mot20_frames.items():
        truth = visible_gt(gt, k)
        dets = yolo(frame)
        assert_masks_inside_boxes(dets, 960, 540)
        tiled += recall(dets, truth)[0]
        yolo.tiles = None
        try:
            one_pass += recall(yolo(frame), truth)[0]
        finally:
            yolo.tiles = "auto"
        total += len(truth)
    print(f"MOT20-01 recall tiled {tiled}/{total}, one pass {one_pass}/{total}")
    assert total > 50
    assert tiled / total >= 0.6
    assert one_pass / total < 0.55 and tiled > one_pass + 0.15 * total


def test_bad_frames_and_models(yolo: YoloSegDetector, tmp_path: Path) -> None:
    with pytest.raises(InputError):
        yolo(np.zeros((10, 10), np.uint8))
    with pytest.raises(InputError):
        yolo(np.zeros((10, 10, 3), np.float32))  # type: ignore[arg-type]
    with pytest.raises(ParameterError):
        make_detector("yolo9000")
    not_onnx = tmp_path / "x.onnx"
    not_onnx.write_bytes(b"not a model")
    with pytest.raises(ModelError):
        make_detector("yoloseg", not_onnx)
    with pytest.raises(ModelError, match="YOLOv8"):
        make_detector("yoloseg", shared_path("models", "osnet_x0_25_msmt17.onnx"))


def test_precomputed_detector_reads_det_file() -> None:
    path = shared_path("data", "PETS09-S2L1-dev", "det", "det.txt")
    rows = np.loadtxt(path, delimiter=",")
    det = PrecomputedDetector(path)
    first = det(np.zeros((4, 4, 3), np.uint8))
    second = det()
    assert len(first) == int((rows[:, 0] == 1).sum())
    assert len(second) == int((rows[:, 0] == 2).sum())
    assert first.masks is None
    np.testing.assert_allclose(first.boxes[0], [500, 158, 530.979, 228.299], rtol=1e-5)
    # MOT15 scores (e.g. 93.673) are min-max mapped into [0, 1] over the file (motio's rule).
    lo, hi = rows[:, 6].min(), rows[:, 6].max()
    assert first.scores[0] == pytest.approx((93.673 - lo) / (hi - lo), abs=1e-5)
    raw = PrecomputedDetector(path, normalize="none")(frame_number=1)
    assert raw.scores[0] == pytest.approx(93.673)
    assert len(det(frame_number=10**6)) == 0


# --- geometry on a synthetic model of the Ultralytics contract ---------------------------------
def tiny_yoloseg(path: Path) -> Path:
    """NCHW [1,3,64,64] model with constant outputs (made batch-shaped from the input).

    Anchors: a person at (cx, cy, w, h) = (0.5, 0.25, 0.25, 0.25) of the input scoring 0.9,
    a class-1 object, and a weaker duplicate of the person. Prototype 0 is +10 on the left
    half of the 16x16 grid and -10 on the right; mask coefficients select it.
    """
    preds = np.zeros((1, 4 + 2 + 2, 12), np.float32)  # anchors > channels, as in real models
    preds[0, :4, 0] = [0.5, 0.25, 0.25, 0.25]
    preds[0, 4:8, 0] = [0.9, 0.0, 1.0, 0.0]
    preds[0, :4, 1] = [0.2, 0.6, 0.1, 0.1]
    preds[0, 4:8, 1] = [0.05, 0.9, 1.0, 0.0]
    preds[0, :4, 2] = [0.51, 0.25, 0.25, 0.25]
    preds[0, 4:8, 2] = [0.8, 0.0, 1.0, 0.0]
    protos = np.zeros((1, 2, 16, 16), np.float32)
    protos[0, 0, :, :8] = 10.0
    protos[0, 0, :, 8:] = -10.0
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["m"], axes=[1, 2, 3], keepdims=1),
        helper.make_node("Constant", [], ["zero"], value=numpy_helper.from_array(np.float32(0))),
        helper.make_node("Mul", ["m", "zero"], ["z4"]),  # [N,1,1,1] zeros
        helper.make_node("Constant", [], ["ax"], value=numpy_helper.from_array(np.array([3]))),
        helper.make_node("Squeeze", ["z4", "ax"], ["z3"]),  # [N,1,1]
        helper.make_node("Constant", [], ["p"], value=numpy_helper.from_array(preds)),
        helper.make_node("Constant", [], ["q"], value=numpy_helper.from_array(protos)),
        helper.make_node("Add", ["z3", "p"], ["output0"]),
        helper.make_node("Add", ["z4", "q"], ["output1"]),
    ]
    graph = helper.make_graph(
        nodes,
        "tiny_yoloseg",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, 64, 64])],
        [
            helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 8, 12]),
            helper.make_tensor_value_info("output1", TensorProto.FLOAT, [1, 2, 16, 16]),
        ],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def test_yoloseg_decoding_geometry(tmp_path: Path) -> None:
    det = make_detector("yoloseg", tiny_yoloseg(tmp_path / "y.onnx"), tiles=None, threads=1)
    assert isinstance(det, YoloSegDetector)
    assert not det.nhwc and not det.proto_nhwc and det.num_classes == 2 and det.num_masks == 2
    # 128x96 frame -> scale 0.5 into the 64x64 input (letterboxed to 64x48).
    dets = det(np.zeros((96, 128, 3), np.uint8))
    # Input box (24, 8)-(40, 24) -> frame (48, 16)-(80, 48); the class-1 object and the
    # overlapping weaker duplicate are gone.
    np.testing.assert_allclose(dets.boxes, [[48, 16, 80, 48]], atol=1e-4)
    np.testing.assert_allclose(dets.scores, [0.9], atol=1e-6)
    assert dets.masks is not None and dets.mask_boxes is not None
    assert dets.mask_boxes.tolist() == [[48, 16, 80, 48]]
    # Prototype cells are 8 frame px; the +/- edge between cells 7 and 8 falls at x = 63.5.
    mask = dets.masks[0]
    assert mask.shape == (32, 32)
    assert mask[:, : 64 - 48].all() and not mask[:, 64 - 48 :].any()
    # Benchmarks read where the time went.
    assert set(det.stage_seconds) == {"preprocess", "inference", "boxes", "masks"}
    assert all(v >= 0 for v in det.stage_seconds.values())


def test_yoloseg_input_is_the_views_in_rgb_over_255(tmp_path: Path) -> None:
    det = make_detector("yoloseg", tiny_yoloseg(tmp_path / "y.onnx"), tiles=None, threads=1)
    assert isinstance(det, YoloSegDetector)
    views = np.random.default_rng(5).integers(0, 256, (3, 64, 80, 3), np.uint8)
    # Element by element, independent of how prepare() orders its passes.
    want = np.empty((3, 3, 64, 80), np.float32)
    for b, c, y, x in np.ndindex(*want.shape):
        want[b, c, y, x] = np.float32(views[b, y, x, 2 - c]) * np.float32(1 / 255)
    got = det.prepare(views)
    assert got.dtype == np.float32 and got.flags.c_contiguous
    np.testing.assert_array_equal(got, want)
    # A view of a bigger array (not contiguous) gives the same.
    wide = np.zeros((3, 64, 100, 3), np.uint8)
    wide[:, :, 10:90] = views
    np.testing.assert_array_equal(det.prepare(wide[:, :, 10:90]), want)
    det.nhwc = True
    np.testing.assert_array_equal(det.prepare(views), want.transpose(0, 2, 3, 1))


def test_yoloseg_tiles_map_back_to_the_frame(tmp_path: Path) -> None:
    model = tiny_yoloseg(tmp_path / "y.onnx")
    det = make_detector("yoloseg", model, tiles=(2, 1), threads=1, full_frame=True)
    assert isinstance(det, YoloSegDetector) and det.rewritten  # batch 1 -> dynamic
    dets = det(np.zeros((64, 128, 3), np.uint8))
    # Every view reports the same relative box: in each tile and in the whole frame; each maps
    # back through its own letterbox scale and origin.
    views = [(t.x0, 64 / max(t.x1 - t.x0, t.y1 - t.y0)) for t in make_tiles(128, 64, 2, 1)]
    expected = []
    for x0, scale in [*views, (0, 0.5)]:
        expected.append([24 / scale + x0, 8 / scale, 40 / scale + x0, 24 / scale])
    got = sorted(dets.boxes.tolist())
    assert len(got) == 3
    np.testing.assert_allclose(got, sorted(expected), atol=0.05)
    # By default a tiled frame is not also seen whole: only the two tiles' boxes.
    tiles_only = make_detector("yoloseg", model, tiles=(2, 1), threads=1)
    assert isinstance(tiles_only, YoloSegDetector) and len(tiles_only.views(128, 64)) == 2
    got = sorted(tiles_only(np.zeros((64, 128, 3), np.uint8)).boxes.tolist())
    np.testing.assert_allclose(got, sorted(expected[:2]), atol=0.05)


def test_dequantized_copy_folds_weights_and_drops_activation_rounding() -> None:
    """DQ(int8 per-channel weights) -> Conv -> Q -> DQ: the float copy equals the original up to
    the activation rounding (half a quantisation step) and has no Q/DQ left."""
    rng = np.random.default_rng(5)
    weights = rng.integers(-5, 6, (3, 2, 1, 1)).astype(np.int8)
    w_scale = np.array([0.1, 0.2, 0.05], np.float32)
    act_scale = np.float32(0.02)
    inits = [
        numpy_helper.from_array(weights, "wq"),
        numpy_helper.from_array(w_scale, "ws"),
        numpy_helper.from_array(np.zeros(3, np.int8), "wz"),
        numpy_helper.from_array(act_scale, "as"),
        numpy_helper.from_array(np.int8(0), "az"),
    ]
    nodes = [
        helper.make_node("DequantizeLinear", ["wq", "ws", "wz"], ["w"], axis=0),
        helper.make_node("Conv", ["x", "w"], ["c"]),
        helper.make_node("QuantizeLinear", ["c", "as", "az"], ["cq"]),
        helper.make_node("DequantizeLinear", ["cq", "as", "az"], ["y"]),
    ]
    graph = helper.make_graph(
        nodes,
        "qdq",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 2, 4, 4])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 3, 4, 4])],
        initializer=inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    onnx.checker.check_model(model)
    floated = dequantized(model)
    assert not {n.op_type for n in floated.graph.node} & {"QuantizeLinear", "DequantizeLinear"}
    x = rng.random((1, 2, 4, 4), dtype=np.float32)
    quant = make_session(model, 1).run(None, {"x": x})[0]
    exact = make_session(floated, 1).run(None, {"x": x})[0]
    reference = np.einsum("oc,nchw->nohw", weights[:, :, 0, 0] * w_scale[:, None], x)
    np.testing.assert_allclose(exact, reference, rtol=1e-5, atol=1e-6)
    assert np.abs(quant - exact).max() <= act_scale / 2 + 1e-6


# --- tiles that follow the people (no data needed) --------------------------------------------
def perspective_people(a: float, b: float, feet: np.ndarray, width: int) -> np.ndarray:
    """Boxes of people standing at foot rows ``feet``, height a + b * foot, spread over x."""
    h = a + b * feet
    x = np.linspace(0, width - 0.4 * h.max(), len(feet))
    return np.c_[x, feet - h, x + 0.4 * h, feet]


def test_fit_perspective_recovers_the_line_despite_outliers() -> None:
    rng = np.random.default_rng(0)
    feet = rng.uniform(200, 540, 80)
    boxes = perspective_people(-30.0, 0.3, feet, 960)
    boxes[:, 1] -= rng.normal(0, 1.0, len(boxes))  # a pixel of noise
    parts = perspective_people(-30.0, 0.3, feet[:8], 960)
    parts[:, 1] = parts[:, 3] - 0.3 * (parts[:, 3] - parts[:, 1])  # 8 people seen in part
    p = fit_perspective(np.r_[boxes, parts])
    assert p is not None
    ref = np.polyfit(feet, boxes[:, 3] - boxes[:, 1], 1)  # the clean people alone
    assert abs(p.b - ref[0]) < 0.01 and abs(p.a - ref[1]) < 3
    # Held inside the rows seen (extended upwards by two person heights): no extrapolation.
    assert p.height(-1000) == p.height(p.y_lo) and p.height(5000) == p.height(p.y_hi)
    assert p.y_lo < np.percentile(feet, 5)
    assert fit_perspective(boxes[:5]) is None  # too few people
    # Nearer people smaller: not a ground plane; the median height everywhere.
    flipped = perspective_people(200.0, -0.3, feet, 960)
    q = fit_perspective(flipped)
    assert q is not None and q.b == 0
    assert q.a == pytest.approx(np.median(flipped[:, 3] - flipped[:, 1]))


@pytest.mark.parametrize(
    ("a", "b", "width", "height"), [(-30, 0.3, 960, 540), (25, 0.18, 768, 576)]
)
def test_people_tiles_keep_everybody_whole_at_their_share(
    a: float, b: float, width: int, height: int
) -> None:
    p = Perspective(a, b, 150.0, float(height))
    share, input_size = 0.25, 320
    tiles = people_tiles(width, height, input_size, p, share, max_tiles=100, max_scale=3.0)
    covered = np.zeros((height, width), int)
    for t in tiles:
        covered[t.y0 : t.y1, t.x0 : t.x1] += 1
        # Interior edges are the ones inside the frame.
        assert t.interior == (t.x0 > 0, t.y0 > 0, t.x1 < width, t.y1 < height)
    assert covered.min() >= 1
    # Every person (feet on any row, anywhere across) is whole in some tile that shows them
    # at about their share of the input or more (magnified at most 3x).
    for foot in np.arange(p.height(0.0) + 1, height + 1, 7.0):
        h = p.height(foot)
        for x in np.arange(0, width - 0.4 * h, 23.0):
            box = (x, foot - h, x + 0.4 * h, foot)
            sizes = [
                h * input_size / max(t.x1 - t.x0, t.y1 - t.y0)
                for t in tiles
                if t.x0 <= box[0] and t.y0 <= box[1] and box[2] <= t.x1 and box[3] <= t.y1
            ]
            assert sizes, (box, tiles)
            assert max(sizes) >= 0.8 * min(share * input_size, 3.0 * h)
    # Far rows get smaller (more magnified) tiles than near ones.
    sides = {t.y0: t.x1 - t.x0 for t in tiles}
    ordered = [sides[y] for y in sorted(sides)]
    assert ordered == sorted(ordered) and ordered[0] < ordered[-1]


def test_people_tiles_cap_the_cost_and_skip_tiling_big_people() -> None:
    p = Perspective(-30.0, 0.3, 150.0, 540.0)
    many = people_tiles(960, 540, 320, p, 0.4, max_tiles=100, max_scale=3.0)
    capped = people_tiles(960, 540, 320, p, 0.4, max_tiles=9, max_scale=3.0)
    assert len(many) > 9 >= len(capped) > 1
    # People already at their share in the whole frame: one view, no tiles.
    assert people_tiles(640, 480, 320, Perspective(300.0, 0.0), 0.25, 12, 3.0) == []


def test_people_tiles_cost_at_most_twice_the_grid() -> None:
    """Small people on a small frame would ask for many magnified tiles: the grid caps them."""
    from densepeds.detect.tiling import GRID_MULTIPLE

    feet = np.linspace(150, 576, 30)
    small = perspective_people(-20.0, 0.2, feet, 768)
    wanted = people_tiles(768, 576, 320, fit_perspective(small), 0.25, 100, 3.0)
    planner = PeopleTiles(320, person_share=0.25, max_tiles=100, max_scale=3.0, full_scan_every=1)
    planner.observe(small, np.full(len(small), 0.9), 768, 576)
    cols, rows = auto_grid(768, 576, 320)
    assert len(wanted) > GRID_MULTIPLE * cols * rows
    assert 1 < len(planner.tiles(768, 576)) <= GRID_MULTIPLE * cols * rows


def test_people_tiles_start_from_the_grid_then_follow_the_people() -> None:
    planner = PeopleTiles(320, person_share=0.25, max_tiles=100, max_scale=3.0, full_scan_every=1)
    first = planner.tiles(960, 540)
    assert first == make_tiles(960, 540, *auto_grid(960, 540, 320))
    feet = np.linspace(250, 540, 30)
    small = perspective_people(-30.0, 0.3, feet, 960)
    planner.observe(small, np.full(len(small), 0.9), 960, 540)
    assert planner.perspective is not None and planner.perspective.b == pytest.approx(0.3)
    # Unsure detections are not people to follow.
    unsure = PeopleTiles(320, 0.25, 100, 3.0, 1)
    unsure.observe(small, np.full(len(small), 0.1), 960, 540)
    assert unsure.perspective is None and unsure.tiles(960, 540) == first
    # Three times as tall people: fewer, larger tiles.
    big = PeopleTiles(320, 0.25, 100, 3.0, 1)
    big.observe(perspective_people(-90.0, 0.9, feet, 960), np.full(len(small), 0.9), 960, 540)
    assert len(big.tiles(960, 540)) < len(planner.tiles(960, 540))
    # Another frame size is another video: the grid again, then its own people.
    assert planner.tiles(768, 576) == make_tiles(768, 576, *auto_grid(768, 576, 320))
    planner.observe(small[:3], np.full(3, 0.9), 768, 576)
    assert planner.perspective is None
    planner.reset()
    assert planner.tiles(960, 540) == first


def test_yoloseg_auto_tiles_follow_its_detections(tmp_path: Path) -> None:
    det = make_detector("yoloseg", tiny_yoloseg(tmp_path / "y.onnx"), threads=1)
    assert isinstance(det, YoloSegDetector)
    frame = np.zeros((128, 256, 3), np.uint8)
    det(frame)
    assert det.last_views == len(det.people_tiles.tiles(256, 128)) or det.last_views == 1
    assert det.people_tiles._seen and len(det.people_tiles._seen[0]) >= 1


def test_a_pipeline_starts_its_detector_afresh(tmp_path: Path) -> None:
    """A loaded detector handed to a new pipeline (a batch's next input) or a pipeline reset
    forgets the people of the last sequence, so every video starts from the fixed grid."""
    from densepeds.pipeline import Pipeline

    det = make_detector("yoloseg", tiny_yoloseg(tmp_path / "y.onnx"), threads=1)
    assert isinstance(det, YoloSegDetector)
    det(np.zeros((128, 256, 3), np.uint8))
    assert det.people_tiles._seen
    pipe = Pipeline(det, features="none")
    assert not det.people_tiles._seen
    pipe.step(np.zeros((128, 256, 3), np.uint8))
    assert det.people_tiles._seen
    pipe.reset()
    assert not det.people_tiles._seen


# --- running only the tiles that hold people, with a periodic full scan -----------------------
def _whole_in(box: np.ndarray, t: Tile) -> bool:
    """The box crosses none of the tile's interior edges (brute force, one box, one tile)."""
    left, top, right, bottom = t.interior
    return (
        (not left or box[0] >= t.x0)
        and (not top or box[1] >= t.y0)
        and (not right or box[2] <= t.x1)
        and (not bottom or box[3] <= t.y1)
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_occupied_tiles_show_every_person_whole_and_skip_only_tiles_without_people(
    seed: int,
) -> None:
    rng = np.random.default_rng(seed)
    p = Perspective(-30.0, 0.3, 150.0, 540.0)
    tiles = people_tiles(960, 540, 320, p, 0.25, 100, 3.0)
    # A crowd in one part of the frame: people at random feet inside a random window.
    x_lo, x_hi = sorted(rng.uniform(0, 960, 2))
    feet = rng.uniform(200, 540, 25)
    h = p.a + p.b * feet
    x = rng.uniform(x_lo, max(x_hi, x_lo + 1), 25)
    people = np.c_[x, feet - h, x + 0.4 * h, feet]
    kept = occupied_tiles(tiles, people, margin=0.1)
    assert kept == sorted(set(kept)) and len(kept) < len(tiles)
    # Brute force: a tile is kept exactly when it shows somebody whole (people grown by a
    # tenth of their height, or the bare box for people no tile shows grown).
    grown = people + np.outer(0.1 * (people[:, 3] - people[:, 1]), [-1, -1, 1, 1])
    expected = set()
    for box, big in zip(people, grown, strict=True):
        holders = [k for k, t in enumerate(tiles) if _whole_in(big, t)]
        holders = holders or [k for k, t in enumerate(tiles) if _whole_in(box, t)]
        assert holders, box  # the layout shows everybody whole somewhere
        expected |= set(holders)
    assert set(kept) == expected
    # Every person is whole in a kept tile; a tile left out shows nobody whole.
    for box in people:
        assert any(_whole_in(box, tiles[k]) for k in kept)
    for k in set(range(len(tiles))) - set(kept):
        assert not any(_whole_in(box, tiles[k]) for box in grown)
    # Nobody: no tile. A person no tile shows whole (taller than every tile): the tile
    # holding most of them.
    assert occupied_tiles(tiles, np.zeros((0, 4)), 0.1) == []
    giant = np.array([[400.0, 0.0, 700.0, 540.0]])
    (only,) = occupied_tiles(tiles, giant, 0.1)
    inter = intersections(giant, np.array([[t.x0, t.y0, t.x1, t.y1] for t in tiles], float))
    assert inter[0, only] == inter.max()


def test_people_tiles_scan_everything_every_k_frames() -> None:
    planner = PeopleTiles(320, 0.25, 100, 3.0, full_scan_every=3)
    feet = np.linspace(250, 540, 30)
    crowd = perspective_people(-30.0, 0.3, feet, 960)
    planner.observe(crowd, np.full(len(crowd), 0.9), 960, 540)
    # The same people in the left third only: the frames between full scans run fewer tiles.
    left = crowd[crowd[:, 2] < 300]
    for _ in range(3):  # a full scan's period later, the crowd beyond is forgotten
        planner.observe(left, np.full(len(left), 0.9), 960, 540)
    assert planner.perspective is not None
    cap = GRID_MULTIPLE * np.prod(auto_grid(960, 540, 320))
    every = people_tiles(960, 540, 320, planner.perspective, 0.25, cap, 3.0)
    fulls = []
    for _ in range(9):
        tiles = planner.tiles(960, 540)
        fulls.append(planner.last_full)
        assert planner.last_full == (tiles == every)
        if not planner.last_full:
            assert 0 < len(tiles) < len(every)
            assert all(t.x0 < 300 for t in tiles)
            left_tiles = tiles
    assert fulls == [True, False, False] * 3
    # The crowd leaves: between full scans, the tiles of whoever was seen in the last three
    # frames (the last full scan's included); then, with nobody, the whole frame in one view.
    views = []
    for _ in range(6):
        tiles = planner.tiles(960, 540)
        views.append(len(tiles) if not planner.last_full else "full")
        planner.observe(np.zeros((0, 4)), np.zeros(0), 960, 540)
    assert views[0] == "full" and views[3] == "full"
    assert views[1] == views[2] == len(left_tiles) and views[4] == views[5] == 0
    # Every frame a full scan (the detector's default).
    always = PeopleTiles(320, 0.25, 100, 3.0, 1)
    always.observe(crowd, np.full(len(crowd), 0.9), 960, 540)
    for _ in range(3):
        always.observe(left, np.full(len(left), 0.9), 960, 540)
    assert always.tiles(960, 540) == every and always.last_full
    with pytest.raises(ParameterError):
        PeopleTiles(320, 0.25, 100, 3.0, full_scan_every=0)


def _full_against_skip(
    frames: dict[int, np.ndarray],
    truth_at: Callable[[int], np.ndarray],
    full: YoloSegDetector,
    skip: YoloSegDetector,
    was_full_scan: Callable[[], bool],
) -> tuple[dict[str, int], dict[str, int], list[bool], int]:
    """People found and views run per detector over the frames, whether each of the skipping
    detector's frames was a full scan, and the ground-truth count."""
    found = {"full": 0, "skip": 0}
    views = {"full": 0, "skip": 0}
    scans = []
    total = 0
    for k, frame in frames.items():
        truth = truth_at(k)
        total += len(truth)
        for name, det in (("full", full), ("skip", skip)):
            found[name] += recall(det(frame), truth)[0]
            views[name] += det.last_views
        scans.append(was_full_scan())
    return found, views, scans, total


def test_full_scans_on_a_real_crowd_skip_views_but_keep_the_people() -> None:
    """MOT20-01 frames 1-12 with a full scan every 4th frame: the frames between run fewer
    views than the full layout and find about the same visible people (the detector alone,
    every frame; the layouts come from the same detections until the first skipped frame)."""
    gt = read_gt(shared_path("data", "MOT20-01-dev", "gt", "gt.txt"))
    frames = video_frames(
        shared_path("data", "MOT20-01-dev", "MOT20-01-raw.mp4"), list(range(1, 13))
    )
    model = shared_path("models", YOLO)
    full = make_detector("yoloseg", model, threads=2)
    skip = make_detector("yoloseg", model, threads=2, full_scan_every=4)
    assert isinstance(full, YoloSegDetector) and isinstance(skip, YoloSegDetector)
    found, views, scans, total = _full_against_skip(
        frames, lambda k: visible_gt(gt, k), full, skip, lambda: skip.people_tiles.last_full
    )
    print(f"MOT20-01 frames 1-12: found {found} of {total}, views {views}")
    # The grid until enough people are seen, then a full scan every 4th frame.
    first = scans.index(False)
    assert all(scans[:first]) and first >= 1
    assert scans[first:] == [(i % 4 == 3) for i in range(len(scans) - first)]
    assert views["skip"] < views["full"]
    assert found["skip"] >= 0.95 * found["full"] and total > 100


# --- a fixed grid that skips empty tiles between full scans -----------------------------------


def test_fixed_grid_skips_empty_tiles_between_full_scans() -> None:
    grid = make_tiles(768, 576, 2, 2)
    schedule = SkipSchedule(full_scan_every=3)
    corner = np.array([[40.0, 40.0, 80.0, 140.0]])  # whole in the top-left tile only
    holders = [k for k, t in enumerate(grid) if _whole_in(corner[0], t)]
    assert holders == [0]
    runs = []
    for frame in range(7):
        tiles = schedule.tiles(grid)
        runs.append((schedule.last_full, [grid.index(t) for t in tiles]))
        schedule.observe(corner if frame < 4 else np.zeros((0, 4)))
    # Every third frame all four tiles; between, only the tile that shows the person whole, and
    # none (the whole frame in one view) once nobody was seen for a full period.
    full = [0, 1, 2, 3]
    assert runs == [
        (True, full),
        (False, [0]),
        (False, [0]),
        (True, full),
        (False, [0]),
        (False, [0]),  # the person of frame 3 (the last full scan) is still recent
        (True, full),
    ]
    schedule.observe(np.zeros((0, 4)))
    assert schedule.tiles(grid) == [] and not schedule.last_full
    # Another layout (another frame size): a full scan at once.
    other = make_tiles(960, 540, 3, 2)
    assert schedule.tiles(other) == other and schedule.last_full
    # full_scan_every=1: every frame all tiles, whatever was seen.
    always = SkipSchedule(1)
    for _ in range(3):
        assert always.tiles(grid) == grid and always.last_full
        always.observe(corner)
    with pytest.raises(ParameterError):
        SkipSchedule(0)


def _grown(people: np.ndarray, margin: float, width: int, height: int) -> np.ndarray:
    h = people[:, 3] - people[:, 1]
    grown = people + np.outer(h * margin, [-1.0, -1.0, 1.0, 1.0])
    return np.clip(grown, 0, [width, height, width, height])


def test_sliding_windows_hold_everyone_whole_in_fewer_views() -> None:
    """Random crowds on a 2x2 grid: where windows are given, each is the grid's tile size inside
    the frame, every person (grown by the margin) lies inside one of them, and they are fewer
    than the tiles occupied_tiles keeps; a person straddling the grid's middle needs one window
    where two tiles show them whole."""
    width, height, margin = 768, 576, 0.1
    grid = make_tiles(width, height, 2, 2)
    tw, th = grid[0].x1 - grid[0].x0, grid[0].y1 - grid[0].y0
    rng = np.random.default_rng(3)
    used = 0
    for _ in range(300):
        n = int(rng.integers(1, 12))
        h = rng.uniform(30, 200, n)
        x = rng.uniform(0, width - 0.45 * h)
        y = rng.uniform(0, height - h)
        people = np.c_[x, y, x + 0.4 * h, y + h]
        windows = sliding_windows(grid, people, margin)
        if windows is None:
            continue
        used += 1
        assert len(windows) < len(occupied_tiles(grid, people, margin))
        for w in windows:
            assert w.x0 >= 0 and w.x1 <= width and w.y0 >= 0 and w.y1 <= height
            assert (w.x1 - w.x0, w.y1 - w.y0) == (tw, th)
            assert w.interior == (w.x0 > 0, w.y0 > 0, w.x1 < width, w.y1 < height)
        for box in _grown(people, margin, width, height):
            # Whole in a window, to the pixel the window's integer edges round to.
            assert any(
                box[0] >= w.x0 and box[1] >= w.y0 and box[2] <= w.x1 + 1 and box[3] <= w.y1 + 1
                for w in windows
            )
    assert used > 50
    middle = np.array([[364.0, 250.0, 404.0, 350.0], [380.0, 260.0, 420.0, 360.0]])
    assert len(occupied_tiles(grid, middle, margin)) >= 2
    windows = sliding_windows(grid, middle, margin)
    assert windows is not None and len(windows) == 1
    # Nobody, or a box larger than a window: no windows.
    assert sliding_windows(grid, np.zeros((0, 4)), margin) is None
    assert sliding_windows(grid, np.array([[0.0, 0.0, 100.0, 500.0]]), margin) is None
    # The schedule runs them between full scans.
    schedule = SkipSchedule(full_scan_every=4, margin=margin)
    assert schedule.tiles(grid) == grid
    schedule.observe(middle)
    assert schedule.tiles(grid) == windows and not schedule.last_full


def test_sliding_windows_on_bands_keep_each_persons_scale() -> None:
    """Random crowds on a layout of two bands (people_tiles: small tiles far away, large ones
    near): where windows are given, every person lies whole in one the size of a layout tile
    that shows them whole (`showing`), so they are seen at the scale the layout has for them,
    and the windows are fewer than the tiles occupied_tiles keeps."""
    width, height, margin = 1920, 1080, 0.1
    persp = Perspective(10.0, 0.12, 100.0, float(height))
    layout = people_tiles(width, height, 320, persp, 0.25, 12, 3.0)
    sizes = {(t.x1 - t.x0, t.y1 - t.y0) for t in layout}
    assert len(sizes) == 2
    rng = np.random.default_rng(5)
    used = 0
    for _ in range(200):
        n = int(rng.integers(1, 25))
        foot = rng.uniform(150, height, n)
        h = np.array([persp.height(f) for f in foot]) * rng.uniform(0.8, 1.1, n)
        x = rng.uniform(0, width - 0.4 * h)
        people = np.c_[x, foot - h, x + 0.4 * h, foot].clip(0, [width, height, width, height])
        windows = sliding_windows(layout, people, margin)
        if windows is None:
            continue
        used += 1
        assert len(windows) < len(occupied_tiles(layout, people, margin))
        shows = showing(layout, people, margin)
        grown = _grown(people, margin, width, height)
        for p, box in enumerate(grown):
            own = {
                (layout[k].x1 - layout[k].x0, layout[k].y1 - layout[k].y0)
                for k in np.flatnonzero(shows[p])
            }
            assert any(
                box[0] >= w.x0
                and box[1] >= w.y0
                and box[2] <= w.x1 + 1
                and box[3] <= w.y1 + 1
                and (w.x1 - w.x0, w.y1 - w.y0) in own
                for w in windows
            )
    assert used > 50


def test_yoloseg_fixed_grid_follows_its_schedule(tmp_path: Path) -> None:
    det = make_detector("yoloseg", tiny_yoloseg(tmp_path / "y.onnx"), threads=1, tiles="2x2")
    skip = make_detector(
        "yoloseg", tiny_yoloseg(tmp_path / "y.onnx"), threads=1, tiles="2x2", full_scan_every=2
    )
    assert isinstance(det, YoloSegDetector) and isinstance(skip, YoloSegDetector)
    frame = np.zeros((128, 128, 3), np.uint8)
    # The tiny model finds a person in every view: every tile stays occupied, the same boxes.
    for _ in range(3):
        a, b = det(frame), skip(frame)
        assert det.last_views == skip.last_views == 4
        np.testing.assert_array_equal(a.boxes, b.boxes)
    # Nobody seen for a period: the frame between full scans is seen whole, in one view.
    skip.reset()
    skip(frame)
    skip.grid_schedule.observe(np.zeros((0, 4)))
    skip.grid_schedule.observe(np.zeros((0, 4)))
    assert len(skip.views(128, 128)) == 1 and not skip.grid_schedule.last_full


def pets09_gt_boxes(gt: np.ndarray, frame: int) -> np.ndarray:
    sel = gt[gt[:, 0] == frame]
    return np.c_[sel[:, 2:4], sel[:, 2:4] + sel[:, 4:6]]


def test_fixed_grid_skipping_on_a_real_video_keeps_the_people() -> None:
    """PETS09-S2L1 frames 41-64 on the reference's 2x2 grid with a full scan every 4th frame:
    the frames between run fewer views and find about as many people as every tile would (the
    model's own input size: the schedule alone; tests/test_anchor_grid.py has the fitted one)."""
    gt = read_gt(shared_path("data", "PETS09-S2L1-dev", "gt", "gt.txt"))
    frames = video_frames(shared_path("data", "PETS09-S2L1-dev", "vtest.avi"), list(range(41, 65)))
    model = shared_path("models", YOLO)
    full = make_detector("yoloseg", model, threads=2, tiles="2x2", fit_input=False)
    skip = make_detector(
        "yoloseg", model, threads=2, tiles="2x2", full_scan_every=4, fit_input=False
    )
    assert isinstance(full, YoloSegDetector) and isinstance(skip, YoloSegDetector)
    found, views, scans, total = _full_against_skip(
        frames, lambda k: pets09_gt_boxes(gt, k), full, skip, lambda: skip.grid_schedule.last_full
    )
    print(f"PETS09 frames 41-64, 2x2: found {found} of {total}, views {views}")
    assert scans == [i % 4 == 0 for i in range(24)]
    assert views["full"] == 4 * 24 and views["skip"] < views["full"]
    assert found["skip"] >= 0.95 * found["full"] and total > 100


def test_one_full_scan_every_frame_leaves_the_tracks_unchanged() -> None:
    """A fixed grid with full_scan_every=1 against the same detector with its schedule bypassed
    (every tile of the grid, by construction): the same tracks on PETS09-S2L1 frames 1-8."""
    from densepeds.pipeline import Pipeline

    frames = video_frames(shared_path("data", "PETS09-S2L1-dev", "vtest.avi"), list(range(1, 9)))
    model = shared_path("models", YOLO)
    out = []
    for bypass in (False, True):
        det = make_detector("yoloseg", model, threads=2, tiles="2x2", full_scan_every=1)
        assert isinstance(det, YoloSegDetector)
        if bypass:
            det.grid_schedule.tiles = lambda layout: layout  # type: ignore[method-assign]
        pipe = Pipeline(det, features="none")
        rows = []
        for k, frame in frames.items():
            tr = pipe.step(frame)
            assert det.last_views == 4
            rows.append(np.c_[np.full(len(tr.ids), k), tr.ids, tr.boxes])
        out.append(np.concatenate(rows))
    assert len(out[0]) > 20
    np.testing.assert_array_equal(out[0], out[1])


def test_a_skipping_grid_has_a_cache_key_of_its_own() -> None:
    """benchmarks/realvideo.py keys cached detections by the detector's settings: a fixed grid
    that skips tiles is its own entry; one that does not keeps the plain grid's key."""
    import sys

    sys.path.insert(0, str(REPO / "benchmarks"))
    import realvideo

    shared_path("models", YOLO)
    key = realvideo.cache_key
    plain = key("PETS09-S2L1-dev", "1:397", {"tiles": "2x2", "quantized": False})
    same = {"tiles": "2x2", "quantized": False, "full_scan_every": 1}
    assert key("PETS09-S2L1-dev", "1:397", same) == plain
    for every in (2, 4):
        skip = {"tiles": "2x2", "quantized": False, "full_scan_every": every}
        assert key("PETS09-S2L1-dev", "1:397", skip) != plain
    two, four = ({"tiles": "2x2", "quantized": False, "full_scan_every": k} for k in (2, 4))
    assert key("PETS09-S2L1-dev", "1:397", two) != key("PETS09-S2L1-dev", "1:397", four)
