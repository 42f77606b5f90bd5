"""Mask R-CNN in torchvision's ONNX export contract (models/export_maskrcnn.py makes one).

Input: one image, float32 [3, H, W] RGB in [0, 1] (any size; the model resizes internally).
Outputs: boxes [N, 4] (x1, y1, x2, y2 in input pixels), labels int64 [N] (COCO, person = 1),
scores [N], masks [N, 1, H, W] probabilities pasted into the whole image. The model takes one
image per call, so tiles (off by default: Mask R-CNN already upsamples small images to 800 px)
are run one after another.
"""

from __future__ import annotations

from pathlib import Path

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
    "a torchvision Mask R-CNN ONNX export: input float [3,H,W] RGB in [0,1]; outputs boxes [N,4], "
    "labels [N], scores [N], masks [N,1,H,W] (make one with models/export_maskrcnn.py)"
)
MASK_THRESHOLD = 0.5


class MaskRCNNDetector:
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
    ) -> None:
        if not 0.0 <= score_threshold <= 1.0:
            raise ParameterError(f"score_threshold must be in [0, 1], got {score_threshold}")
        if not 0.0 < iou_threshold <= 1.0:
            raise ParameterError(f"iou_threshold must be in (0, 1], got {iou_threshold}")
        self.path = model
        self.tiles = tiles
        self.score_threshold = score_threshold
        self.iou_threshold = iou_threshold
        self.person_label = person_label
        self.tile_input_size = tile_input_size
        self.session = onnxutil.make_session(onnxutil.load_model(model), threads)
        inputs = onnxutil.specs(self.session.get_inputs())
        outputs = onnxutil.specs(self.session.get_outputs())
        if len(inputs) != 1 or len(inputs[0].shape) != 3 or inputs[0].shape[0] != 3:
            raise ModelError(f"{model}: expected {EXPECTED}; got inputs {inputs}")
        ranks = [len(o.shape) for o in outputs]
        if len(outputs) != 4 or ranks != [2, 1, 1, 4]:
            raise ModelError(f"{model}: expected {EXPECTED}; got outputs {outputs}")
        self.input_name = inputs[0].name

    def _run(self, image_bgr: npt.NDArray[np.uint8]) -> tuple[np.ndarray, ...]:
        x = np.ascontiguousarray(image_bgr[..., ::-1].transpose(2, 0, 1), dtype=np.float32)
        x *= np.float32(1 / 255)
        boxes, labels, scores, masks = self.session.run(None, {self.input_name: x})
        keep = (labels == self.person_label) & (scores >= self.score_threshold)
        rows = np.concatenate([boxes[keep], scores[keep].reshape(-1, 1)], axis=1)
        keep = np.flatnonzero(keep)[onnxutil.finite_rows(rows, self.path, _NONFINITE_WARNED)]
        return boxes[keep].astype(np.float64), scores[keep], masks[keep][:, 0]

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
            local = prob[y0 - tile.y0 : y1 - tile.y0, x0 - tile.x0 : x1 - tile.x0]
            masks.append(local > MASK_THRESHOLD)
        return Detections(boxes[keep], scores[keep], masks, mask_boxes)
