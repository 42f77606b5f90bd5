"""DensePeds: pedestrian tracking in dense crowds."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

# FFmpeg (inside OpenCV) and OpenCV print their own lines on stderr (a damaged block, a missing
# header) before our one-line error says the same: off the terminal unless the user asks for
# them by setting these before the import (read once, when cv2 loads; -8 is FFmpeg's "quiet").
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

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
