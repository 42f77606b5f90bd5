"""Plain data passed between the stages of the pipeline."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt


@dataclass
class Detections:
    """People found in one frame.

    boxes: float32 [N, 4] as (x1, y1, x2, y2) in frame pixels (may extend past the frame).
    scores: float32 [N]; any range (MOT15 det files use e.g. 93.7 or negative values).
    masks: None (no segmentation: the whole box is the person) or a list of N boolean arrays, mask
        i covering the integer region ``mask_boxes[i]`` = (x0, y0, x1, y1), clipped to the frame,
        with shape (y1 - y0, x1 - x0).
    mask_boxes: int32 [N, 4]; present whenever masks is.
    """

    boxes: npt.NDArray[np.float32]
    scores: npt.NDArray[np.float32]
    masks: list[npt.NDArray[np.bool_]] | None = None
    mask_boxes: npt.NDArray[np.int32] | None = None
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.boxes = np.asarray(self.boxes, dtype=np.float32).reshape(-1, 4)
        self.scores = np.asarray(self.scores, dtype=np.float32).reshape(-1)
        if len(self.scores) != len(self.boxes):
            raise ValueError(f"{len(self.boxes)} boxes but {len(self.scores)} scores")
        if self.masks is not None:
            if self.mask_boxes is None or len(self.masks) != len(self.boxes):
                raise ValueError("masks need one mask and one mask_box per detection")
            self.mask_boxes = np.asarray(self.mask_boxes, dtype=np.int32).reshape(-1, 4)

    def __len__(self) -> int:
        return len(self.boxes)

    @classmethod
    def empty(cls) -> Detections:
        return cls(np.zeros((0, 4), np.float32), np.zeros(0, np.float32))

    def subset(self, keep: npt.NDArray[np.bool_] | npt.NDArray[np.intp]) -> Detections:
        """The detections selected by a boolean mask or an index array."""
        idx = np.flatnonzero(keep) if np.asarray(keep).dtype == bool else np.asarray(keep)
        masks = None if self.masks is None else [self.masks[i] for i in idx]
        mboxes = None if self.mask_boxes is None else self.mask_boxes[idx]
        extra = {k: v[idx] for k, v in self.extra.items()}
        return Detections(self.boxes[idx], self.scores[idx], masks, mboxes, extra)
