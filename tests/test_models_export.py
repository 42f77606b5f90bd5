"""`densepeds models export yoloseg|osnet`: the official exporters on random-weight models built
from their own configs (no download), checked against our contract and installed. The exporters
are optional (ultralytics; the export extra's torch + torchreid): skipped where absent. In CI
they cost installing torch (CPU wheel ~200 MB) plus ultralytics / torchreid, about 2-3 minutes,
and about half a minute per export."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from densepeds.cli import main
from densepeds.models.files import MODELS


def _missing(*modules: str) -> str | None:
    absent = [m for m in modules if importlib.util.find_spec(m) is None]
    return ", ".join(absent) if absent else None


def test_export_without_the_exporter_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for model, modules in (("yoloseg", ("ultralytics",)), ("osnet", ("torch", "torchreid"))):
        absent = _missing(*modules)
        if absent is None:
            continue
        rc = main(["models", "export", model, "--random", "--dir", str(tmp_path)])
        err = capsys.readouterr().err
        assert rc == 2 and len(err.strip().splitlines()) == 1, err
        assert "the export needs" in err and "pip install" in err
        assert not any(tmp_path.iterdir())


@pytest.mark.skipif(
    _missing("ultralytics") is not None,
    reason="ultralytics not installed (pip install ultralytics)",
)
def test_export_yoloseg_random_weights(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from densepeds.detect.yoloseg import YoloSegDetector

    rc = main(["models", "export", "yoloseg", "--random", "--dir", str(tmp_path)])
    out = capsys.readouterr().out
    path = tmp_path / MODELS["yoloseg-export"].file
    assert rc == 0 and str(path) in out
    detector = YoloSegDetector(path, tiles=None, threads=1)
    detector(np.full((240, 320, 3), 114, np.uint8))


@pytest.mark.skipif(
    _missing("torch", "torchreid") is not None,
    reason="the export extra is not installed (pip install 'densepeds[export]')",
)
def test_export_osnet_random_weights(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from densepeds.reid import ReID

    rc = main(["models", "export", "osnet", "--dir", str(tmp_path)])
    assert rc == 2 and "--weights" in capsys.readouterr().err
    rc = main(["models", "export", "osnet", "--random", "--dir", str(tmp_path)])
    path = tmp_path / MODELS["osnet-export"].file
    assert rc == 0 and str(path) in capsys.readouterr().out
    reid = ReID(path, threads=1)
    assert reid.dim == 512 and not reid.one_at_a_time
    assert reid.embed_crops([np.zeros((90, 40, 3), np.uint8)] * 3).shape == (3, 512)


class _StandInYOLO:
    """Ultralytics' ``YOLO(source).export(...)`` call as densepeds makes it, writing a tiny
    graph of the yoloseg contract (or a wrong one) into the working folder, like the real one."""

    calls: list[tuple[str, dict[str, object]]] = []
    wrong = False

    def __init__(self, source: str) -> None:
        self.source = source

    def export(self, **options: object) -> str:
        from test_detect import tiny_yoloseg

        type(self).calls.append((self.source, options))
        name = Path(self.source).with_suffix(".onnx").name
        if self.wrong:
            Path(name).write_bytes(b"not onnx")
        else:
            tiny_yoloseg(Path(name))
        return name  # relative, as Ultralytics returns it


def test_export_yoloseg_glue_with_a_stand_in_exporter(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """What densepeds does around the exporter: the call (ONNX, 320 px, the config for
    --random), the written file found, checked with YoloSegDetector, installed; a file that is
    not a yoloseg model refused with nothing installed; the working folder left as it was."""
    import types

    module = types.ModuleType("ultralytics")
    module.YOLO = _StandInYOLO  # type: ignore[attr-defined]
    monkeypatch.setitem(__import__("sys").modules, "ultralytics", module)
    monkeypatch.setattr(_StandInYOLO, "calls", [])
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    dest = tmp_path / "models"
    rc = main(["models", "export", "yoloseg", "--random", "--dir", str(dest)])
    assert rc == 0, capsys.readouterr().err
    ((source, options),) = _StandInYOLO.calls
    assert source == "yolov8n-seg.yaml" and options["format"] == "onnx" and options["imgsz"] == 320
    assert (dest / MODELS["yoloseg-export"].file).is_file()
    assert Path.cwd() == work and not any(work.iterdir())
    monkeypatch.setattr(_StandInYOLO, "wrong", True)
    rc = main(["models", "export", "yoloseg", "--dir", str(tmp_path / "other")])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert _StandInYOLO.calls[-1][0] == "yolov8n-seg.pt"
    assert not (tmp_path / "other").exists() or not any((tmp_path / "other").iterdir())
