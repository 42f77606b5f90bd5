"""The built-in dense-crowd scene: determinism, density, perspective, occlusion by depth, the
detector model, mask noise, export."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from densepeds.evaluate import evaluate
from densepeds.io.mot import read_detections, read_seqinfo, write_tracks
from densepeds.scene import HistogramEmbedder, Scene, make_crossing_scene, make_scene
from densepeds.scene.detector import noisy_mask
from scipy import ndimage


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


def _identity_scores(scene: Scene, kind: str) -> tuple[float, float]:
    """Mean cosine margin (same person - different people) and rank-1 accuracy between the
    detections of frames k and k + 4, over a few k."""
    emb = HistogramEmbedder()
    margins, rank1 = [], []
    for k in (10, 20, 30, 40):
        a, b = scene.detections[k], scene.detections[k + 4]
        ea, eb = emb.embed(scene.frame(k), a, kind), emb.embed(scene.frame(k + 4), b, kind)
        assert ea.dtype == np.float32 and np.allclose(np.linalg.norm(ea, axis=1), 1, atol=1e-5)
        sim = ea @ eb.T
        ga, gb = a.extra["gt_id"], b.extra["gt_id"]
        same = (ga[:, None] == gb[None, :]) & (ga[:, None] > 0)
        margins.append(sim[same].mean() - sim[~same].mean())
        rows = np.flatnonzero(same.any(1))
        rank1.append(float(np.mean(same[rows, sim[rows].argmax(1)])))
    return float(np.mean(margins)), float(np.mean(rank1))


def test_exact_masks_identify_people_better_than_boxes(scene: Scene) -> None:
    """With exact masks (the default) counting only the person's pixels beats the whole box:
    true by construction (the mask holds no neighbour), which is why mask noise exists."""
    scores = {k: _identity_scores(scene, k) for k in ("segmented", "masked_pool", "bbox")}
    assert scores["masked_pool"][0] > scores["bbox"][0] > 0
    assert scores["segmented"][1] > scores["bbox"][1]
    assert scores["masked_pool"][1] > 0.9


def test_mask_noise_makes_masked_features_less_distinctive() -> None:
    exact = make_scene(seed=3, frames=50)
    noisy = make_scene(seed=3, frames=50, mask_dilate=4, mask_shift=4)
    # The noise touches the masks only: the same people are found in the same boxes.
    np.testing.assert_array_equal(noisy.detections[20].boxes, exact.detections[20].boxes)
    assert noisy.detections[20].masks is not None and exact.detections[20].masks is not None
    assert any(
        not np.array_equal(m, e)
        for m, e in zip(noisy.detections[20].masks, exact.detections[20].masks, strict=True)
    )
    assert _identity_scores(noisy, "masked_pool")[0] < _identity_scores(exact, "masked_pool")[0]


def test_noisy_mask_matches_scipy_morphology() -> None:
    rng = np.random.default_rng(5)
    label = np.full((40, 50), -1, np.int32)
    label[10:30, 15:28] = 3
    label[rng.random(label.shape) < 0.1] = -1  # holes
    label[12:20, 30:40] = 3  # a second blob that reaches past the region's right edge
    region = np.array([12, 5, 36, 35], np.int32)
    for dilate in (0, 2, -1):
        for shift in ((0, 0), (3, -2), (-4, 5)):
            got = noisy_mask(label, 3, region, dilate, shift)
            person = label == 3
            moved = np.zeros_like(person)
            for y, x in zip(*np.nonzero(person), strict=True):
                if 0 <= y + shift[1] < person.shape[0] and 0 <= x + shift[0] < person.shape[1]:
                    moved[y + shift[1], x + shift[0]] = True
            r = abs(dilate)
            disk = np.hypot(*np.mgrid[-r : r + 1, -r : r + 1]) <= r + 0.5
            padded = np.pad(moved, r + 1)
            if dilate > 0:
                padded = ndimage.binary_dilation(padded, disk)
            elif dilate < 0:
                padded = ndimage.binary_erosion(padded, disk, border_value=0)
            want = padded[r + 1 : -(r + 1), r + 1 : -(r + 1)][5:35, 12:36]
            np.testing.assert_array_equal(got, want, err_msg=f"dilate {dilate} shift {shift}")


def test_nearer_people_cover_farther_ones(scene: Scene) -> None:
    """Each pixel shows the nearest person whose silhouette covers it (a z-buffer reference)."""
    renderer = scene.renderer
    for k in (15, 35):
        _, label, people = scene.render(k)
        depth = np.full(label.shape, np.inf)
        nearest = np.full(label.shape, -1, np.int32)
        for i, person in people:
            x1, y1, x2, y2 = np.round(person.box).astype(int)
            w, h = max(x2 - x1, 2), max(y2 - y1, 4)
            body = np.zeros(label.shape, bool)
            sil = np.any(renderer.silhouette(w, h, person.phase), axis=0).astype(bool)
            ys, xs = np.nonzero(sil)
            ok = (ys + y1 >= 0) & (ys + y1 < label.shape[0]) & (xs + x1 >= 0)
            ok &= xs + x1 < label.shape[1]
            body[ys[ok] + y1, xs[ok] + x1] = True
            closer = body & (person.depth < depth)
            depth[closer], nearest[closer] = person.depth, i
        np.testing.assert_array_equal(label, nearest)
        # Somebody is partly covered in a crowd.
        assert (scene.gt_rows[scene.gt_rows[:, 0] == k, 8] < 0.5).any()


def test_crossing_scene_hides_a_walker_for_a_few_frames() -> None:
    for same_direction in (True, False):
        scene = make_crossing_scene(same_direction=same_direction)
        spans = scene.occlusions()
        assert len(spans) == 1
        span = spans[0]
        assert span.person == 2 and 4 <= span.frames <= 12
        vis, found = scene.visibility(), scene.detected()
        hidden = slice(span.first - 1, span.last)
        assert np.nanmax(vis[hidden, 1]) < 0.25 and found[hidden, 0].all()
        assert not found[span.first + span.frames // 2 - 1, 1]  # missed while covered
        # Seen and detected before and after, with one id each in the ground truth.
        assert found[: span.first - 5, 1].all() and found[span.last + 5 :, 1].all()
        assert set(scene.gt_rows[:, 1].astype(int)) == {1, 2}


def test_matched_ids_follow_the_people_a_tracker_reports(scene: Scene) -> None:
    gt = scene.gt_rows
    boxes = np.column_stack([gt[:, 2:4], gt[:, 2:4] + gt[:, 4:6]])
    rows = np.column_stack([gt[:, 0], gt[:, 1] + 100, boxes, np.ones(len(gt))])
    # Person 5's track swaps to id 999 from frame 30; frame 10 is not reported at all.
    rows[(gt[:, 1] == 5) & (gt[:, 0] >= 30), 1] = 999
    rows = rows[rows[:, 0] != 10]
    ids = scene.matched_ids(rows)
    vis = scene.visibility()
    for k in (5, 20, 40):
        seen = ~np.isnan(vis[k - 1])
        people = np.flatnonzero(seen) + 1
        want = np.where(people == 5, 999 if k >= 30 else 105, people + 100)
        np.testing.assert_array_equal(ids[k - 1, seen], want)
        assert (ids[k - 1, ~seen] == 0).all()
    assert (ids[9] == 0).all()
    # Boxes away from everybody match nobody.
    moved = rows.copy()
    moved[:, 2:6] += 2000.0  # off the frame
    assert (scene.matched_ids(moved) == 0).all()


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
