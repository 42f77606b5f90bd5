"""densepeds.Pipeline: what each stage hands the next, where detections come from, timings, and
the whole tracker on the built-in scene."""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pytest
from densepeds.errors import InputError, ParameterError
from densepeds.pipeline import Pipeline, StageTimes, track_rows
from densepeds.scene import Scene, make_scene
from densepeds.types import Detections


class _Tracks(NamedTuple):
    ids: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray
    det_index: np.ndarray


class RecordingTracker:
    """Returns every detection as a track with id = 100 + index, and records its inputs."""

    def __init__(self) -> None:
        self.calls: list[tuple[np.ndarray, np.ndarray, np.ndarray | None]] = []

    def update(self, boxes: np.ndarray, scores: np.ndarray, embeddings: Any = None) -> _Tracks:
        self.calls.append((boxes, scores, embeddings))
        n = len(boxes)
        return _Tracks(np.arange(100, 100 + n), boxes, scores, np.arange(n))

    def reset(self) -> None:
        self.calls.clear()


class FixedDetector:
    def __init__(self) -> None:
        self.frames = 0

    def __call__(self, frame: np.ndarray) -> Detections:
        self.frames += 1
        return Detections([[1, 2, 11, 42], [20, 5, 30, 45]], [0.9, 0.4])


class RecordingEmbedder:
    def __init__(self) -> None:
        self.kinds: list[str] = []

    def embed(self, frame: np.ndarray, dets: Detections, features: str = "segmented") -> np.ndarray:
        self.kinds.append(features)
        e = np.ones((len(dets), 4), np.float32)
        return e / 2


FRAME = np.zeros((48, 64, 3), np.uint8)


def test_step_runs_detection_features_and_tracking() -> None:
    tracker, embedder, detector = RecordingTracker(), RecordingEmbedder(), FixedDetector()
    pipe = Pipeline(detector, reid=embedder, features="bbox", tracker=tracker)
    tracks = pipe.step(FRAME)
    boxes, scores, emb = tracker.calls[-1]
    assert boxes.dtype == np.float64 and boxes.shape == (2, 4)
    np.testing.assert_allclose(scores, [0.9, 0.4])
    assert emb is not None and emb.shape == (2, 4) and embedder.kinds == ["bbox"]
    assert list(tracks.ids) == [100, 101]
    assert track_rows(7, tracks)[1] == (7, 101, 20.0, 5.0, 30.0, 45.0, pytest.approx(0.4))
    # Given detections win over the detector; no frame = no appearance features.
    pipe.step(None, Detections([[0, 0, 5, 5]], [1.0]))
    assert detector.frames == 1 and tracker.calls[-1][2] is None and len(embedder.kinds) == 1
    # features="none" never embeds, even with a frame.
    pipe2 = Pipeline(detector, reid=embedder, features="none", tracker=tracker)
    pipe2.step(FRAME)
    assert tracker.calls[-1][2] is None and len(embedder.kinds) == 1
    assert pipe.times.frames == 2 and pipe.times.seconds["detection"] > 0


def test_run_frames_yields_the_detectors_detections(tmp_path: Path) -> None:
    import cv2

    for k in range(1, 4):
        cv2.imwrite(str(tmp_path / f"{k:06d}.png"), FRAME)
    detector = FixedDetector()
    pipe = Pipeline(detector, features="none", tracker=RecordingTracker())
    results = list(pipe.run_frames(tmp_path))
    assert [r.frame_no for r in results] == [1, 2, 3] and detector.frames == 3
    for r in results:
        np.testing.assert_array_equal(r.detections.boxes, [[1, 2, 11, 42], [20, 5, 30, 45]])
        np.testing.assert_allclose(r.detections.scores, [0.9, 0.4])
        assert list(r.tracks.det_index) == [0, 1]


def test_bad_options_and_inputs_are_clear_errors() -> None:
    tracker = RecordingTracker()
    with pytest.raises(ParameterError, match="motion"):
        Pipeline(motion="teleport", tracker=tracker)
    with pytest.raises(ParameterError, match="features"):
        Pipeline(features="colour", tracker=tracker)
    with pytest.raises(ParameterError, match="detector"):
        Pipeline("fasterrcnn", tracker=tracker)
    pipe = Pipeline(reid=RecordingEmbedder(), tracker=tracker)
    with pytest.raises(InputError, match="no detector"):
        pipe.step(FRAME)
    with pytest.raises(InputError, match="BGR uint8"):
        pipe.step(FRAME.astype(np.float32), Detections.empty())
    with pytest.raises(InputError, match="needs a frame"):
        pipe.step()
    with pytest.raises(InputError, match=r"\[N, D\]"):
        pipe.step(None, Detections([[0, 0, 1, 1]], [1]), embeddings=np.zeros((3, 4), np.float32))


