"""densepeds._core.step_crowd: shapes, errors, and crowd behaviour of the motion models."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from densepeds import _core
from densepeds.errors import ParameterError


def head_on(offset: float = 1.0) -> tuple[np.ndarray, ...]:
    """Two 20 x 40 px pedestrians 200 px apart walking at each other at 2 px/frame."""
    pos = np.array([[0.0, 0.0], [200.0, offset]])
    vel = np.array([[2.0, 0.0], [-2.0, 0.0]])
    axes = np.array([[20.0, 40.0], [20.0, 40.0]])
    return pos, vel, vel.copy(), axes


def ellipses_overlap(
    p: np.ndarray, q: np.ndarray, hp: np.ndarray, hq: np.ndarray, axes: np.ndarray
) -> bool:
    """Sampled test: does a boundary point of either ellipse fall inside the other?"""
    t = np.linspace(0.0, 2.0 * np.pi, 720, endpoint=False)

    def boundary(c: np.ndarray, h: np.ndarray, ax: np.ndarray) -> np.ndarray:
        u, v = 0.5 * ax[0] * np.cos(t), 0.5 * ax[1] * np.sin(t)
        return c + np.stack([h[0] * u - h[1] * v, h[1] * u + h[0] * v], axis=1)

    def inside(pts: np.ndarray, c: np.ndarray, h: np.ndarray, ax: np.ndarray) -> np.ndarray:
        d = pts - c
        u = (d @ h) / (0.5 * ax[0])
        v = (h[0] * d[:, 1] - h[1] * d[:, 0]) / (0.5 * ax[1])
        return u * u + v * v < 1.0 - 1e-6

    return bool(
        inside(boundary(p, hp, axes), q, hq, axes).any()
        or inside(boundary(q, hq, axes), p, hp, axes).any()
    )


def heading(v: np.ndarray, pref: np.ndarray) -> np.ndarray:
    """The model's orientation rule: the preferred direction, else the velocity."""
    for w in (pref, v):
        n = float(np.hypot(*w))
        if n > 1e-9:
            return w / n
    return np.array([1.0, 0.0])


def test_shapes_and_dtypes() -> None:
    pos, vel, pref, axes = head_on()
    new_vel, new_pos = _core.step_crowd(pos, vel, pref, axes)
    assert new_vel.shape == (2, 2) and new_pos.shape == (2, 2)
    assert new_vel.dtype == np.float64 and new_pos.dtype == np.float64
    np.testing.assert_allclose(new_pos, pos + new_vel)
    # Lists and float32 are converted; an empty crowd is fine.
    v32, _ = _core.step_crowd(pos.astype(np.float32), vel.tolist(), pref, axes, dt=0.5)
    assert v32.shape == (2, 2)
    empty = np.zeros((0, 2))
    ev, ep = _core.step_crowd(empty, empty, empty, empty)
    assert ev.shape == (0, 2) and ep.shape == (0, 2)


@pytest.mark.parametrize(
    ("kwargs", "exc"),
    [
        ({"positions": np.zeros((2, 3))}, ValueError),
        ({"positions": np.zeros(4)}, ValueError),
        ({"axes": np.zeros((3, 2))}, ValueError),
        ({"velocities": "abc"}, ValueError),
        ({"motion": "magic"}, ParameterError),
        ({"dt": 0.0}, ParameterError),
        ({"dt": float("nan")}, ParameterError),
        ({"time_horizon": -1.0}, ParameterError),
        ({"polygon_sides": 2}, ParameterError),
        ({"max_speed": float("inf")}, ParameterError),
        ({"threads": -1}, ParameterError),
        ({"threads": 100_000}, ParameterError),
    ],
)
def test_bad_input_raises(kwargs: dict[str, Any], exc: type[Exception]) -> None:
    pos, vel, pref, axes = head_on()
    args: dict[str, Any] = {
        "positions": pos,
        "velocities": vel,
        "pref_velocities": pref,
        "axes": axes,
    }
    options = {k: v for k, v in kwargs.items() if k not in args}
    args.update({k: v for k, v in kwargs.items() if k in args})
    with pytest.raises(exc):
        _core.step_crowd(
            args["positions"], args["velocities"], args["pref_velocities"], args["axes"], **options
        )


@pytest.mark.parametrize("motion", ["frvo", "rvo"])
def test_threads_give_the_same_velocities(motion: str) -> None:
    # 1,500 agents x 10 neighbours: large enough for the step to spread over threads.
    rng = np.random.default_rng(3)
    n = 1500
    pos = rng.uniform(0.0, 25.0 * np.sqrt(n), size=(n, 2))
    vel, pref = rng.uniform(-2.0, 2.0, size=(2, n, 2))
    axes = np.column_stack([rng.uniform(10, 30, n), rng.uniform(20, 50, n)])
    one, _ = _core.step_crowd(pos, vel, pref, axes, motion=motion, max_speed=4.0, threads=1)
    for threads in (0, 2, 3):
        many, _ = _core.step_crowd(
            pos, vel, pref, axes, motion=motion, max_speed=4.0, threads=threads
        )
        np.testing.assert_array_equal(one, many)
    assert not np.allclose(one, vel)  # the crowd constrains its agents


