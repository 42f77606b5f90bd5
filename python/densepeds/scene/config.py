"""The built-in scene's settings, in one place."""

from __future__ import annotations

from dataclasses import dataclass

from densepeds.errors import ParameterError

# Most frames the scene simulates (2.8 hours at 10 fps): its trajectories and ground truth are
# held in memory, so a larger count is refused rather than exhausting it.
MAX_SCENE_FRAMES = 100_000
# Largest image side the scene draws (pixels).
MAX_SCENE_SIDE = 8192


@dataclass(frozen=True)
class SceneConfig:
    """What the scene simulates, how it is drawn and how its stand-in detector errs.

    Mask noise (off by default) makes the detector's masks differ from the rendered people the
    way a real segmenter's do: ``mask_dilate`` grows each mask by that many pixels (negative
    values erode it), and ``mask_shift`` moves each mask by up to that many pixels in x and y
    (uniformly at random, per detection), so that masks cover some background or neighbour and
    miss part of the person.
    """

    seed: int = 0
    frames: int = 150
    fps: float = 10.0
    width: int = 640
    height: int = 480
    groups: int = 6
    group_size: tuple[int, int] = (8, 12)  # members per group, inclusive range
    group_density: float = 3.2  # people per m^2 when a group is formed
    region: tuple[float, float, float, float] = (-4.0, 4.0, 4.5, 12.0)  # x0, x1, y0, y1 metres
    speed: tuple[float, float] = (0.9, 1.3)  # m/s
    miss_visibility: float = 0.1  # below this visible fraction a person is never detected
    false_positives: float = 0.7  # mean per frame
    box_jitter: float = 0.04  # standard deviation, as a fraction of the box size
    mask_dilate: int = 0  # pixels; negative erodes
    mask_shift: int = 0  # largest shift in pixels, per axis

    def check(self) -> None:
        if self.frames < 1 or self.groups < 1 or self.group_size[0] < 1:
            raise ParameterError("scene needs at least one frame, one group and one person")
        if self.frames > MAX_SCENE_FRAMES:
            raise ParameterError(
                f"scene: {self.frames} frames is too many (at most {MAX_SCENE_FRAMES})"
            )
        if not (16 <= self.width <= MAX_SCENE_SIDE and 16 <= self.height <= MAX_SCENE_SIDE):
            raise ParameterError(
                f"scene: image size {self.width}x{self.height} is outside 16..{MAX_SCENE_SIDE}"
            )
        if self.group_size[1] < self.group_size[0] or self.fps <= 0 or self.group_density <= 0:
            raise ParameterError("scene: bad group size, fps or density")
        if self.mask_shift < 0:
            raise ParameterError(f"scene: mask_shift must be >= 0, got {self.mask_shift}")
