"""The tracker's score reading against numpy: which detections start a track under the quantile
floor and ceiling, and as given."""

from __future__ import annotations

import numpy as np
import pytest
from densepeds.presets import PRESETS
from densepeds.tracking import PURE_PARAMS, Tracker


def far_boxes(n: int, row: int) -> np.ndarray:
    """``n`` boxes far apart from each other and from every other row's."""
    x = 300.0 * np.arange(n)
    y = np.full(n, 400.0 * row)
    return np.c_[x, y, x + 40, y + 100]


def started(t: Tracker, scores: np.ndarray, row: int) -> set[int]:
    """Indices of this frame's detections reported (n_init=1: started now; output_lost=0)."""
    out = t.update(far_boxes(len(scores), row), scores)
    return set(out.det_index.tolist())


@pytest.mark.parametrize("q", [0.15, 0.6])
def test_quantile_floor_keeps_the_window_s_lowest_scores_from_starting_tracks(q: float) -> None:
    rng = np.random.default_rng(9)
    window = 20
    t = Tracker(
        "cv",
        n_init=1,
        output_lost=0,
        score_quantile_floor=q,
        score_window=window,
        score_warm_up=0,
        det_threshold=0.2,
        new_track_threshold=0.2,
    )
    seen: list[float] = []
    for row in range(6):
        scores = rng.random(int(rng.integers(2, 10)))
        seen += scores.tolist()
        cut = max(0.2, np.quantile(seen[-window:], q, method="inverted_cdf"))
        assert started(t, scores, row) == set(np.flatnonzero(scores >= cut).tolist())


@pytest.mark.parametrize("ceiling", [0.5, 0.7, 1.0])
def test_quantile_ceiling_tracks_a_detector_scoring_below_the_cuts(ceiling: float) -> None:
    # Every score in [0, 0.25), below the 0.3 cuts: the cuts drop to the ceiling's quantile of
    # the last scores and to 0.3 of the highest score seen, whichever is lower.
    rng = np.random.default_rng(21)
    window = 30
    kw = dict(n_init=1, output_lost=0, score_warm_up=0, score_quantile_floor=0.0)
    t = Tracker("cv", score_window=window, score_quantile_ceiling=ceiling, **kw)
    off = Tracker("cv", score_quantile_ceiling=0.0, **kw)
    seen: list[float] = []
    for row in range(6):
        scores = 0.25 * rng.random(int(rng.integers(3, 12)))
        seen += scores.tolist()
        q = np.quantile(seen[-window:], ceiling, method="inverted_cdf")
        cut = min(q, 0.3 * max(seen))
        assert started(t, scores, row) == set(np.flatnonzero(scores >= cut).tolist())
        assert started(off, scores, row) == set()


def test_the_pure_tracker_reads_scores_as_given() -> None:
    pure = Tracker(**PURE_PARAMS).params
    assert pure["score_quantile_floor"] == 0 and pure["score_quantile_ceiling"] == 0
    t = Tracker("cv", n_init=1, output_lost=0, new_track_threshold=0.6)
    scores = np.array([0.55, 0.6, 0.9, 0.59])
    assert started(t, scores, 0) == {1, 2}


def test_cnn_presets_cut_above_the_detector_floor() -> None:
    # Read as given, each CNN preset's cuts sit at or above the
    # floor of its detector, so that each stage sees some scores.
    for name in ("yoloseg", "maskrcnn"):
        preset = PRESETS[name]
        assert preset.score_floor is not None
        assert preset.tracker["det_threshold"] > preset.score_floor
        assert preset.tracker["low_threshold"] >= preset.score_floor
    for preset in PRESETS.values():
        preset.check()
