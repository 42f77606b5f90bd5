"""A stand-in for the re-ID network on the scene: colour histograms of the upper and lower body."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from densepeds.errors import ParameterError
from densepeds.types import Detections

Image = npt.NDArray[np.uint8]
KINDS = ("segmented", "masked_pool", "bbox")
WHITE = (255, 255, 255)


class HistogramEmbedder:
    """Colour histograms (4 levels per BGR channel) of the box's upper and lower halves.

    Implements the ReID ``embed`` contract with the pipeline's feature kinds: ``segmented`` (the
    method's white fill) paints every pixel outside the detection's mask white before counting,
    as the method does before its CNN; ``masked_pool`` counts only the mask's pixels (the
    histogram counterpart of pooling re-ID features over the mask); ``bbox`` counts the whole
    box, background and neighbours included. With the scene's exact masks (no mask noise) the
    mask holds only the person's own visible pixels, so ``masked_pool`` sees no neighbour by
    construction; mask noise (``SceneConfig.mask_dilate`` / ``mask_shift``) removes that.
    """

    bins = 4

    def embed(
        self, frame: Image, dets: Detections, features: str = "segmented"
    ) -> npt.NDArray[np.float32]:
        if features not in KINDS:
            raise ParameterError(f"features {features!r}: expected one of {', '.join(KINDS)}")
        out = np.zeros((len(dets), 2 * self.bins**3), np.float32)
        height, width = frame.shape[:2]
        white = self._code(np.array([[WHITE]], np.uint8))[0, 0]
        for j, box in enumerate(dets.boxes):
            if features != "bbox" and dets.masks is not None and dets.mask_boxes is not None:
                x0, y0, x1, y1 = dets.mask_boxes[j]
                mask = dets.masks[j]
            else:
                x0, y0 = int(max(np.floor(box[0]), 0)), int(max(np.floor(box[1]), 0))
                x1, y1 = int(min(np.ceil(box[2]), width)), int(min(np.ceil(box[3]), height))
                mask = np.ones((max(y1 - y0, 0), max(x1 - x0, 0)), bool)
            crop = frame[y0:y1, x0:x1]
            if crop.size == 0 or not mask.any():
                continue
            code = self._code(crop)
            if features == "segmented":
                code = np.where(mask, code, white)
                mask = np.ones_like(mask)
            half = crop.shape[0] // 2
            for part, rows in enumerate((slice(0, half), slice(half, None))):
                sel = code[rows][mask[rows]]
                hist = np.bincount(sel, minlength=self.bins**3).astype(np.float32)
                out[j, part * self.bins**3 : (part + 1) * self.bins**3] = np.sqrt(hist)
        norms = np.linalg.norm(out, axis=1, keepdims=True)
        return (out / np.where(norms > 0, norms, 1)).astype(np.float32)

    def _code(self, crop: Image) -> npt.NDArray[np.int32]:
        q = (crop // (256 // self.bins)).astype(np.int32)
        return (q[..., 0] * self.bins + q[..., 1]) * self.bins + q[..., 2]
