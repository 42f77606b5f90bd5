"""Model lookup: explicit path, $DENSEPEDS_MODEL_DIR, then the user cache; clear errors."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from densepeds.errors import ModelError
from densepeds.models.files import ENV_VAR, cache_dir, find_model, search_dirs


@pytest.fixture(autouse=True)
def _own_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))


def test_explicit_path_wins(tmp_path: Path) -> None:
    model = tmp_path / "mine.onnx"
    model.write_bytes(b"x")
    assert find_model("osnet_x0_25_msmt17.onnx", model) == model
    assert find_model(str(model)) == model
    with pytest.raises(ModelError, match="does not exist"):
        find_model("whatever.onnx", tmp_path / "missing.onnx")
    with pytest.raises(ModelError, match="does not exist"):
        find_model(str(tmp_path / "missing.onnx"))


def test_env_dir_is_searched_first(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "osnet_x0_25_msmt17.onnx").write_bytes(b"x")
    monkeypatch.setenv(ENV_VAR, str(tmp_path))
    assert search_dirs() == [tmp_path, cache_dir()]
    assert find_model("osnet_x0_25_msmt17.onnx") == tmp_path / "osnet_x0_25_msmt17.onnx"


def test_only_the_env_dirs_and_the_cache_are_searched(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No look-up beside the package or the working directory (../shared/models was one)."""
    monkeypatch.delenv(ENV_VAR, raising=False)
    shared = tmp_path / "shared" / "models"
    shared.mkdir(parents=True)
    (shared / "osnet_x0_25_msmt17.onnx").write_bytes(b"x")
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    assert search_dirs() == [cache_dir()]
    with pytest.raises(ModelError, match="not found"):
        find_model("osnet_x0_25_msmt17.onnx")
    cache_dir().mkdir(parents=True)
    (cache_dir() / "osnet_x0_25_msmt17.onnx").write_bytes(b"y")
    assert find_model("osnet_x0_25_msmt17.onnx") == cache_dir() / "osnet_x0_25_msmt17.onnx"


def test_missing_model_says_where_and_how(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV_VAR, str(tmp_path))
    with pytest.raises(ModelError) as err:
        find_model("maskrcnn_resnet50_fpn.onnx")
    message = str(err.value)
    assert str(tmp_path) in message and str(cache_dir()) in message
    assert "export_maskrcnn.py" in message and "densepeds models install" in message
    with pytest.raises(ModelError, match="not a model densepeds knows"):
        find_model("no-such-model.onnx")


def _unreadable_folder(tmp_path: Path) -> Path:
    """A folder whose files cannot even be looked at: a name too long for the file system
    (stat fails with ENAMETOOLONG even for root), or, for other users, one with mode 000."""
    return tmp_path / ("x" * 300)


def test_an_unreadable_folder_does_not_hide_later_ones(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from densepeds.cli import main

    later = tmp_path / "later"
    later.mkdir()
    (later / "osnet_x0_25_msmt17.onnx").write_bytes(b"x")
    locked = tmp_path / "locked"
    locked.mkdir()
    (locked / "osnet_x0_25_msmt17.onnx").write_bytes(b"y")
    locked.chmod(0)
    try:
        first = [_unreadable_folder(tmp_path), locked]
        monkeypatch.setenv(ENV_VAR, os.pathsep.join(str(p) for p in [*first, later]))
        readable_locked = os.access(locked, os.X_OK)  # root reads it anyway
        found = find_model("osnet_x0_25_msmt17.onnx")
        assert found == (locked if readable_locked else later) / "osnet_x0_25_msmt17.onnx"
        assert main(["models"]) == 0
        out = capsys.readouterr().out
        assert f"found: {found}" in out
        assert f"{_unreadable_folder(tmp_path)} (unreadable: File name too long)" in out
        with pytest.raises(ModelError, match="unreadable: File name too long"):
            find_model("maskrcnn_resnet50_fpn.onnx")
    finally:
        locked.chmod(0o755)


def test_run_picks_the_first_model_present(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """yoloseg + OSNet where present (every published figure); else the fetched zoo models,
    float before int8; an explicit model file's kind by its name."""
    from densepeds.models.files import (
        MODELS,
        default_detector,
        default_model_file,
        default_reid_file,
    )

    monkeypatch.setenv(ENV_VAR, str(tmp_path))
    assert default_detector() == "maskrcnn"  # nothing: the default set's, whose error says fetch
    assert default_model_file("maskrcnn") == "MaskRCNN-12-int8.onnx"
    assert default_model_file("yoloseg") == "yolov8n-seg-320-int8.onnx"
    assert default_reid_file() == "person_reid_youtu_2021nov_int8.onnx"
    steps = [
        ("maskrcnn-zoo-int8", "maskrcnn", "MaskRCNN-12-int8.onnx"),
        ("maskrcnn-zoo", "maskrcnn", "MaskRCNN-12.onnx"),
        ("yoloseg", "yoloseg", "MaskRCNN-12.onnx"),
    ]
    for name, kind, maskrcnn_file in steps:
        (tmp_path / MODELS[name].file).write_bytes(b"x")
        assert default_detector() == kind
        assert default_model_file("maskrcnn") == maskrcnn_file
    for name, reid_file in [
        ("youtureid-int8", "person_reid_youtu_2021nov_int8.onnx"),
        ("youtureid", "person_reid_youtu_2021nov.onnx"),
        ("osnet", "osnet_x0_25_msmt17.onnx"),
    ]:
        (tmp_path / MODELS[name].file).write_bytes(b"x")
        assert default_reid_file() == reid_file
    assert default_detector("some/dir/MaskRCNN-12.onnx") == "maskrcnn"
    assert default_detector("my-own-detector.onnx") == "yoloseg"