def _step_large_crowd(threads: int) -> np.ndarray:
    """FRVO on 1,500 agents (15,000 agent-neighbour pairs: enough to spread over threads)."""
    rng = np.random.default_rng(4)
    n = 1500
    pos = rng.uniform(0.0, 25.0 * np.sqrt(n), size=(n, 2))
    vel, pref = rng.uniform(-2.0, 2.0, size=(2, n, 2))
    axes = np.column_stack([rng.uniform(10, 30, n), rng.uniform(20, 50, n)])
    new_vel, _ = _core.step_crowd(pos, vel, pref, axes, max_speed=4.0, threads=threads)
    return new_vel


def _forked_child_step(expected: np.ndarray) -> None:
    np.testing.assert_array_equal(_step_large_crowd(0), expected)


def test_forked_child_steps_without_the_parents_threads() -> None:
    # The parent's thread pool does not exist in a forked child: the child's every-core step
    # must run on its own thread and finish, not wait for workers that are not there.
    import multiprocessing

    expected = _step_large_crowd(1)
    np.testing.assert_array_equal(_step_large_crowd(0), expected)  # makes the parent's pool
    child = multiprocessing.get_context("fork").Process(target=_forked_child_step, args=(expected,))
    child.start()
    child.join(timeout=60)
    if child.is_alive():
        child.kill()
        pytest.fail("the forked child's step hung")
    assert child.exitcode == 0


def test_concurrent_callers_share_the_threads_safely() -> None:
    # Python threads stepping at once (the GIL is released): every-core steps share the
    # process's thread pool (crowds from 1,100 agents spread over it). Each must still get the
    # one-thread velocities.
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(5)
    crowds = []
    for n in (60, 200, 1100, 2000):
        pos = rng.uniform(0.0, 25.0 * np.sqrt(n), size=(n, 2))
        vel, pref = rng.uniform(-2.0, 2.0, size=(2, n, 2))
        axes = np.column_stack([rng.uniform(10, 30, n), rng.uniform(20, 50, n)])
        crowds.append((pos, vel, pref, axes))

    def step(crowd: tuple[np.ndarray, ...], threads: int) -> np.ndarray:
        vel, _ = _core.step_crowd(*crowd, motion="frvo", max_speed=4.0, threads=threads)
        return vel

    expected = [step(c, 1) for c in crowds]
    jobs = [(k, threads) for _ in range(5) for k in range(len(crowds)) for threads in (0, 2)]
    with ThreadPoolExecutor(max_workers=4) as pool:
        results = list(pool.map(lambda job: step(crowds[job[0]], job[1]), jobs))
    for (k, _), got in zip(jobs, results, strict=True):
        np.testing.assert_array_equal(got, expected[k])


def test_constant_velocity_returns_preferred() -> None:
    rng = np.random.default_rng(0)
    pos, vel, pref = rng.normal(size=(3, 30, 2)) * 10
    axes = np.full((30, 2), 20.0)
    new_vel, new_pos = _core.step_crowd(pos, vel, pref, axes, motion="cv", dt=2.0)
    np.testing.assert_array_equal(new_vel, pref)
    np.testing.assert_allclose(new_pos, pos + 2.0 * pref)


@pytest.mark.parametrize("motion", ["frvo", "rvo"])
def test_head_on_pair_passes_without_overlap(motion: str) -> None:
    pos, vel, pref, axes = head_on()
    for _ in range(150):
        h = [heading(vel[i], pref[i]) for i in range(2)]
        assert not ellipses_overlap(pos[0], pos[1], h[0], h[1], axes[0]), pos
        vel, pos = _core.step_crowd(pos, vel, pref, axes, motion=motion, max_speed=4.0)
    # They got past each other rather than stopping.
    assert pos[0, 0] > pos[1, 0] + 20.0


def test_constant_velocity_head_on_collides() -> None:
    """The check above can fail: without avoidance the same pair overlaps."""
    pos, vel, pref, axes = head_on()
    overlapped = False
    for _ in range(100):
        overlapped |= ellipses_overlap(
            pos[0], pos[1], np.array([1.0, 0]), np.array([-1.0, 0]), axes[0]
        )
        vel, pos = _core.step_crowd(pos, vel, pref, axes, motion="cv")
    assert overlapped


def test_social_force_pushes_apart() -> None:
    pos = np.array([[0.0, 0.0], [10.0, 0.0]])
    zero = np.zeros((2, 2))
    axes = np.full((2, 2), 20.0)
    new_vel, _ = _core.step_crowd(pos, zero, zero, axes, motion="sf")
    assert new_vel[0, 0] < 0.0 < new_vel[1, 0]
    np.testing.assert_allclose(new_vel[0], -new_vel[1])


def test_degenerate_rows_are_defined() -> None:
    pos = np.array([[0.0, 0.0], [0.0, 0.0], [np.nan, 1.0], [5.0, 5.0]])
    vel = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 1.0], [np.inf, 0.0]])
    pref = np.array([[1.0, 0.0], [0.0, 0.0], [3.0, 4.0], [1.0, 1.0]])
    axes = np.array([[0.0, 0.0], [20.0, 40.0], [20.0, 40.0], [np.nan, 10.0]])
    for motion in ("frvo", "rvo", "sf", "cv"):
        new_vel, _ = _core.step_crowd(pos, vel, pref, axes, motion=motion)
        assert np.isfinite(new_vel).all(), motion
        # Rows with a non-finite position or velocity keep their preferred velocity.
        np.testing.assert_array_equal(new_vel[2:], pref[2:])
