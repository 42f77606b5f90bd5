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
        return Detections([[1, 2, 11, 32], [20, 5, 30, 40]], [0.9, 0.4])


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
    assert track_rows(7, tracks)[1] == (7, 101, 20.0, 5.0, 30.0, 40.0, pytest.approx(0.4))
    # Given detections win over the detector; no frame = no appearance features.
    pipe.step(None, Detections([[0, 0, 5, 5]], [1.0]))
    assert detector.frames == 1 and tracker.calls[-1][2] is None and len(embedder.kinds) == 1
    # features="none" never embeds, even with a frame.
    pipe2 = Pipeline(detector, reid=embedder, features="none", tracker=tracker)
    pipe2.step(FRAME)
    assert tracker.calls[-1][2] is None and len(embedder.kinds) == 1
    assert pipe.times.frames == 2 and pipe.times.seconds["detection"] > 0


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
    pytest.importorskip("densepeds.tracking", reason="needs densepeds.tracking (engineer assoc)")
    return make_scene(seed=0, frames=80)


def test_real_tracker_on_the_scene(scene: Scene, tmp_path: Path) -> None:
    """The whole method (detections with masks, segmented features, FRVO) beats a floor."""
    from densepeds.evaluate import evaluate
    from densepeds.motio import write_tracks

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
