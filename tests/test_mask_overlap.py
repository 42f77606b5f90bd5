"""benchmarks/mask_overlap.py: mask IoU against full bitmaps, and candidate pairs on a constructed
two-frame scene whose answer is known."""

from __future__ import annotations

import sys

import numpy as np
from conftest import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import mask_overlap  # noqa: E402
from densepeds.types import Detections  # noqa: E402


def _paint(frame: np.ndarray, mask: np.ndarray, box: np.ndarray, shift=(0, 0)) -> None:
    """Brute force: the box-local mask pixel by pixel onto a full bitmap (offset 50 px)."""
    for y, x in zip(*np.nonzero(mask), strict=True):
        frame[50 + box[1] + shift[1] + y, 50 + box[0] + shift[0] + x] = True


def test_mask_iou_matches_full_bitmaps() -> None:
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(200):
        boxes, masks = [], []
        for _ in range(2):
            x0, y0 = rng.integers(0, 40, 2)
            w, h = rng.integers(1, 30, 2)
            boxes.append(np.array([x0, y0, x0 + w, y0 + h]))
            masks.append(rng.random((h, w)) < rng.uniform(0.1, 0.9))
        shift = tuple(int(s) for s in rng.integers(-20, 21, 2))
        a, b = np.zeros((200, 200), bool), np.zeros((200, 200), bool)
        _paint(a, masks[0], boxes[0], shift)
        _paint(b, masks[1], boxes[1])
        union = np.count_nonzero(a | b)
        expected = np.count_nonzero(a & b) / union if union else 0.0
        got = mask_overlap.mask_iou(masks[0], boxes[0], masks[1], boxes[1], shift)
        assert abs(got - expected) < 1e-12
        checked += expected > 0
    assert checked > 20  # enough overlapping cases to mean something


def _person(x0: int, left_half: bool) -> tuple[np.ndarray, np.ndarray]:
    """A 20x40 box at x0 whose mask fills its left or its right half."""
    mask = np.zeros((40, 20), bool)
    mask[:, :10] = left_half
    mask[:, 10:] = not left_half
    return np.array([x0, 0, x0 + 20, 40]), mask


def test_pairs_rank_the_continuation_by_mask_where_boxes_tie() -> None:
    # Frame 1: person 1 at x 100 (mask: left half). Frame 2: person 1 at x 102 (left half) and
    # person 2 at x 98 (right half): both boxes overlap frame 1's equally (shift 2 px), but
    # only person 1's mask overlaps its own earlier mask much (8 of 12 columns; 2 of 18).
    b1, m1 = _person(100, True)
    b2, m2 = _person(102, True)
    b3, m3 = _person(98, False)
    frame1 = Detections(b1[None].astype(np.float32), np.ones(1), [m1], b1[None])
    frame2 = Detections(
        np.stack([b2, b3]).astype(np.float32), np.ones(2), [m2, m3], np.stack([b2, b3])
    )
    gt = {
        1: (np.array([1]), b1[None].astype(np.float64), np.ones(1)),
        2: (np.array([1, 2]), np.stack([b2, b3]).astype(np.float64), np.ones(2)),
    }
    pairs = mask_overlap.collect([frame1, frame2], gt, min_iou=0.3)
    assert pairs.same.tolist() == [True, False]
    box, mask = pairs.values[:, 0], pairs.values[:, 1]
    assert box[0] == box[1]  # the boxes cannot tell
    assert abs(mask[0] - 8 / 12) < 1e-12 and abs(mask[1] - 2 / 18) < 1e-12
    # Moved by person 1's ground-truth motion (+2 px): its box and mask coincide with frame 2's.
    assert pairs.values[0, 2] == 1.0 and pairs.values[0, 3] == 1.0
    first = mask_overlap.ranked_first(pairs)
    assert first.shape == (1, len(mask_overlap.MEASURES))
    assert first[0].tolist() == [True, True, True, True]  # argmax ties go to the first pair
    assert mask_overlap.auc(mask[:1], mask[1:]) == 1.0
