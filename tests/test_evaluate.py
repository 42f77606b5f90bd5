"""Evaluation via trackeval: exact cases on real gt; CLEAR MOT and IDF1 against a brute force."""

from __future__ import annotations

import csv
import io
import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_path
from densepeds.errors import DetFileError, InputError, ParameterError
from densepeds.evaluate import detect_benchmark, evaluate, format_results
from densepeds.io import mot as motio

MOT17_DISTRACTORS = (2, 7, 8, 12)  # person on vehicle, static person, distractor, reflection


def scored_gt(gt: np.ndarray) -> np.ndarray:
    """The gt boxes the MOTChallenge rules score, as tracks rows (frame, id, x1, y1, x2, y2, 1)."""
    keep = gt[:, 6] != 0
    if gt.shape[1] == 9:
        keep &= gt[:, 7] == 1
    return as_tracks(gt[keep])


def as_tracks(gt: np.ndarray) -> np.ndarray:
    xy, wh = gt[:, 2:4], gt[:, 4:6]
    return np.c_[gt[:, :2], xy, xy + wh, np.ones(len(gt))]


def run_one(seq: Path, rows: np.ndarray, tmp_path: Path, name: str = "t.txt"):
    out = tmp_path / name
    motio.write_tracks(out, rows)
    return evaluate([seq], out)


def test_ground_truth_as_tracks_scores_perfectly(tmp_path: Path) -> None:
    seqs = [shared_path("data", "TUD-Stadtmitte"), shared_path("data", "MOT17-02-FRCNN")]
    for seq in seqs:
        motio.write_tracks(
            tmp_path / f"{seq.name}.txt", scored_gt(motio.read_gt(seq / "gt/gt.txt"))
        )
    result = evaluate(seqs, tmp_path)
    assert result.benchmarks == {"TUD-Stadtmitte": "MOT15", "MOT17-02-FRCNN": "MOT17"}
    for _, m in result.rows():
        for key in ("HOTA", "DetA", "AssA", "MOTA", "MOTP", "IDF1"):
            assert m[key] == pytest.approx(100.0), key
        assert m["FP"] == m["FN"] == m["IDSW"] == m["ML"] == 0
    tud = motio.read_gt(seqs[0] / "gt/gt.txt")
    assert result.sequences["TUD-Stadtmitte"]["MT"] == len(np.unique(tud[:, 1]))


def test_mot17_rules_ignore_distractors_but_count_other_classes(tmp_path: Path) -> None:
    seq = shared_path("data", "MOT17-02-FRCNN")
    gt = motio.read_gt(seq / "gt/gt.txt")
    distractors = as_tracks(gt[np.isin(gt[:, 7], MOT17_DISTRACTORS)])
    assert len(distractors) > 1000  # the sequence has many: the check below means something
    bicycles = as_tracks(gt[gt[:, 7] == 4])  # not a distractor class: boxes on them are FP
    assert len(bicycles) > 0
    m = run_one(seq, np.r_[scored_gt(gt), distractors, bicycles], tmp_path).combined
    assert m["FP"] == len(bicycles) and m["FN"] == 0 and m["IDSW"] == 0


def test_mot15_rules_ignore_zero_flag_gt(tmp_path: Path) -> None:
    seq = shared_path("data", "KITTI-17")
    gt = motio.read_gt(seq / "gt/gt.txt")
    zero = gt[:, 6] == 0
    assert zero.sum() > 0
    m = run_one(seq, scored_gt(gt), tmp_path).combined
    assert m["FN"] == 0 and m["FP"] == 0
    m = run_one(seq, as_tracks(gt), tmp_path).combined  # boxes on flag-0 gt are plain FP
    assert m["FP"] == zero.sum() and m["FN"] == 0


def test_dropping_boxes_gives_exactly_that_many_fn(tmp_path: Path) -> None:
    seq = shared_path("data", "TUD-Stadtmitte")
    rows = scored_gt(motio.read_gt(seq / "gt/gt.txt"))
    drop = np.random.default_rng(1).choice(len(rows), 37, replace=False)
    m = run_one(seq, np.delete(rows, drop, axis=0), tmp_path).combined
    assert m["FN"] == 37 and m["FP"] == 0 and m["IDSW"] == 0
    assert m["MOTA"] == pytest.approx(100.0 * (1 - 37 / len(rows)))
    assert m["HOTA"] < 100.0


