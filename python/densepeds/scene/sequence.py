"""The scene as a sequence: a frame source with ground truth and detections, written to disk
in the MOTChallenge layout, and per-person visibility for tests of occlusion handling."""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from densepeds.errors import ParameterError
from densepeds.io.video import FrameRange, FrameSource
from densepeds.scene.config import SceneConfig
from densepeds.scene.detector import annotate
from densepeds.scene.embedder import HistogramEmbedder
from densepeds.scene.rendering import Image, Labels, Person, Renderer
from densepeds.scene.simulation import Camera, simulate, straight_lines

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Occlusion:
    """A person (gt id) hidden from ``first`` to ``last`` (1-based frames, inclusive), seen
    before and after."""

    person: int
    first: int
    last: int

    @property
    def frames(self) -> int:
        return self.last - self.first + 1


class Scene(FrameSource):
    """The simulated sequence: frames, ground truth, detections with masks, an embedder.

    ``trajectories``: positions and velocities [T, P, 2] on the ground (metres) to draw instead
    of the config's simulated groups (T must equal ``config.frames``).
    """

    def __init__(
        self,
        config: SceneConfig | None = None,
        camera: Camera | None = None,
        trajectories: tuple[FloatArray, FloatArray] | None = None,
    ) -> None:
        self.config = cfg = config or SceneConfig()
        cfg.check()
        self.camera = camera or Camera(cx=cfg.width / 2, cy=cfg.height / 2)
        rng = np.random.default_rng(cfg.seed)
        if trajectories is None:
            self.positions, self.velocities = simulate(cfg, rng)
        else:
            self.positions, self.velocities = (np.asarray(a, np.float64) for a in trajectories)
            if self.positions.shape[0] != cfg.frames:
                raise ParameterError(
                    f"trajectories have {self.positions.shape[0]} frames, not {cfg.frames}"
                )
        self.renderer = Renderer(cfg, self.camera, self.positions, self.velocities, rng)
        self.name = f"DensePeds-scene-{cfg.seed}"
        self.fps = cfg.fps
        self.size = (cfg.width, cfg.height)
        self.length = cfg.frames
        self.gt_rows, self.detections = annotate(
            self.renderer, np.random.default_rng(cfg.seed + 1), np.random.default_rng(cfg.seed + 2)
        )

    @property
    def _background(self) -> Image:
        return self.renderer.background

    def render(self, frame: int) -> tuple[Image, Labels, list[tuple[int, Person]]]:
        """The image, a per-pixel person label (-1 = background, else gt id - 1), the people."""
        return self.renderer.render(frame)

    def frame(self, frame: int) -> Image:
        return self.render(frame)[0]

    def frames(self, rng: FrameRange | None = None) -> Iterator[tuple[int, Image | None]]:
        rng = (rng or FrameRange()).clip(self.config.frames)
        assert rng.last is not None
        for k in range(rng.first, rng.last + 1):
            yield k, self.frame(k)

    # --- summaries ----------------------------------------------------------------------------

    def local_density(self) -> float:
        """Mean over frames and people in view of the people within 1 m (self included) per m^2."""
        values = []
        for k in range(1, self.config.frames + 1):
            ids = [i for i, _ in self.renderer.people(k)]
            if len(ids) < 2:
                continue
            p = self.positions[k - 1, ids]
            d = np.hypot(*(p[:, None, :] - p[None, :, :]).transpose(2, 0, 1))
            values.append(((d <= 1.0).sum(1) / np.pi).mean())
        return float(np.mean(values)) if values else 0.0

    def visibility(self) -> FloatArray:
        """Visibility [frames, people] of every person (gt id = column + 1) in every frame: the
        share of the silhouette shown; NaN where the person's box is out of the frame."""
        out = np.full((self.config.frames, self.positions.shape[1]), np.nan)
        rows = self.gt_rows
        out[rows[:, 0].astype(int) - 1, rows[:, 1].astype(int) - 1] = rows[:, 8]
        return out

    def detected(self) -> npt.NDArray[np.bool_]:
        """Whether the stand-in detector found each person [frames, people] in each frame."""
        out = np.zeros((self.config.frames, self.positions.shape[1]), bool)
        for k, dets in self.detections.items():
            ids = dets.extra["gt_id"]
            out[k - 1, ids[ids > 0] - 1] = True
        return out

    def occlusions(self, hidden_below: float = 0.25, seen_above: float = 0.5) -> list[Occlusion]:
        """Every longest run of frames in which a person is mostly hidden (visibility <
        ``hidden_below``) while well seen (visibility >= ``seen_above``) before and after it
        without leaving the view in between."""
        vis = self.visibility()
        out = []
        for person in range(vis.shape[1]):
            v = vis[:, person]
            hidden = v < hidden_below  # NaN (out of view) compares False
            k = 0
            while k < len(v):
                if not hidden[k]:
                    k += 1
                    continue
                end = k
                while end + 1 < len(v) and hidden[end + 1]:
                    end += 1
                if self._seen(v[k - 1 :: -1] if k else v[:0], seen_above) and self._seen(
                    v[end + 1 :], seen_above
                ):
                    out.append(Occlusion(person + 1, k + 1, end + 1))
                k = end + 1
        return out

    def matched_ids(self, rows: npt.ArrayLike, min_iou: float = 0.5) -> npt.NDArray[np.int64]:
        """Which track id covers each person [frames, people] (0: none), from tracker output
        ``rows`` (frame, id, x1, y1, x2, y2, ...): per frame, the one-to-one assignment of
        output boxes to every person's full box with the largest total IoU, pairs under
        ``min_iou`` dropped. A person hidden and found again under one id keeps that id here."""
        from densepeds.boxes import match_boxes

        out = np.zeros((self.config.frames, self.positions.shape[1]), np.int64)
        r = np.asarray(rows, np.float64).reshape(-1, np.shape(rows)[-1] if np.size(rows) else 7)
        gt = self.gt_rows
        for k in range(1, self.config.frames + 1):
            g, t = gt[gt[:, 0] == k], r[r[:, 0] == k]
            if not len(g) or not len(t):
                continue
            boxes = np.c_[g[:, 2:4], g[:, 2:4] + g[:, 4:6]]
            for i, j in zip(*match_boxes(boxes, t[:, 2:6], min_iou), strict=True):
                out[k - 1, int(g[i, 1]) - 1] = int(t[j, 1])
        return out

    @staticmethod
    def _seen(v: FloatArray, seen_above: float) -> bool:
        """Whether visibilities ``v`` reach ``seen_above`` before the person leaves the view."""
        for x in v:
            if np.isnan(x):
                return False
            if x >= seen_above:
                return True
        return False

    def embedder(self) -> HistogramEmbedder:
        return HistogramEmbedder()

    # --- export -------------------------------------------------------------------------------

    def write(self, out_dir: str | os.PathLike[str], *, images: bool = True) -> Path:
        """Save as a MOTChallenge sequence folder ``out_dir/<name>`` and return its path.

        Every file is written completely or not at all (a failure raises
        :class:`~densepeds.errors.OutputError`), and ``seqinfo.ini`` last, so that a folder
        left by a failed write is not a sequence."""
        from densepeds.io.mot import write_bytes, write_text

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


