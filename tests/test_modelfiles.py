"""Model lookup: explicit path, $DENSEPEDS_MODEL_DIR, then the user cache; clear errors."""

from __future__ import annotations

from pathlib import Path

import pytest
from densepeds.errors import ModelError
from densepeds.modelfiles import ENV_VAR, cache_dir, find_model, search_dirs


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
