"""The detector's closer look at people the tracker reports without a detection (focus_scale,
``densepeds run --focus-lost``)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from conftest import shared_path
from densepeds.cli import main
from densepeds.detect import onnxutil
from densepeds.detect.yoloseg import YoloSegDetector
from densepeds.errors import ParameterError
from densepeds.pipeline import Pipeline
from densepeds.types import Detections
from test_detect import video_frames

YOLO = "yolov8n-seg-320-int8.onnx"


def _frames(*numbers: int) -> list[np.ndarray]:
    video = shared_path("data", "MOT20-01-dev", "MOT20-01-raw.mp4")
    found = video_frames(video, list(numbers))
    return [found[k] for k in numbers]


@pytest.mark.parametrize("scale", [-1.0, float("inf"), float("nan")])
def test_a_bad_focus_scale_is_refused(scale: float) -> None:
    with pytest.raises(ParameterError, match="focus_scale"):
        YoloSegDetector(shared_path("models", YOLO), focus_scale=scale)


def test_each_focus_box_adds_one_view_to_the_next_frame_only() -> None:
    (frame,) = _frames(1)
    det = YoloSegDetector(shared_path("models", YOLO), tiles=(3, 2), focus_scale=2.5)
    det(frame)
    assert det.last_views == 6
    box = [400.0, 200.0, 430.0, 280.0]
    det.focus([box, [0.0, 0.0, 2.0, 3.0]])  # the second is cut below MIN_FOCUS_SIDE: skipped
    (view,) = det.focus_views(960, 540)
    # The input's shape (cut to the 3x2 tiles' shape, fit_input), its longer side 2.5 heights.
    assert (det.input_h, det.input_w) == (288, 320)
    assert (view.tile.x0, view.tile.y0, view.tile.x1, view.tile.y1) == (315, 150, 515, 330)
    assert view.tile.x1 - view.tile.x0 == 2.5 * 80
    found = det(frame)
    assert det.last_views == 7 and len(found) > 10
    det(frame)
    assert det.last_views == 6  # used once
    off = YoloSegDetector(shared_path("models", YOLO), tiles=(3, 2), focus_scale=0)
    off.focus([box])
    off(frame)
    assert off.last_views == 6  # focus_scale 0: no closer look


def test_the_tile_choice_learns_only_from_the_detections_kept_from_the_tiles(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    frames = _frames(1, 2, 3)
    det = YoloSegDetector(shared_path("models", YOLO), focus_scale=2.5)
    kept_from: list[np.ndarray] = []  # per frame: the view of each kept detection
    observed: list[int] = []
    merge, observe = det._merge, det.people_tiles.observe

    def spy_merge(*args: Any) -> Any:
        found = merge(*args)
        kept_from.append(found.view_idx.copy())
        return found

    def spy_observe(boxes: Any, *args: Any) -> None:
        observed.append(len(boxes))
        observe(boxes, *args)

    monkeypatch.setattr(det, "_merge", spy_merge)
    monkeypatch.setattr(det.people_tiles, "observe", spy_observe)
    from_focus = 0
    for k, frame in enumerate(frames):
        tiles = len(det.views(960, 540))
        found = det(frame)
        det.focus(found.boxes[:5])
        assert det.last_views == tiles + (5 if k else 0)
        assert observed[-1] == int((kept_from[-1] < tiles).sum())
        from_focus += int((kept_from[-1] >= tiles).sum())
    assert from_focus > 0  # the focus views' detections are kept, and not observed


class _Detector:
    """One person at a fixed box for ``seen`` frames, then nobody; remembers its focus boxes."""

    def __init__(self, seen: int) -> None:
        self.seen = seen
        self.calls = 0
        self.focused: list[np.ndarray] = []

    def __call__(self, frame: np.ndarray) -> Detections:
        self.calls += 1
        if self.calls > self.seen:
            return Detections.empty()
        return Detections(np.array([[100, 100, 140, 200]], np.float32), np.array([0.9]))

    def focus(self, boxes: Any) -> None:
        self.focused.append(np.asarray(boxes))


def test_the_pipeline_focuses_the_detector_on_the_tracks_reported_without_a_detection() -> None:
    det = _Detector(seen=10)
    pipe = Pipeline(det, features="none", output_lost_adaptive=False)
    frame = np.zeros((300, 400, 3), np.uint8)
    lost_shown = 0
    for k in range(14):
        tracks = pipe.step(frame)
        expected = tracks.boxes[tracks.det_index < 0]
        assert np.array_equal(det.focused[k], expected)
        lost_shown += len(expected)
    assert lost_shown > 0  # the person lost after frame 10 was reported, and looked for


def test_focus_lost_without_the_detector_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    seq = shared_path("data", "TUD-Stadtmitte")
    rc = main(["run", str(seq), "--focus-lost", "2.5", "--frames", "1:2"])
    err = capsys.readouterr().err
    assert rc == 2 and "--focus-lost" in err and len(err.strip().splitlines()) == 1


def test_many_views_run_a_few_at_a_time_with_the_same_detections(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Focus views grow with the people lost: the detector runs VIEWS_PER_THREAD views per
    thread at a time (letterboxed, run and reduced to their candidates: bounded memory), and
    finds exactly what one call on them all finds."""
    import densepeds.detect.yoloseg as yoloseg

    (frame,) = _frames(100)
    boxes = [[x, 250.0, x + 20.0, 300.0] for x in range(60, 900, 60)]  # 14 people, 960 x 540
    found = {}
    for per_thread in (yoloseg.VIEWS_PER_THREAD, 100):
        monkeypatch.setattr(yoloseg, "VIEWS_PER_THREAD", per_thread)
        det = YoloSegDetector(shared_path("models", YOLO), tiles=(3, 2), focus_scale=2.5)
        det.views(*frame.shape[1::-1])  # the input cut to the tiles' shape (and probed) first
        calls: list[int] = []
        infer = det._infer
        monkeypatch.setattr(
            det, "_infer", lambda x, infer=infer, calls=calls: calls.append(len(x)) or infer(x)
        )
        det.focus(boxes)
        found[per_thread] = det(frame)
        assert det.last_views == 6 + len(boxes)
        most = per_thread * onnxutil.available_cpus()
        assert sum(calls) == 20 and max(calls) <= most and len(calls) == -(-20 // most)
    small, whole = found[yoloseg.VIEWS_PER_THREAD], found[100]
    assert len(small) > 20
    assert np.array_equal(small.boxes, whole.boxes) and np.array_equal(small.scores, whole.scores)
    assert all(np.array_equal(a, b) for a, b in zip(small.masks, whole.masks, strict=True))
