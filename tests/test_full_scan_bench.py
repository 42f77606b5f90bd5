"""benchmarks/full_scan.py measures what `densepeds run --detector yoloseg --full-scan-every K`
does (package defaults, focus views included)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from conftest import REPO, shared_path
from densepeds.cli import main
from densepeds.motio import read_tracks

sys.path.insert(0, str(REPO / "benchmarks"))
import focus_lost  # noqa: E402
import full_scan  # noqa: E402

FRAMES = "1:16"


def test_a_skipping_cell_tracks_as_the_cli(tmp_path: Path) -> None:
    seq = shared_path("data", "PETS09-S2L1-dev")
    shared_path("models", "yolov8n-seg-320-int8.onnx")
    every = full_scan.ScanCell("PETS09-S2L1-dev", "float", 1)
    skip = full_scan.ScanCell("PETS09-S2L1-dev", "float", 4)
    assert skip.detector_options["full_scan_every"] == 4 and skip.name == every.name
    scale = focus_lost.default_scale()
    run = focus_lost.run_cell(skip, scale, tmp_path / "cache", FRAMES)
    full = focus_lost.run_cell(every, scale, tmp_path / "cache", FRAMES)
    assert run.views < full.views  # the period reached the detector
    out = tmp_path / "cli.txt"
    args = ["run", str(seq), "--detector", "yoloseg", "--frames", FRAMES, "--full-scan-every", "4"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    ours = np.array(sorted(map(tuple, run.rows[:, :7])))
    theirs = np.array(sorted(map(tuple, read_tracks(out)[:, :7])))
    assert ours.shape == theirs.shape and len(ours) > 0
    np.testing.assert_allclose(ours, theirs, atol=0.01)  # the CLI writes two decimals
    assert len(list((tmp_path / "cache").glob("focus-*.npz"))) == 2  # one entry per period
