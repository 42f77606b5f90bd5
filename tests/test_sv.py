"""supervision.Detections in and out of Tracker.update and Pipeline.step (densepeds.sv_adapter)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pytest
from conftest import REPO, shared_path
from densepeds.errors import InputError
from densepeds.pipeline import Pipeline
from densepeds.tracking import Tracker
from densepeds.types import Detections

sv = pytest.importorskip("supervision")

H, W = 120, 240


def _frame_dets(
    f: int, hide: tuple[int, ...] = (), compact: bool = False, conf: bool = True
) -> sv.Detections:
    """Three people walking right, person k at x = 10 + 70 k + 2 f; ``hide`` leaves some out."""
    people = [k for k in range(3) if k not in hide]
    xyxy = np.array([[10 + 70 * k + 2 * f, 20, 40 + 70 * k + 2 * f, 100] for k in people], float)
    mask = np.zeros((len(people), H, W), bool)
    for j, (x1, y1, x2, y2) in enumerate(xyxy.astype(int).tolist()):
        mask[j, y1 + 5 : y2 - 5, x1 + 3 : x2 - 3] = True  # inside the box, not the whole box
    return sv.Detections(
        xyxy=xyxy.reshape(-1, 4),
        mask=sv.CompactMask.from_dense(mask, xyxy, (H, W)) if compact else mask,
        confidence=np.array([0.9, 0.8, 0.7])[people] if conf else None,
        class_id=np.array([0, 0, 0])[people],
        data={"class_name": np.array(["person"] * len(people)), "person": np.array(people)},
    )


def _plain(d: sv.Detections) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float32]]:
    return d.xyxy, (np.ones(len(d), np.float32) if d.confidence is None else d.confidence)


def test_ids_and_coasted_rows_follow_the_plain_tracker() -> None:
    sv_tracker, plain = Tracker(), Tracker()
    hidden = (9, 10)  # person 1 missed by the detector: coasted
    for f in range(14):
        d = _frame_dets(f, hide=(1,) if f in hidden else ())
        given = d[np.arange(len(d))]  # a copy, to see the input is not changed
        out = sv_tracker.update(d)
        ref = plain.update(*_plain(d))
        assert d.tracker_id is None and "coasted" not in d.data
        assert np.array_equal(d.xyxy, given.xyxy)
        # every input row first, in order, with its own fields; then the coasted people
        n = len(d)
        assert len(out) == n + int(np.sum(ref.det_index < 0))
        assert np.array_equal(out.xyxy[:n], d.xyxy)
        assert np.array_equal(out.confidence[:n], d.confidence)
        assert np.array_equal(out.class_id[:n], d.class_id)
        assert np.array_equal(out.mask[:n], d.mask)
        assert np.array_equal(out.data["person"][:n], d.data["person"])
        expected = np.full(n, -1)
        expected[ref.det_index[ref.det_index >= 0]] = ref.ids[ref.det_index >= 0]
        assert np.array_equal(out.tracker_id[:n], expected)
        assert not out.data["coasted"][:n].any()
        coasted = ref.det_index < 0
        assert np.array_equal(out.tracker_id[n:], ref.ids[coasted])
        assert np.allclose(out.xyxy[n:], ref.boxes[coasted])
        assert np.allclose(out.confidence[n:], ref.scores[coasted])
        assert out.data["coasted"][n:].all()
        assert not out.mask[n:].any()  # not seen this frame: an empty mask
        # the reported set is DensePeds' tracks
        reported = out[out.tracker_id != -1]
        assert sorted(reported.tracker_id.tolist()) == ref.ids.tolist()
        if f in hidden:
            assert coasted.sum() == 1
            row = out[out.data["coasted"]]
            # copied from that person's last detection: the class and the caller's data
            assert row.data["person"].tolist() == [1] and row.class_id.tolist() == [0]
            assert row.data["class_name"].tolist() == ["person"]
    # ids stay with their people across the gap
    last = out[out.tracker_id != -1]
    assert len(set(last.tracker_id.tolist())) == 3
    first_ids = dict(zip(last.data["person"].tolist(), last.tracker_id.tolist(), strict=True))
    assert sorted(first_ids) == [0, 1, 2]


def test_empty_detections_and_no_confidence() -> None:
    t = Tracker()
    out = t.update(sv.Detections.empty())
    assert len(out) == 0 and out.tracker_id.tolist() == [] and out.data["coasted"].tolist() == []
    for f in range(10):
        out = t.update(_frame_dets(f, conf=False))
    assert out.confidence is None and sorted(out.tracker_id.tolist()) == [1, 2, 3]
    out = t.update(sv.Detections.empty())  # nobody detected: everyone coasted
    assert sorted(out.tracker_id.tolist()) == [1, 2, 3] and out.data["coasted"].all()
    assert out.class_id.tolist() == [0, 0, 0]
    t.reset()
    assert len(t.update(sv.Detections.empty())) == 0


def test_arguments_are_checked() -> None:
    t = Tracker()
    d = _frame_dets(0)
    with pytest.raises(InputError, match="alone"):
        t.update(d, d.confidence)  # type: ignore[call-overload]
    with pytest.raises(InputError, match="scores are needed"):
        t.update(d.xyxy)  # type: ignore[call-overload]
    bad = sv.Detections(xyxy=np.array([[10.0, 10, 5, 50]]), confidence=np.array([0.9]))
    with pytest.raises(InputError):
        t.update(bad)


class _Recorder:
    """An embedder that keeps what it was given and answers one fixed vector a person."""

    def __init__(self) -> None:
        self.seen: list[Detections] = []

    def embed(
        self, frame: npt.NDArray[np.uint8], dets: Detections, features: str = "segmented"
    ) -> npt.NDArray[np.float32]:
        self.seen.append(dets)
        e = np.zeros((len(dets), 8), np.float32)
        e[np.arange(len(dets)), (dets.boxes[:, 0] // 70).astype(int)] = 1.0
        return e


@pytest.mark.parametrize("compact", [False, True])
def test_pipeline_step_carries_masks_to_reid_and_back(compact: bool) -> None:
    rec = _Recorder()
    pipe = Pipeline(reid=rec)
    frame = np.zeros((H, W, 3), np.uint8)
    for f in range(12):
        d = _frame_dets(f, hide=(2,) if f == 11 else (), compact=compact)
        out = pipe.step(frame, d)
    # the re-ID crops got each person's own mask, cut to its box
    got = rec.seen[-1]
    assert got.masks is not None and got.mask_boxes is not None
    dense = d.mask.to_dense() if compact else d.mask
    for i in range(len(d)):
        x0, y0, x1, y1 = got.mask_boxes[i].tolist()
        canvas = np.zeros((H, W), bool)
        canvas[y0:y1, x0:x1] = got.masks[i]
        assert np.array_equal(canvas, dense[i])
    assert sorted(out.tracker_id.tolist()) == [1, 2, 3]
    assert out.data["coasted"].tolist() == [False, False, True]
    assert out.data["person"].tolist() == [0, 1, 2]
    assert len(out.mask) == 3 and not out.mask[2].any() and out.mask[0].any()
    assert pipe.times.frames == 12
    pipe.reset()
    assert pipe.step(frame, _frame_dets(0)).tracker_id.tolist() == [-1, -1, -1]


def test_supervision_is_not_imported_for_arrays() -> None:
    code = (
        "import sys, numpy as np\n"
        "from densepeds.pipeline import Pipeline\n"
        "from densepeds.types import Detections\n"
        "p = Pipeline(features='none')\n"
        "p.step(detections=Detections(np.array([[0, 0, 10, 20]]), np.array([0.9])))\n"
        "assert 'supervision' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_the_docs_example_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """docs/python-api.md's loop, with a 'detector' reading PETS09's ground truth on a clip."""
    seq = shared_path("data", "PETS09-S2L1-dev")
    clip = tmp_path / "clip.avi"
    cap = cv2.VideoCapture(str(seq / "vtest.avi"))
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter_fourcc(*"MJPG"), 7, (768, 576))
    for _ in range(20):
        ok, image = cap.read()
        assert ok
        writer.write(image)
    cap.release()
    writer.release()
    gt = np.loadtxt(seq / "gt" / "gt.txt", delimiter=",")
    calls = []

    def detect(frame: npt.NDArray[np.uint8]) -> sv.Detections:
        calls.append(frame.shape)
        rows = gt[gt[:, 0] == len(calls)]
        xyxy = np.c_[rows[:, 2:4], rows[:, 2:4] + rows[:, 4:6]]
        n = len(rows)
        return sv.Detections(xyxy, confidence=np.full(n, 0.9), class_id=np.zeros(n, int))

    text = (REPO / "docs" / "python-api.md").read_text(encoding="utf-8")
    (block,) = re.findall(r"```python\n(.*?)```", text, re.S)
    exec(compile(block, "docs/python-api.md", "exec"), {"VIDEO": str(clip), "detect": detect})
    lines = capsys.readouterr().out.splitlines()
    assert len(calls) == 20 and len(lines) == 2
    people = len(gt[gt[:, 0] == 20])
    assert lines[1].startswith(f"frame 20: {people} people (0 hidden), ids ")
