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
from densepeds.motio import read_tracks

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
