"""Model lookup: explicit path, $DENSEPEDS_MODEL_DIR, cache, ../shared; clear errors."""

from __future__ import annotations

from pathlib import Path

import pytest
from densepeds.errors import ModelError
from densepeds.modelfiles import CACHE_DIR, ENV_VAR, find_model, search_dirs


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
    assert search_dirs()[0] == tmp_path
    assert search_dirs()[1] == CACHE_DIR.expanduser()
    assert find_model("osnet_x0_25_msmt17.onnx") == tmp_path / "osnet_x0_25_msmt17.onnx"


def test_missing_model_says_where_and_how(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV_VAR, str(tmp_path))
    with pytest.raises(ModelError) as err:
        find_model("maskrcnn_resnet50_fpn.onnx")
    message = str(err.value)
    assert str(tmp_path) in message and ENV_VAR in message
    assert "export_maskrcnn.py" in message
    with pytest.raises(ModelError, match="models/README.md"):
        find_model("no-such-model.onnx")
