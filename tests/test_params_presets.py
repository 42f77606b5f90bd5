"""Presets: named data, applied visibly, each score cut able to fire above its detector's floor."""

from __future__ import annotations

import dataclasses
import inspect
from pathlib import Path

import pytest
from densepeds.cli import main
from densepeds.errors import ParameterError
from densepeds.pipeline import Pipeline
from densepeds.presets import DEFAULT_PRESET, PRESETS, get_preset
from densepeds.tracking import Tracker

from tests.conftest import shared_path


@pytest.mark.parametrize("name", list(PRESETS))
def test_every_preset_can_fire_above_its_floor(name: str) -> None:
    PRESETS[name].check()


def test_the_check_refuses_thresholds_under_the_floor() -> None:
    # Cuts of 0.15 / 0.3 under a floor of 0.5 leave the second pass nothing to work on; above
    # it they fire.
    cuts = {"low_threshold": 0.15, "det_threshold": 0.3}
    bad = dataclasses.replace(PRESETS["yoloseg"], name="bad", score_floor=0.5, tracker=cuts)
    with pytest.raises(ParameterError, match="second pass"):
        bad.check()
    dataclasses.replace(bad, score_floor=0.1).check()
    unborn = dataclasses.replace(PRESETS["detfile"], tracker={"new_track_threshold": 1.5})
    with pytest.raises(ParameterError, match="starts a track"):
        unborn.check()


@pytest.mark.parametrize("name", ["yoloseg", "maskrcnn"])
def test_preset_floor_is_the_detectors_own_default(name: str) -> None:
    from densepeds.detect.maskrcnn import MaskRCNNDetector
    from densepeds.detect.yoloseg import YoloSegDetector

    cls = {"yoloseg": YoloSegDetector, "maskrcnn": MaskRCNNDetector}[name]
    default = inspect.signature(cls).parameters["score_threshold"].default
    assert PRESETS[name].score_floor == default


def test_preset_values_are_known_parameters_in_range() -> None:
    for preset in PRESETS.values():
        Tracker(**preset.tracker)  # type: ignore[arg-type]  # ParameterError if not
        Pipeline(None, preset=preset.name)


def test_pipeline_applies_and_shows_its_preset() -> None:
    det = Pipeline(None)
    assert det.preset.name == DEFAULT_PRESET and det.params["preset"] == DEFAULT_PRESET
    assert det.params["score_floor"] is None
    assert {k: det.params[k] for k in Tracker().params} == Tracker().params
    for name in ("yoloseg", "maskrcnn"):
        pipe = Pipeline(name)  # the model is loaded on first use only
        preset = PRESETS[name]
        assert pipe.params["preset"] == name and pipe.params["score_floor"] == preset.score_floor
        for key, value in {**preset.detection, **preset.tracker}.items():
            assert pipe.params[key] == value, (name, key)
    # Named explicitly, for detections given by the caller; the caller's values win.
    pipe = Pipeline(None, preset="maskrcnn", det_threshold=0.8, min_height=10)
    assert pipe.params["preset"] == "maskrcnn" and pipe.params["det_threshold"] == 0.8
    assert pipe.params["new_track_threshold"] == 0.7 and pipe.params["min_height"] == 10
    with pytest.raises(ParameterError, match="unknown preset 'nope'"):
        get_preset("nope")
    with pytest.raises(ParameterError, match="unknown preset"):
        Pipeline(None, preset="nope")


def test_run_help_lists_every_preset_and_its_values(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "--preset {" + ",".join(PRESETS) + "}" in out
    for preset in PRESETS.values():
        assert " ".join(preset.describe().split()) in out


def test_run_with_an_unknown_preset_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["run", "--preset", "nope"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--preset" in err


def test_run_says_which_preset_it_used(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    seq = shared_path("data", "TUD-Stadtmitte")
    out = tmp_path / "t.txt"
    for extra, name in (([], DEFAULT_PRESET), (["--preset", "yoloseg"], "yoloseg")):
        argv = ["run", str(seq), "--frames", "1:5", "--out", str(out), "-q", *extra]
        assert main(argv) == 0
        assert f"(preset {name})" in capsys.readouterr().out


def test_motion_as_a_param_points_to_its_option(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["run", "--param", "motion=cv"])
    assert exit_.value.code == 2 and "--motion" in capsys.readouterr().err
