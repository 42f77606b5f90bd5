"""The built-in dense-crowd scene: determinism, density, perspective, detector model, export."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from densepeds.evaluate import evaluate
from densepeds.motio import read_detections, read_seqinfo, write_tracks
from densepeds.scene import HistogramEmbedder, Scene, make_scene


@pytest.fixture(scope="module")
def scene() -> Scene:
    return make_scene(seed=3, frames=60)


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(rb - lt, 0, None), axis=2)
    area = lambda z: np.prod(z[:, 2:] - z[:, :2], axis=1)  # noqa: E731
    return inter / (area(a)[:, None] + area(b)[None, :] - inter)


def _gt_boxes(scene: Scene, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rows = scene.gt_rows[scene.gt_rows[:, 0] == frame]
    boxes = np.column_stack([rows[:, 2:4], rows[:, 2:4] + rows[:, 4:6]])
    return rows[:, 1].astype(int), boxes, rows[:, 8]


def test_same_seed_same_scene() -> None:
    first, again = make_scene(seed=3, frames=20), make_scene(seed=3, frames=20)
    np.testing.assert_array_equal(again.gt_rows, first.gt_rows)
    np.testing.assert_array_equal(again.detections[15].boxes, first.detections[15].boxes)
    np.testing.assert_array_equal(again.frame(15), first.frame(15))
    other = make_scene(seed=4, frames=20)
    assert not np.array_equal(other.frame(15), first.frame(15))


def test_dense_crowd_seen_in_perspective(scene: Scene) -> None:
    assert scene.local_density() >= 2.0
    assert 30 <= scene.positions.shape[1] <= 80
    ids, _, _ = _gt_boxes(scene, 30)
    assert len(ids) >= 20
    # Further away = higher in the image = smaller: boxes whose feet are low in the frame are
    # wider than those whose feet are high.
    gt = scene.gt_rows
    width, foot = gt[:, 4], gt[:, 3] + gt[:, 5]
    assert np.corrcoef(width, foot)[0, 1] > 0.6
    near, far = foot > np.quantile(foot, 0.8), foot < np.quantile(foot, 0.2)
    assert width[near].mean() > 1.3 * width[far].mean()


def test_detector_misses_occluded_people_and_adds_false_positives(scene: Scene) -> None:
    hit_low, n_low, hit_high, n_high, fps = 0, 0, 0, 0, 0
    for k in range(1, scene.config.frames + 1):
        ids, gt, vis = _gt_boxes(scene, k)
        dets = scene.detections.get(k)
        if dets is None or not len(gt):
            continue
        source = dets.extra["gt_id"]
        detected = np.isin(ids, source)
        hit_low += int(detected[vis < 0.1].sum())
        n_low += int((vis < 0.1).sum())
        hit_high += int(detected[vis > 0.6].sum())
        n_high += int((vis > 0.6).sum())
        fps += int((source < 0).sum())
        # A detection lies near its person: jittered, not moved to someone else.
        own = {i: b for i, b in zip(ids, gt, strict=True)}
        for j in np.flatnonzero(source > 0):
            iou = _iou(own[source[j]][None], dets.boxes[j : j + 1].astype(float))
            assert iou[0, 0] > 0.5
    assert n_low > 0 and hit_low == 0  # hidden people are never detected
    assert hit_high / n_high > 0.85  # visible ones nearly always
    assert fps > 5  # there are false positives


def test_masks_cover_the_visible_person(scene: Scene) -> None:
    dets = scene.detections[20]
    assert dets.masks is not None and dets.mask_boxes is not None
    frame = scene.frame(20)
    background = scene._background
    inside = 0
    for mask, (x0, y0, x1, y1) in zip(dets.masks, dets.mask_boxes, strict=True):
        assert mask.shape == (y1 - y0, x1 - x0)
        if mask.sum() > 20:
            crop = frame[y0:y1, x0:x1][mask].astype(int)
            bg = background[y0:y1, x0:x1][mask].astype(int)
            # Mask pixels are painted figure, not the ground behind it.
            inside += int(np.mean(np.abs(crop - bg).sum(1) > 10) > 0.9)
    assert inside >= 0.8 * sum(int(m.sum() > 20) for m in dets.masks)


def test_segmented_histograms_identify_people_better_than_boxes(scene: Scene) -> None:
    emb = HistogramEmbedder()
    a, b = scene.detections[20], scene.detections[24]
    margins, rank1 = {}, {}
    for kind in ("segmented", "bbox"):
        ea, eb = emb.embed(scene.frame(20), a, kind), emb.embed(scene.frame(24), b, kind)
        assert ea.dtype == np.float32 and np.allclose(np.linalg.norm(ea, axis=1), 1, atol=1e-5)
        sim = ea @ eb.T
        ga, gb = a.extra["gt_id"], b.extra["gt_id"]
        same = (ga[:, None] == gb[None, :]) & (ga[:, None] > 0)
        margins[kind] = sim[same].mean() - sim[~same].mean()
        rows = np.flatnonzero(same.any(1))
        rank1[kind] = float(np.mean(same[rows, sim[rows].argmax(1)]))
    assert margins["segmented"] > margins["bbox"] > 0
    assert rank1["segmented"] > 0.9 and rank1["segmented"] > rank1["bbox"]


def test_written_sequence_reads_back_and_perfect_tracks_score_100(
    scene: Scene, tmp_path: Path
) -> None:
    seq = scene.write(tmp_path, images=True)
    info = read_seqinfo(seq)
    assert (info.length, info.width, info.height) == (60, 640, 480)
    assert len(list((seq / "img1").glob("*.jpg"))) == 60
    dets = read_detections(seq / "det" / "det.txt")
    np.testing.assert_allclose(dets[10].boxes, scene.detections[10].boxes, atol=0.01)
    gt = scene.gt_rows
    rows = np.column_stack([gt[:, :2], gt[:, 2:4], gt[:, 2:4] + gt[:, 4:6], np.ones(len(gt))])
    write_tracks(tmp_path / "perfect.txt", rows)
    result = evaluate([seq], tmp_path / "perfect.txt")
    assert result.combined["MOTA"] == pytest.approx(100.0)
    assert result.combined["IDSW"] == 0