def _det_only_sequence(root: Path, length: int = 5) -> Path:
    seq = root / "S"
    (seq / "det").mkdir(parents=True)
    (seq / "seqinfo.ini").write_text(
        f"[Sequence]\nname=S\nimDir=img1\nframeRate=10\nseqLength={length}\nimWidth=64\n"
        "imHeight=48\nimExt=.jpg\n"
    )
    (seq / "det" / "det.txt").write_text(
        "1,-1,1,1,10,20,0.9\n2,-1,2,1,10,20,0.8\n2,-1,30,1,10,20,0.7\n4,-1,3,1,10,20,0.9\n"
    )
    return seq


def test_run_reads_a_sequence_det_file_and_respects_the_range(tmp_path: Path) -> None:
    seq = _det_only_sequence(tmp_path)
    tracker = RecordingTracker()
    pipe = Pipeline(tracker=tracker)
    out = list(pipe.run(seq, frames="2:4"))
    assert [n for n, _ in out] == [2, 3, 4]
    assert [len(t.ids) for _, t in out] == [2, 0, 1]  # frame 3 has no detections
    assert pipe.times.frames == 3
    # Explicit detections override the sequence's own.
    own = {3: Detections([[5, 5, 9, 9]], [0.5])}
    assert [len(t.ids) for _, t in Pipeline(tracker=tracker).run(seq, "2:4", own)] == [0, 1, 0]
    # A detector needs frames, which this sequence lacks.
    with pytest.raises(InputError, match="no images"):
        list(Pipeline(FixedDetector(), tracker=tracker).run(seq))


def test_stage_times_breakdown() -> None:
    t = StageTimes()
    t.seconds.update(decode=0.1, detection=0.3, reid=0.1, tracking=0.05, output=0.05)
    t.frames = 10
    assert t.fps == pytest.approx(16.666, rel=1e-3)
    assert t.per_frame_ms()["detection"] == pytest.approx(30.0)
    assert "detection 30.0" in t.breakdown()


@pytest.fixture(scope="module")
def scene() -> Scene:
    return make_scene(seed=0, frames=80)


def test_real_tracker_on_the_scene(scene: Scene, tmp_path: Path) -> None:
    """The whole method (detections with masks, segmented features, FRVO) beats a floor."""
    from densepeds.evaluate import evaluate
    from densepeds.io.mot import write_tracks

    seq = scene.write(tmp_path, images=False)
    results = {}
    for features in ("segmented", "none"):
        pipe = Pipeline(reid=scene.embedder(), motion="frvo", features=features)
        rows = []
        for frame_no, tracks in pipe.run(scene):
            assert tracks.ids.dtype == np.int64 and tracks.boxes.shape == (len(tracks.ids), 4)
            assert len(set(tracks.ids.tolist())) == len(tracks.ids)  # ids unique per frame
            rows += track_rows(frame_no, tracks)
        write_tracks(tmp_path / f"{features}.txt", rows)
        results[features] = evaluate([seq], tmp_path / f"{features}.txt").combined
    assert results["segmented"]["MOTA"] > 50
    assert results["segmented"]["IDF1"] > 40
    # Appearance keeps identities that motion alone swaps in the crowd.
    assert results["segmented"]["IDF1"] > results["none"]["IDF1"] + 5
    assert results["segmented"]["IDSW"] < results["none"]["IDSW"]


def _greedy_nms_reference(boxes: np.ndarray, scores: np.ndarray, thr: float) -> list[int]:
    """Textbook greedy NMS, one pair at a time."""

    def iou(a: np.ndarray, b: np.ndarray) -> float:
        w = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
        h = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
        inter = w * h
        union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
        return inter / union

    kept: list[int] = []
    for i in sorted(range(len(boxes)), key=lambda k: (-scores[k], k)):
        if all(iou(boxes[i], boxes[k]) <= thr for k in kept):
            kept.append(i)
    return sorted(kept)


def test_suppress_duplicates_matches_greedy_nms_on_random_boxes() -> None:
    from densepeds.pipeline import suppress_duplicates

    rng = np.random.default_rng(3)
    for _ in range(30):
        n = int(rng.integers(0, 25))
        xy = rng.uniform(0, 100, (n, 2))
        wh = rng.uniform(5, 40, (n, 2))
        boxes = np.c_[xy, xy + wh].astype(np.float32)
        scores = rng.choice([0.3, 0.5, 0.9], n).astype(np.float32)  # ties: index order
        dets = Detections(boxes, scores)
        for thr in (0.3, 0.6):
            got = suppress_duplicates(dets, iou=thr).tolist()
            assert got == _greedy_nms_reference(boxes, scores, thr)
        assert suppress_duplicates(dets).tolist() == list(range(n))  # defaults keep all


