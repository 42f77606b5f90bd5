"""Where the scene's people walk: groups crossing a plaza (social forces), and the camera."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from densepeds.scene.config import SceneConfig

FloatArray = npt.NDArray[np.float64]


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


def pack_disc(rng: np.random.Generator, n: int, density: float) -> FloatArray:
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


def simulate(cfg: SceneConfig, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
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
        offsets = pack_disc(rng, n, cfg.group_density)
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


def straight_lines(
    starts: FloatArray, velocities: FloatArray, frames: int, fps: float
) -> tuple[FloatArray, FloatArray]:
    """Positions and velocities [T, P, 2] of people walking at constant velocity from ``starts``."""
    t = np.arange(frames)[:, None, None] / fps
    vel = np.broadcast_to(np.asarray(velocities, np.float64), (frames, *np.shape(velocities)))
    return np.asarray(starts, np.float64)[None] + t * vel, vel.copy()
