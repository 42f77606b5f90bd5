"""Person detectors: frame (BGR uint8 [H, W, 3]) in, Detections (boxes, scores, masks) out."""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np
import numpy.typing as npt

from densepeds.detect.onnxutil import DEVICES
from densepeds.types import Detections


class Detector(Protocol):
    def __call__(self, frame: npt.NDArray[np.uint8]) -> Detections: ...


DETECTOR_KINDS = ("yoloseg", "maskrcnn")
# Where models run (densepeds.detect.onnxutil): a GPU where usable, the CPU, a GPU, the CPU
# through OpenVINO.
DEFAULT_MODELS = {"yoloseg": "yolov8n-seg-320-int8.onnx", "maskrcnn": "maskrcnn_resnet50_fpn.onnx"}


def make_detector(
    kind: str,
    model: str | Path | None = None,
    *,
    tiles: str | int | tuple[int, int] | None = "auto",
    score_threshold: float | None = None,
    threads: int | None = None,
    **options: object,
) -> Detector:
    """A detector of ``kind`` ('yoloseg' | 'maskrcnn') from a model path or name.

    ``model`` None uses the kind's first model file present (densepeds.models.files
    .default_model_file), found by densepeds.models.files.find_model.
    ``score_threshold`` None keeps the backend's default (0.15 yoloseg: the tracker decides what
    starts a track; 0.5 maskrcnn). ``tiles``: 'auto', None/'none', 'CxR' or (columns, rows);
    Mask R-CNN ignores 'auto' (it upsamples internally) unless given an explicit grid.
    """
    from densepeds.errors import ParameterError
    from densepeds.models.files import default_model_file, find_model

    if kind not in DETECTOR_KINDS:
        raise ParameterError(f"detector kind must be one of {DETECTOR_KINDS}, got {kind!r}")
    path = find_model(default_model_file(kind)) if model is None else find_model(str(model))
    extra: dict[str, object] = dict(options)
    if score_threshold is not None:
        extra["score_threshold"] = score_threshold
    if kind == "yoloseg":
        from densepeds.detect.yoloseg import YoloSegDetector

        return YoloSegDetector(path, tiles=tiles, threads=threads, **extra)  # type: ignore[arg-type]
    from densepeds.detect.maskrcnn import MaskRCNNDetector

    grid = None if tiles == "auto" else tiles
    return MaskRCNNDetector(path, tiles=grid, threads=threads, **extra)  # type: ignore[arg-type]


__all__ = ["DETECTOR_KINDS", "DEVICES", "Detector", "make_detector"]
