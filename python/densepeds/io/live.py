"""Live sources for ``densepeds run``: network cameras (``rtsp://``, ``http(s)://``, ...) and
local ones (``/dev/videoN``), read with OpenCV's FFmpeg (or V4L2) backend.

A live run writes each frame's tracks to the tracks file as soon as the frame is tracked (the
file is flushed after every frame, so ``tail -f`` follows it), and ends:

- when the stream ends or the camera stops answering for ``TIMEOUT_S`` seconds (after
  ``--reconnect N`` failed tries to open it again, 1 s apart): a one-line message on stderr and
  exit code ``EXIT_DISCONNECTED`` (3); everything tracked so far is in the tracks file and the
  annotated video;
- at the last frame of ``--frames A:B``: exit 0;
- on Ctrl-C: the same files kept, exit 130.

Frames are numbered from 1 in the order they arrive, across reconnections.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

import cv2
import numpy as np

from densepeds.errors import InputError, ParameterError
from densepeds.io.video import FrameRange, FrameSource, Image, as_bgr

__all__ = ["EXIT_DISCONNECTED", "LiveSource", "is_live", "shown"]

#: Exit code of ``densepeds run`` on a live source that ended or disconnected.
EXIT_DISCONNECTED = 3
#: Seconds to wait for a connection, and then for each frame, before the camera counts as gone.
TIMEOUT_S = 10.0
NETWORK_SCHEMES = ("rtsp", "rtsps", "rtmp", "rtmps", "http", "https", "srt", "udp", "tcp")
_DEVICE = re.compile(r"/dev/video\d+")


def is_live(text: str) -> bool:
    """A camera URL (one of ``NETWORK_SCHEMES``) or a V4L2 device ``/dev/videoN``."""
    scheme = re.match(r"([A-Za-z][A-Za-z0-9+.-]*)://", text)
    return (scheme is not None and scheme.group(1).lower() in NETWORK_SCHEMES) or bool(
        _DEVICE.fullmatch(text)
    )


def shown(url: str) -> str:
    """The URL as it may be printed: a password in it replaced by ``***``."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    host = parts.hostname or ""
    netloc = f"{parts.username}:***@{host}" + (f":{parts.port}" if parts.port else "")
    return urlunsplit(parts._replace(netloc=netloc))


def _name(url: str) -> str:
    from densepeds.io.mot import safe_name

    if _DEVICE.fullmatch(url):
        return Path(url).name
    parts = urlsplit(url)
    where = f"{parts.hostname or ''}{'_' + str(parts.port) if parts.port else ''}{parts.path}"
    return safe_name(where.strip("/").replace("/", "_"), "camera")


class LiveSource(FrameSource):
    """Frames from a camera as they arrive (``length`` None: no end is known).

    Opening connects and reads the first frame (its size is the source's ``size``); a camera
    that cannot be reached or sends nothing raises InputError. ``reconnect``: how many times in
    a row to try to open the stream again, 1 s apart, when it ends or stalls. After
    ``frames()`` ends, ``ended`` says why where the stream stopped (None: the frame range was
    done).
    """

    live = True

    def __init__(self, url: str, reconnect: int = 0) -> None:
        if reconnect < 0:
            raise ParameterError(f"--reconnect must be >= 0, got {reconnect}")
        self.url = url
        self.reconnect = reconnect
        self.name = _name(url)
        self.reconnections = 0
        self.ended: str | None = None
        cap = self._open()
        if cap is None:
            raise InputError(f"{shown(url)}: cannot open the stream (no answer or not a video)")
        ok, first = cap.read()
        if not ok or first is None:
            cap.release()
            raise InputError(f"{shown(url)}: connected, but no frame came in {TIMEOUT_S:g} s")
        self._cap: Any = cap
        self._first: Image | None = as_bgr(first)
        fps = cap.get(cv2.CAP_PROP_FPS)
        # RTP's clock rate (90000) is no frame rate; the video writer needs a plausible one.
        self.fps = float(fps) if fps and np.isfinite(fps) and 0 < fps <= 240 else 25.0
        self.size = (first.shape[1], first.shape[0])
        self.length = None

    def _open(self) -> Any:
        timeout_ms = int(TIMEOUT_S * 1000)
        if _DEVICE.fullmatch(self.url):
            cap = cv2.VideoCapture(self.url, cv2.CAP_V4L2)
        else:
            params = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, timeout_ms]
            params += [cv2.CAP_PROP_READ_TIMEOUT_MSEC, timeout_ms]
            cap = cv2.VideoCapture(self.url, cv2.CAP_FFMPEG, params)
        if not cap.isOpened():
            cap.release()
            return None
        return cap

    def _read(self) -> Image | None:
        """The next frame, reopening the stream up to ``reconnect`` times; None at the end."""
        if self._first is not None:
            image, self._first = self._first, None
            return image
        tries = 0
        while True:
            if self._cap is not None:
                ok, image = self._cap.read()
                if ok and image is not None:
                    return as_bgr(image)
                self._cap.release()
                self._cap = None
            if tries >= self.reconnect:
                again = f" ({tries} reconnection tries failed)" if tries else ""
                self.ended = f"the stream ended or stopped answering{again}"
                return None
            tries += 1
            time.sleep(1.0)
            self._cap = self._open()
            if self._cap is not None:
                self.reconnections += 1

    def frames(self, rng: FrameRange | None = None) -> Iterator[tuple[int, Image | None]]:
        rng = rng or FrameRange()
        frame_no = 0
        try:
            while rng.last is None or frame_no < rng.last:
                image = self._read()
                if image is None:
                    return
                frame_no += 1
                if frame_no >= rng.first:
                    yield frame_no, image
        finally:
            self.close()

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None
