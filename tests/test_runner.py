"""The run layer: `run` and `batch` build their settings from the same option declarations, and a
batch job's run (with models loaded once per worker) gets every setting a `densepeds run` gets."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path
from typing import Any

import pytest
from densepeds import batch
from densepeds.batch.plan import Job, Settings
from densepeds.batch.worker import run_args
from densepeds.cli import build_parser
from densepeds.errors import ParameterError
from densepeds.presets import get_preset
from densepeds.runner import RunOptions, RunSpec, open_run
from densepeds.runner.spec import OPTIONS, SHARED
from densepeds.scene import make_scene

SETTINGS = [
    "--detector", "yoloseg", "--detector-model", "det.onnx", "--tiles", "3x2",
    "--full-scan-every", "4", "--focus-lost", "1.5", "--reid-model", "reid.onnx",
    "--reid-reuse", "--motion", "cv", "--preset", "detfile", "--features", "bbox",
    "--frames", "2:9", "--fill-gaps", "5", "--param", "max_age=7", "--param", "max_age=9",
    "--allow-partial",
]  # fmt: skip


def test_every_run_setting_is_a_batch_option_and_reaches_its_jobs(tmp_path: Path) -> None:
    # Every run option that does not name one input's files is declared once and shared.
    assert {o.dest for o in OPTIONS} - {o.dest for o in SHARED} == {
        "input", "detections", "reconnect", "out", "video", "seed", "scene_frames", "quiet",
    }  # fmt: skip
    settings = {f.name for f in fields(RunOptions)}
    assert {o.dest for o in SHARED} == settings - {"params"} | {"param"}
    clip = tmp_path / "a.mp4"
    parser = build_parser()
    ran = parser.parse_args(["run", str(clip), *SETTINGS, "--out", str(tmp_path / "a.txt"), "-q"])
    batched = parser.parse_args(["batch", str(clip), "--out", str(tmp_path), *SETTINGS])
    settings = Settings.from_args(batched)
    assert settings.params == (("max_age", 9),) and settings.tiles == "3x2"
    job = Job(name="a", input=clip, out_dir=tmp_path, video=False)
    assert run_args(settings, job, None) == RunSpec.from_args(ran)
    # With the worker's threads, only the motion step's thread count is added.
    threaded = run_args(settings, job, 2)
    assert dict(threaded.params) == {"max_age": 9, "threads": 2}


def test_batch_refuses_an_unknown_or_contradictory_setting_before_any_input(
    tmp_path: Path,
) -> None:
    with pytest.raises(ParameterError, match="unknown batch option.*tile"):
        batch.run([tmp_path / "missing.mp4"], tmp_path / "out", tile="3x2")
    with pytest.raises(ParameterError, match="reid_reuse"):
        batch.run([tmp_path / "missing.mp4"], tmp_path / "out", reid_reuse=True, features="none")
    with pytest.raises(ParameterError, match="preset"):
        Settings(preset="nonesuch").check()
    assert Settings.make(params={"max_age": 3}, detector_model=Path("m.onnx")) == Settings(
        params=(("max_age", 3),), detector_model="m.onnx"
    )


class _Models:
    """A batch's shared models, recording what the run asked for."""

    def __init__(self) -> None:
        self.calls: list[tuple[Any, ...]] = []

    def detector(self, kind: str, given: str | None, **options: Any) -> Any:
        self.calls.append(("detector", kind, given, options))
        return lambda image: None

    def reid(self, given: str | None, reuse: bool = False) -> Any:
        self.calls.append(("reid", given, reuse))
        return _Embedder()


class _Embedder:
    def embed(self, image: Any, dets: Any) -> Any:
        raise AssertionError("not run here")


def test_loaded_models_get_the_runs_detector_options_and_reid_reuse(tmp_path: Path) -> None:
    seq = make_scene(seed=0, frames=3).write(tmp_path, images=True)
    spec = RunSpec(
        input=str(seq),
        detector="yoloseg",
        tiles="2x1",
        full_scan_every=3,
        focus_lost=1.5,
        reid_reuse=True,
        features="bbox",
        out=tmp_path / "t.txt",
    )
    models = _Models()
    _, pipe, dets, out, _ = open_run(spec, models)
    floor = get_preset("yoloseg").score_floor
    assert floor is not None
    assert models.calls == [
        (
            "detector",
            "yoloseg",
            None,
            {"score_threshold": floor, "tiles": "2x1", "full_scan_every": 3, "focus_scale": 1.5},
        ),
        ("reid", None, True),
    ]
    assert dets is None and out == spec.out and pipe.preset.name == "yoloseg"
    # A detector-less preset keeps the detector's own score floor, as a pipeline-built one does.
    models = _Models()
    open_run(RunSpec(input=str(seq), detector="yoloseg", preset="detfile"), models)
    assert "score_threshold" not in models.calls[0][3]


def test_a_workers_models_take_the_detector_options_and_reid_reuse() -> None:
    """A batch worker loads each model once per distinct setting, with the run's options."""
    from densepeds.batch.worker import WorkerModels

    models = WorkerModels({}, threads=1)
    grid = models.detector("yoloseg", None, tiles="2x1", focus_scale=0.0, score_threshold=0.3)
    assert (grid.tiles, grid.focus_scale, grid.score_threshold) == ("2x1", 0.0, 0.3)
    assert (
        models.detector("yoloseg", None, tiles="2x1", focus_scale=0.0, score_threshold=0.3) is grid
    )
    assert models.detector("yoloseg", None, tiles="none").tiles == "none"
    plain, reusing = models.reid(None), models.reid(None, reuse=True)
    assert plain.reuse is None and reusing.reuse is not None
