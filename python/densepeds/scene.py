"""A built-in dense-crowd scene: try, test and demo DensePeds with nothing to download.

A seeded simulation of groups of pedestrians (packed at 2+ people per m^2) crossing a plaza, seen
by an elevated, tilted pinhole camera (people further away are smaller). Every frame is rendered
(simple figures with distinct shirt/trouser colours, painted far to near so near people occlude far
ones), which gives exact ground truth with visibility and per-person segmentation masks. A
detector model then misses mostly-occluded people, jitters boxes and adds false positives, and a
colour-histogram embedder stands in for the re-ID network. ``Scene.write`` saves it as a
MOTChallenge sequence (seqinfo.ini, gt/gt.txt, det/det.txt, img1/) so ``run``/``eval`` treat it
like real data.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from densepeds.errors import ParameterError
from densepeds.types import Detections
from densepeds.video import FrameRange, FrameSource

__all__ = ["Camera", "HistogramEmbedder", "Scene", "SceneConfig", "make_scene"]

FloatArray = npt.NDArray[np.float64]
Image = npt.NDArray[np.uint8]

TROUSERS = np.array(
    [[60, 40, 30], [30, 30, 30], [110, 110, 110], [40, 70, 110], [120, 160, 180], [90, 50, 20]],
    np.uint8,
)  # BGR: navy, black, grey, brown, khaki, blue
SKIN = np.array([[140, 170, 220], [90, 120, 170], [60, 80, 120]], np.uint8)


@dataclass(frozen=True)
class SceneConfig:
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

    def check(self) -> None:
        if self.frames < 1 or self.groups < 1 or self.group_size[0] < 1:
            raise ParameterError("scene needs at least one frame, one group and one person")
        if self.group_size[1] < self.group_size[0] or self.fps <= 0 or self.group_density <= 0:
            raise ParameterError("scene: bad group size, fps or density")


@dataclass(frozen=True)
class Camera:
    """Pinhole camera at (0, 0, height) metres looking along +y, tilted down by ``pitch_deg``."""

    height: float = 6.0
    pitch_deg: float = 35.0
    focal: float = 600.0
    cx: float = 320.0
    cy: float = 240.0

    def project(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """World points [N, 3] (x right, y ahead, z up) to pixels [N, 2] and depth [N]."""
        pitch = np.radians(self.pitch_deg)
        x, y, z = points[:, 0], points[:, 1], points[:, 2] - self.height
        depth = y * np.cos(pitch) - z * np.sin(pitch)
        down = -(y * np.sin(pitch) + z * np.cos(pitch))
        uv = np.stack([self.cx + self.focal * x / depth, self.cy + self.focal * down / depth], 1)
        return uv, depth


def _pack_disc(rng: np.random.Generator, n: int, density: float) -> FloatArray:
    """n points in a disc at about ``density`` per m^2, at least 0.45 m apart where possible."""
    radius = np.sqrt(n / (np.pi * density))
    pts: list[FloatArray] = []
    for _ in range(n):
        for _ in range(200):
            r, a = radius * np.sqrt(rng.random()), 2 * np.pi * rng.random()
            p = np.array([r * np.cos(a), r * np.sin(a)])
            if all(np.hypot(*(p - q)) >= 0.45 for q in pts):
                break
        pts.append(p)
    return np.array(pts)


def _simulate(cfg: SceneConfig, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
    """Ground positions [T, P, 2] and velocities [T, P, 2] of every person (social forces)."""
    x0, x1, y0, y1 = cfg.region
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    duration = cfg.frames / cfg.fps
    pos, goal_vel, group_of = [], [], []
    for g in range(cfg.groups):
        # Directions spread round the circle so groups cross each other near the middle.
        angle = 2 * np.pi * (g / cfg.groups) + rng.normal(0, 0.25)
        direction = np.array([np.cos(angle), np.sin(angle)])
        speed = rng.uniform(*cfg.speed)
        n = int(rng.integers(cfg.group_size[0], cfg.group_size[1] + 1))
        meet = centre + rng.uniform(-1.5, 1.5, 2)
        # Stagger the groups' arrival times over the clip.
        t_meet = duration * (0.25 + 0.5 * (g + rng.random()) / cfg.groups)
        start = meet - direction * speed * t_meet
        offsets = _pack_disc(rng, n, cfg.group_density)
        pos.append(start + offsets)
        goal_vel.append(np.tile(direction * speed, (n, 1)) + rng.normal(0, 0.05, (n, 2)))
        group_of.append(np.full(n, g))
    p = np.concatenate(pos)
    v0 = np.concatenate(goal_vel)
    groups = np.concatenate(group_of)
    v = v0.copy()
    substeps = 4
    dt = 1.0 / cfg.fps / substeps
    traj = np.empty((cfg.frames, len(p), 2))
    vels = np.empty_like(traj)
    same_group = groups[:, None] == groups[None, :]
    for t in range(cfg.frames):
        traj[t], vels[t] = p, v
        for _ in range(substeps):
            d = p[:, None, :] - p[None, :, :]
            dist = np.hypot(d[..., 0], d[..., 1]) + np.eye(len(p))
            # Exponential repulsion keeps ~0.5 m between bodies; a weak pull keeps groups together.
            push = 2.0 * np.exp((0.42 - dist) / 0.1)
            push[dist > 2.0] = 0
            np.fill_diagonal(push, 0)
            force = (push[..., None] * d / dist[..., None]).sum(1)
            members = same_group.sum(1, keepdims=True)
            centroid = (same_group @ p) / members
            force += 0.6 * (centroid - p) + (v0 - v) / 0.5
            v = v + dt * force
            speed = np.hypot(v[:, 0], v[:, 1])[:, None]
            v = np.where(speed > 2.0, v * 2.0 / np.maximum(speed, 1e-9), v)
            p = p + dt * v
    return traj, vels


@dataclass
class _Person:
    box: FloatArray  # x1, y1, x2, y2 (unclipped, full extent)
    depth: float
    phase: float
    area: int = 0  # silhouette pixels if nothing covered it and the frame did not clip it


class Scene(FrameSource):
    """The simulated sequence: frames, ground truth, detections with masks, an embedder."""

    def __init__(self, config: SceneConfig | None = None, camera: Camera | None = None) -> None:
        self.config = cfg = config or SceneConfig()
        cfg.check()
        self.camera = camera or Camera(cx=cfg.width / 2, cy=cfg.height / 2)
        rng = np.random.default_rng(cfg.seed)
        self.positions, self.velocities = _simulate(cfg, rng)
        self._walked = np.cumsum(np.hypot(*self.velocities.transpose(2, 0, 1)), axis=0) / cfg.fps
        n = self.positions.shape[1]
        self.body_height = np.clip(rng.normal(1.72, 0.08, n), 1.5, 1.95)
        self.body_width = np.clip(rng.normal(0.48, 0.04, n), 0.38, 0.6)
        hue = (np.arange(n) * 0.618033988749895 * 180 + rng.uniform(0, 180)) % 180
        hsv = np.stack([hue, rng.uniform(150, 255, n), rng.uniform(120, 250, n)], 1)
        self.shirt = cv2.cvtColor(hsv.astype(np.uint8)[None], cv2.COLOR_HSV2BGR)[0]
        self.trousers = TROUSERS[rng.integers(0, len(TROUSERS), n)]
        self.skin = SKIN[rng.integers(0, len(SKIN), n)]
        self.name = f"DensePeds-scene-{cfg.seed}"
        self.fps = cfg.fps
        self.size = (cfg.width, cfg.height)
        self.length = cfg.frames
        self._background = self._render_background()
        self.gt_rows, self.detections = self._annotate(np.random.default_rng(cfg.seed + 1))

    # --- geometry and rendering --------------------------------------------------------------

    def _people(self, frame: int) -> list[tuple[int, _Person]]:
        """People whose box touches the image at a 1-based frame, sorted far to near."""
        p = self.positions[frame - 1]
        n = len(p)
        feet = np.column_stack([p, np.zeros(n)])
        heads = np.column_stack([p, self.body_height])
        uv_f, depth = self.camera.project(feet)
        uv_h, _ = self.camera.project(heads)
        half_w = 0.5 * self.body_width * self.camera.focal / np.maximum(depth, 1e-6)
        walked = self._walked[frame - 1]
        out = []
        for i in range(n):
            if depth[i] <= 0.5:
                continue
            box = np.array([uv_f[i, 0] - half_w[i], uv_h[i, 1], uv_f[i, 0] + half_w[i], uv_f[i, 1]])
            if (
                box[2] < 0
                or box[0] >= self.config.width
                or box[3] < 0
                or box[1] >= self.config.height
            ):
                continue
            phase = walked[i] * 2 * np.pi / 1.3  # a stride of ~1.3 m
            out.append((i, _Person(box, float(depth[i]), float(phase))))
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
    def _silhouette(w: int, h: int, phase: float) -> tuple[npt.NDArray[np.uint8], ...]:
        """Masks (head, torso, legs) of a walking figure in a w x h box."""
        head = np.zeros((h, w), np.uint8)
        torso = np.zeros_like(head)
        legs = np.zeros_like(head)
        cv2.ellipse(
            head,
            (w // 2, int(0.075 * h)),
            (max(int(0.2 * w), 1), max(int(0.075 * h), 1)),
            0,
            0,
            360,
            1,
            -1,
        )
        cv2.rectangle(torso, (int(0.08 * w), int(0.15 * h)), (int(0.92 * w), int(0.53 * h)), 1, -1)
        swing = 0.18 * w * np.sin(phase)
        for side, sgn in ((0.33, 1.0), (0.67, -1.0)):
            hip = (int(side * w), int(0.5 * h))
            foot = (int(side * w + sgn * swing), h - 1)
            cv2.line(legs, hip, foot, 1, max(int(0.22 * w), 1))
        return head, torso, legs

    def render(self, frame: int) -> tuple[Image, npt.NDArray[np.int32], list[tuple[int, _Person]]]:
        """The image, a per-pixel person label (-1 = background) and the people drawn."""
        cfg = self.config
        img = self._background.copy()
        label = np.full((cfg.height, cfg.width), -1, np.int32)
        people = self._people(frame)
        for i, person in people:
            x1, y1, x2, y2 = np.round(person.box).astype(int)
            w, h = max(x2 - x1, 2), max(y2 - y1, 4)
            parts = self._silhouette(w, h, person.phase)
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

    def frame(self, frame: int) -> Image:
        return self.render(frame)[0]

    def frames(self, rng: FrameRange | None = None) -> Iterator[tuple[int, Image | None]]:
        rng = (rng or FrameRange()).clip(self.config.frames)
        assert rng.last is not None
        for k in range(rng.first, rng.last + 1):
            yield k, self.frame(k)

    # --- ground truth and the detector model --------------------------------------------------

    def _annotate(self, rng: np.random.Generator) -> tuple[FloatArray, dict[int, Detections]]:
        cfg = self.config
        gt: list[list[float]] = []
        dets: dict[int, Detections] = {}
        for k in range(1, cfg.frames + 1):
            _, label, people = self.render(k)
            boxes, scores, masks, mboxes, sources = [], [], [], [], []
            for i, person in people:
                x1, y1, x2, y2 = np.round(person.box).astype(int)
                w, h = max(x2 - x1, 2), max(y2 - y1, 4)
                full = person.area
                region = label[max(y1, 0) : max(y1 + h, 0), max(x1, 0) : max(x1 + w, 0)]
                visible = int((region == i).sum())
                vis = visible / max(full, 1)
                gt.append(
                    [k, i + 1, *person.box[:2], *(person.box[2:] - person.box[:2]), 1, 1, vis]
                )
                # Detection probability rises from 0 at miss_visibility to 0.97 a quarter higher.
                p_det = 0.97 * np.clip((vis - cfg.miss_visibility) / 0.25, 0, 1)
                if rng.random() >= p_det:
                    continue
                size = person.box[2:] - person.box[:2]
                centre = (person.box[:2] + person.box[2:]) / 2 + rng.normal(
                    0, cfg.box_jitter, 2
                ) * size
                size = size * rng.normal(1.0, cfg.box_jitter, 2).clip(0.8, 1.2)
                box = np.concatenate([centre - size / 2, centre + size / 2])
                mb = self._mask_box(box)
                boxes.append(box)
                scores.append(float(np.clip(0.35 + 0.6 * vis + rng.normal(0, 0.05), 0.05, 1.0)))
                masks.append(label[mb[1] : mb[3], mb[0] : mb[2]] == i)
                mboxes.append(mb)
                sources.append(i + 1)
            for _ in range(rng.poisson(cfg.false_positives)):
                box = self._false_positive(rng)
                mb = self._mask_box(box)
                m = np.zeros((mb[3] - mb[1], mb[2] - mb[0]), np.uint8)
                if m.size:
                    cv2.ellipse(
                        m,
                        (m.shape[1] // 2, m.shape[0] // 2),
                        (max(m.shape[1] // 2, 1), max(m.shape[0] // 2, 1)),
                        0,
                        0,
                        360,
                        1,
                        -1,
                    )
                boxes.append(box)
                scores.append(float(rng.uniform(0.1, 0.5)))
                masks.append(m.astype(bool))
                mboxes.append(mb)
                sources.append(-1)
            if boxes:
                # extra["gt_id"]: the person each detection came from (-1: false positive).
                extra = {"gt_id": np.array(sources, np.int64)}
                dets[k] = Detections(
                    np.array(boxes), np.array(scores), masks, np.array(mboxes), extra
                )
        return np.array(gt, np.float64).reshape(-1, 9), dets

    def _mask_box(self, box: FloatArray) -> npt.NDArray[np.int32]:
        cfg = self.config
        x0, y0 = (
            int(np.clip(np.floor(box[0]), 0, cfg.width)),
            int(np.clip(np.floor(box[1]), 0, cfg.height)),
        )
        x1, y1 = (
            int(np.clip(np.ceil(box[2]), x0, cfg.width)),
            int(np.clip(np.ceil(box[3]), y0, cfg.height)),
        )
        return np.array([x0, y0, x1, y1], np.int32)

    def _false_positive(self, rng: np.random.Generator) -> FloatArray:
        x0, x1, y0, y1 = self.config.region
        g = np.array([[rng.uniform(x0, x1), rng.uniform(y0, y1), 0.0]])
        (foot,), (depth,) = self.camera.project(g)
        h = rng.uniform(0.8, 1.9) * self.camera.focal / depth
        w = h * rng.uniform(0.25, 0.4)
        return np.array([foot[0] - w / 2, foot[1] - h, foot[0] + w / 2, foot[1]])

    # --- summaries and export -----------------------------------------------------------------

    def local_density(self) -> float:
        """Mean over frames and people in view of the people within 1 m (self included) per m^2."""
        values = []
        for k in range(1, self.config.frames + 1):
            ids = [i for i, _ in self._people(k)]
            if len(ids) < 2:
                continue
            p = self.positions[k - 1, ids]
            d = np.hypot(*(p[:, None, :] - p[None, :, :]).transpose(2, 0, 1))
            values.append(((d <= 1.0).sum(1) / np.pi).mean())
        return float(np.mean(values)) if values else 0.0

    def embedder(self) -> HistogramEmbedder:
        return HistogramEmbedder()

    def write(self, out_dir: str | os.PathLike[str], *, images: bool = True) -> Path:
        """Save as a MOTChallenge sequence folder ``out_dir/<name>`` and return its path.

        Every file is written completely or not at all (a failure raises
        :class:`~densepeds.errors.OutputError`), and ``seqinfo.ini`` last, so that a folder
        left by a failed write is not a sequence."""
        from densepeds.motio import write_bytes, write_text

        cfg = self.config
        seq = Path(out_dir) / self.name
        gt_lines = [
            f"{int(f)},{int(i)},{x:.2f},{y:.2f},{w:.2f},{h:.2f},1,1,{v:.3f}\n"
            for f, i, x, y, w, h, _, _, v in self.gt_rows.tolist()
        ]
        write_text(seq / "gt" / "gt.txt", "".join(gt_lines))
        det_lines = []
        for k in sorted(self.detections):
            d = self.detections[k]
            for (x1, y1, x2, y2), s in zip(d.boxes.tolist(), d.scores.tolist(), strict=True):
                det_lines.append(
                    f"{k},-1,{x1:.2f},{y1:.2f},{x2 - x1:.2f},{y2 - y1:.2f},{s:.4f},-1,-1,-1\n"
                )
        write_text(seq / "det" / "det.txt", "".join(det_lines))
        if images:
            for k, image in self.frames():
                assert image is not None
                ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])
                assert ok, "JPEG encoding of a rendered frame failed"
                write_bytes(seq / "img1" / f"{k:06d}.jpg", jpeg.tobytes())
        write_text(
            seq / "seqinfo.ini",
            f"[Sequence]\nname={self.name}\nimDir=img1\nframeRate={cfg.fps:g}\n"
            f"seqLength={cfg.frames}\nimWidth={cfg.width}\nimHeight={cfg.height}\nimExt=.jpg\n",
        )
        return seq


def make_scene(seed: int = 0, frames: int = 150, **overrides: object) -> Scene:
    """The default scene (seeded: the same seed gives the same frames, gt and detections)."""
    return Scene(SceneConfig(seed=seed, frames=frames, **overrides))  # type: ignore[arg-type]


class HistogramEmbedder:
    """A stand-in for re-ID on the scene: colour histograms of the upper and lower body.

    Implements the ReID ``embed`` contract. ``segmented`` counts only the person's mask pixels
    (the histogram equivalent of painting the background white); ``bbox`` counts the whole box,
    background and neighbours included.
    """

    bins = 4

    def embed(
        self, frame: Image, dets: Detections, features: str = "segmented"
    ) -> npt.NDArray[np.float32]:
        if features not in ("segmented", "bbox"):
            raise ParameterError(f"features {features!r}: expected segmented or bbox")
        out = np.zeros((len(dets), 2 * self.bins**3), np.float32)
        height, width = frame.shape[:2]
        for j, box in enumerate(dets.boxes):
            if features == "segmented" and dets.masks is not None and dets.mask_boxes is not None:
                x0, y0, x1, y1 = dets.mask_boxes[j]
                mask = dets.masks[j]
            else:
                x0, y0 = int(max(np.floor(box[0]), 0)), int(max(np.floor(box[1]), 0))
                x1, y1 = int(min(np.ceil(box[2]), width)), int(min(np.ceil(box[3]), height))
                mask = np.ones((max(y1 - y0, 0), max(x1 - x0, 0)), bool)
            crop = frame[y0:y1, x0:x1]
            if crop.size == 0 or not mask.any():
                continue
            q = (crop // (256 // self.bins)).astype(np.int32)
            code = (q[..., 0] * self.bins + q[..., 1]) * self.bins + q[..., 2]
            half = crop.shape[0] // 2
            for part, rows in enumerate((slice(0, half), slice(half, None))):
                sel = code[rows][mask[rows]]
                hist = np.bincount(sel, minlength=self.bins**3).astype(np.float32)
                out[j, part * self.bins**3 : (part + 1) * self.bins**3] = np.sqrt(hist)
        norms = np.linalg.norm(out, axis=1, keepdims=True)
        return (out / np.where(norms > 0, norms, 1)).astype(np.float32)
