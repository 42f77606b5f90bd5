"""How the scene looks: simple walking figures painted far to near over a paved plaza.

Painting far to near makes nearer people cover farther ones; the per-pixel label image says
which person (if any) each pixel shows, so visibilities and masks come out exact.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from densepeds.scene.config import SceneConfig
from densepeds.scene.simulation import Camera

FloatArray = npt.NDArray[np.float64]
Image = npt.NDArray[np.uint8]
Labels = npt.NDArray[np.int32]

TROUSERS = np.array(
    [[60, 40, 30], [30, 30, 30], [110, 110, 110], [40, 70, 110], [120, 160, 180], [90, 50, 20]],
    np.uint8,
)  # BGR: navy, black, grey, brown, khaki, blue
SKIN = np.array([[140, 170, 220], [90, 120, 170], [60, 80, 120]], np.uint8)
STRIDE = 1.3  # metres per gait cycle


@dataclass
class Person:
    """One person as drawn in one frame."""

    box: FloatArray  # x1, y1, x2, y2 (unclipped, full extent)
    depth: float
    phase: float
    area: int = 0  # silhouette pixels if nothing covered it and the frame did not clip it


class Renderer:
    """Draws the people of a simulation (positions [T, P, 2]) through a camera."""

    def __init__(
        self,
        cfg: SceneConfig,
        camera: Camera,
        positions: FloatArray,
        velocities: FloatArray,
        rng: np.random.Generator,
    ) -> None:
        self.config = cfg
        self.camera = camera
        self.positions = positions
        self._walked = np.cumsum(np.hypot(*velocities.transpose(2, 0, 1)), axis=0) / cfg.fps
        n = positions.shape[1]
        self.body_height = np.clip(rng.normal(1.72, 0.08, n), 1.5, 1.95)
        self.body_width = np.clip(rng.normal(0.48, 0.04, n), 0.38, 0.6)
        hue = (np.arange(n) * 0.618033988749895 * 180 + rng.uniform(0, 180)) % 180
        hsv = np.stack([hue, rng.uniform(150, 255, n), rng.uniform(120, 250, n)], 1)
        self.shirt = cv2.cvtColor(hsv.astype(np.uint8)[None], cv2.COLOR_HSV2BGR)[0]
        self.trousers = TROUSERS[rng.integers(0, len(TROUSERS), n)]
        self.skin = SKIN[rng.integers(0, len(SKIN), n)]
        self.background = self._render_background()

    def people(self, frame: int) -> list[tuple[int, Person]]:
        """People whose box touches the image at a 1-based frame, sorted far to near."""
        p = self.positions[frame - 1]
        n = len(p)
        feet = np.column_stack([p, np.zeros(n)])
        heads = np.column_stack([p, self.body_height])
        uv_f, depth = self.camera.project(feet)
        uv_h, _ = self.camera.project(heads)
        half_w = 0.5 * self.body_width * self.camera.focal / np.maximum(depth, 1e-6)
        walked = self._walked[frame - 1]
        cfg = self.config
        out = []
        for i in range(n):
            if depth[i] <= 0.5:
                continue
            box = np.array([uv_f[i, 0] - half_w[i], uv_h[i, 1], uv_f[i, 0] + half_w[i], uv_f[i, 1]])
            if box[2] < 0 or box[0] >= cfg.width or box[3] < 0 or box[1] >= cfg.height:
                continue
            phase = walked[i] * 2 * np.pi / STRIDE
            out.append((i, Person(box, float(depth[i]), float(phase))))
        out.sort(key=lambda t: -t[1].depth)
        return out

    def _render_background(self) -> Image:
        cfg = self.config
        img = np.empty((cfg.height, cfg.width, 3), np.uint8)
        rows = np.linspace(0, 1, cfg.height)[:, None]
        img[:] = (
            np.array([150, 160, 150]) * (1 - 0.3 * rows) + np.array([60, 70, 70]) * 0.3 * rows
        )[:, None, :].astype(np.uint8)
        # Paving lines on the ground plane give the background some texture.
        for k in range(-10, 11):
            a, _ = self.camera.project(np.array([[k, 2.0, 0.0], [k, 30.0, 0.0]]))
            cv2.line(img, tuple(a[0].astype(int)), tuple(a[1].astype(int)), (120, 128, 125), 1)
        for yk in np.arange(2.0, 30.0, 1.0):
            a, _ = self.camera.project(np.array([[-20, yk, 0.0], [20, yk, 0.0]]))
            cv2.line(img, tuple(a[0].astype(int)), tuple(a[1].astype(int)), (120, 128, 125), 1)
        return img

    @staticmethod
    def silhouette(w: int, h: int, phase: float) -> tuple[npt.NDArray[np.uint8], ...]:
        """Masks (head, torso, legs) of a walking figure in a w x h box."""
        head = np.zeros((h, w), np.uint8)
        torso = np.zeros_like(head)
        legs = np.zeros_like(head)
        axes = (max(int(0.2 * w), 1), max(int(0.075 * h), 1))
        cv2.ellipse(head, (w // 2, int(0.075 * h)), axes, 0, 0, 360, 1, -1)
        cv2.rectangle(torso, (int(0.08 * w), int(0.15 * h)), (int(0.92 * w), int(0.53 * h)), 1, -1)
        swing = 0.18 * w * np.sin(phase)
        for side, sgn in ((0.33, 1.0), (0.67, -1.0)):
            hip = (int(side * w), int(0.5 * h))
            foot = (int(side * w + sgn * swing), h - 1)
            cv2.line(legs, hip, foot, 1, max(int(0.22 * w), 1))
        return head, torso, legs

    def render(self, frame: int) -> tuple[Image, Labels, list[tuple[int, Person]]]:
        """The image, a per-pixel person label (-1 = background) and the people drawn."""
        cfg = self.config
        img = self.background.copy()
        label = np.full((cfg.height, cfg.width), -1, np.int32)
        people = self.people(frame)
        for i, person in people:
            x1, y1, x2, y2 = np.round(person.box).astype(int)
            w, h = max(x2 - x1, 2), max(y2 - y1, 4)
            parts = self.silhouette(w, h, person.phase)
            person.area = sum(int(p.sum()) for p in parts)
            colours = (self.skin[i], self.shirt[i], self.trousers[i])
            # Clip the figure's box to the frame.
            cx0, cy0 = max(x1, 0), max(y1, 0)
            cx1, cy1 = min(x1 + w, cfg.width), min(y1 + h, cfg.height)
            if cx1 <= cx0 or cy1 <= cy0:
                continue
            sl = (slice(cy0 - y1, cy1 - y1), slice(cx0 - x1, cx1 - x1))
            region = (slice(cy0, cy1), slice(cx0, cx1))
            for part, colour in zip(parts, colours, strict=True):
                m = part[sl].astype(bool)
                img[region][m] = colour
                label[region][m] = i
        return img, label, people
