"""DensePeds: pedestrian tracking in dense crowds."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from densepeds._core import __version__
from densepeds.errors import DensePedsError, DetFileError, InputError, ModelError, ParameterError

if TYPE_CHECKING:
    from densepeds.pipeline import Pipeline
    from densepeds.scene import make_scene
    from densepeds.tracking import Tracker, Tracks
    from densepeds.types import Detections

__all__ = [
    "DensePedsError",
    "DetFileError",
    "Detections",
    "InputError",
    "ModelError",
    "ParameterError",
    "Pipeline",
    "Tracker",
    "Tracks",
    "__version__",
    "make_scene",
]

# Heavier modules (numpy, OpenCV, onnxruntime) load on first use, so `import densepeds` stays
# quick (and the command can take Ctrl-C cleanly from its first moment).
_LAZY = {
    "Detections": "densepeds.types",
    "Pipeline": "densepeds.pipeline",
    "Tracker": "densepeds.tracking",
    "Tracks": "densepeds.tracking",
    "make_scene": "densepeds.scene",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'densepeds' has no attribute {name!r}")