def _masked(boxes: list[list[int]], scores: list[float], fills: list[slice]) -> Detections:
    """Detections whose masks cover the given column slices of their (integer) boxes."""
    masks = []
    for b, cols in zip(boxes, fills, strict=True):
        m = np.zeros((b[3] - b[1], b[2] - b[0]), bool)
        m[:, cols] = True
        masks.append(m)
    return Detections(np.array(boxes, np.float32), scores, masks, np.array(boxes))


def test_suppress_duplicates_by_containment_and_masks() -> None:
    from densepeds.pipeline import suppress_duplicates

    # A tile-cut half body (index 1) inside the whole-body box of the same person.
    dets = Detections([[0, 0, 20, 60], [0, 0, 20, 28], [40, 0, 60, 60]], [0.95, 0.9, 0.5])
    assert suppress_duplicates(dets, containment=0.8).tolist() == [0, 2]
    # Only the box inside a better one goes: a better half body leaves the whole body be.
    dets.scores[:] = [0.9, 0.95, 0.5]
    assert suppress_duplicates(dets, containment=0.8).tolist() == [0, 1, 2]
    # Boxes overlapping by IoU 0.6: two people (disjoint masks) or one (same mask).
    boxes = [[0, 0, 40, 80], [10, 0, 50, 80]]
    two = _masked(boxes, [0.9, 0.6], [slice(0, 15), slice(25, 40)])
    one = _masked(boxes, [0.9, 0.6], [slice(10, 40), slice(0, 30)])
    assert suppress_duplicates(two, mask_overlap=0.5).tolist() == [0, 1]
    assert suppress_duplicates(one, mask_overlap=0.5).tolist() == [0]
    assert suppress_duplicates(one, mask_overlap=0.5, mask_min_iou=0.7).tolist() == [0, 1]
    assert suppress_duplicates(two, iou=0.5).tolist() == [0]  # boxes alone cannot tell


def test_cnn_detections_are_filtered_and_det_index_refers_to_the_input() -> None:
    tracker, embedder = RecordingTracker(), RecordingEmbedder()
    dets = Detections(
        [[0, 0, 10, 40], [1, 0, 11, 40], [40, 0, 50, 40], [60, 0, 70, 40]],
        [0.9, 0.8, 0.05, 0.6],
    )
    emb = np.arange(16, dtype=np.float32).reshape(4, 4)
    pipe = Pipeline(FixedDetector(), reid=embedder, tracker=tracker, min_score=0.1, nms_iou=0.5)
    assert pipe.detection_options["min_score"] == 0.1
    tracks = pipe.step(FRAME, dets, embeddings=emb)
    boxes, scores, got_emb = tracker.calls[-1]
    np.testing.assert_allclose(scores, [0.9, 0.6])  # the duplicate and the low score dropped
    np.testing.assert_array_equal(got_emb, emb[[0, 3]])
    assert tracks.det_index.tolist() == [0, 3]
    # Detections from a det file (no detector) are tracked as given.
    plain = Pipeline(None, reid=embedder, tracker=RecordingTracker())
    assert plain.detection_options == {}
    assert len(plain.step(None, dets).ids) == 4


def test_cnn_preset_applies_only_to_cnn_detections() -> None:
    from densepeds.pipeline import DEFAULT_FEATURES, FEATURES, default_features
    from densepeds.presets import PRESETS
    from densepeds.tracking import Tracker

    cnn = Pipeline("yoloseg")  # the model is loaded on first use only
    yolo = PRESETS["yoloseg"]
    assert cnn.preset is yolo and cnn.detection_options == yolo.detection
    for key, value in yolo.tracker.items():
        assert cnn.tracker.params[key] == value, key
    # The caller's values win over the preset.
    mine = Pipeline("yoloseg", min_score=0.5, n_init=4)
    assert mine.detection_options["min_score"] == 0.5 and mine.tracker.params["n_init"] == 4
    # A det file keeps the tracker's own defaults and every detection.
    plain = Pipeline(None)
    assert plain.detection_options == {} and plain.tracker.params == Tracker().params
    assert DEFAULT_FEATURES in FEATURES and default_features(True) == DEFAULT_FEATURES
    assert default_features(False) == "none"
