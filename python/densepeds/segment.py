"""Crops of detections for appearance: plain boxes and segmented boxes.

The DensePeds method paints every pixel outside a person's mask white ("segmented box") before
embedding. With OSNet that white fill was measured to make different people *more* alike, so
alternatives are offered: the ImageNet mean colour (zero after the network's normalisation, i.e.
"no signal") and a blurred background (keeps the crop's statistics, removes the neighbours' detail).
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from densepeds.errors import InputError, ParameterError
from densepeds.types import Detections

Image = npt.NDArray[np.uint8]
WHITE = (255, 255, 255)
IMAGENET_MEAN_BGR = (104, 116, 124)  # 255 * (0.406, 0.456, 0.485)
BLUR_SIGMA_FRACTION = 0.08  # of the crop height: enough to wipe out a neighbour's features

# Appearance features from crops: "bbox" is the plain crop, "masked_pool" the plain crop with the
# mask weighting the re-ID network's final pooling, the others repaint the background.
FEATURES = ("segmented", "bbox", "masked_mean", "masked_blur", "masked_pool")
FILLS = {"segmented": "white", "masked_mean": "mean", "masked_blur": "blur"}


def box_region(box: npt.ArrayLike, width: int, height: int) -> tuple[int, int, int, int]:
    """Integer pixel region (x0, y0, x1, y1) covering ``box``, clipped to the frame, >= 1 px."""
    x1, y1, x2, y2 = (float(v) for v in np.asarray(box, dtype=np.float64).reshape(4))
    if not all(np.isfinite([x1, y1, x2, y2])):
        raise InputError(f"box {(x1, y1, x2, y2)} is not finite")
    x0 = min(max(int(np.floor(x1)), 0), width - 1)
    y0 = min(max(int(np.floor(y1)), 0), height - 1)
    xe = min(max(int(np.ceil(x2)), x0 + 1), width)
    ye = min(max(int(np.ceil(y2)), y0 + 1), height)
    return x0, y0, xe, ye


def bbox_crop(frame: Image, box: npt.ArrayLike) -> Image:
    """The plain crop of ``box`` (clipped to the frame; a copy)."""
    x0, y0, x1, y1 = box_region(box, frame.shape[1], frame.shape[0])
    return frame[y0:y1, x0:x1].copy()


def crop_mask(
    region: tuple[int, int, int, int],
    mask: npt.NDArray[np.bool_] | None,
    mask_box: npt.ArrayLike | None,
) -> npt.NDArray[np.bool_]:
    """The person mask over ``region``: True where the mask is; outside the mask's box, False.

    No mask means the whole box is the person.
    """
    x0, y0, x1, y1 = region
    if mask is None or mask_box is None:
        return np.ones((y1 - y0, x1 - x0), bool)
    mx0, my0, mx1, my1 = (int(v) for v in np.asarray(mask_box).reshape(4))
    if mask.shape != (my1 - my0, mx1 - mx0):
        raise InputError(f"mask shape {mask.shape} does not match its mask box {mask_box}")
    out = np.zeros((y1 - y0, x1 - x0), bool)
    ix0, iy0, ix1, iy1 = max(x0, mx0), max(y0, my0), min(x1, mx1), min(y1, my1)
    if ix1 > ix0 and iy1 > iy0:
        out[iy0 - y0 : iy1 - y0, ix0 - x0 : ix1 - x0] = mask[
            iy0 - my0 : iy1 - my0, ix0 - mx0 : ix1 - mx0
        ]
    return out


def segmented_crop(
    frame: Image,
    box: npt.ArrayLike,
    mask: npt.NDArray[np.bool_] | None,
    mask_box: npt.ArrayLike | None,
    fill: str = "white",
) -> Image:
    """Crop of ``box`` with pixels outside the mask replaced; inside, the original pixels.

    fill: "white" (the method's segmented box), "mean" (ImageNet mean colour) or "blur".
    """
    region = box_region(box, frame.shape[1], frame.shape[0])
    x0, y0, x1, y1 = region
    crop = frame[y0:y1, x0:x1].copy()
    person = crop_mask(region, mask, mask_box)
    outside = ~person
    if not outside.any():
        return crop
    if fill == "white":
        crop[outside] = WHITE
    elif fill == "mean":
        crop[outside] = IMAGENET_MEAN_BGR
    elif fill == "blur":
        sigma = max(1.0, BLUR_SIGMA_FRACTION * crop.shape[0])
        blurred = cv2.GaussianBlur(crop, (0, 0), sigma)
        crop[outside] = blurred[outside]
    else:
        raise ParameterError(f"fill must be one of {sorted(set(FILLS.values()))}, got {fill!r}")
    return crop


def crops_for(frame: Image, dets: Detections, features: str = "segmented") -> list[Image]:
    """One crop per detection for the appearance ``features`` (see FEATURES)."""
    if features not in FEATURES:
        raise ParameterError(f"features must be one of {FEATURES}, got {features!r}")
    if features in ("bbox", "masked_pool"):  # masked_pool weights features, not pixels
        return [bbox_crop(frame, b) for b in dets.boxes]
    fill = FILLS[features]
    masks = dets.masks
    mboxes = dets.mask_boxes
    return [
        segmented_crop(
            frame,
            b,
            None if masks is None else masks[i],
            None if mboxes is None else mboxes[i],
            fill,
        )
        for i, b in enumerate(dets.boxes)
    ]


def person_masks(frame: Image, dets: Detections) -> list[npt.NDArray[np.bool_]]:
    """Each detection's person mask over its plain crop (``bbox_crop``); no masks: all True."""
    regions = [box_region(b, frame.shape[1], frame.shape[0]) for b in dets.boxes]
    return [
        crop_mask(
            r,
            None if dets.masks is None else dets.masks[i],
            None if dets.mask_boxes is None else dets.mask_boxes[i],
        )
        for i, r in enumerate(regions)
    ]


def masks_for_boxes(
    dets: Detections, boxes: npt.ArrayLike, min_iou: float = 0.5
) -> tuple[Detections, npt.NDArray[np.intp]]:
    """Give other boxes (e.g. ground truth) the masks of the detections matching them.

    Boxes are matched one-to-one to ``dets`` by IoU (Hungarian, at least ``min_iou``); returns
    the matched boxes carrying their detection's mask, and the indices of those boxes.
    """
    from densepeds.boxes import match_boxes

    target = np.asarray(boxes, np.float64).reshape(-1, 4)
    if len(target) == 0 or len(dets) == 0 or dets.masks is None or dets.mask_boxes is None:
        return Detections.empty(), np.zeros(0, np.intp)
    rows, cols = match_boxes(target, dets.boxes, min_iou)
    masks = [dets.masks[c] for c in cols]
    out = Detections(
        target[rows].astype(np.float32), dets.scores[cols], masks, dets.mask_boxes[cols]
    )
    return out, rows.astype(np.intp)