def make_crossing_scene(
    seed: int = 0, frames: int = 50, same_direction: bool = True, **overrides: object
) -> Scene:
    """A two-person scene made for occlusion: a near walker (4 m from the camera, 1.4 m/s)
    passes in front of a far one (10 m, 0.8 m/s) in the middle of the clip and hides all but a
    glimpse between their legs for several frames (``Scene.occlusions`` and ``Scene.detected``
    say which). The far walker goes the
    same way as the near one, or the other way with ``same_direction=False`` (a shorter
    occlusion). Seen at 25 fps by a level camera at waist height, so that the near walker's
    figure covers the far one's from head to feet; no false positives by default."""
    settings: dict[str, object] = {"fps": 25.0, "false_positives": 0.0, **overrides}
    cfg = SceneConfig(seed=seed, frames=frames, **settings)  # type: ignore[arg-type]
    duration = frames / cfg.fps
    walkers = ((4.0, 1.4, 1.0), (10.0, 0.8, 1.0 if same_direction else -1.0))
    starts, vels = [], []
    for y, speed, sign in walkers:
        # Both reach x = 0 (in line with the camera) in the middle of the clip.
        starts.append([-sign * speed * duration / 2, y])
        vels.append([sign * speed, 0.0])
    camera = Camera(height=1.0, pitch_deg=0.0, cx=cfg.width / 2, cy=cfg.height / 2)
    return Scene(cfg, camera, straight_lines(np.array(starts), np.array(vels), frames, cfg.fps))
