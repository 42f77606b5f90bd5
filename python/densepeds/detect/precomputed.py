"""Precomputed detections (MOTChallenge det.txt) behind the Detector interface."""

from __future__ import annotations

import os

import numpy as np
import numpy.typing as npt

from densepeds.io.mot import ScoreMapping, read_detections
from densepeds.types import Detections


class PrecomputedDetector:
    """Returns the det file's detections frame by frame; masks None (the whole box).

    Frames are counted from ``first_frame`` on each call, or chosen with ``frame_number=``.
    Scores are mapped into [0, 1] by densepeds.io.mot's rule (``normalize``; MOT15 files use e.g.
    93.7 or negative values); ``score_threshold`` applies in the mapped scale.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        score_threshold: float | None = None,
        first_frame: int = 1,
        normalize: ScoreMapping = "auto",
    ) -> None:
        self.by_frame = read_detections(path, min_score=score_threshold, normalize=normalize)
        self.first_frame = first_frame
        self.next_frame = first_frame

    def reset(self) -> None:
        self.next_frame = self.first_frame

    def detections(self, frame_number: int) -> Detections:
        dets = self.by_frame.get(frame_number)
        return Detections.empty() if dets is None else dets.subset(np.arange(len(dets)))

    def __call__(
        self, frame: npt.NDArray[np.uint8] | None = None, *, frame_number: int | None = None
    ) -> Detections:
        number = self.next_frame if frame_number is None else frame_number
        self.next_frame = number + 1
        return self.detections(number)
