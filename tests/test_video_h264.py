"""The annotated video's encoder: browser-playable H.264 MP4 through imageio-ffmpeg's FFmpeg,
OpenCV as the fallback (with a one-line note saying why), and the writer's guarantees (no file
after a failure, Ctrl-C at a terminal keeps the frames so far) on the FFmpeg path.

Every file is checked independently of the writer: decoded by OpenCV, described by FFmpeg itself
(``ffmpeg -i``), and its MP4 boxes read from the bytes."""

from __future__ import annotations

import os
import re
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import cv2
import imageio_ffmpeg
import numpy as np
import pytest
from conftest import shared_path
from densepeds.errors import OutputError
from densepeds.io.video import AnnotatedVideoWriter, id_colour
from densepeds.io.video_encoder import CODEC_NAMES, h264_ffmpeg


def _stream(path: Path) -> str:
    """FFmpeg's description of the first video stream, e.g. ``h264 (High) (avc1 / ...),
    yuv420p(tv, bt709, progressive), 162x122, ...``."""
    proc = subprocess.run(
        [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(path)],
        capture_output=True,
        text=True,
        check=False,
    )
    lines = [ln for ln in proc.stderr.splitlines() if re.search(r"Stream #0:\d.*: Video: ", ln)]
    assert len(lines) == 1, proc.stderr
    return lines[0].split("Video: ", 1)[1]


def _top_level_boxes(path: Path) -> list[str]:
    """The MP4 (ISO BMFF) top-level box types, in file order."""
    data = path.read_bytes()
    types, pos = [], 0
    while pos + 8 <= len(data):
        size, kind = int.from_bytes(data[pos : pos + 4], "big"), data[pos + 4 : pos + 8]
        if size == 1:
            size = int.from_bytes(data[pos + 8 : pos + 16], "big")
        elif size == 0:
            size = len(data) - pos
        assert size >= 8, f"bad box at {pos}"
        types.append(kind.decode("latin-1"))
        pos += size
    assert pos == len(data), "boxes do not cover the file"
    return types


def _decode(path: Path) -> tuple[list[np.ndarray], str]:
    cap = cv2.VideoCapture(str(path))
    try:
        code = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").decode("latin-1").lower()
        frames = []
        while True:
            ok, img = cap.read()
            if not ok:
                break
            frames.append(img)
    finally:
        cap.release()
    return frames, code


def _backgrounds(n: int) -> list[np.ndarray]:
    """Frames of 161x121 (odd on purpose) whose grey level steps by 15 from one to the next."""
    return [np.full((121, 161, 3), 30 + 15 * k, np.uint8) for k in range(n)]


@pytest.mark.parametrize("suffix", [".mp4", ".m4v", ".mov"])
def test_mp4_is_h264_yuv420p_with_the_index_first(tmp_path: Path, suffix: str) -> None:
    out = tmp_path / f"v{suffix}"
    images = _backgrounds(12)
    with AnnotatedVideoWriter(out, fps=7) as writer:
        for k, image in enumerate(images):
            writer.write(image, [4], [[20 + k, 30, 60 + k, 110]])
    assert writer.codec == "libx264" and writer.note is None
    assert "H.264" in CODEC_NAMES[writer.codec]
    stream = _stream(out)
    assert stream.startswith("h264 (High)"), stream
    assert "yuv420p(tv, bt709" in stream, stream
    assert "162x122" in stream, stream  # odd sizes padded by one pixel to even
    assert re.search(r"\b7 fps\b", stream), stream
    boxes = _top_level_boxes(out)
    assert boxes.index("moov") < boxes.index("mdat"), boxes  # +faststart: streamable
    frames, fourcc = _decode(out)
    assert fourcc in ("avc1", "h264")
    assert len(frames) == len(images) and frames[0].shape == (122, 162, 3)
    for k, frame in enumerate(frames):  # each frame in its place: grey 30 + 15 k away from drawings
        assert abs(float(frame[100:118, 110:158].mean()) - (30 + 15 * k)) < 3, k
    # The box of id 4 keeps its colour through BGR -> BT.709 yuv420p -> BGR.
    edge = frames[-1][70, 70:73].astype(int).mean(0)  # the right edge, x = 60 + 11 = 71
    assert np.abs(edge - np.array(id_colour(4))).max() < 60, edge
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~_umask()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def test_ffmpeg_is_found_and_encodes_h264() -> None:
    exe, why = h264_ffmpeg()
    assert exe is not None and why is None, why
    listed = subprocess.run(
        [exe, "-hide_banner", "-encoders"], capture_output=True, text=True, check=True
    ).stdout
    assert re.search(r"^\s*V\S*\s+libx264\s", listed, re.M)


