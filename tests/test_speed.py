"""Speed profiles (``densepeds run --speed``): their figures come from the results files, they set
the yoloseg detector's options unless given explicitly, and ``fast`` runs the fixed grid."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from conftest import REPO, shared_path
from densepeds.cli import build_parser, open_run
from densepeds.errors import ModelError, ParameterError
from densepeds.speed import MEASURED, SPEEDS, get_speed

sys.path.insert(0, str(REPO / "benchmarks"))
import speed_profiles  # noqa: E402


def test_the_figures_are_those_of_the_results_files() -> None:
    assert speed_profiles.main(["--check"]) == 0  # speed.py and docs/speed.md are up to date
    rows = speed_profiles.figures()
    assert set(rows) == set(SPEEDS) == set(MEASURED)
    for name, row in rows.items():
        assert speed_profiles.measured_line(row) == MEASURED[name]
        assert MEASURED[name] in SPEEDS[name].describe()
    # Faster profiles are measured faster on both videos.
    for video, _ in speed_profiles.VIDEOS:
        ups = [float(rows[n][f"{video} speed"]) for n in ("accurate", "balanced", "fast")]
        assert ups == sorted(ups) and ups[0] > 1


def test_a_missing_figure_is_an_error_not_a_guess() -> None:
    speed = (speed_profiles.RESULTS / "speed.md").read_text(encoding="utf-8")
    row = get_speed("fast").speed_row
    assert speed_profiles.speed_ups(speed, row)["MOT20-01-dev"][0] > 1
    with pytest.raises(speed_profiles.ResultsError, match="no speed-up"):
        speed_profiles.speed_ups(speed.replace(f"reference / {row}:", "reference / x:"), row)
    fast = (speed_profiles.RESULTS / "fast.md").read_text(encoding="utf-8")
    assert speed_profiles.hota(fast, "/scan4", "PETS09-S2L1-dev", "fast.md") == pytest.approx(
        float(speed_profiles.figures()["balanced"]["PETS09-S2L1-dev HOTA"])
    )
    with pytest.raises(speed_profiles.ResultsError, match="no HOTA"):
        speed_profiles.hota(fast, "/nothing", "MOT20-01-dev", "fast.md")
    with pytest.raises(ParameterError, match="expected one of accurate, balanced, fast"):
        get_speed("turbo")


def _detector(argv: list[str]) -> object:
    args = build_parser().parse_args(["run", *argv, "--frames", "1:2"])
    _src, pipe, *_ = open_run(args)
    return pipe.detector()


def test_a_profile_sets_the_detector_and_explicit_options_win() -> None:
    video = str(shared_path("data", "PETS09-S2L1-dev", "vtest.avi"))
    shared_path("models", "yolov8n-seg-320-int8.onnx")
    det = _detector([video, "--speed", "balanced"])
    assert (det.tiles, det.focus_scale, det.quantized) == ("auto", 0.0, False)  # type: ignore[attr-defined]
    assert det.grid_schedule.full_scan_every == 4  # type: ignore[attr-defined]
    det = _detector([video, "--speed", "balanced", "--full-scan-every", "2", "--focus-lost", "2"])
    assert (det.focus_scale, det.grid_schedule.full_scan_every) == (2.0, 2)  # type: ignore[attr-defined]
    det = _detector([video, "--speed", "accurate"])
    assert (det.tiles, det.focus_scale, det.grid_schedule.full_scan_every) == ("auto", 2.5, 1)  # type: ignore[attr-defined]
    # fast needs the int8 copy: without one, the error says how to make it.
    with pytest.raises(ModelError, match="densepeds models quantize"):
        _detector([video, "--speed", "fast"])
    det = _detector([video, "--speed", "balanced", "--tiles", "2x1"])
    assert det.tiles == "2x1"  # type: ignore[attr-defined]
    with pytest.raises(ParameterError, match="--speed fast sets the yoloseg detector"):
        _detector([str(shared_path("data", "PETS09-S2L1-dev")), "--speed", "fast"])


def test_grid_tiles_are_the_fixed_grid_for_the_frame_size() -> None:
    from densepeds.detect.yoloseg import YoloSegDetector

    det = YoloSegDetector(shared_path("models", "yolov8n-seg-320-int8.onnx"), tiles="grid")
    assert len(det.views(768, 576)) == 4  # PETS09: 2x2, as the reference's grid
    assert len(det.views(960, 540)) == 6  # MOT20-01 at half size: 3x2
    assert len(det.views(300, 200)) == 1  # smaller than a tile: the whole frame


def test_run_help_shows_the_profiles(capsys: pytest.CaptureFixture[str]) -> None:
    from densepeds.cli import main

    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    for name in SPEEDS:
        assert f"{name}:" in out
    assert Path(REPO / "docs" / "speed.md").is_file()
