"""Live sources (densepeds.io.live): cameras served on 127.0.0.1 by tests/streamserver.py, read by
LiveSource and by `densepeds run URL`. Every server stops by itself after a few seconds."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_path
from densepeds.errors import InputError
from densepeds.io.live import EXIT_DISCONNECTED, LiveSource, is_live, shown
from densepeds.io.mot import read_tracks
from densepeds.io.video import FrameRange
from streamserver import RtspCamera, free_port, http_camera


def test_live_inputs_are_recognised() -> None:
    for text in (
        "rtsp://cam/stream",
        "RTSP://cam:554/a?b=1",
        "http://10.0.0.2/video.mjpg",
        "https://x/y",
        "/dev/video0",
        "/dev/video12",
    ):
        assert is_live(text), text
    for text in (
        "video.mp4",
        "rtsp:/cam/stream",
        "/dev/video",
        "/dev/videoX",
        "file://a.mp4",
        "data/http://x",
    ):
        assert not is_live(text), text
    assert shown("rtsp://admin:secret@cam:554/s") == "rtsp://admin:***@cam:554/s"
    assert shown("rtsp://cam/s") == "rtsp://cam/s"


def test_unreachable_camera_is_one_clear_error() -> None:
    url = f"rtsp://admin:secret@127.0.0.1:{free_port()}/none"  # nobody listens there
    start = time.monotonic()
    with pytest.raises(InputError, match=r"rtsp://admin:\*\*\*@127\.0\.0\.1:\d+/none: cannot open"):
        LiveSource(url)
    assert time.monotonic() - start < 15


@pytest.mark.parametrize("kind", ["http", "rtsp"])
def test_frames_come_in_order_until_the_camera_hangs_up(kind: str) -> None:
    if kind == "http":
        with http_camera(seconds=2, rate=10) as url:
            frames = _read_all(url)
    else:
        with RtspCamera(seconds=2, rate=10) as cam:
            frames = _read_all(cam.url)
    numbers, shapes, src = frames
    assert numbers == list(range(1, len(numbers) + 1))
    assert 15 <= len(numbers) <= 21  # 2 s at 10 frames/s
    assert shapes == {(120, 160, 3)}
    assert src.size == (160, 120) and src.length is None
    assert src.ended is not None and "ended" in src.ended


def _read_all(url: str) -> tuple[list[int], set[tuple[int, ...]], LiveSource]:
    src = LiveSource(url)
    assert isinstance(src, LiveSource)
    numbers, shapes = [], set()
    for frame_no, image in src.frames():
        assert image is not None
        numbers.append(frame_no)
        shapes.add(image.shape)
    return numbers, shapes, src


def test_reconnect_keeps_numbering_and_gives_up_when_the_camera_is_gone() -> None:
    with RtspCamera(seconds=1, rate=10) as cam:
        src = LiveSource(cam.url, reconnect=2)
        got = [n for n, _ in src.frames(FrameRange(5, 25))]
        assert got == list(range(5, 26))  # one camera second is 10 frames: reconnected twice
        assert src.reconnections >= 1 and src.ended is None
        src = LiveSource(cam.url, reconnect=1)
        it = src.frames()
        next(it)
        cam.close()  # the camera goes away for good
        rest = list(it)
    assert len(rest) <= 10
    assert src.ended == "the stream ended or stopped answering (1 reconnection tries failed)"


def _densepeds(*args: str) -> subprocess.Popen[str]:
    cmd = [sys.executable, "-m", "densepeds", "run", *args, "--features", "none", "--tiles"]
    return subprocess.Popen(
        [*cmd, "none", "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def _lines(path: Path) -> int:
    try:
        return len(path.read_text().splitlines())
    except FileNotFoundError:
        return 0


def test_run_on_rtsp_writes_frame_by_frame_and_ends_on_disconnect(tmp_path: Path) -> None:
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    out = tmp_path / "live.txt"
    with RtspCamera(seconds=4, video=str(video)) as cam:
        proc = _densepeds(cam.url, "--out", str(out), "--video", str(tmp_path / "live.mp4"))
        seen: set[str] = set()  # the file's text as found while the run goes on
        while proc.poll() is None:
            if out.is_file():
                seen.add(out.read_text())
            time.sleep(0.1)
        stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == EXIT_DISCONNECTED, stderr
    # written frame by frame, each flushed whole: many growing states, each of whole lines
    seen.discard("")
    assert len(seen) >= 5 and all(text.endswith("\n") for text in seen)
    ours = [line for line in stderr.splitlines() if line.startswith("densepeds run:")]
    assert len(ours) == 1 and "the stream ended or stopped answering after" in ours[0]
    frames = int(ours[0].split(" after ")[1].split()[0])
    assert 20 <= frames <= 41
    tracks = read_tracks(out)
    rows = np.unique(tracks[:, 0])  # people in nearly every frame, none past the last
    assert rows.max() <= frames and len(rows) >= frames - 5
    assert (tmp_path / "live.mp4").is_file() and "live" in stdout


def test_ctrl_c_keeps_what_was_written(tmp_path: Path) -> None:
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    out = tmp_path / "live.txt"
    with http_camera(seconds=30, video=str(video)) as url:
        proc = _densepeds(url, "--out", str(out))
        deadline = time.monotonic() + 60
        while _lines(out) == 0 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 130, stderr
    assert "interrupted after" in stderr and str(out) in stderr
    assert len(read_tracks(out)) > 0


def test_run_on_http_stops_at_the_frame_range(tmp_path: Path) -> None:
    out = tmp_path / "cam.txt"
    with http_camera(seconds=5) as url:
        proc = _densepeds(url, "--out", str(out), "--frames", "3:6")
        stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 0, stderr
    assert "4 frames" in stdout and out.is_file()  # a test pattern: nobody to track
