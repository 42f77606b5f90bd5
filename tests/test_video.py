"""Frame sources, frame ranges and the annotated video writer."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import shared_path
from densepeds.errors import InputError, ParameterError
from densepeds.io.video import (
    AnnotatedVideoWriter,
    FrameRange,
    ImageFolderSource,
    SequenceSource,
    VideoSource,
    id_colour,
    open_source,
    parse_frame_range,
    prefetched,
)


def test_parse_frame_range() -> None:
    assert parse_frame_range("3:7") == FrameRange(3, 7)
    assert parse_frame_range("5:") == FrameRange(5, None)
    assert parse_frame_range(":9") == FrameRange(1, 9)
    assert parse_frame_range("4") == FrameRange(4, 4)
    assert parse_frame_range(None) == FrameRange(1, None)
    assert 7 in FrameRange(3, 7) and 8 not in FrameRange(3, 7) and 2 not in FrameRange(3, 7)
    assert FrameRange(3, None).clip(10) == FrameRange(3, 10)
    for bad in ("0:5", "7:3", "a:b", ":", "", "1:2:3", "-1:4"):
        with pytest.raises(ParameterError):
            parse_frame_range(bad)


def _grey(value: int, size: tuple[int, int] = (64, 48)) -> np.ndarray:
    return np.full((size[1], size[0], 3), value, np.uint8)


def test_image_folder_is_in_natural_order(tmp_path: Path) -> None:
    for k in (10, 2, 1, 11):
        cv2.imwrite(str(tmp_path / f"img{k}.png"), _grey(k * 10))
    (tmp_path / "notes.txt").write_text("not an image")
    src = open_source(tmp_path)
    assert isinstance(src, ImageFolderSource) and src.length == 4
    values = [(n, int(img[0, 0, 0])) for n, img in src.frames()]  # type: ignore[index]
    assert values == [(1, 10), (2, 20), (3, 100), (4, 110)]
    assert [n for n, _ in src.frames(FrameRange(2, 3))] == [2, 3]


def _write_video(path: Path, values: list[int]) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 10.0, (64, 48))
    assert writer.isOpened()
    for v in values:
        writer.write(_grey(v))
    writer.release()


def test_video_source_reads_exact_frames(tmp_path: Path) -> None:
    values = [20 * k for k in range(10)]
    path = tmp_path / "clip.avi"
    _write_video(path, values)
    src = open_source(path)
    assert isinstance(src, VideoSource) and src.size == (64, 48)
    got = [(n, float(img.mean())) for n, img in src.frames(parse_frame_range("4:6"))]  # type: ignore[union-attr]
    assert [n for n, _ in got] == [4, 5, 6]
    for n, mean in got:  # frame n is the n-th written image (value 20 * (n - 1))
        assert abs(mean - values[n - 1]) < 4
    assert [n for n, _ in src.frames(FrameRange(9, None))] == [9, 10]


def test_unreadable_inputs_raise_input_error(tmp_path: Path) -> None:
    bad = tmp_path / "corrupt.mp4"
    bad.write_bytes(np.random.default_rng(0).integers(0, 255, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(InputError, match="corrupt.mp4"):
        open_source(bad)
    with pytest.raises(InputError, match="no such file"):
        open_source(tmp_path / "missing.mp4")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="no images"):
        open_source(empty)


def test_sequence_without_images_yields_no_frames(tmp_path: Path) -> None:
    seq = tmp_path / "S"
    (seq / "det").mkdir(parents=True)
    (seq / "seqinfo.ini").write_text(
        "[Sequence]\nname=S\nimDir=img1\nframeRate=5\nseqLength=6\nimWidth=320\nimHeight=240\n"
        "imExt=.jpg\n"
    )
    (seq / "det" / "det.txt").write_text("1,-1,1,2,3,4,0.9\n")
    src = open_source(seq)
    assert isinstance(src, SequenceSource) and not src.has_images and src.det_path is not None
    assert list(src.frames(FrameRange(4, 99))) == [(4, None), (5, None), (6, None)]
    assert src.size == (320, 240) and src.fps == 5


def test_sequence_folder_uses_its_video() -> None:
    src = open_source(shared_path("data", "PETS09-S2L1-dev"))
    assert isinstance(src, SequenceSource) and src.has_images
    (n, img), *_ = list(src.frames(FrameRange(1, 2)))
    assert n == 1 and img is not None and img.shape == (576, 768, 3)


def test_id_colours_are_stable_and_distinct() -> None:
    assert id_colour(7) == id_colour(7)
    colours = {id_colour(i) for i in range(1, 30)}
    assert len(colours) >= 25


def test_annotated_writer_draws_boxes_and_is_atomic(tmp_path: Path) -> None:
    out = tmp_path / "out.avi"
    with AnnotatedVideoWriter(out, fps=5) as writer:
        for k in range(5):
            boxes = np.array([[10 + k, 10, 40 + k, 40], [80, 20, 120, 90]], float)
            writer.write(_grey(200, (160, 120)), np.array([3, 8]), boxes)
    cap = cv2.VideoCapture(str(out))
    frames = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        frames.append(img)
    assert len(frames) == 5
    # The right edge of id 8's box (x = 120) is drawn in its colour; the background is not.
    edge = frames[-1][50, 119:122].astype(int).mean(0)
    assert np.abs(edge - np.array(id_colour(8))).max() < 60
    assert np.abs(frames[-1][110, 150].astype(int) - 200).max() < 20
    # An exception mid-write leaves no file under the final name.
    partial = tmp_path / "partial.mp4"
    with pytest.raises(RuntimeError), AnnotatedVideoWriter(partial) as writer:
        writer.write(None, [1], [[0, 0, 5, 5]], size=(64, 48))
        raise RuntimeError("interrupted")
    assert not partial.exists() and not list(tmp_path.glob(".partial*"))
    with pytest.raises(ParameterError):
        AnnotatedVideoWriter(tmp_path / "out.txt")


def test_prefetched_video_matches_direct_decoding(tmp_path: Path) -> None:
    path = tmp_path / "v.avi"
    _write_video(path, [10, 60, 110, 160, 210])
    direct = list(VideoSource(path, prefetch=0).frames(FrameRange(2, 4)))
    ahead = list(VideoSource(path, prefetch=2).frames(FrameRange(2, 4)))
    assert [n for n, _ in ahead] == [n for n, _ in direct] == [2, 3, 4]
    for (_, a), (_, b) in zip(ahead, direct, strict=True):
        assert a is not None and b is not None
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ParameterError):
        VideoSource(path, prefetch=-1)


def test_prefetched_keeps_order_and_reraises_in_the_consumer() -> None:
    def items() -> Iterator[int]:
        yield from range(5)
        raise ValueError("decoder broke")

    got: list[int] = []
    with pytest.raises(ValueError, match="decoder broke"):
        for item in prefetched(items(), depth=2):
            got.append(item)
    assert got == [0, 1, 2, 3, 4]


def test_prefetched_closing_early_stops_the_producer() -> None:
    produced: list[int] = []
    closed = threading.Event()

    def items() -> Iterator[int]:
        try:
            for k in range(1000):
                produced.append(k)
                yield k
        finally:
            closed.set()

    gen = prefetched(items(), depth=2)
    assert [next(gen) for _ in range(3)] == [0, 1, 2]
    gen.close()
    assert closed.is_set()  # the producer closed its source before close() returned
    assert len(produced) <= 3 + 2 + 1  # taken, queued, one in hand: no run-away decoding
    assert not any(t.name == "densepeds-decode" and t.is_alive() for t in threading.enumerate())
