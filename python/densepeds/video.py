"""Frame sources (video file, image folder, MOTChallenge sequence) and the annotated video writer.

Frames are numbered from 1 as in MOTChallenge: frame k of a video is the k-th decoded image.
A source yields ``(frame_no, image)`` with ``image`` a BGR uint8 HxWx3 array, or ``None`` for a
sequence that has detections but no images (tracking from ``det/det.txt`` alone).
"""

from __future__ import annotations

import os
import re
import tempfile
import threading
from collections import deque
from collections.abc import Generator, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from queue import Full, Queue
from typing import Any, TypeVar

import cv2
import numpy as np
import numpy.typing as npt

from densepeds.errors import InputError, ParameterError

__all__ = [
    "AnnotatedVideoWriter",
    "FrameRange",
    "FrameSource",
    "ImageFolderSource",
    "SequenceSource",
    "VideoSource",
    "id_colour",
    "open_source",
    "parse_frame_range",
]

Image = npt.NDArray[np.uint8]
VIDEO_EXTS = {".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".wmv"}
T = TypeVar("T")
IMAGE_EXTS = {".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp"}


@dataclass(frozen=True)
class FrameRange:
    """Frames ``first..last`` inclusive, 1-based; ``last=None`` runs to the end."""

    first: int = 1
    last: int | None = None

    def __contains__(self, frame: object) -> bool:
        return (
            isinstance(frame, int)
            and frame >= self.first
            and (self.last is None or frame <= self.last)
        )

    def clip(self, length: int) -> FrameRange:
        last = length if self.last is None else min(self.last, length)
        return FrameRange(self.first, last)


def parse_frame_range(text: str | FrameRange | None) -> FrameRange:
    """Parse ``A:B`` (inclusive, 1-based), ``A:``, ``:B`` or a single frame ``A``."""
    if text is None:
        return FrameRange()
    if isinstance(text, FrameRange):
        rng = text
    else:
        m = re.fullmatch(r"\s*(\d*)\s*(:?)\s*(\d*)\s*", text)
        if not m or (not m.group(1) and not m.group(3)):
            raise ParameterError(f"frame range {text!r}: expected A:B (1-based, inclusive)")
        first = int(m.group(1)) if m.group(1) else 1
        last = (int(m.group(3)) if m.group(3) else None) if m.group(2) else first
        rng = FrameRange(first, last)
    if rng.first < 1:
        raise ParameterError(f"frame range starts at {rng.first}: frames are numbered from 1")
    if rng.last is not None and rng.last < rng.first:
        raise ParameterError(f"frame range {rng.first}:{rng.last} is empty")
    return rng


def _natural_key(path: Path) -> list[int | str]:
    """Sort key so that img2 < img10."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", path.name)]


class FrameSource:
    """Base class: iterate ``(frame_no, image | None)`` over a frame range."""

    name: str = "input"
    fps: float = 25.0
    size: tuple[int, int] | None = None  # (width, height) where known before decoding
    length: int | None = None

    def frames(self, rng: FrameRange | None = None) -> Iterator[tuple[int, Image | None]]:
        raise NotImplementedError

    def __iter__(self) -> Iterator[tuple[int, Image | None]]:
        return self.frames()


class VideoSource(FrameSource):
    """A video file decoded with OpenCV.

    ``prefetch`` frames are decoded ahead on a background thread (OpenCV releases the GIL), so
    decoding overlaps the consumer's work; 0 decodes in the caller's thread.
    """

    def __init__(self, path: str | os.PathLike[str], prefetch: int = 2) -> None:
        if prefetch < 0:
            raise ParameterError(f"prefetch must be >= 0, got {prefetch}")
        self.prefetch = prefetch
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError(f"{self.path}: video file not found")
        cap = cv2.VideoCapture(str(self.path))
        try:
            ok, first = cap.read() if cap.isOpened() else (False, None)
            if not ok or first is None:
                raise InputError(f"{self.path}: cannot decode video (unreadable or corrupt)")
            fps = cap.get(cv2.CAP_PROP_FPS)
            count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        finally:
            cap.release()
        self.name = self.path.stem
        self.fps = float(fps) if fps and np.isfinite(fps) and fps > 0 else 25.0
        self.size = (first.shape[1], first.shape[0])
        self.length = count if count > 0 else None

    def frames(self, rng: FrameRange | None = None) -> Iterator[tuple[int, Image | None]]:
        if self.prefetch < 1:
            return self._decode(rng)
        return prefetched(self._decode(rng), self.prefetch)

    def _decode(self, rng: FrameRange | None = None) -> Iterator[tuple[int, Image | None]]:
        rng = rng or FrameRange()
        cap = cv2.VideoCapture(str(self.path))
        if not cap.isOpened():
            raise InputError(f"{self.path}: cannot open video")
        try:
            # grab() decodes nothing for skipped frames and, unlike seeking, is frame-exact.
            for _ in range(rng.first - 1):
                if not cap.grab():
                    return
            frame_no = rng.first
            while rng.last is None or frame_no <= rng.last:
                ok, image = cap.read()
                if not ok or image is None:
                    return
                yield frame_no, _as_bgr(image)
                frame_no += 1
        finally:
            cap.release()


_END = object()


def prefetched(items: Iterator[T], depth: int = 2) -> Generator[T, None, None]:
    """``items`` produced ahead on a background thread, at most ``depth`` waiting.

    The producer's exceptions are re-raised in the consumer; closing the returned generator
    (or dropping it) stops the producer and closes ``items`` in its own thread.
    """
    queue: Queue[Any] = Queue(maxsize=depth)
    stop = threading.Event()

    def produce() -> None:
        try:
            for item in items:
                while not stop.is_set():
                    try:
                        queue.put(item, timeout=0.05)
                        break
                    except Full:
                        continue
                if stop.is_set():
                    break
        except BaseException as exc:  # handed to the consumer, raised there
            _put_final(queue, stop, exc)
            return
        finally:
            close = getattr(items, "close", None)
            if close is not None:
                close()
        _put_final(queue, stop, _END)

    # Started on the first next(), so a generator never iterated leaves no thread behind.
    worker = threading.Thread(target=produce, name="densepeds-decode", daemon=True)
    worker.start()
    try:
        while True:
            item = queue.get()
            if item is _END:
                return
            if isinstance(item, BaseException):
                raise item
            yield item
    finally:
        stop.set()
        worker.join()


def _put_final(queue: Queue[Any], stop: threading.Event, item: object) -> None:
    while not stop.is_set():
        try:
            queue.put(item, timeout=0.05)
            return
        except Full:
            continue


class ImageFolderSource(FrameSource):
    """A folder of images taken in natural order (frame k = the k-th image)."""

    def __init__(self, path: str | os.PathLike[str], fps: float = 25.0) -> None:
        self.path = Path(path)
        if not self.path.is_dir():
            raise InputError(f"{self.path}: image folder not found")
        self.files = sorted(
            (p for p in self.path.iterdir() if p.suffix.lower() in IMAGE_EXTS), key=_natural_key
        )
        if not self.files:
            raise InputError(f"{self.path}: no images ({', '.join(sorted(IMAGE_EXTS))})")
        self.name = self.path.name
        self.fps = fps
        self.length = len(self.files)

    def frames(self, rng: FrameRange | None = None) -> Iterator[tuple[int, Image | None]]:
        rng = (rng or FrameRange()).clip(len(self.files))
        assert rng.last is not None
        for frame_no in range(rng.first, rng.last + 1):
            yield frame_no, _read_image(self.files[frame_no - 1])


class SequenceSource(FrameSource):
    """A MOTChallenge sequence folder: ``seqinfo.ini``, images in ``img1/`` (or one video file in
    the folder), ``det/det.txt``. Without images it yields ``None`` frames for every frame."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        from densepeds.motio import read_seqinfo

        self.info = read_seqinfo(path)
        self.path = self.info.path
        self.name = self.info.name
        self.fps = self.info.fps
        self.size = (self.info.width, self.info.height)
        self.length = self.info.length
        self.image_source: FrameSource | None = None
        if self.info.image_dir.is_dir() and any(self.info.image_dir.iterdir()):
            self.image_source = ImageFolderSource(self.info.image_dir, self.fps)
        else:
            videos = sorted(p for p in self.path.iterdir() if p.suffix.lower() in VIDEO_EXTS)
            if len(videos) == 1:
                self.image_source = VideoSource(videos[0])
        det = self.path / "det" / "det.txt"
        self.det_path: Path | None = det if det.is_file() else None

    @property
    def has_images(self) -> bool:
        return self.image_source is not None

    def frames(self, rng: FrameRange | None = None) -> Iterator[tuple[int, Image | None]]:
        rng = (rng or FrameRange()).clip(self.length or 0)
        assert rng.last is not None
        if self.image_source is None:
            for frame_no in range(rng.first, rng.last + 1):
                yield frame_no, None
            return
        yield from self.image_source.frames(rng)


def open_source(path: str | os.PathLike[str]) -> FrameSource:
    """A video file, a MOTChallenge sequence folder, or a folder of images."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file or folder")
    if p.is_file():
        if p.name == "seqinfo.ini":
            return SequenceSource(p.parent)
        return VideoSource(p)
    if (p / "seqinfo.ini").is_file():
        return SequenceSource(p)
    return ImageFolderSource(p)


def _read_image(path: Path) -> Image:
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise InputError(f"{path}: cannot read image")
    return _as_bgr(image)


def _as_bgr(image: npt.NDArray[Any]) -> Image:
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    return np.ascontiguousarray(image[:, :, :3], dtype=np.uint8)


def id_colour(track_id: int) -> tuple[int, int, int]:
    """A bright BGR colour fixed per id (golden-ratio hue steps keep neighbours distinct)."""
    hue = int((track_id * 0.618033988749895 % 1.0) * 180)
    hsv = np.array([[[hue, 220, 255]]], np.uint8)
    b, g, r = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0]
    return int(b), int(g), int(r)


@dataclass
class AnnotatedVideoWriter:
    """Writes frames with each track's box, id and a short trail of its recent foot points.

    The video goes to a temporary file beside ``path`` and is moved into place by ``close()``,
    so an interrupted run leaves no half-written video under the final name.
    """

    path: Path
    fps: float = 25.0
    trail: int = 20
    _writer: cv2.VideoWriter | None = None
    _tmp: Path | None = None
    _size: tuple[int, int] | None = None
    _trails: dict[int, deque[tuple[int, int]]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.path = Path(self.path)
        if self.path.suffix.lower() not in VIDEO_EXTS:
            raise ParameterError(f"{self.path}: video output needs a video extension like .mp4")

    def _open(self, width: int, height: int) -> cv2.VideoWriter:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(
            dir=self.path.parent, prefix=f".{self.path.stem}.", suffix=self.path.suffix
        )
        os.close(fd)
        self._tmp = Path(tmp)
        codec = "mp4v" if self.path.suffix.lower() in {".mp4", ".m4v", ".mov"} else "MJPG"
        writer = cv2.VideoWriter(tmp, cv2.VideoWriter.fourcc(*codec), self.fps, (width, height))
        if not writer.isOpened():
            self._tmp.unlink(missing_ok=True)
            raise InputError(f"{self.path}: cannot open a video writer ({codec})")
        self._size = (width, height)
        return writer

    def write(
        self,
        image: Image | None,
        ids: npt.ArrayLike,
        boxes: npt.ArrayLike,
        size: tuple[int, int] | None = None,
    ) -> None:
        """Draw the tracks on a copy of ``image`` (white canvas of ``size`` if None), add it."""
        if image is None:
            if size is None and self._size is None:
                raise InputError("annotated video needs frames or a frame size")
            w, h = size or self._size  # type: ignore[misc]
            canvas = np.full((h, w, 3), 255, np.uint8)
        else:
            canvas = image.copy()
        if self._writer is None:
            self._writer = self._open(canvas.shape[1], canvas.shape[0])
        if (canvas.shape[1], canvas.shape[0]) != self._size:
            raise InputError(f"frame size changed mid-video: {canvas.shape[1::-1]} != {self._size}")
        ids_arr = np.asarray(ids, dtype=np.int64).reshape(-1)
        box_arr = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        self._draw(canvas, ids_arr, box_arr)
        self._writer.write(canvas)

    def _draw(
        self, canvas: Image, ids: npt.NDArray[np.int64], boxes: npt.NDArray[np.float64]
    ) -> None:
        seen = set()
        for tid, (x1, y1, x2, y2) in zip(ids.tolist(), boxes.tolist(), strict=True):
            seen.add(tid)
            colour = id_colour(tid)
            trail = self._trails.setdefault(tid, deque(maxlen=self.trail))
            trail.append((int(round((x1 + x2) / 2)), int(round(y2))))
            if len(trail) > 1:
                pts = np.array(trail, np.int32).reshape(-1, 1, 2)
                cv2.polylines(canvas, [pts], False, colour, 2, cv2.LINE_AA)
            p1, p2 = (int(round(x1)), int(round(y1))), (int(round(x2)), int(round(y2)))
            cv2.rectangle(canvas, p1, p2, colour, 2)
            label = str(tid)
            (tw, th), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.5, 1)
            top = max(p1[1] - th - 4, 0)
            cv2.rectangle(canvas, (p1[0], top), (p1[0] + tw + 4, top + th + 4), colour, -1)
            cv2.putText(
                canvas,
                label,
                (p1[0] + 2, top + th + 1),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.5,
                (0, 0, 0),
                1,
                cv2.LINE_AA,
            )
        for tid in list(self._trails):  # forget trails of tracks not shown this frame
            if tid not in seen:
                del self._trails[tid]

    def close(self) -> None:
        """Finish the file and move it into place (nothing is written if no frame came)."""
        if self._writer is not None:
            self._writer.release()
            self._writer = None
            assert self._tmp is not None
            os.replace(self._tmp, self.path)
            self._tmp = None

    def abort(self) -> None:
        """Drop a partial video."""
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        if self._tmp is not None:
            self._tmp.unlink(missing_ok=True)
            self._tmp = None

    def __enter__(self) -> AnnotatedVideoWriter:
        return self

    def __exit__(self, exc_type: object, *_: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
