"""Outputs people can use (issue 18, item 4): permissions that follow the umask, a video codec
that is reported (the encoder itself is tested in test_video_h264.py), legible labels in a crowd
and a frame counter, no empty tracks file on failure, and Ctrl-C keeping what was tracked."""

from __future__ import annotations

import itertools
import os
import stat
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import shared_path
from densepeds.cli import main
from densepeds.io.mot import read_gt, read_tracks
from densepeds.io.video import AnnotatedVideoWriter, _tag_size, label_layout
from densepeds.pipeline import Pipeline
from densepeds.scene import make_scene


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture
def umask() -> Iterator[None]:
    old = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(old)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_outputs_follow_the_umask(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, umask: None
) -> None:
    seq = make_scene(seed=1, frames=8).write(tmp_path / "seqs")
    for mask in (0o022, 0o002, 0o077):
        os.umask(mask)
        out, video = tmp_path / f"t{mask:o}.txt", tmp_path / f"v{mask:o}.mp4"
        rc, _, err = _run(capsys, "run", str(seq), "--out", str(out), "--video", str(video), "-q")
        assert rc == 0, err
        assert _mode(out) == 0o666 & ~mask, oct(_mode(out))
        assert _mode(video) == 0o666 & ~mask, oct(_mode(video))
    os.umask(0o022)
    scene = tmp_path / "scene"
    assert _run(capsys, "scene", str(scene), "--frames", "2")[0] == 0
    for f in scene.rglob("*"):
        if f.is_file():
            assert _mode(f) == 0o644, f


def test_cli_says_which_codec(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    seq = make_scene(seed=1, frames=5).write(tmp_path / "seqs")
    video = tmp_path / "v.mp4"
    out = tmp_path / "t.txt"
    rc, _, err = _run(capsys, "run", str(seq), "--out", str(out), "--video", str(video))
    assert rc == 0
    assert "H.264" in err or "MPEG-4 Part 2" in err, err


def _overlaps(rects: list[tuple[int, int, int, int]]) -> int:
    bad = 0
    for a, b in itertools.combinations(rects, 2):
        if min(a[2], b[2]) > max(a[0], b[0]) and min(a[3], b[3]) > max(a[1], b[1]):
            bad += 1
    return bad


def _check_layout(boxes: np.ndarray, ids: list[int], size: tuple[int, int]) -> None:
    sizes = [_tag_size(str(i))[0] for i in ids]
    counter = (0, 0, 80, 22)
    rects = label_layout(boxes, sizes, size, reserved=[counter])
    assert _overlaps([*rects, counter]) == 0
    for (x1, y1, x2, y2), (w, h) in zip(rects, sizes, strict=True):
        assert (x2 - x1, y2 - y1) == (w, h)
        assert x1 >= 0 and y1 >= 0 and x2 <= size[0] and y2 <= size[1]


def test_labels_do_not_overlap_in_a_dense_crowd() -> None:
    """48 people packed shoulder to shoulder in 960x540 (ids up to 3 digits): no tag covers
    another or the frame counter, and each keeps its full size inside the frame."""
    rng = np.random.default_rng(0)
    boxes = []
    for row in range(4):
        for col in range(12):
            x, y = 20 + col * 78 + rng.uniform(-8, 8), 40 + row * 120 + rng.uniform(-8, 8)
            boxes.append([x, y, x + 50, y + 130])
    ids = rng.choice(np.arange(1, 1000), len(boxes), replace=False).tolist()
    _check_layout(np.array(boxes), ids, (960, 540))


def test_labels_do_not_overlap_on_mot20() -> None:
    """The ground-truth people of the MOT20-01 frames holding 40 or more (up to 52, with
    overlapping boxes), every fifth such frame."""
    gt = read_gt(shared_path("data", "MOT20-01-dev", "gt", "gt.txt"))
    people = gt[gt[:, 7] == 1]
    frames, counts = np.unique(people[:, 0], return_counts=True)
    crowded = frames[counts >= 40]
    assert len(crowded) > 0
    for frame in crowded[::5]:
        rows = people[people[:, 0] == frame]
        boxes = np.c_[rows[:, 2:4], rows[:, 2:4] + rows[:, 4:6]]
        _check_layout(boxes, rows[:, 1].astype(int).tolist(), (960, 540))


def test_frame_counter_is_drawn(tmp_path: Path) -> None:
    out = tmp_path / "v.avi"
    with AnnotatedVideoWriter(out, fps=5) as writer:
        writer.write(None, [], np.zeros((0, 4)), size=(200, 120), frame_no=7)
        writer.write(None, [], np.zeros((0, 4)), size=(200, 120), frame_no=12345)
    cap = cv2.VideoCapture(str(out))
    images = [cap.read()[1] for _ in range(2)]
    cap.release()
    for img in images:
        corner = img[:20, :60].astype(int)
        assert (corner.sum(axis=2) < 100).mean() > 0.3  # a dark tag with light text
        assert (corner.sum(axis=2) > 600).any()
        assert np.abs(img[80:, 100:].astype(int) - 255).max() < 20  # the rest stays blank
    # Different numbers: different pixels.
    assert np.abs(images[0][:20, :80].astype(int) - images[1][:20, :80]).max() > 100


def test_no_empty_tracks_file_on_failure(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    seq = make_scene(seed=1, frames=10).write(tmp_path / "seqs")
    out = tmp_path / "t.txt"
    rc, _, err = _run(capsys, "run", str(seq), "--frames", "2000:2010", "--out", str(out), "-q")
    assert rc == 2 and "no frames" in err
    assert not out.exists() and list(tmp_path.glob(".*")) == []


def test_ctrl_c_keeps_the_tracks_so_far(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    seq = make_scene(seed=1, frames=40).write(tmp_path / "seqs")
    full = tmp_path / "full.txt"
    assert _run(capsys, "run", str(seq), "--out", str(full), "-q")[0] == 0
    original = Pipeline.run_frames

    def interrupted_after_25(self: Pipeline, *args: object, **kwargs: object) -> Iterator[object]:
        for k, res in enumerate(original(self, *args, **kwargs), start=1):  # type: ignore[arg-type]
            yield res
            if k == 25:
                raise KeyboardInterrupt

    monkeypatch.setattr(Pipeline, "run_frames", interrupted_after_25)
    out, video = tmp_path / "t.txt", tmp_path / "v.mp4"
    rc, _, err = _run(capsys, "run", str(seq), "--out", str(out), "--video", str(video), "-q")
    assert rc == 130
    line = [x for x in err.splitlines() if x.startswith("densepeds")][-1]
    assert "interrupted after 25 frames" in line and str(out) in line
    a, b = read_tracks(full), read_tracks(out)
    np.testing.assert_array_equal(b, a[a[:, 0] <= 25])
    cap = cv2.VideoCapture(str(video))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 25
    cap.release()
    assert [p.name for p in tmp_path.glob(".*")] == []
