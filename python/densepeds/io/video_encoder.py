"""Encoders behind the annotated video: H.264 through FFmpeg where it can be had, else OpenCV.

An ``.mp4``, ``.m4v`` or ``.mov`` output is H.264 (libx264, High profile), yuv420p, BT.709, with
its index at the front of the file (``+faststart``), so that browsers play it while it downloads.
The encoder is the FFmpeg executable shipped by the ``imageio-ffmpeg`` package (or the one named
by ``$IMAGEIO_FFMPEG_EXE``), run as a separate process that reads raw frames from a pipe. It is
tried once per process (one frame encoded); where it is missing or cannot encode H.264, OpenCV's
writer is used instead (H.264 where its FFmpeg build has an encoder, else MPEG-4 Part 2) and the
encoder's ``note`` says why in one line. Other containers (``.avi``, ``.mkv``, ...) are written by
OpenCV as Motion JPEG.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext, suppress
from fractions import Fraction
from functools import lru_cache
from pathlib import Path
from typing import IO, Protocol

import cv2
import numpy as np
import numpy.typing as npt

from densepeds.errors import OutputError

__all__ = ["CODEC_NAMES", "FrameEncoder", "h264_ffmpeg", "open_encoder"]

Image = npt.NDArray[np.uint8]

# Containers written as H.264 by FFmpeg, with FFmpeg's muxer name for each.
H264_CONTAINERS = {".mp4": "mp4", ".m4v": "mp4", ".mov": "mov"}
# x264's constant rate factor (0 lossless .. 51 worst): 20 keeps thin boxes and small id text
# sharp; the preset trades file size for encoding time (veryfast: a few ms a 960x540 frame).
H264_CRF = 20
H264_PRESET = "veryfast"

# Even size (pad one pixel), BGR -> BT.709 limited-range yuv420p, and the colour tags that tell
# a player so (untagged, browsers guess the matrix and shift the id colours).
_FILTERS = (
    "pad=ceil(iw/2)*2:ceil(ih/2)*2,scale=out_color_matrix=bt709:out_range=tv,format=yuv420p,"
    "setparams=range=tv:color_primaries=bt709:color_trc=bt709:colorspace=bt709"
)

# OpenCV codecs tried, in order, by container.
_OPENCV_CODECS = {".mp4": ("avc1", "mp4v"), ".m4v": ("avc1", "mp4v"), ".mov": ("avc1", "mp4v")}
_OPENCV_DEFAULT = ("MJPG",)

# Codec names shown to users, by the ``codec`` an encoder reports.
CODEC_NAMES = {
    "libx264": "H.264 (libx264 through FFmpeg)",
    "avc1": "H.264 (through OpenCV)",
    "mp4v": "MPEG-4 Part 2",
    "MJPG": "Motion JPEG",
}


class FrameEncoder(Protocol):
    """Writes BGR frames of one size into a file; ``finish`` raises
    :class:`~densepeds.errors.OutputError` when the file could not be written."""

    codec: str
    note: str | None

    def write(self, image: Image) -> None: ...

    def finish(self) -> None: ...

    def kill(self) -> None: ...


@lru_cache(maxsize=8)
def _probe(exe: str) -> str | None:
    """Why ``exe`` cannot encode H.264 for us (None: it can): one 16x16 frame is encoded."""
    cmd = [exe, "-hide_banner", "-nostdin", "-loglevel", "error", "-f", "rawvideo"]
    cmd += ["-pix_fmt", "bgr24", "-video_size", "16x16", "-i", "pipe:0", "-frames:v", "1"]
    cmd += ["-c:v", "libx264", "-pix_fmt", "yuv420p", "-f", "null", "-"]
    try:
        proc = subprocess.run(
            cmd, input=bytes(16 * 16 * 3), capture_output=True, timeout=60, check=False
        )
    except (OSError, subprocess.SubprocessError) as err:
        return f"cannot run FFmpeg ({exe}): {err}"
    if proc.returncode != 0:
        last = _last_line(proc.stderr.decode("utf-8", "replace")) or f"exit {proc.returncode}"
        return f"FFmpeg ({exe}) cannot encode H.264: {last}"
    return None


def h264_ffmpeg() -> tuple[str | None, str | None]:
    """The FFmpeg executable that encodes H.264 here, or ``(None, why not)``.

    ``$IMAGEIO_FFMPEG_EXE`` names one explicitly; otherwise imageio-ffmpeg's own binary (or a
    system FFmpeg it finds) is used. The check runs once per executable and process."""
    try:
        import imageio_ffmpeg
    except ImportError:
        return None, "imageio-ffmpeg is not installed (pip install imageio-ffmpeg)"
    try:
        exe = str(imageio_ffmpeg.get_ffmpeg_exe())
    except RuntimeError as err:
        return None, f"no FFmpeg executable: {_last_line(str(err))}"
    why = _probe(exe)
    return (None, why) if why else (exe, None)


def _last_line(text: str) -> str:
    """The last non-empty line of FFmpeg's messages, without its ``[component @ 0x...]`` tag."""
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return re.sub(r"^\[[^\]]*\]\s*", "", lines[-1]) if lines else ""


def _rate(fps: float) -> str:
    """``fps`` as FFmpeg's rational: 25 -> 25/1, 29.97 -> 2997/100, 30000/1001 kept exact."""
    return str(Fraction(fps).limit_denominator(1001))


