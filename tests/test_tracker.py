"""densepeds.tracking.Tracker: lifecycle, crossing, determinism, inputs, parameters, real dets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from densepeds import _core
from densepeds.errors import InputError, ParameterError
from densepeds.tracking import Tracker, Tracks

from tests.conftest import shared_path


def box(cx: float, cy: float, w: float = 40.0, h: float = 100.0) -> list[float]:
    return [cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2]


def step(t: Tracker, boxes: list[list[float]]) -> Tracks:
    return t.update(np.array(boxes, np.float64).reshape(-1, 4), np.ones(len(boxes)))


def test_tentative_until_n_init_and_deleted_after_max_age() -> None:
    t = Tracker("cv", n_init=2, max_age=3, output_lost=0)  # report matched tracks only
    assert len(step(t, [box(100, 100)]).ids) == 0
    out = step(t, [box(102, 100)])
    assert out.ids.tolist() == [1] and out.det_index.tolist() == [0]
    for _ in range(4):  # unmatched: kept for max_age frames, then gone
        assert len(step(t, []).ids) == 0
    out = step(t, [box(110, 100)])
    assert len(out.ids) == 0  # a new tentative track, not id 1
    out = step(t, [box(112, 100)])
    assert out.ids.tolist() == [2]


def test_output_types_and_matched_boxes_are_the_detections() -> None:
    t = Tracker("cv", n_init=1)
    boxes = np.array([box(100, 100), box(300, 100)], np.float32)
    out = t.update(boxes, np.array([0.9, 0.8], np.float32))
    assert isinstance(out, Tracks)
    assert out.ids.dtype == np.int64 and out.boxes.dtype == np.float64
    assert out.scores.dtype == np.float32 and out.det_index.dtype == np.int64
    assert out.boxes.shape == (2, 4)
    np.testing.assert_array_equal(out.boxes, boxes[out.det_index].astype(np.float64))
    np.testing.assert_allclose(out.scores, [0.9, 0.8])


def test_two_crossing_tracks_keep_ids_with_constant_velocity() -> None:
    t = Tracker("cv", n_init=1)
    for k in range(60):
        out = step(t, [box(100 + 6 * k, 200), box(460 - 6 * k, 215)])
        # detection 0 (walking right) got id 1 in the first frame and keeps it through the crossing
        assert dict(zip(out.det_index.tolist(), out.ids.tolist(), strict=True)) == {0: 1, 1: 2}, k


def _crowd(n_people: int, n_frames: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    pos = rng.random((n_people, 2)) * [1800, 900] + [60, 90]
    vel = rng.normal(0, 2, (n_people, 2))
    frames = []
    for _ in range(n_frames):
        pos += vel
        keep = rng.random(n_people) > 0.1  # missed detections
        jitter = rng.normal(0, 1.5, (n_people, 2))
        c = (pos + jitter)[keep]
        b = np.hstack([c - [20, 50], c + [20, 50]])
        frames.append((b, rng.random(len(b)).astype(np.float32)))
    return frames


@pytest.mark.parametrize("motion", ["frvo", "rvo", "sf", "cv"])
def test_same_input_gives_same_ids(motion: str) -> None:
    frames = _crowd(60, 40, seed=3)

    def run(t: Tracker) -> list[tuple[list[int], list[int]]]:
        return [(o.ids.tolist(), o.det_index.tolist()) for o in (t.update(b, s) for b, s in frames)]

    t = Tracker(motion)
    first = run(t)
    assert sum(len(ids) for ids, _ in first) > 0
    assert run(Tracker(motion)) == first
    t.reset()
    assert run(t) == first


def test_float32_float64_lists_and_noncontiguous_agree() -> None:
    frames = _crowd(30, 15, seed=4)
    outs = []
    for convert in (
        lambda a: a.astype(np.float64),
        lambda a: a.astype(np.float32).astype(np.float64),
        lambda a: np.asfortranarray(a.astype(np.float32).astype(np.float64)),
        lambda a: a.astype(np.float32).astype(np.float64).tolist(),
    ):
        t = Tracker("cv")
        outs.append([t.update(convert(b), s).ids.tolist() for b, s in frames])
    assert outs[1] == outs[2] == outs[3]
    t32 = Tracker("cv")
    assert [t32.update(b.astype(np.float32), s).ids.tolist() for b, s in frames] == outs[1]


def test_embeddings_drive_the_first_stage() -> None:
    # Two people swap places between frames 2 and 3: IoU alone swaps ids, appearance does not.
    ea, eb = [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]
    emb = np.array([ea, eb], np.float32)
    for use_emb, expected in ((True, {0: 1, 1: 2}), (False, {0: 2, 1: 1})):
        t = Tracker("cv", n_init=1, gate_radius=2.0)
        e = emb if use_emb else None
        for _ in range(2):
            t.update(np.array([box(100, 100), box(130, 100)]), np.ones(2), e)
        out = t.update(np.array([box(128, 100), box(102, 100)]), np.ones(2), e)
        assert dict(zip(out.det_index.tolist(), out.ids.tolist(), strict=True)) == expected


BAD_INPUTS = {
    "boxes wrong width": (np.zeros((2, 3)), np.ones(2), None),
    "boxes 1-d": (np.zeros(4), np.ones(1), None),
    "scores length": (np.array([box(1, 1)]), np.ones(2), None),
    "scores 2-d": (np.array([box(1, 1)]), np.ones((1, 1)), None),
    "nan box": (np.array([[0, 0, np.nan, 1.0]]), np.ones(1), None),
    "inf box": (np.array([[0, 0, np.inf, 1.0]]), np.ones(1), None),
    "inverted box": (np.array([[5.0, 0, 1, 1]]), np.ones(1), None),
    # Areas overflow from about 1e154 (accepted and never tracked before).
    "huge box": (np.array([[0, 0, 1e154, 2e154]]), np.ones(1), None),
    "nan score": (np.array([box(1, 1)]), np.array([np.nan]), None),
    "string boxes": (np.array([["a", "b", "c", "d"]]), np.ones(1), None),
    "embedding rows": (np.array([box(1, 1)]), np.ones(1), np.ones((2, 8), np.float32)),
    "embedding 1-d": (np.array([box(1, 1)]), np.ones(1), np.ones(8, np.float32)),
    "embedding nan": (np.array([box(1, 1)]), np.ones(1), np.full((1, 8), np.nan, np.float32)),
}


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_input_raises_and_leaves_state_unchanged(case: str) -> None:
    boxes, scores, emb = BAD_INPUTS[case]
    t = Tracker("cv")
    with pytest.raises(InputError):
        t.update(boxes, scores, emb)
    assert t.frame_count == 0
    # The raw extension raises ValueError (InputError is one; it never panics).
    core = _core.Tracker("cv")
    with pytest.raises(ValueError):
        core.update(np.asarray(boxes, np.float64), np.asarray(scores, np.float64), emb)


def test_wrong_dtype_in_core_is_input_error() -> None:
    core = _core.Tracker("cv")
    with pytest.raises(InputError, match="dtype"):
        core.update(np.zeros((1, 4), np.int64), np.ones(1))  # type: ignore[arg-type]
    with pytest.raises(InputError, match="numpy array"):
        core.update([[0, 0, 1, 1]], np.ones(1))  # type: ignore[arg-type]


@pytest.mark.parametrize("which", ["boxes", "scores", "embeddings"])
def test_complex_arrays_are_refused_not_truncated(which: str) -> None:
    args: dict[str, object] = {
        "boxes": np.array([box(1, 1)]),
        "scores": np.ones(1),
        "embeddings": np.ones((1, 4), np.float32),
    }
    args[which] = np.asarray(args[which]) + 1j
    t = Tracker("cv")
    with pytest.raises(InputError, match=f"{which} must hold real numbers"):
        t.update(**args)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=f"{which} must be a float32 or float64"):
        _core.Tracker("cv").update(**args)  # type: ignore[arg-type]
    assert t.frame_count == 0
    pts = np.zeros((2, 2))
    with pytest.raises(InputError, match="axes must be a real-valued"):
        _core.step_crowd(pts, pts, pts, pts + 1j)


def test_boxes_up_to_the_coordinate_limit_are_tracked_as_small_ones() -> None:
    def ids_and_boxes(scale: float, motion: str) -> tuple[list[int], np.ndarray]:
        # Reported boxes are the detections' (no pull toward the prediction, whose speed is
        # capped at max_speed pixels a frame at any scale).
        t = Tracker(motion, n_init=1, output_lost=0, position_smoothing=0.0)
        base = np.array([box(1.0, 1.0, 0.1, 0.3), box(1.12, 1.0, 0.1, 0.3)])
        for k in range(5):
            out = t.update(base * scale * (1 + 1e-3 * k), np.ones(2))
        return out.ids.tolist(), out.boxes / scale

    for motion in ("cv", "frvo"):
        small_ids, small = ids_and_boxes(1e3, motion)
        big_ids, big = ids_and_boxes(7e149, motion)  # 1.15 * 7e149 is within 1e150
        assert small_ids == big_ids == [1, 2]
        np.testing.assert_allclose(big, small, rtol=1e-12)
    with pytest.raises(InputError, match="beyond 1e150"):
        Tracker("cv").update(np.array([[0, 0, 1e154, 2e154]]), np.ones(1))


def test_a_tracker_used_by_two_threads_at_once_says_so() -> None:
    """One tracker holds one sequence: concurrent use is a clear RuntimeError, never a mix."""
    import threading

    rng = np.random.default_rng(0)
    corners = rng.uniform(0, 2000, (1500, 2))
    boxes = np.hstack([corners, corners + [30, 80]])
    t = Tracker("frvo", threads=1)
    errors: list[BaseException] = []
    updated: list[int] = []
    start = threading.Barrier(4)

    def worker() -> None:
        start.wait()
        for _ in range(10):
            try:
                t.update(boxes, np.ones(len(boxes)))
                updated.append(1)
                _ = t.params, t.frame_count
            except Exception as e:  # every failure is checked below
                errors.append(e)

    threads = [threading.Thread(target=worker) for _ in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert errors, "no overlap happened (the updates are expected to release the GIL)"
    for e in errors:
        assert isinstance(e, RuntimeError) and "one Tracker per thread" in str(e), repr(e)
    # Each update ran whole or not at all: the frame count is the number that succeeded.
    assert t.frame_count == len(updated)


def test_embedding_dimension_must_not_change() -> None:
    t = Tracker("cv")
    b = np.array([box(100, 100)])
    t.update(b, np.ones(1), np.ones((1, 8), np.float32))
    t.update(b, np.ones(1))  # frames without embeddings are allowed
    with pytest.raises(InputError, match="dimension changed"):
        t.update(b, np.ones(1), np.ones((1, 16), np.float32))
    t.reset()
    t.update(b, np.ones(1), np.ones((1, 16), np.float32))


def test_any_score_range_and_empty_frames() -> None:
    boxes = np.array([box(100, 100), box(300, 100)])
    # Any score is accepted; the default thresholds are for [0, 1] scores, so -12 starts no track.
    out = Tracker("cv", n_init=1).update(boxes, np.array([93.7, -12.0]))
    assert out.det_index.tolist() == [0]
    inf = float("-inf")
    t = Tracker("cv", n_init=1, det_threshold=inf, new_track_threshold=inf, output_lost=0)
    assert len(t.update(boxes, np.array([93.7, -12.0])).ids) == 2
    assert len(t.update(np.zeros((0, 4)), np.zeros(0)).ids) == 0
    assert len(t.update([], []).ids) == 0


def test_default_thresholds_low_scores_extend_tracks_but_start_none() -> None:
    t = Tracker("cv", n_init=1)
    assert step(t, [box(100, 100)]).ids.tolist() == [1]
    low = np.array([box(103, 100), box(400, 100)])
    out = t.update(low, np.array([0.1, 0.1]))
    assert out.ids.tolist() == [1] and out.det_index.tolist() == [0]
    assert t.params["det_threshold"] == 0.3 and t.params["second_pass"] is True


@pytest.mark.parametrize(
    "params",
    [
        {"nope": 1},
        {"n_init": 0},
        {"n_init": 1.5},
        {"max_age": -1},
        {"iou_threshold": 1.5},
        {"appearance_threshold": -0.1},
        {"gate_radius": 0.0},
        {"second_pass": 1},
        {"det_threshold": float("nan")},
        {"det_threshold": True},
        {"max_speed": -1.0},
        {"output_lost": -1},
        {"threads": -1},
        {"threads": 100_000},
    ],
)
def test_bad_parameters_raise(params: dict[str, object]) -> None:
    with pytest.raises(ParameterError):
        Tracker("cv", **params)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        _core.Tracker("cv", **params)  # type: ignore[arg-type]


def test_unknown_motion_and_params_round_trip() -> None:
    with pytest.raises(ParameterError, match="motion"):
        Tracker("kalman")
    t = Tracker("sf", n_init=5, recovery=True, det_threshold=0.3, neighbor_radius=80.0)
    p = t.params
    assert p["motion"] == "sf" and p["n_init"] == 5 and p["recovery"] is True
    assert p["det_threshold"] == 0.3 and p["neighbor_radius"] == 80.0
    assert Tracker(**p).params == p  # type: ignore[arg-type]


def _mot_det(path: Path, frames: int) -> dict[int, np.ndarray]:
    rows = np.loadtxt(path, delimiter=",", usecols=range(7), ndmin=2)
    return {f: rows[rows[:, 0] == f] for f in range(1, frames + 1)}


def test_real_detections_mot17_02_motion_only() -> None:
    det = shared_path("data", "MOT17-02-FRCNN", "det", "det.txt")
    t = Tracker("frvo", position_smoothing=0.0)
    seen: dict[int, int] = {}
    for rows in _mot_det(det, 100).values():
        boxes = np.hstack([rows[:, 2:4], rows[:, 2:4] + rows[:, 4:6]])
        out = t.update(boxes, rows[:, 6])
        matched = out.det_index >= 0

        # Matched tracks sit on their detection's centre (sizes are smoothed by default;
        # position_smoothing=0: no pull toward the prediction).
        def centres(b: np.ndarray) -> np.ndarray:
            return (b[:, :2] + b[:, 2:]) / 2

        np.testing.assert_allclose(
            centres(out.boxes[matched]), centres(boxes[out.det_index[matched]]), atol=1e-9
        )
        assert len(set(out.det_index[matched].tolist())) == matched.sum()
        for i in out.ids.tolist():
            seen[i] = seen.get(i, 0) + 1
    # A dense scene with ~30 people: ids are reused over many frames, not restarted every frame.
    assert 10 <= len(seen) <= 150
    assert np.median(list(seen.values())) >= 10


def test_pure_params_give_the_plain_two_stage_tracker() -> None:
    from densepeds.tracking import PURE_PARAMS

    t = Tracker("frvo", n_init=1, **PURE_PARAMS)
    assert {k: t.params[k] for k in PURE_PARAMS} == PURE_PARAMS
    out = t.update(np.array([box(100, 100)]), np.array([0.01]))  # every detection starts tracks
    assert out.ids.tolist() == [1]
    assert len(t.update([], []).ids) == 0  # only matched tracks are reported
