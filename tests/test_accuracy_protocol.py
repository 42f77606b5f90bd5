"""The accuracy protocol of benchmarks/: leave-one-out selection, paired statistics, recall per
visibility bin, one cell through two code paths, and the peer adapters on the built-in scene."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO, shared_path
from densepeds.scene import Scene, make_scene

sys.path.insert(0, str(REPO / "benchmarks"))
import accuracy_grid as grid  # noqa: E402
import accuracy_tables as tables  # noqa: E402
import peers  # noqa: E402


def _results(table: np.ndarray, cells: list[str], names: list[str]) -> dict:
    return {
        n: {c: {"HOTA": float(table[i, j])} for j, c in enumerate(cells)}
        for i, n in enumerate(names)
    }


def test_leave_one_out_matches_brute_force() -> None:
    rng = np.random.default_rng(1)
    cells = [f"c{j}" for j in range(6)]
    names = [f"n{i}" for i in range(5)]
    table = rng.normal(50, 5, (5, 6))
    table[3] += 1.5  # one candidate better on most cells
    table[3, 2] -= 20  # but bad on one
    got = tables.leave_one_out(_results(table, cells, names))
    tuned = max(names, key=lambda n: sum(table[names.index(n)]))
    for j, row in enumerate(got):
        scores = {n: sum(table[i, k] for k in range(6) if k != j) for i, n in enumerate(names)}
        chosen = max(names, key=lambda n: scores[n])
        assert (row.cell, row.chosen, row.tuned) == (cells[j], chosen, tuned)
        assert row.held_out == pytest.approx(table[names.index(chosen), j])
        assert row.tuned_value == pytest.approx(table[names.index(tuned), j])
    assert got[2].chosen == "n3" or got[2].held_out < got[2].tuned_value + 1e-9


def test_paired_counts_sign_test_and_bootstrap() -> None:
    cells = [f"c{j}" for j in range(9)]
    a = np.array([50, 51, 52, 40, 41, 60, 61, 30, 30.0])
    b = np.array([49, 50, 51, 39, 42, 59, 60, 31, 30.0])
    wins, ties, losses, p, mean, lo, hi = tables.paired(
        _results(a[None], cells, ["a"])["a"],
        _results(b[None], cells, ["b"])["b"],
        np.random.default_rng(0),
    )
    assert (wins, ties, losses) == (6, 1, 2)
    # Exact two-sided binomial test (p = 0.5 is symmetric: twice the smaller tail).
    n = wins + losses
    tail = sum(math.comb(n, k) for k in range(min(wins, losses) + 1)) / 2**n
    assert p == pytest.approx(min(1.0, 2 * tail))
    assert mean == pytest.approx(float(np.mean(a - b)))
    assert lo <= mean <= hi and lo > -1 and hi < 1.01
    # Equal differences everywhere: no spread.
    same = tables.paired(
        _results(a[None] + 2, cells, ["a"])["a"],
        _results(a[None], cells, ["b"])["b"],
        np.random.default_rng(0),
    )
    assert same[:3] == (9, 0, 0) and same[5] == pytest.approx(2) and same[6] == pytest.approx(2)


def test_matches_are_an_optimal_one_to_one_assignment() -> None:
    from itertools import permutations

    rng = np.random.default_rng(3)
    for _ in range(20):
        a = rng.uniform(0, 50, (4, 2))
        a = np.c_[a, a + rng.uniform(5, 20, (4, 2))]
        b = a[rng.permutation(4)[:3]] + np.tile(rng.normal(0, 4, (3, 2)), 2)
        got = tables.match_pairs(a, b)
        assert len({i for i, _ in got}) == len(got) == len({j for _, j in got})
        assert all(peers.iou_matrix(a[[i]], b[[j]])[0, 0] >= 0.5 for i, j in got)
        # Brute force: the largest number of pairs with IoU >= 0.5 over all assignments.
        iou = peers.iou_matrix(a, b)
        best = max(
            sum(iou[i, j] >= 0.5 for j, i in enumerate(perm)) for perm in permutations(range(4), 3)
        )
        assert len(got) == best


@pytest.fixture(scope="module")
def scene() -> Scene:
    return make_scene(seed=2, frames=40)


def _scene_cell(scene: Scene, tmp: Path) -> grid.CellData:
    seq = scene.write(tmp, images=False)
    dets = [scene.detections.get(k) for k in range(1, scene.length + 1)]
    from densepeds.types import Detections

    return grid.CellData(
        grid.Cell(scene.name, "scene"),
        seq,
        scene.fps,
        (scene.config.width, scene.config.height),
        [d if d is not None else Detections.empty() for d in dets],
    )


def test_visibility_recall_on_the_scene(scene: Scene, tmp_path: Path) -> None:
    data = _scene_cell(scene, tmp_path)
    gt = scene.gt_rows
    # Perfect output (every gt box, as if matched to a detection) plus five coasting boxes off
    # everybody, and five coasting boxes on people.
    perfect = np.c_[
        gt[:, :2], gt[:, 2:4], gt[:, 2:4] + gt[:, 4:6], np.ones(len(gt)), np.ones(len(gt))
    ]
    off = np.array([[k, 900 + k, -300, -300, -250, -200, 1, 0] for k in range(1, 6)], float)
    on = perfect[gt[:, 0] == 7][:5].copy()
    on[:, 7] = 0
    rows = np.r_[np.delete(perfect, np.flatnonzero(gt[:, 0] == 7)[:5], 0), off, on]
    fed = [d.boxes.astype(np.float64) for d in data.dets]
    r = tables.visibility_recall(data, fed, rows)
    vis, found = np.round(scene.visibility(), 3), scene.detected()  # gt.txt holds 3 decimals
    v = vis[~np.isnan(vis)]
    bins = np.digitize(v, [b[1] for b in tables.VISIBILITY_BINS[:-1]])
    assert r.gt == [int((bins == b).sum()) for b in range(len(tables.VISIBILITY_BINS))]
    assert r.found["tracker"] == r.gt
    # The stand-in detector's hits: its boxes lie on their person (IoU > 0.5, test_scene), so
    # the matched counts per bin are about the detected people per bin (in a crowd a box can
    # also reach IoU 0.5 with a covered neighbour and be matched to them instead).
    want = [int(found[~np.isnan(vis)][bins == b].sum()) for b in range(len(tables.VISIBILITY_BINS))]
    for got_b, want_b, n in zip(r.found["detector"], want, r.gt, strict=True):
        assert abs(got_b - want_b) <= 0.02 * n
    assert r.found["detector"][0] < 0.5 * r.gt[0] and r.found["detector"][3] > 0.85 * r.gt[3]
    assert (r.coasting_rows, r.coasting_fp, r.output_fp) == (10, 5, 5)


def test_a_det_cell_scores_the_same_through_the_pipeline_and_the_tracker(tmp_path: Path) -> None:
    """The grid tracks through densepeds.Pipeline; the tracker fed directly gives the same."""
    seq = shared_path("data", "TUD-Stadtmitte")
    from densepeds.evaluate import evaluate
    from densepeds.io.mot import read_detections, write_tracks
    from densepeds.tracking import Tracker

    data = grid.load_cell(grid.Cell("TUD-Stadtmitte", "det"), tmp_path)
    via_grid = grid.score_grid([data], grid.Config())["TUD-Stadtmitte/det"]
    dets = read_detections(seq / "det" / "det.txt")
    tracker = Tracker()
    tracker.set_image_size(*data.size)
    rows = []
    for k in range(1, len(data.dets) + 1):
        d = dets.get(k)
        boxes = d.boxes if d is not None else np.zeros((0, 4), np.float32)
        scores = d.scores if d is not None else np.zeros(0, np.float32)
        t = tracker.update(boxes.astype(np.float64), scores)
        rows += [(k, i, *b, s) for i, b, s in zip(t.ids, t.boxes, t.scores, strict=True)]
    write_tracks(tmp_path / "direct.txt", rows)
    direct = evaluate([seq], tmp_path / "direct.txt").combined
    assert via_grid["HOTA"] == pytest.approx(direct["HOTA"])
    assert via_grid["IDF1"] == pytest.approx(direct["IDF1"])


def test_peer_adapters_track_the_scene(scene: Scene) -> None:
    pytest.importorskip("trackforge", reason="the peers extra: pip install -e '.[peers]'")
    pytest.importorskip("trackers", reason="the peers extra")
    pytest.importorskip("deep_sort_realtime", reason="the peers extra")
    pytest.importorskip("motpy", reason="the peers extra")
    emb = scene.embedder()
    frames = [(k, scene.detections[k]) for k in range(1, 31) if k in scene.detections]
    for name in peers.PEERS:
        tracker = peers.make_tracker(name, scene.fps)
        reported = 0
        for k, d in frames:
            e = emb.embed(scene.frame(k), d) if name in peers.APPEARANCE else None
            ids, boxes, scores = tracker.update(d.boxes, d.scores, e)
            assert (
                ids.dtype == np.int64 and boxes.shape == (len(ids), 4) and len(scores) == len(ids)
            )
            assert len(set(ids.tolist())) == len(ids), name
            if len(ids):
                # Every reported box lies on a detection of the frame or near one.
                iou = peers.iou_matrix(boxes, d.boxes.astype(np.float64))
                assert np.mean(iou.max(1) > 0.3) > 0.8, name
            reported += len(ids)
        assert reported > 0.25 * sum(int((d.extra["gt_id"] > 0).sum()) for _, d in frames), name


def test_fast_sources_run_on_the_reference_grid_and_stay_out_of_the_grid() -> None:
    """``/grid`` and ``/ortq-grid`` cells get the tiles the reference runs on (pipeline_speed)."""
    import pipeline_speed

    shared_path("models", "yolov8n-seg-320-int8.onnx")
    tiles = {}
    for seq in grid.VIDEOS:
        expected = pipeline_speed.reference_tiles(shared_path("data", seq))
        for source in ("grid", "ortq-grid"):
            options = grid.Cell(seq, source).detector_options
            assert options["tiles"] == expected
            assert options["quantized"] == (source == "ortq-grid")
        tiles[seq] = expected
    assert tiles == {"MOT20-01-dev": "3x2", "PETS09-S2L1-dev": "2x2"}
    assert grid.Cell("MOT20-01-dev", "float").detector_options == {"quantized": False}
    chosen = grid.select_cells(["*/grid", "*/ortq-grid"])
    assert sorted(c.name for c in chosen) == sorted(
        f"{seq}/{src}" for seq in grid.VIDEOS for src in ("grid", "ortq-grid")
    )
    assert not {c.source for c in grid.CELLS} & set(grid.OPTIONAL_SOURCES)
    assert len(grid.CELLS) == 15
