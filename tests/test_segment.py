"""Segmented and plain crops: exact pixels, fills, masks moved onto other boxes."""

from __future__ import annotations

import numpy as np
import pytest
from densepeds.errors import InputError, ParameterError
from densepeds.segment import (
    IMAGENET_MEAN_BGR,
    bbox_crop,
    box_region,
    crop_mask,
    crops_for,
    masks_for_boxes,
    segmented_crop,
)
from densepeds.types import Detections

RNG = np.random.default_rng(7)


def random_frame(h: int = 60, w: int = 80) -> np.ndarray:
    frame = RNG.integers(0, 255, (h, w, 3), dtype=np.uint8)
    frame[frame == 255] = 254  # so "exactly white" can only come from the fill
    return frame


def test_segmented_crop_is_white_outside_and_original_inside() -> None:
    frame = random_frame()
    box = (10.4, 5.2, 40.7, 50.0)  # region x 10..41, y 5..50
    mask_box = (15, 0, 45, 30)  # overlaps the box only partly
    mask = RNG.random((30, 30)) > 0.5
    crop = segmented_crop(frame, box, mask, mask_box, "white")
    assert crop.shape == (45, 31, 3)
    expected_person = np.zeros((45, 31), bool)
    # frame rows 5..30 and columns 15..41 are covered by the mask.
    expected_person[0:25, 5:31] = mask[5:30, 0:26]
    original = frame[5:50, 10:41]
    assert np.array_equal(crop[expected_person], original[expected_person])
    assert (crop[~expected_person] == 255).all()


def test_segmented_crop_other_fills() -> None:
    frame = random_frame()
    mask = np.zeros((20, 20), bool)
    mask[5:15, 5:15] = True
    mean_crop = segmented_crop(frame, (0, 0, 20, 20), mask, (0, 0, 20, 20), "mean")
    assert (mean_crop[~mask] == IMAGENET_MEAN_BGR).all()
    assert np.array_equal(mean_crop[mask], frame[:20, :20][mask])
    blur = segmented_crop(frame, (0, 0, 20, 20), mask, (0, 0, 20, 20), "blur")
    assert np.array_equal(blur[mask], frame[:20, :20][mask])
    # A blurred random background is much smoother than the original one.
    assert (
        np.abs(np.diff(blur[~mask].astype(int), axis=0)).mean()
        < np.abs(np.diff(frame[:20, :20][~mask].astype(int), axis=0)).mean()
    )
    with pytest.raises(ParameterError):
        segmented_crop(frame, (0, 0, 20, 20), mask, (0, 0, 20, 20), "pink")


def test_no_mask_means_whole_box_and_bbox_crop_is_plain() -> None:
    frame = random_frame()
    assert np.array_equal(segmented_crop(frame, (3, 4, 20, 30), None, None), frame[4:30, 3:20])
    assert np.array_equal(bbox_crop(frame, (-5, -5, 10, 12)), frame[0:12, 0:10])
    assert box_region((70, 50, 200, 200), 80, 60) == (70, 50, 80, 60)
    # A box entirely outside still gives a 1-px crop, never an empty array.
    assert bbox_crop(frame, (500, 500, 600, 600)).shape == (1, 1, 3)
    with pytest.raises(InputError):
        bbox_crop(frame, (np.nan, 0, 5, 5))


def test_crop_mask_rejects_mismatched_mask() -> None:
    with pytest.raises(InputError):
        crop_mask((0, 0, 10, 10), np.ones((5, 5), bool), (0, 0, 6, 5))


def test_crops_for_features() -> None:
    frame = random_frame()
    mask = np.zeros((10, 10), bool)
    mask[2:8, 2:8] = True
    box = np.array([[0, 0, 10, 10]])
    dets = Detections(box, np.array([1.0]), [mask], box)
    seg = crops_for(frame, dets, "segmented")[0]
    plain = crops_for(frame, dets, "bbox")[0]
    assert (seg[~mask] == 255).all() and np.array_equal(plain, frame[:10, :10])
    with pytest.raises(ParameterError):
        crops_for(frame, dets, "nope")


def test_masks_for_boxes_matches_by_iou() -> None:
    mask_a = np.ones((10, 10), bool)
    mask_b = np.zeros((20, 10), bool)
    dets = Detections(
        np.array([[0, 0, 10, 10], [50, 50, 60, 70]]),
        np.array([0.9, 0.8]),
        [mask_a, mask_b],
        np.array([[0, 0, 10, 10], [50, 50, 60, 70]]),
    )
    gt = np.array([[51, 51, 60, 70], [200, 200, 210, 210], [1, 0, 10, 10]], float)
    out, rows = masks_for_boxes(dets, gt)
    assert rows.tolist() == [0, 2]
    assert out.masks is not None
    assert out.masks[0] is mask_b and out.masks[1] is mask_a
    assert np.allclose(out.boxes, gt[[0, 2]])
