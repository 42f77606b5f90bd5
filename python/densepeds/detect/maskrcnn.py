"""Mask R-CNN in either of two ONNX contracts, recognised from the graph.

- **Model zoo** (the ONNX Model Zoo's ``MaskRCNN-12.onnx`` / ``MaskRCNN-12-int8.onnx``, the
  detector network the DensePeds paper uses): input ``image`` float32 [3, H, W], BGR 0-255
  minus the mean (102.9801, 115.9465, 122.7717), resized here so the short side is about 800
  (the long side at most 1333, as the model was trained) and zero-padded to multiples of 32;
  outputs boxes [N, 4] (x1, y1, x2, y2 in input pixels), labels int64 [N] (COCO, person = 1),
  scores [N] and masks [N, 1, 28, 28], probabilities inside each box (pasted here into the box,
  resized).
- **torchvision** (``models/export_maskrcnn.py``): input float32 [3, H, W] RGB in [0, 1] at any
  size (the model resizes internally); masks [N, 1, H, W] probabilities over the whole image.

Which one: masks whose last two dimensions are fixed numbers in the graph are the zoo's; ones
that follow the input's dimensions are torchvision's; where the graph does not say, one blank
64x64 image decides (torchvision gives 64x64 masks, the zoo its fixed size).

Cost in crowds: a view costs about its padded pixel count through the ResNet-50 FPN backbone
(one ~800x1067 view of a 768x576 frame; a 1920x1080 frame is scaled down to ~800x1422), plus the
mask head per kept box. By default a frame is one view at the scale the model was trained at:
its FPN anchors (32-512 px at that scale) cover people down to roughly 30 px tall, and its
per-image limit of 100 detections is above the densest shared sequence (MOT20-01, ~46 people a
frame). ``tiles`` (a CxR grid, off by default) runs each tile at that scale too, so it costs C x R
views: worth it only where people are far smaller than that or more than 100 are in view.
Tiles are run one after another (the model takes one image per call) and merged like yoloseg's.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from densepeds.detect import onnxutil
from densepeds.detect.tiling import Tile, TilesSpec, cut_flags, make_tiles, merge_views, parse_grid
from densepeds.errors import ModelError, ParameterError
from densepeds.frames import check_frame
from densepeds.types import Detections

# Models whose non-finite output was reported (once each).
_NONFINITE_WARNED: set[object] = set()

EXPECTED = (
    "a Mask R-CNN ONNX model: input float [3,H,W]; outputs boxes [N,4], labels [N], scores "
    "[N], masks [N,1,h,w] (the ONNX Model Zoo's MaskRCNN-12 files, `densepeds models fetch`, "
    "or a torchvision export made with models/export_maskrcnn.py)"
)
MASK_THRESHOLD = 0.5
ZOO_MEAN_BGR = (102.9801, 115.9465, 122.7717)
ZOO_MAX_SIDE = 1333  # the long side's limit at the training scale
ZOO_STRIDE = 32  # sides padded to multiples of this
PROBE_SIDE = 64
CONTRACTS = ("zoo", "torchvision")


class MaskRCNNDetector:
    """``tile_input_size``: the short side each view is resized to (zoo contract; default 800,
    the training scale). The torchvision contract resizes inside the model."""

    def __init__(
        self,
        model: Path,
        *,
        tiles: TilesSpec = None,
        score_threshold: float = 0.5,
        iou_threshold: float = 0.6,
        threads: int | None = None,
        person_label: int = 1,
        tile_input_size: int = 800,
        device: str = "auto",
    ) -> None:
        if not 0.0 <= score_threshold <= 1.0:
            raise ParameterError(f"score_threshold must be in [0, 1], got {score_threshold}")
        if not 0.0 < iou_threshold <= 1.0:
            raise ParameterError(f"iou_threshold must be in (0, 1], got {iou_threshold}")
        if tile_input_size < ZOO_STRIDE:
            raise ParameterError(f"tile_input_size must be >= {ZOO_STRIDE}, got {tile_input_size}")
        self.path = model
        self.tiles = tiles
        self.score_threshold = score_threshold
        self.iou_threshold = iou_threshold
        self.person_label = person_label
        self.tile_input_size = tile_input_size
        self.session = onnxutil.make_session(onnxutil.load_model(model), threads, device=device)
        inputs = onnxutil.specs(self.session.get_inputs())
        outputs = onnxutil.specs(self.session.get_outputs())
        if len(inputs) != 1 or len(inputs[0].shape) != 3 or inputs[0].shape[0] != 3:
            raise ModelError(f"{model}: expected {EXPECTED}; got inputs {inputs}")
        self.input_name = inputs[0].name
        order = _output_order(outputs)
        if order is None:
            raise ModelError(f"{model}: expected {EXPECTED}; got outputs {outputs}")
        self._order = order
        masks = outputs[order[3]]
        self.contract = _contract_from_graph(inputs[0].shape, masks.shape) or self._probe()

    def _probe(self) -> str:
        """The contract from the masks of one blank image (graphs without output shapes)."""
        blank = np.zeros((3, PROBE_SIDE, PROBE_SIDE), np.float32)
        try:
            masks = self.session.run(None, {self.input_name: blank})[self._order[3]]
        except Exception as err:  # noqa: BLE001 (onnxruntime's own errors, in one line)
            first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            raise ModelError(
                f"{self.path}: cannot tell its Mask R-CNN contract (a blank "
                f"{PROBE_SIDE}x{PROBE_SIDE} image failed: {first}); expected {EXPECTED}"
            ) from None
        return "torchvision" if tuple(np.shape(masks)[2:]) == (PROBE_SIDE,) * 2 else "zoo"

    def _outputs(self, x: np.ndarray) -> tuple[np.ndarray, ...]:
        raw = self.session.run(None, {self.input_name: x})
        boxes, labels, scores, masks = (np.asarray(raw[i]) for i in self._order)
        n = len(boxes)
        if boxes.shape != (n, 4) or labels.shape != (n,) or scores.shape != (n,):
            raise ModelError(
                f"{self.path}: outputs of {n} boxes do not match: boxes {list(boxes.shape)}, "
                f"labels {list(labels.shape)}, scores {list(scores.shape)}"
            )
        if masks.ndim != 4 or masks.shape[:2] != (n, 1):
            raise ModelError(f"{self.path}: masks {list(masks.shape)}, expected [{n},1,h,w]")
        return boxes, labels, scores, masks

    def zoo_input(
        self, view_bgr: npt.NDArray[np.uint8]
    ) -> tuple[np.ndarray, npt.NDArray[np.float64]]:
        """The zoo contract's input for a BGR view, and what box coordinates (x1, y1, x2, y2)
        were scaled by."""
        height, width = view_bgr.shape[:2]
        scale = min(self.tile_input_size / min(height, width), ZOO_MAX_SIDE / max(height, width))
        size = (max(1, round(width * scale)), max(1, round(height * scale)))
        resized = view_bgr if size == (width, height) else cv2.resize(view_bgr, size)
        padded_h = math.ceil(size[1] / ZOO_STRIDE) * ZOO_STRIDE
        padded_w = math.ceil(size[0] / ZOO_STRIDE) * ZOO_STRIDE
        x = np.zeros((3, padded_h, padded_w), np.float32)
        for c in range(3):
            np.subtract(
                resized[..., c], np.float32(ZOO_MEAN_BGR[c]), out=x[c, : size[1], : size[0]]
            )
        sx, sy = size[0] / width, size[1] / height  # exactly what each axis was resized by
        return x, np.array([sx, sy, sx, sy])

    def _run(self, view_bgr: npt.NDArray[np.uint8]) -> tuple[np.ndarray, np.ndarray, list]:
        """Person boxes (view pixels), scores, and for each a (probabilities, kind) mask."""
        if self.contract == "zoo":
            x, scale = self.zoo_input(view_bgr)
        else:
            x = np.ascontiguousarray(view_bgr[..., ::-1].transpose(2, 0, 1), dtype=np.float32)
            x *= np.float32(1 / 255)
            scale = np.ones(4)
        boxes, labels, scores, masks = self._outputs(x)
        keep = (labels == self.person_label) & (scores >= self.score_threshold)
        rows = np.concatenate([boxes[keep], scores[keep].reshape(-1, 1)], axis=1)
        keep = np.flatnonzero(keep)[onnxutil.finite_rows(rows, self.path, _NONFINITE_WARNED)]
        return boxes[keep].astype(np.float64) / scale, scores[keep], list(masks[keep][:, 0])

    def __call__(self, frame: npt.NDArray[np.uint8]) -> Detections:
        check_frame(frame)
        height, width = frame.shape[:2]
        cols, rows = parse_grid(self.tiles, width, height, self.tile_input_size)
        tiles = (
            make_tiles(width, height, cols, rows)
            if cols * rows > 1
            else [Tile(0, 0, width, height, (False, False, False, False))]
        )
        all_boxes, all_scores, views, cuts = [], [], [], []
        prob_maps: list[tuple[Tile, np.ndarray]] = []
        for k, tile in enumerate(tiles):
            boxes, scores, probs = self._run(frame[tile.y0 : tile.y1, tile.x0 : tile.x1])
            boxes += [tile.x0, tile.y0, tile.x0, tile.y0]
            np.clip(boxes, 0, [width, height, width, height], out=boxes)
            all_boxes.append(boxes)
            all_scores.append(scores)
            views.append(np.full(len(boxes), k))
            cuts.append(cut_flags(boxes, tile))
            prob_maps.extend((tile, p) for p in probs)
        boxes = np.concatenate(all_boxes)
        scores = np.concatenate(all_scores).astype(np.float32)
        view = np.concatenate(views)
        valid = np.flatnonzero((boxes[:, 2] - boxes[:, 0] >= 1) & (boxes[:, 3] - boxes[:, 1] >= 1))
        keep = valid[
            merge_views(
                boxes[valid],
                scores[valid],
                view[valid],
                np.concatenate(cuts)[valid],
                self.iou_threshold,
            )
        ]
        mask_boxes = np.empty((len(keep), 4), np.int32)
        masks = []
        for j, i in enumerate(keep):
            tile, prob = prob_maps[i]
            x0, y0 = (int(np.floor(v)) for v in boxes[i, :2])
            x1, y1 = (int(np.ceil(v)) for v in boxes[i, 2:])
            x0, x1 = max(x0, 0), min(x1, width)
            y0, y1 = max(y0, 0), min(y1, height)
            mask_boxes[j] = (x0, y0, x1, y1)
            if self.contract == "zoo":
                local = cv2.resize(prob.astype(np.float32), (x1 - x0, y1 - y0))
            else:
                local = prob[y0 - tile.y0 : y1 - tile.y0, x0 - tile.x0 : x1 - tile.x0]
            masks.append(local > MASK_THRESHOLD)
        return Detections(boxes[keep], scores[keep], masks, mask_boxes)


def _output_order(outputs: list[onnxutil.TensorSpec]) -> tuple[int, int, int, int] | None:
    """Indices of (boxes, labels, scores, masks) among the outputs, by rank and type: boxes the
    rank-2 output, masks the rank-4 one, labels the rank-1 integer one, scores the rank-1 float
    one. None where the outputs are not exactly those four."""
    if len(outputs) != 4:
        return None
    by_rank: dict[int, list[int]] = {}
    for i, o in enumerate(outputs):
        by_rank.setdefault(len(o.shape), []).append(i)
    if sorted(by_rank) != [1, 2, 4] or len(by_rank[1]) != 2:
        return None
    a, b = by_rank[1]
    a_int = "int" in outputs[a].dtype
    if a_int == ("int" in outputs[b].dtype):
        return None
    labels, scores = (a, b) if a_int else (b, a)
    return by_rank[2][0], labels, scores, by_rank[4][0]


def _contract_from_graph(
    image: tuple[int | str | None, ...], masks: tuple[int | str | None, ...]
) -> str | None:
    """'torchvision' for masks as large as the input (the same dimension names, or the same
    fixed sizes), 'zoo' for masks of another fixed size, None where the graph does not say."""
    tail = tuple(masks[2:])
    if len(tail) == 2 and all(d is not None for d in tail) and tail == tuple(image[1:]):
        return "torchvision"
    if len(tail) == 2 and all(isinstance(d, int) for d in tail):
        return "zoo"
    return None
