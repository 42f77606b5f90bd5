"""The scene's stand-in detector, and its exact ground truth.

For every frame and every person in view, the ground truth row holds the person's full box and
visibility: the share of the person's silhouette that the frame shows (nearer people and the
frame's edge hide the rest). The detector then finds a person with a probability that rises from
0 at ``miss_visibility`` to 0.97 a quarter of the silhouette higher (so mostly covered people are
missed), jitters the box, scores it by visibility, adds false positives, and gives each detection
the person's visible pixels as its mask (made imperfect by the config's mask noise).
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from densepeds.scene.config import SceneConfig
from densepeds.scene.rendering import Labels, Renderer
from densepeds.scene.simulation import Camera
from densepeds.types import Detections

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

__all__ = ["annotate", "mask_box", "noisy_mask"]


def mask_box(cfg: SceneConfig, box: FloatArray) -> npt.NDArray[np.int32]:
    """The integer region of a box clipped to the frame (where its mask lives)."""
    x0 = int(np.clip(np.floor(box[0]), 0, cfg.width))
    y0 = int(np.clip(np.floor(box[1]), 0, cfg.height))
    x1 = int(np.clip(np.ceil(box[2]), x0, cfg.width))
    y1 = int(np.clip(np.ceil(box[3]), y0, cfg.height))
    return np.array([x0, y0, x1, y1], np.int32)


def noisy_mask(
    label: Labels,
    person: int,
    region: npt.NDArray[np.int32],
    dilate: int = 0,
    shift: tuple[int, int] = (0, 0),
) -> BoolArray:
    """The pixels of ``region`` (x0, y0, x1, y1) labelled ``person``, grown by ``dilate`` pixels
    (eroded where negative; by a disc of that radius) and moved by ``shift`` (dx, dy) pixels.
    Exact when both are 0."""
    x0, y0, x1, y1 = (int(v) for v in region)
    pad = abs(dilate) + max(abs(shift[0]), abs(shift[1])) + 1
    h, w = label.shape
    # The person's pixels around the region, moved by the shift (pixels from outside the frame
    # are background).
    px0, py0, px1, py1 = x0 - pad, y0 - pad, x1 + pad, y1 + pad
    window = np.zeros((py1 - py0, px1 - px0), np.uint8)
    sx0, sy0 = max(px0 - shift[0], 0), max(py0 - shift[1], 0)
    sx1, sy1 = min(px1 - shift[0], w), min(py1 - shift[1], h)
    if sx1 > sx0 and sy1 > sy0:
        ox, oy = sx0 - (px0 - shift[0]), sy0 - (py0 - shift[1])
        window[oy : oy + sy1 - sy0, ox : ox + sx1 - sx0] = label[sy0:sy1, sx0:sx1] == person
    if dilate:
        r = abs(dilate)
        kernel = (np.hypot(*np.mgrid[-r : r + 1, -r : r + 1]) <= r + 0.5).astype(np.uint8)  # disc
        op = cv2.dilate if dilate > 0 else cv2.erode
        window = np.asarray(op(window, kernel), np.uint8)
    return window[pad : pad + y1 - y0, pad : pad + x1 - x0].astype(bool)


def _false_positive(cfg: SceneConfig, camera: Camera, rng: np.random.Generator) -> FloatArray:
    x0, x1, y0, y1 = cfg.region
    g = np.array([[rng.uniform(x0, x1), rng.uniform(y0, y1), 0.0]])
    (foot,), (depth,) = camera.project(g)
    h = rng.uniform(0.8, 1.9) * camera.focal / depth
    w = h * rng.uniform(0.25, 0.4)
    return np.array([foot[0] - w / 2, foot[1] - h, foot[0] + w / 2, foot[1]])


def _ellipse_mask(shape: tuple[int, int]) -> BoolArray:
    m = np.zeros(shape, np.uint8)
    if m.size:
        centre = (m.shape[1] // 2, m.shape[0] // 2)
        axes = (max(m.shape[1] // 2, 1), max(m.shape[0] // 2, 1))
        cv2.ellipse(m, centre, axes, 0, 0, 360, 1, -1)
    return m.astype(bool)


def annotate(
    renderer: Renderer, rng: np.random.Generator, noise_rng: np.random.Generator
) -> tuple[FloatArray, dict[int, Detections]]:
    """Ground-truth rows (frame, id, x, y, w, h, 1, 1, visibility) and detections per frame.

    Each detection's ``extra["gt_id"]`` is the person it came from (-1: a false positive).
    ``rng`` drives the detector; ``noise_rng`` only the mask noise, so that turning the noise on
    leaves the boxes, scores and misses as they were.
    """
    cfg = renderer.config
    gt: list[list[float]] = []
    dets: dict[int, Detections] = {}
    for k in range(1, cfg.frames + 1):
        _, label, people = renderer.render(k)
        boxes, scores, masks, mboxes, sources = [], [], [], [], []
        for i, person in people:
            x1, y1, x2, y2 = np.round(person.box).astype(int)
            w, h = max(x2 - x1, 2), max(y2 - y1, 4)
            region = label[max(y1, 0) : max(y1 + h, 0), max(x1, 0) : max(x1 + w, 0)]
            vis = int((region == i).sum()) / max(person.area, 1)
            gt.append([k, i + 1, *person.box[:2], *(person.box[2:] - person.box[:2]), 1, 1, vis])
            p_det = 0.97 * np.clip((vis - cfg.miss_visibility) / 0.25, 0, 1)
            if rng.random() >= p_det:
                continue
            size = person.box[2:] - person.box[:2]
            centre = (person.box[:2] + person.box[2:]) / 2 + rng.normal(0, cfg.box_jitter, 2) * size
            size = size * rng.normal(1.0, cfg.box_jitter, 2).clip(0.8, 1.2)
            box = np.concatenate([centre - size / 2, centre + size / 2])
            mb = mask_box(cfg, box)
            boxes.append(box)
            scores.append(float(np.clip(0.35 + 0.6 * vis + rng.normal(0, 0.05), 0.05, 1.0)))
            shift = (0, 0)
            if cfg.mask_shift:
                dx, dy = noise_rng.integers(-cfg.mask_shift, cfg.mask_shift + 1, 2)
                shift = (int(dx), int(dy))
            masks.append(noisy_mask(label, i, mb, cfg.mask_dilate, shift))
            mboxes.append(mb)
            sources.append(i + 1)
        for _ in range(rng.poisson(cfg.false_positives)):
            box = _false_positive(cfg, renderer.camera, rng)
            mb = mask_box(cfg, box)
            boxes.append(box)
            scores.append(float(rng.uniform(0.1, 0.5)))
            masks.append(_ellipse_mask((int(mb[3] - mb[1]), int(mb[2] - mb[0]))))
            mboxes.append(mb)
            sources.append(-1)
        if boxes:
            extra = {"gt_id": np.array(sources, np.int64)}
            dets[k] = Detections(np.array(boxes), np.array(scores), masks, np.array(mboxes), extra)
    return np.array(gt, np.float64).reshape(-1, 9), dets