class FFmpegEncoder:
    """libx264 in an FFmpeg process fed raw BGR frames through its stdin.

    FFmpeg runs in its own session, so that a Ctrl-C at the terminal reaches only this process
    (which then finishes the file with the frames written so far). An odd width or height is
    padded by one pixel (yuv420p needs even sizes)."""

    codec = "libx264"
    note: str | None = None

    def __init__(
        self, exe: str, tmp: Path, out: Path, size: tuple[int, int], fps: float, muxer: str
    ) -> None:
        self.tmp, self.out, self.size = tmp, out, size
        self.frames = 0
        width, height = size
        cmd = [exe, "-hide_banner", "-nostdin", "-nostats", "-loglevel", "error", "-y"]
        cmd += ["-f", "rawvideo", "-pix_fmt", "bgr24", "-video_size", f"{width}x{height}"]
        cmd += ["-framerate", _rate(fps), "-i", "pipe:0", "-an"]
        cmd += ["-vf", _FILTERS, "-c:v", "libx264", "-preset", H264_PRESET, "-crf", str(H264_CRF)]
        cmd += ["-movflags", "+faststart"]
        cmd += ["-f", muxer, str(tmp)]
        # FFmpeg's messages, read back to explain a failure; open while FFmpeg runs.
        self._log: IO[bytes] = tempfile.TemporaryFile()  # noqa: SIM115
        try:
            self._proc = subprocess.Popen(
                cmd,
                stdin=subprocess.PIPE,
                stdout=subprocess.DEVNULL,
                stderr=self._log,
                start_new_session=True,
            )
        except OSError as err:
            self._log.close()
            raise OutputError(f"{out}: cannot start FFmpeg ({exe}): {err}") from err

    def write(self, image: Image) -> None:
        stdin = self._proc.stdin
        assert stdin is not None
        try:
            stdin.write(np.ascontiguousarray(image).data)
        except OSError as err:  # FFmpeg exited: a full disk, a killed process
            self._proc.wait()
            raise OutputError(self._failure(str(err))) from err
        self.frames += 1

    def finish(self) -> None:
        """Close the pipe, wait for FFmpeg to write the file; raise if it failed."""
        try:
            if self._proc.stdin is not None:
                with suppress(OSError):  # a broken pipe: the exit status says why
                    self._proc.stdin.close()
            code = self._proc.wait()
        except BaseException:
            self.kill()
            raise
        if code != 0:
            raise OutputError(self._failure(f"exit {code}"))
        self._log.close()

    def kill(self) -> None:
        """Stop FFmpeg now (its output is left for the caller to remove)."""
        if self._proc.poll() is None:
            self._proc.kill()
        if self._proc.stdin is not None:
            with suppress(OSError):
                self._proc.stdin.close()
        self._proc.wait()
        self._log.close()

    def _failure(self, fallback: str) -> str:
        try:
            self._log.seek(0)
            text = self._log.read().decode("utf-8", "replace")
        except (OSError, ValueError):
            text = ""
        finally:
            with suppress(OSError):
                self._log.close()
        reason = _last_line(text.replace(str(self.tmp), str(self.out)))
        code = self._proc.returncode
        if not reason and code is not None and code < 0:
            name = signal.Signals(-code).name
            reason = f"killed by {name}" + (
                " (over the file size limit)" if name == "SIGXFSZ" else ""
            )
        reason = reason or fallback
        return (
            f"{self.out}: the video could not be written (FFmpeg stopped after {self.frames} "
            f"frames: {reason})"
        )


@contextmanager
def quiet_stderr() -> Iterator[None]:
    """Silence file descriptor 2 (FFmpeg and OpenCV print there directly) for the block."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


@contextmanager
def _opencv_log_level(level: int) -> Iterator[None]:
    """OpenCV's log level lowered to ``level`` (never raised) for the block."""
    old = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(min(old, level))
    try:
        yield
    finally:
        cv2.utils.logging.setLogLevel(old)


class OpenCVEncoder:
    """OpenCV's ``VideoWriter``: the first of the container's codecs that opens.

    A failed write only logs an OpenCV warning (``VideoWriter.write`` returns nothing): the
    caller reads the file back to find out."""

    def __init__(self, tmp: Path, out: Path, size: tuple[int, int], fps: float) -> None:
        codecs = _OPENCV_CODECS.get(out.suffix.lower(), _OPENCV_DEFAULT)
        for i, codec in enumerate(codecs):
            last = i == len(codecs) - 1
            # Probing a missing encoder makes FFmpeg print several lines: keep them quiet.
            with nullcontext() if last else quiet_stderr():
                writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter.fourcc(*codec), fps, size)
            if writer.isOpened():
                self._writer: cv2.VideoWriter | None = writer
                self.codec = codec
                self.note: str | None = None
                return
        raise OutputError(f"{out}: cannot open a video writer ({', '.join(codecs)})")

    def write(self, image: Image) -> None:
        assert self._writer is not None
        with _opencv_log_level(cv2.utils.logging.LOG_LEVEL_ERROR):
            self._writer.write(image)

    def finish(self) -> None:
        if self._writer is not None:
            self._writer.release()
            self._writer = None

    def kill(self) -> None:
        self.finish()


def open_encoder(tmp: Path, out: Path, size: tuple[int, int], fps: float) -> FrameEncoder:
    """The encoder for ``out`` (written to ``tmp`` until the caller moves it into place)."""
    muxer = H264_CONTAINERS.get(out.suffix.lower())
    if muxer is None:
        return OpenCVEncoder(tmp, out, size, fps)
    exe, why = h264_ffmpeg()
    if exe is not None:
        return FFmpegEncoder(exe, tmp, out, size, fps, muxer)
    enc = OpenCVEncoder(tmp, out, size, fps)
    name = f"{CODEC_NAMES[enc.codec]} ({enc.codec})"
    enc.note = f"no H.264 from FFmpeg ({why}); {out.name} is {name} written by OpenCV" + (
        ", which browsers may not play" if enc.codec != "avc1" else ""
    )
    return enc