def test_swapping_two_ids_mid_sequence_is_an_id_switch(tmp_path: Path) -> None:
    seq = shared_path("data", "TUD-Stadtmitte")
    rows = scored_gt(motio.read_gt(seq / "gt/gt.txt"))
    ids, counts = np.unique(rows[:, 1], return_counts=True)
    a, b = ids[np.argsort(counts)[-2:]]  # the two longest tracks
    both = np.intersect1d(rows[rows[:, 1] == a, 0], rows[rows[:, 1] == b, 0])
    assert len(both) > 20
    cut = both[len(both) // 2]
    swapped = rows.copy()
    late = swapped[:, 0] >= cut
    swapped[late & (rows[:, 1] == a), 1] = b
    swapped[late & (rows[:, 1] == b), 1] = a
    m = run_one(seq, swapped, tmp_path).combined
    assert m["IDSW"] == 2  # each of the two people changes id once
    assert m["FP"] == 0 and m["FN"] == 0
    assert m["MOTA"] == pytest.approx(100.0 * (1 - 2 / len(rows)))
    assert m["IDF1"] < 100.0 and m["HOTA"] < 100.0 and m["AssA"] < 100.0
    assert m["DetA"] == pytest.approx(100.0)


# ---------------------------------------------------------------------------------------------
# Independent reference: CLEAR MOT and IDF1 from their definitions, by exhaustive search.


def iou(a: np.ndarray, b: np.ndarray) -> float:
    iw = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    ih = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = iw * ih
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union


def best_frame_matching(gt: np.ndarray, tr: np.ndarray, prev: dict[int, int]) -> list[tuple]:
    """All partial matchings with IoU >= 0.5; keep tracks matched in the previous frame first,
    then maximise the total IoU (CLEAR MOT, Bernardin & Stiefelhagen 2008)."""
    best: tuple[float, list[tuple]] = (-1.0, [])

    def search(i: int, used: frozenset[int], score: float, pairs: list[tuple]) -> None:
        nonlocal best
        if i == len(gt):
            if score > best[0]:
                best = (score, list(pairs))
            return
        search(i + 1, used, score, pairs)
        for j in range(len(tr)):
            if j in used:
                continue
            o = iou(gt[i, 2:6], tr[j, 2:6])
            if o >= 0.5:
                keep = 1000.0 if prev.get(int(gt[i, 1])) == int(tr[j, 1]) else 0.0
                pairs.append((i, j, o))
                search(i + 1, used | {j}, score + keep + o, pairs)
                pairs.pop()

    search(0, frozenset(), 0.0, [])
    return best[1]


def brute_force_clear_and_idf1(gt: np.ndarray, tr: np.ndarray) -> dict[str, float]:
    frames = np.union1d(gt[:, 0], tr[:, 0])
    fp = fn = idsw = tp = 0
    last: dict[int, int] = {}  # gt id -> last tracker id matched, any time before (for IDSW)
    prev: dict[int, int] = {}  # gt id -> tracker id matched in the previous frame (for matching)
    for f in frames:
        g, t = gt[gt[:, 0] == f], tr[tr[:, 0] == f]
        pairs = best_frame_matching(g, t, prev)
        now: dict[int, int] = {}
        for i, j, _ in pairs:
            gid, tid = int(g[i, 1]), int(t[j, 1])
            if gid in last and last[gid] != tid:
                idsw += 1
            last[gid] = tid
            now[gid] = tid
        prev = now
        tp += len(pairs)
        fn += len(g) - len(pairs)
        fp += len(t) - len(pairs)
    mota = 100.0 * (1 - (fn + fp + idsw) / len(gt))

    # IDF1: the one-to-one map of gt ids to tracker ids with the most frames overlapping at IoU 0.5.
    gids, tids = np.unique(gt[:, 1]).astype(int), np.unique(tr[:, 1]).astype(int)
    overlap = np.zeros((len(gids), len(tids)))
    for a, gid in enumerate(gids):
        for b, tid in enumerate(tids):
            ga, tb = gt[gt[:, 1] == gid], tr[tr[:, 1] == tid]
            for row in ga:
                same = tb[tb[:, 0] == row[0]]
                overlap[a, b] += sum(iou(row[2:6], s[2:6]) >= 0.5 for s in same)
    slots = list(range(len(tids))) + [-1] * len(gids)
    idtp = max(
        sum(overlap[a, b] for a, b in enumerate(perm) if b >= 0)
        for perm in itertools.permutations(slots, len(gids))
    )
    idf1 = 100.0 * 2 * idtp / (len(gt) + len(tr))
    return {"FP": fp, "FN": fn, "IDSW": idsw, "MOTA": mota, "IDF1": idf1}


def synthetic_case(seed: int, n_frames: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Four people walking close together; a noisy tracker with misses, FPs and id changes."""
    rng = np.random.default_rng(seed)
    gt_rows, tr_rows = [], []
    next_id = 100
    track_of = {}
    for pid in range(1, 5):
        start, end = sorted(rng.integers(1, n_frames + 1, 2))
        pos, vel = rng.uniform(0, 120, 2), rng.uniform(-3, 3, 2)
        track_of[pid] = next_id
        next_id += 1
        for f in range(start, end + 1):
            p = pos + vel * f
            box = np.r_[p, p + [40.0, 80.0]].round(3)
            gt_rows.append([f, pid, *box])
            if rng.random() < 0.08:  # the tracker changes this person's id from now on
                track_of[pid] = next_id
                next_id += 1
            if rng.random() < 0.85:  # detected, with jitter that sometimes breaks IoU 0.5
                tr_rows.append([f, track_of[pid], *(box + rng.normal(0, 7, 4)).round(3)])
    for f in range(1, n_frames + 1):
        if rng.random() < 0.3:  # a false positive somewhere in the same area
            p = rng.uniform(0, 150, 2)
            tr_rows.append([f, 900 + f, *np.r_[p, p + [40.0, 80.0]].round(3)])
    gt = np.array(gt_rows)
    tr = np.array(tr_rows)
    tr = tr[(tr[:, 4] > tr[:, 2]) & (tr[:, 5] > tr[:, 3])]
    return gt, tr


def make_seq(root: Path, gt: np.ndarray, length: int, flag0: np.ndarray | None = None) -> Path:
    """A MOT15-style sequence folder (gt without class columns)."""
    seq = root / "SYN"
    (seq / "gt").mkdir(parents=True)
    (seq / "seqinfo.ini").write_text(
        f"[Sequence]\nname=SYN\nseqLength={length}\nframeRate=25\nimWidth=640\nimHeight=480\n"
    )
    lines = [
        f"{int(r[0])},{int(r[1])},{r[2]},{r[3]},{r[4] - r[2]},{r[5] - r[3]},1,-1,-1,-1" for r in gt
    ]
    if flag0 is not None:  # rows the MOT15 rules must ignore
        lines += [
            f"{int(r[0])},{int(r[1])},{r[2]},{r[3]},{r[4] - r[2]},{r[5] - r[3]},0,-1,-1,-1"
            for r in flag0
        ]
    (seq / "gt" / "gt.txt").write_text("\n".join(lines) + "\n")
    return seq


@pytest.mark.parametrize("seed", [0, 2, 5, 9])
def test_clear_and_idf1_match_brute_force(tmp_path: Path, seed: int) -> None:
    gt, tr = synthetic_case(seed)
    seq = make_seq(tmp_path, gt, length=30)
    motio.write_tracks(tmp_path / "SYN.txt", np.c_[tr, np.full(len(tr), 0.9)])
    got = evaluate([seq], tmp_path / "SYN.txt").combined
    want = brute_force_clear_and_idf1(gt, tr)
    assert want["IDSW"] > 0 and want["FN"] > 0 and want["FP"] > 0  # a case that tests something
    for key in ("FP", "FN", "IDSW"):
        assert got[key] == want[key], key
    for key in ("MOTA", "IDF1"):
        assert got[key] == pytest.approx(want[key], abs=1e-9), key


def test_synthetic_flag_zero_gt_is_not_scored(tmp_path: Path) -> None:
    gt, tr = synthetic_case(5)
    ignored = gt[:10].copy()
    ignored[:, 1] = 77
    ignored[:, 2:6] += 500.0  # far from everyone, no tracker box there
    seq = make_seq(tmp_path, gt, length=30, flag0=ignored)
    motio.write_tracks(tmp_path / "SYN.txt", np.c_[tr, np.ones(len(tr))])
    got = evaluate([seq], tmp_path / "SYN.txt").combined
    assert got["FN"] == brute_force_clear_and_idf1(gt, tr)["FN"]


# ---------------------------------------------------------------------------------------------
# Benchmark detection, errors and formats.


def test_detect_benchmark_from_columns_and_name() -> None:
    data = shared_path("data")
    assert detect_benchmark("MOT17-02-FRCNN", motio.read_gt(data / "MOT17-02-FRCNN/gt/gt.txt")) == (
        "MOT17"
    )
    assert detect_benchmark("anything", motio.read_gt(data / "MOT17-02-FRCNN/gt/gt.txt")) == "MOT17"
    assert detect_benchmark("MOT20-01-dev", motio.read_gt(data / "MOT20-01-dev/gt/gt.txt")) == (
        "MOT20"
    )
    for name in ("TUD-Stadtmitte", "PETS09-S2L1-dev", "KITTI-17", "ETH-Sunnyday", "Venice-2"):
        assert detect_benchmark(name, motio.read_gt(data / name / "gt/gt.txt")) == "MOT15", name


@pytest.fixture
def syn(tmp_path: Path) -> tuple[Path, np.ndarray]:
    gt, tr = synthetic_case(0)
    return make_seq(tmp_path, gt, length=30), np.c_[tr, np.ones(len(tr))]


def test_tracks_past_sequence_end_are_rejected(tmp_path: Path, syn) -> None:
    seq, tr = syn
    tr[0, 0] = 31
    motio.write_tracks(tmp_path / "t.txt", tr)
    with pytest.raises(InputError, match="has 30 frames"):
        evaluate([seq], tmp_path / "t.txt")


def test_duplicate_id_in_a_frame_is_rejected(tmp_path: Path, syn) -> None:
    seq, tr = syn
    motio.write_tracks(tmp_path / "t.txt", np.r_[tr, tr[:1]])
    with pytest.raises(InputError, match="appears twice"):
        evaluate([seq], tmp_path / "t.txt")


def test_bad_inputs(tmp_path: Path, syn) -> None:
    seq, tr = syn
    with pytest.raises(InputError, match="no tracks given"):
        evaluate([seq], {"OTHER": tmp_path / "x.txt"})
    with pytest.raises(InputError, match="no SYN.txt"):
        evaluate([seq], tmp_path / "SYN")  # a folder without the file
    (tmp_path / "bad.txt").write_text("1,1,0,0,5\n")
    with pytest.raises(DetFileError, match=r"bad.txt:1:"):
        evaluate([seq], tmp_path / "bad.txt")
    with pytest.raises(InputError, match="not found"):
        evaluate([tmp_path / "missing"], tmp_path / "bad.txt")
    motio.write_tracks(tmp_path / "t.txt", tr)
    with pytest.raises(ParameterError, match="benchmark"):
        evaluate([seq], tmp_path / "t.txt", benchmark="MOT99")
    with pytest.raises(InputError, match="class and visibility columns"):
        evaluate([seq], tmp_path / "t.txt", benchmark="MOT17")  # MOT15-style gt


def test_empty_tracks_give_all_fn(tmp_path: Path, syn, capsys: pytest.CaptureFixture) -> None:
    seq, _ = syn
    (tmp_path / "t.txt").write_text("")
    m = evaluate([seq], tmp_path / "t.txt").combined
    n_gt = len(motio.read_gt(seq / "gt/gt.txt"))
    assert m["FN"] == n_gt and m["FP"] == 0 and m["HOTA"] == 0.0
    assert capsys.readouterr().out == ""  # trackeval kept quiet


def test_format_results(tmp_path: Path, syn) -> None:
    seq, tr = syn
    motio.write_tracks(tmp_path / "t.txt", tr)
    result = evaluate([seq], tmp_path / "t.txt")
    md = format_results(result, "md").splitlines()
    assert md[0].startswith("| sequence | HOTA |") and len(md) == 4
    assert md[2].startswith("| SYN |") and "**COMBINED**" in md[3]
    rows = list(csv.DictReader(io.StringIO(format_results(result, "csv"))))
    assert [r["sequence"] for r in rows] == ["SYN", "COMBINED"]
    for key in ("HOTA", "MOTA", "IDF1", "FN"):
        assert float(rows[1][key]) == result.combined[key]
    js = json.loads(format_results(result, "json"))
    assert js["combined"]["IDSW"] == result.combined["IDSW"]
    assert js["benchmarks"] == {"SYN": "MOT15"}
    with pytest.raises(ParameterError):
        format_results(result, "xml")