def test_fallback_to_opencv_says_why(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import densepeds.io.video_encoder as encoder

    monkeypatch.setattr(encoder, "h264_ffmpeg", lambda: (None, "no FFmpeg in this test"))
    out = tmp_path / "v.mp4"
    with AnnotatedVideoWriter(out, fps=10) as writer:
        for image in _backgrounds(5):
            writer.write(image, [1], [[10, 10, 40, 60]])
    assert writer.codec in ("avc1", "mp4v")
    note = writer.note
    assert note is not None and "\n" not in note
    assert (
        "no FFmpeg in this test" in note and "OpenCV" in note and CODEC_NAMES[writer.codec] in note
    )
    assert ("browsers may not play" in note) == (writer.codec == "mp4v")
    frames, fourcc = _decode(out)
    assert len(frames) == 5
    assert fourcc in {"avc1": ("avc1", "h264"), "mp4v": ("mp4v", "fmp4")}[writer.codec]
    assert _stream(out).startswith({"avc1": "h264", "mp4v": "mpeg4"}[writer.codec])


def test_non_mp4_containers_stay_with_opencv(tmp_path: Path) -> None:
    out = tmp_path / "v.avi"
    with AnnotatedVideoWriter(out, fps=10) as writer:
        for image in _backgrounds(3):
            writer.write(image, [], np.zeros((0, 4)))
    assert writer.codec == "MJPG" and writer.note is None
    assert len(_decode(out)[0]) == 3


def _fake_ffmpeg(tmp_path: Path, script: str) -> str:
    exe = tmp_path / "ffmpeg"
    exe.write_text("#!/bin/sh\n" + script + "\n")
    exe.chmod(0o755)
    return str(exe)


def test_an_ffmpeg_without_libx264_is_not_used(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``$IMAGEIO_FFMPEG_EXE`` naming an FFmpeg that cannot encode H.264 (here a script answering
    as such a build does), or nothing runnable: the fallback, with FFmpeg's reason in the note."""
    no_x264 = _fake_ffmpeg(tmp_path, "echo \"Unknown encoder 'libx264'\" >&2; exit 8")
    monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", no_x264)
    exe, why = h264_ffmpeg()
    assert exe is None and why is not None and "Unknown encoder 'libx264'" in why
    out = tmp_path / "v.mp4"
    with AnnotatedVideoWriter(out, fps=10) as writer:
        writer.write(_backgrounds(1)[0], [], np.zeros((0, 4)))
    assert writer.codec in ("avc1", "mp4v") and "Unknown encoder 'libx264'" in str(writer.note)
    monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", str(tmp_path / "missing-ffmpeg"))
    exe, why = h264_ffmpeg()
    assert exe is None and why is not None and "cannot run FFmpeg" in why


def _ffmpeg_process(writer: AnnotatedVideoWriter) -> subprocess.Popen[bytes]:
    proc = getattr(writer._writer, "_proc", None)
    assert isinstance(proc, subprocess.Popen)
    return proc


def test_ffmpeg_dying_is_one_error_and_leaves_nothing(tmp_path: Path) -> None:
    # Dying between two frames: the next write says so.
    out = tmp_path / "a.mp4"
    writer = AnnotatedVideoWriter(out, fps=10)
    images = _backgrounds(4)
    writer.write(images[0], [], np.zeros((0, 4)))
    proc = _ffmpeg_process(writer)
    proc.kill()
    proc.wait()
    with pytest.raises(OutputError, match=r"a\.mp4: the video could not be written") as err:
        for image in images[1:]:  # the pipe's buffer may take a frame before it breaks
            writer.write(image, [], np.zeros((0, 4)))
    assert "\n" not in str(err.value)
    writer.abort()
    assert list(tmp_path.iterdir()) == []
    # Dying before close(): close() says so and removes the temporary.
    out = tmp_path / "b.mp4"
    writer = AnnotatedVideoWriter(out, fps=10)
    writer.write(images[0], [], np.zeros((0, 4)))
    _ffmpeg_process(writer).kill()
    with pytest.raises(OutputError, match=r"b\.mp4: the video could not be written.*1 frames"):
        writer.close()
    assert list(tmp_path.iterdir()) == []


def test_abort_stops_ffmpeg_and_removes_the_file(tmp_path: Path) -> None:
    writer = AnnotatedVideoWriter(tmp_path / "v.mp4", fps=10)
    writer.write(_backgrounds(1)[0], [], np.zeros((0, 4)))
    proc = _ffmpeg_process(writer)
    assert os.getsid(proc.pid) != os.getsid(0)  # its own session: a terminal's Ctrl-C is ours
    writer.abort()
    assert proc.returncode is not None
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_at_a_terminal_keeps_the_video_so_far(tmp_path: Path) -> None:
    """SIGINT to the whole foreground process group, as a terminal sends it: the run writes
    the frames tracked so far into a complete H.264 file and says how many."""
    seq = shared_path("data", "PETS09-S2L1-dev")  # 397 frames from a video, det.txt boxes
    for attempt in range(3):  # on a loaded machine the run may end before the signal lands
        outdir = tmp_path / f"out{attempt}"
        proc = subprocess.Popen(
            [sys.executable, "-m", "densepeds", "run", str(seq), "--features", "none", "-q"]
            + ["--out", str(outdir / "t.txt"), "--video", str(outdir / "v.mp4")],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=dict(os.environ, PYTHONDONTWRITEBYTECODE="1"),
            start_new_session=True,  # a process group of its own, like a shell's job
        )
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            temps = list(outdir.glob(".v.mp4*")) if outdir.is_dir() else []
            if temps and temps[0].stat().st_size > 0:  # FFmpeg has written frames
                break
            time.sleep(0.02)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
        if proc.returncode == 0 and "interrupted" not in err:
            continue  # it finished before the signal landed: nothing was interrupted, try again
        break
    assert proc.returncode == 130, f"the run was never interrupted in 3 tries: {err}"
    match = re.search(r"interrupted after (\d+) frames", err)
    assert match, err
    frames, fourcc = _decode(outdir / "v.mp4")
    assert fourcc in ("avc1", "h264") and len(frames) == int(match.group(1)) > 0
    assert sorted(p.name for p in outdir.iterdir()) == ["t.txt", "v.mp4"]


def test_ctrl_c_inside_a_frames_output_counts_that_frame(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A Ctrl-C that lands while a frame's video frame is being written (in-process, so the
    moment is exact) is held until that frame's output is complete: the count the run reports
    is the number of frames in the video and of frames in the tracks file."""
    from densepeds.cli import main

    seq = shared_path("data", "PETS09-S2L1-dev")
    plain_write = AnnotatedVideoWriter.write
    written: list[int] = []

    def write(self: AnnotatedVideoWriter, *args: object, **kwargs: object) -> None:
        if len(written) == 3:  # the fourth frame: Ctrl-C arrives before it is encoded
            os.kill(os.getpid(), signal.SIGINT)
        plain_write(self, *args, **kwargs)  # type: ignore[arg-type]
        written.append(1)

    monkeypatch.setattr(AnnotatedVideoWriter, "write", write)
    out, video = tmp_path / "t.txt", tmp_path / "v.mp4"
    argv = ["run", str(seq), "--features", "none", "-q", "--out", str(out), "--video", str(video)]
    assert main(argv) == 130
    err = capsys.readouterr().err
    match = re.search(r"interrupted after (\d+) frames", err)
    assert match, err
    frames, _ = _decode(video)
    tracked = {int(line.split(",")[0]) for line in out.read_text().splitlines()}
    assert int(match.group(1)) == len(written) == len(frames) == 4
    assert max(tracked) <= 4
