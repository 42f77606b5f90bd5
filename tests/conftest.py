"""Shared fixtures: the real data in ../shared, skipped with a clear reason where it is absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("DENSEPEDS_SHARED", REPO.parent / "shared"))


def shared_path(*parts: str) -> Path:
    """A path under ../shared, or skip the test saying what is missing."""
    p = SHARED.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"needs {p} (the shared data and models beside the repo; set DENSEPEDS_SHARED)")
    return p


@pytest.fixture
def shared() -> Path:
    return shared_path()


# Model lookup by bare name (the CLI's defaults) searches only $DENSEPEDS_MODEL_DIR and the user
# cache: point it at the shared models (an explicit DENSEPEDS_MODEL_DIR from the environment wins).
if (SHARED / "models").is_dir():
    os.environ.setdefault("DENSEPEDS_MODEL_DIR", str(SHARED / "models"))


@pytest.fixture(scope="session", autouse=True)
def _ort_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Optimised onnxruntime graphs go to a temporary folder, not the user cache (an explicit
    DENSEPEDS_ORT_CACHE from the environment wins)."""
    os.environ.setdefault("DENSEPEDS_ORT_CACHE", str(tmp_path_factory.mktemp("ort-cache")))
