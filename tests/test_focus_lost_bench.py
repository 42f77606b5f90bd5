"""benchmarks/focus_lost.py measures what `densepeds run --detector yoloseg` does (focus views at
the detector's default scale), and keeps it."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO, shared_path
from densepeds.cli import main
from densepeds.detect.yoloseg import YoloSegDetector
from densepeds.io.mot import read_tracks
from densepeds.types import Detections

sys.path.insert(0, str(REPO / "benchmarks"))
import accuracy_grid as grid  # noqa: E402
import focus_lost  # noqa: E402

FRAMES = "1:30"  # long enough for people to be lost behind others


def test_a_live_cell_tracks_as_the_cli_and_is_kept(tmp_path: Path) -> None:
    seq = shared_path("data", "PETS09-S2L1-dev")
    shared_path("models", "yolov8n-seg-320-int8.onnx")
    cell = grid.Cell("PETS09-S2L1-dev", "float")
    scale = YoloSegDetector.__init__.__kwdefaults__["focus_scale"]  # the package default
    assert scale > 0
    run = focus_lost.run_cell(cell, scale, tmp_path / "cache", FRAMES)
    assert len(run.detected) == len(run.fed) == 30 and run.seconds > 0
    without = focus_lost.run_cell(cell, 0.0, tmp_path / "cache", FRAMES)
    assert run.views > without.views  # the scale reached the detector, and it looked closer
    out = tmp_path / "cli.txt"
    args = ["run", str(seq), "--detector", "yoloseg", "--frames", FRAMES]  # its default scale
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    cli = read_tracks(out)
    ours = np.array(sorted(map(tuple, run.rows[:, :7])))
    theirs = np.array(sorted(map(tuple, cli[:, :7])))
    assert ours.shape == theirs.shape and len(ours) > 0
    np.testing.assert_allclose(ours, theirs, atol=0.01)  # the CLI writes two decimals
    again = focus_lost.run_cell(cell, scale, tmp_path / "cache", FRAMES)
    assert np.array_equal(again.rows, run.rows) and again.views == run.views
    assert len(list((tmp_path / "cache").glob("focus-*.npz"))) == 2


def test_leave_one_out_over_scales_picks_on_the_other_cells() -> None:
    scales = (0.0, 2.5)
    hota = {  # cell -> (scale 0, scale 2.5); scale 2.5 wins on three cells, loses on one
        "MOT20-01-dev/float": (46.0, 47.0),
        "PETS09-S2L1-dev/float": (63.0, 62.0),
        "MOT20-01-dev/int8": (45.0, 46.0),
        "PETS09-S2L1-dev/int8": (60.0, 60.5),
    }
    assert [c.name for c in focus_lost.CELLS] == list(hota)
    scored = {
        (name, s): focus_lost.Scored({"HOTA": v[k]}, 1, None)  # type: ignore[arg-type]
        for name, v in hota.items()
        for k, s in enumerate(scales)
    }
    results = focus_lost.by_scale(scored, scales)
    assert list(results) == ["focus_scale=0", "focus_scale=2.5"]
    from accuracy_tables import leave_one_out

    loo = leave_one_out(results)
    assert [r.chosen for r in loo] == ["focus_scale=2.5"] * 4
    assert loo[1].held_out == pytest.approx(62.0)


class _Fixed:
    """Two people at fixed boxes every frame; remembers what it was asked to focus on."""

    last_views = 7

    def __init__(self) -> None:
        self.focused: list[object] = []

    def __call__(self, frame: object) -> Detections:
        boxes = np.array([[10, 20, 30, 80], [100, 20, 130, 90]], np.float32)
        return Detections(boxes, np.array([0.9, 0.8], np.float32))

    def focus(self, boxes: object) -> None:
        self.focused.append(boxes)


def test_the_noise_runs_move_each_box_by_a_new_sub_pixel_draw_per_frame() -> None:
    inner = _Fixed()
    jittered = focus_lost.Jittered(inner, seed=3)
    moved = [jittered(None) for _ in range(2)]  # two frames
    again = focus_lost.Jittered(_Fixed(), seed=3)(None)
    fixed = inner(None).boxes
    for dets in moved:
        shift = dets.boxes - fixed
        assert dets.boxes.dtype == np.float32 and np.all(np.abs(shift) <= 0.5)
        assert np.all(shift != 0) and np.array_equal(dets.scores, inner(None).scores)
    assert not np.array_equal(moved[0].boxes, moved[1].boxes)  # a new draw each frame
    assert np.array_equal(moved[0].boxes, again.boxes)  # the seed decides the draws
    wrapped = focus_lost.Jittered(inner, seed=1)
    wrapped.focus("boxes")  # everything else is the detector's
    assert inner.focused == ["boxes"] and wrapped.last_views == 7


def test_a_noise_run_is_kept_apart_from_the_unmoved_run(tmp_path: Path) -> None:
    shared_path("data", "PETS09-S2L1-dev")
    shared_path("models", "yolov8n-seg-320-int8.onnx")
    cell = grid.Cell("PETS09-S2L1-dev", "float")
    plain = focus_lost.run_cell(cell, 0.0, tmp_path, "1:10")
    moved = focus_lost.run_cell(cell, 0.0, tmp_path, "1:10", seed=1)
    assert len(list(tmp_path.glob("focus-*.npz"))) == 2
    assert plain.rows.shape[1] == moved.rows.shape[1] and len(moved.rows) > 0
    assert not np.array_equal(plain.rows, moved.rows)
    for a, b in zip(plain.detected, moved.detected, strict=True):
        assert a.shape == b.shape and np.all(np.abs(a - b) <= 0.5 + 1e-4)
