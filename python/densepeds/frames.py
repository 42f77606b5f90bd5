"""Frames as every stage takes them: BGR uint8 arrays [H, W, 3], as OpenCV decodes them."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from densepeds.errors import InputError

Image = npt.NDArray[np.uint8]


def check_frame(frame: object) -> None:
    """InputError unless ``frame`` is a BGR uint8 array [H, W, 3] of at least 2x2 pixels."""
    if not isinstance(frame, np.ndarray) or frame.ndim != 3 or frame.shape[2] != 3:
        shape = getattr(frame, "shape", None)
        raise InputError(f"frame must be a BGR uint8 array [H, W, 3], got shape {shape}")
    if frame.dtype != np.uint8:
        raise InputError(f"frame must be a BGR uint8 array [H, W, 3], got dtype {frame.dtype}")
    if frame.shape[0] < 2 or frame.shape[1] < 2:
        raise InputError(f"frame is too small: {frame.shape}")
