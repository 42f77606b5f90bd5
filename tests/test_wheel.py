"""Packaging: a light core with one OpenCV, the eval extra, and (where built) the manylinux abi3
wheel. The wheel installed into a fresh venv (core + eval extra + trackeval without its
dependencies) is exercised by scripts/smoke-wheel.sh (CI), which also scores a run there."""

from __future__ import annotations

import re
import zipfile

import pytest
from conftest import REPO

tomllib = pytest.importorskip("tomllib", reason="needs Python 3.11+ to read pyproject.toml")

CORE = {"numpy", "onnxruntime", "onnx", "opencv-python-headless", "tqdm", "imageio-ffmpeg"}


def _name(requirement: str) -> str:
    return re.split(r"[<>=!~;\[ ]", requirement, maxsplit=1)[0].strip().lower()


def _project() -> dict:  # type: ignore[type-arg]
    return tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]


def test_core_is_light_and_has_one_opencv() -> None:
    project = _project()
    assert {_name(r) for r in project["dependencies"]} == CORE
    for extra, reqs in project["optional-dependencies"].items():
        names = {_name(r) for r in reqs}
        assert "opencv-python" not in names, extra
        if extra == "eval":
            # What trackeval imports for MOTChallenge boxes; trackeval itself goes in --no-deps.
            assert {"scipy", "pycocotools", "tabulate"} <= names and "trackeval" not in names


def test_built_wheel_is_manylinux_abi3() -> None:
    wheels = sorted((REPO / "target" / "wheels").glob("densepeds-*.whl"))
    if not wheels:
        pytest.skip("no wheel in target/wheels (scripts/build-wheel.sh makes it)")
    wheel = wheels[-1]
    assert re.search(r"-cp310-abi3-manylinux2014_x86_64\.manylinux_2_17_x86_64\.whl$", wheel.name)
    with zipfile.ZipFile(wheel) as zf:
        names = zf.namelist()
        meta = zf.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert "densepeds/_core.abi3.so" in names and "densepeds/models/fetch.py" in names
    required = {
        _name(line.split(":", 1)[1].strip())
        for line in meta.splitlines()
        if line.startswith("Requires-Dist:") and "extra ==" not in line
    }
    assert required == CORE
