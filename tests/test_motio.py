"""MOTChallenge text I/O: parsing, validation with file:line errors, atomic writes."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_path
from densepeds.errors import DetFileError, InputError
from densepeds.io import mot as motio

DET_LINES = [
    "1,-1,10,20,30,40,0.9,-1,-1,-1",
    "1,-1,100,200,10,20,-3.5,-1,-1,-1",
    "3,-1,0.5,1.5,2.5,3.5,93.7,-1,-1,-1",
]


def write(tmp_path: Path, lines: list[str], name: str = "det.txt") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def test_read_detections_converts_to_corner_boxes_and_keeps_any_score(tmp_path: Path) -> None:
    dets = motio.read_detections(write(tmp_path, DET_LINES), normalize="none")
    assert sorted(dets) == [1, 3]
    np.testing.assert_allclose(dets[1].boxes, [[10, 20, 40, 60], [100, 200, 110, 220]])
    np.testing.assert_allclose(dets[1].scores, [0.9, -3.5], rtol=1e-6)
    np.testing.assert_allclose(dets[3].boxes, [[0.5, 1.5, 3.0, 5.0]])
    assert dets[3].scores.dtype == np.float32 and dets[3].boxes.dtype == np.float32


def test_read_detections_min_score_and_unsorted_frames(tmp_path: Path) -> None:
    lines = [DET_LINES[2], DET_LINES[0], DET_LINES[1]]  # frame 3 first: files need not be sorted
    dets = motio.read_detections(write(tmp_path, lines), min_score=0.0, normalize="none")
    assert sorted(dets) == [1, 3]
    assert len(dets[1]) == 1 and dets[1].scores[0] == pytest.approx(0.9)


def test_read_detections_rescales_out_of_range_scores_per_file(tmp_path: Path) -> None:
    # -3.5 .. 93.7 is not a [0, 1] file: min-max over the whole file, before min_score.
    dets = motio.read_detections(write(tmp_path, DET_LINES))
    span = 93.7 - -3.5
    np.testing.assert_allclose(dets[1].scores, [(0.9 + 3.5) / span, 0.0], rtol=1e-6)
    np.testing.assert_allclose(dets[3].scores, [1.0])
    kept = motio.read_detections(write(tmp_path, DET_LINES), min_score=0.5)
    assert sorted(kept) == [3]  # 0.9 maps to 0.045, below 0.5 in the mapped scale
    forced = motio.read_detections(
        write(tmp_path, ["1,-1,0,0,1,1,0.2", "1,-1,0,0,1,1,0.6"]), normalize="minmax"
    )
    np.testing.assert_allclose(forced[1].scores, [0.0, 1.0])


def test_read_detections_keeps_unit_range_files_and_constant_scores_map_to_one(
    tmp_path: Path,
) -> None:
    unit = ["1,-1,0,0,1,1,0.25", "2,-1,0,0,1,1,1.0", "2,-1,0,0,1,1,0"]
    dets = motio.read_detections(write(tmp_path, unit))
    np.testing.assert_allclose(dets[1].scores, [0.25])
    np.testing.assert_allclose(dets[2].scores, [1.0, 0.0])
    const = motio.read_detections(write(tmp_path, ["1,-1,0,0,1,1,7", "2,-1,0,0,1,1,7"]))
    assert [float(d.scores[0]) for d in const.values()] == [1.0, 1.0]


def test_score_scale_rules_and_bad_mode(tmp_path: Path) -> None:
    assert motio.score_scale([0.0, 0.5, 1.0]) is None
    assert motio.score_scale([-1.0, 3.0]) == (-1.0, 3.0)
    assert motio.score_scale([0.2, 0.4], "minmax") == (0.2, 0.4)
    assert motio.score_scale([-1.0, 3.0], "none") is None
    assert motio.score_scale([], "minmax") is None
    np.testing.assert_allclose(motio.rescale_scores([-1.0, 0.0, 3.0], (-1.0, 3.0)), [0, 0.25, 1])
    with pytest.raises(InputError, match="normalize"):
        motio.score_scale([1.0], "rank")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="normalize"):
        motio.read_detections(write(tmp_path, DET_LINES), normalize="zscore")  # type: ignore[arg-type]


def test_read_detections_seven_columns_and_blank_lines(tmp_path: Path) -> None:
    p = write(tmp_path, ["", "2,-1,1,2,3,4,1", "   ", "2,-1,5,6,7,8,0.5", ""])
    dets = motio.read_detections(p)
    assert list(dets) == [2] and len(dets[2]) == 2


def test_empty_det_file_gives_empty_dict(tmp_path: Path) -> None:
    p = tmp_path / "det.txt"
    p.write_text("")
    assert motio.read_detections(p) == {}


@pytest.mark.parametrize(
    ("bad_line", "message"),
    [
        ("2,-1,1,2,3", "columns"),  # too few columns
        ("2,-1,1,2,3,4,0.5,-1,-1,-1,7", "columns"),  # one column too many
        ("2,-1,1,abc,3,4,0.5,-1,-1,-1", "not a number"),
        ("2,-1,1,2,0,4,0.5,-1,-1,-1", "positive"),  # zero width
        ("2,-1,1,2,3,-4,0.5,-1,-1,-1", "positive"),  # negative height
        ("2,-1,1,2,nan,4,0.5,-1,-1,-1", "NaN"),
        ("2,-1,1,2,3,4,inf,-1,-1,-1", "NaN"),
        ("0,-1,1,2,3,4,0.5,-1,-1,-1", "frame"),
        ("2.5,-1,1,2,3,4,0.5,-1,-1,-1", "frame"),
    ],
)
def test_malformed_det_line_reports_file_and_line(
    tmp_path: Path, bad_line: str, message: str
) -> None:
    # The bad row is on line 4: a blank line before it must still count.
    p = write(tmp_path, [DET_LINES[0], "", DET_LINES[1], bad_line, DET_LINES[2]])
    with pytest.raises(DetFileError, match=message) as info:
        motio.read_detections(p)
    assert f"{p}:4:" in str(info.value)


def test_missing_det_file(tmp_path: Path) -> None:
    with pytest.raises(DetFileError, match="not found"):
        motio.read_detections(tmp_path / "nope.txt")


def test_write_then_read_tracks_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    k = 50
    xy = rng.uniform(-20, 1900, (k, 2)).round(3)
    wh = rng.uniform(1, 300, (k, 2)).round(3)
    rows = np.c_[rng.integers(1, 20, k), rng.integers(1, 9, k), xy, xy + wh, rng.uniform(0, 1, k)]
    rows = rows[np.unique(rows[:, :2], axis=0, return_index=True)[1]]  # unique (frame, id)
    out = tmp_path / "sub" / "tracks.txt"
    assert motio.write_tracks(out, rows[::-1]) == len(rows)  # input order does not matter
    back = motio.read_tracks(out)
    order = np.lexsort((rows[:, 1], rows[:, 0]))
    np.testing.assert_allclose(back[:, :6], rows[order, :6], atol=2e-3)
    np.testing.assert_allclose(back[:, 6], rows[order, 6], rtol=1e-5)
    first = out.read_text().splitlines()[0].split(",")
    assert len(first) == 10 and first[7:] == ["-1", "-1", "-1"]
    # MOTChallenge stores width/height, not corners
    r = rows[order][0]
    assert float(first[4]) == pytest.approx(r[4] - r[2], abs=2e-3)


def test_write_tracks_accepts_tuples_and_empty(tmp_path: Path) -> None:
    p = tmp_path / "t.txt"
    assert motio.write_tracks(p, [(2, 7, 1.0, 2.0, 11.0, 22.0, 0.5)]) == 1
    assert p.read_text() == "2,7,1.000,2.000,10.000,20.000,0.5,-1,-1,-1\n"
    assert motio.write_tracks(p, []) == 0
    assert p.read_text() == "" and motio.read_tracks(p).shape == (0, 7)


@pytest.mark.parametrize(
    "row",
    [
        (1, 1, 0, 0, np.nan, 5, 1),
        (0, 1, 0, 0, 5, 5, 1),
        (1, 1.5, 0, 0, 5, 5, 1),
        (1, 1, 10, 0, 5, 5, 1),  # x2 < x1
    ],
)
def test_write_tracks_rejects_bad_rows_and_keeps_old_file(tmp_path: Path, row: tuple) -> None:
    p = tmp_path / "t.txt"
    motio.write_tracks(p, [(1, 1, 0, 0, 5, 5, 1)])
    before = p.read_text()
    with pytest.raises(InputError):
        motio.write_tracks(p, [(1, 2, 0, 0, 5, 5, 1), row])
    assert p.read_text() == before


def test_write_tracks_is_atomic_when_interrupted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    p = tmp_path / "t.txt"
    motio.write_tracks(p, [(1, 1, 0, 0, 5, 5, 1)])
    before = p.read_text()

    def interrupted(src: str, dst: str) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        motio.write_tracks(p, [(f, 1, 0, 0, 5, 5, 1) for f in range(1, 1000)])
    assert p.read_text() == before
    assert sorted(x.name for x in tmp_path.iterdir()) == ["t.txt"]  # no temp file left behind


def test_read_tracks_rejects_fractional_ids(tmp_path: Path) -> None:
    p = write(tmp_path, ["1,1,0,0,5,5,1,-1,-1,-1", "1,2.5,0,0,5,5,1,-1,-1,-1"], "t.txt")
    with pytest.raises(DetFileError, match=r":2: track id"):
        motio.read_tracks(p)


def test_read_seqinfo(tmp_path: Path) -> None:
    (tmp_path / "seqinfo.ini").write_text(
        "[Sequence]\nname=S\nimDir=img1\nframeRate=25\nseqLength=9\n"
        "imWidth=640\nimHeight=480\nimExt=.png\n"
    )
    info = motio.read_seqinfo(tmp_path)
    assert (info.name, info.length, info.width, info.height, info.fps) == ("S", 9, 640, 480, 25.0)
    assert info.frame_path(3) == tmp_path / "img1" / "000003.png"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (None, "no seqinfo.ini"),
        ("name=S\n", "not a valid ini"),
        ("[Other]\nx=1\n", r"\[Sequence\]"),
        ("[Sequence]\nframeRate=25\nimWidth=1\nimHeight=1\n", "seqLength"),
        ("[Sequence]\nseqLength=ten\nframeRate=25\nimWidth=1\nimHeight=1\n", "seqLength='ten'"),
        ("[Sequence]\nseqLength=0\nframeRate=25\nimWidth=1\nimHeight=1\n", "positive"),
    ],
)
def test_read_seqinfo_errors(tmp_path: Path, text: str | None, message: str) -> None:
    if text is not None:
        (tmp_path / "seqinfo.ini").write_text(text)
    with pytest.raises(InputError, match=message):
        motio.read_seqinfo(tmp_path)


def test_real_sequences_parse() -> None:
    seq = shared_path("data", "MOT17-02-FRCNN")
    info = motio.read_seqinfo(seq)
    assert (info.name, info.length, info.width, info.height) == ("MOT17-02-FRCNN", 600, 1920, 1080)
    dets = motio.read_detections(seq / "det" / "det.txt")
    n_lines = sum(1 for line in (seq / "det" / "det.txt").read_text().splitlines() if line.strip())
    assert sum(len(d) for d in dets.values()) == n_lines
    assert min(dets) >= 1 and max(dets) <= info.length
    gt = motio.read_gt(seq / "gt" / "gt.txt")
    assert gt.shape[1] == 9 and set(np.unique(gt[:, 7])) >= {1.0}
    # MOT15 det scores are outside [0, 1]; by default they are read min-max rescaled into it,
    # while MOT17's [0, 1] scores come through unchanged.
    pets = shared_path("data", "PETS09-S2L1-dev", "det", "det.txt")
    raw = np.concatenate([d.scores for d in motio.read_detections(pets, normalize="none").values()])
    assert raw.max() > 1.0 and raw.min() < 0.0
    mapped = np.concatenate([d.scores for d in motio.read_detections(pets).values()])
    np.testing.assert_allclose(mapped, (raw - raw.min()) / (raw.max() - raw.min()), atol=1e-6)
    mot17_raw = motio.read_detections(seq / "det" / "det.txt", normalize="none")
    for f, d in dets.items():
        np.testing.assert_array_equal(d.scores, mot17_raw[f].scores)
