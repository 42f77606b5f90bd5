"""Frame sources (video file, image folder, MOTChallenge sequence) and the annotated video writer.

Frames are numbered from 1 as in MOTChallenge: frame k of a video is the k-th decoded image.
A source yields ``(frame_no, image)`` with ``image`` a BGR uint8 HxWx3 array, or ``None`` for a
sequence that has detections but no images (tracking from ``det/det.txt`` alone).
"""

from __future__ import annotations

import os
import re
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

from densepeds.errors import InputError, OutputError, ParameterError, warn_input
from densepeds.io.video_encoder import CODEC_NAMES, FrameEncoder, open_encoder, quiet_stderr

__all__ = [
    "CODEC_NAMES",
    "AnnotatedVideoWriter",
    "FrameRange",
    "FrameSource",
    "ImageFolderSource",
    "SequenceSource",
    "VideoSource",
    "id_colour",
    "label_layout",
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
                yield frame_no, as_bgr(image)
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
        size: tuple[int, int] | None = None
        for frame_no in range(rng.first, rng.last + 1):
            image = _read_image(self.files[frame_no - 1])
            shape = (image.shape[1], image.shape[0])
            if size is None:
                size = shape
            elif shape != size:
                warn_input(
                    f"{self.files[frame_no - 1]}: {shape[0]}x{shape[1]}, but the frames before "
                    f"it are {size[0]}x{size[1]}; each image is tracked in its own pixels"
                )
                size = shape
            yield frame_no, image


class SequenceSource(FrameSource):
    """A MOTChallenge sequence folder: ``seqinfo.ini``, images in ``img1/`` (or one video file in
    the folder), ``det/det.txt``. Without images it yields ``None`` frames for every frame."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        from densepeds.io.mot import read_seqinfo

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
    """A video file, a MOTChallenge sequence folder, or a folder of images (live cameras:
    ``densepeds.io.live.LiveSource``)."""
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
    return as_bgr(image)


def as_bgr(image: npt.NDArray[Any]) -> Image:
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    return np.ascontiguousarray(image[:, :, :3], dtype=np.uint8)


def id_colour(track_id: int) -> tuple[int, int, int]:
    """A bright BGR colour fixed per id (golden-ratio hue steps keep neighbours distinct)."""
    hue = int((track_id * 0.618033988749895 % 1.0) * 180)
    hsv = np.array([[[hue, 220, 255]]], np.uint8)
    b, g, r = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0]
    return int(b), int(g), int(r)


_LABEL_FONT = cv2.FONT_HERSHEY_SIMPLEX
_LABEL_SCALE = 0.4
_LABEL_PAD = 2
# From this many people in a frame, boxes are drawn one pixel wide so that they hide less.
_DENSE = 15

Rect = tuple[int, int, int, int]  # x1, y1, x2, y2 (exclusive)


def _overlap(a: Rect, b: Rect) -> int:
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    return w * h if w > 0 and h > 0 else 0


def label_layout(
    boxes: npt.ArrayLike,
    sizes: list[tuple[int, int]],
    frame_size: tuple[int, int],
    reserved: list[Rect] | None = None,
) -> list[Rect]:
    """Where to draw each box's id tag (``sizes``: tag width, height) so that tags avoid each
    other and ``reserved`` areas (the frame counter).

    Each tag tries, in order: above the box's top-left corner, inside it, above its top-right
    corner, at the foot point (below the box, centred), inside the bottom edge, then the same
    spots shifted sideways by one tag width; it takes the first spot inside the frame that
    overlaps nothing placed so far, or else the one overlapping least. People lowest in the frame
    (nearest the camera in a crowd) are placed first.
    """
    arr = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    width, height = frame_size
    placed: list[Rect] = list(reserved or [])
    out: list[Rect] = [(0, 0, 0, 0)] * len(arr)
    for k in np.argsort(-arr[:, 3], kind="stable").tolist():
        x1, y1, x2, y2 = (int(round(v)) for v in arr[k])
        tw, th = sizes[k]
        cx = (x1 + x2) // 2
        spots = [
            (x1, y1 - th),
            (x1, y1),
            (x2 - tw, y1 - th),
            (cx - tw // 2, y2),
            (cx - tw // 2, y2 - th),
        ]
        spots += [(x + dx, y) for dx in (tw, -tw) for x, y in spots]
        best: Rect | None = None
        best_cost = -1
        for x, y in spots:
            x = min(max(x, 0), max(width - tw, 0))
            y = min(max(y, 0), max(height - th, 0))
            rect = (x, y, x + tw, y + th)
            cost = sum(_overlap(rect, r) for r in placed)
            if best is None or cost < best_cost:
                best, best_cost = rect, cost
            if cost == 0:
                break
        assert best is not None
        placed.append(best)
        out[k] = best
    return out


def _tag_size(text: str) -> tuple[tuple[int, int], int]:
    (tw, th), base = cv2.getTextSize(text, _LABEL_FONT, _LABEL_SCALE, 1)
    return (tw + 2 * _LABEL_PAD, th + base + 2 * _LABEL_PAD), base


@dataclass
class AnnotatedVideoWriter:
    """Writes frames with each track's box, id tag, a short trail of its recent foot points and a
    frame counter.

    The video goes to a hidden temporary file beside ``path`` and is moved into place by
    ``close()`` only after it has been read back with every frame (a full disk or a failed write
    raises :class:`~densepeds.errors.OutputError` and leaves nothing under the final name);
    ``abort()`` (and any exception inside a ``with`` block) removes it. The file follows the
    umask. MP4/MOV output is H.264 for browsers where FFmpeg can encode it, else what OpenCV
    can write (see :mod:`densepeds.io.video_encoder`): ``codec`` says which was used (a key of
    ``CODEC_NAMES``), and ``note`` explains a fallback in one line.
    """

    path: Path
    fps: float = 25.0
    trail: int = 20
    codec: str | None = None
    note: str | None = None
    frames_written: int = 0
    _writer: FrameEncoder | None = None
    _tmp: Path | None = None
    _size: tuple[int, int] | None = None
    _trails: dict[int, deque[tuple[int, int]]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.path = Path(self.path)
        if self.path.suffix.lower() not in VIDEO_EXTS:
            raise ParameterError(f"{self.path}: video output needs a video extension like .mp4")

    def _open(self, width: int, height: int) -> FrameEncoder:
        from densepeds.io.mot import discard_temp, reserve_temp

        self._tmp = reserve_temp(self.path)
        try:
            encoder = open_encoder(self._tmp, self.path, (width, height), self.fps)
        except BaseException:
            discard_temp(self._tmp)
            self._tmp = None
            raise
        self.codec, self.note = encoder.codec, encoder.note
        self._size = (width, height)
        return encoder

    def write(
        self,
        image: Image | None,
        ids: npt.ArrayLike,
        boxes: npt.ArrayLike,
        size: tuple[int, int] | None = None,
        frame_no: int | None = None,
    ) -> None:
        """Draw the tracks on a copy of ``image`` (white canvas of ``size`` if None), add it.
        ``frame_no`` is drawn as the frame counter (default: frames written so far + 1)."""
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
        counter = self._draw_counter(
            canvas, self.frames_written + 1 if frame_no is None else frame_no
        )
        self._draw(canvas, ids_arr, box_arr, counter)
        self._writer.write(canvas)
        self.frames_written += 1

    @staticmethod
    def _draw_counter(canvas: Image, frame_no: int) -> Rect:
        text = f"frame {frame_no}"
        (tw, th), base = cv2.getTextSize(text, _LABEL_FONT, 0.5, 1)
        rect = (0, 0, tw + 8, th + base + 8)
        cv2.rectangle(canvas, rect[:2], (rect[2] - 1, rect[3] - 1), (0, 0, 0), -1)
        cv2.putText(canvas, text, (4, 4 + th), _LABEL_FONT, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
        return rect

    def _draw(
        self,
        canvas: Image,
        ids: npt.NDArray[np.int64],
        boxes: npt.NDArray[np.float64],
        counter: Rect,
    ) -> None:
        seen = set()
        thickness = 1 if len(ids) >= _DENSE else 2
        for tid, (x1, y1, x2, y2) in zip(ids.tolist(), boxes.tolist(), strict=True):
            seen.add(tid)
            colour = id_colour(tid)
            trail = self._trails.setdefault(tid, deque(maxlen=self.trail))
            trail.append((int(round((x1 + x2) / 2)), int(round(y2))))
            if len(trail) > 1:
                pts = np.array(trail, np.int32).reshape(-1, 1, 2)
                cv2.polylines(canvas, [pts], False, colour, thickness, cv2.LINE_AA)
            p1, p2 = (int(round(x1)), int(round(y1))), (int(round(x2)), int(round(y2)))
            cv2.rectangle(canvas, p1, p2, colour, thickness)
        # Tags last, so that no box or trail crosses them.
        labels = [str(t) for t in ids.tolist()]
        sizes = [_tag_size(t)[0] for t in labels]
        h, w = canvas.shape[:2]
        rects = label_layout(boxes, sizes, (w, h), reserved=[counter])
        for tid, label, (rx1, ry1, rx2, ry2) in zip(ids.tolist(), labels, rects, strict=True):
            cv2.rectangle(canvas, (rx1, ry1), (rx2 - 1, ry2 - 1), id_colour(tid), -1)
            _, base = _tag_size(label)
            cv2.putText(
                canvas,
                label,
                (rx1 + _LABEL_PAD, ry2 - _LABEL_PAD - base),
                _LABEL_FONT,
                _LABEL_SCALE,
                (0, 0, 0),
                1,
                cv2.LINE_AA,
            )
        for tid in list(self._trails):  # forget trails of tracks not shown this frame
            if tid not in seen:
                del self._trails[tid]

    def close(self) -> None:
        """Finish the file, check it, and move it into place (nothing is written if no frame
        came). Raises :class:`OutputError` (and removes the file) when fewer frames than were
        written can be read back."""
        from densepeds.io.mot import commit_temp, discard_temp

        if self._writer is None:
            return
        writer, self._writer = self._writer, None
        tmp, self._tmp = self._tmp, None
        assert tmp is not None
        try:
            writer.finish()
            readable = _readable_frames(tmp)
        except BaseException:
            discard_temp(tmp)
            raise
        if readable < self.frames_written:
            discard_temp(tmp)
            raise OutputError(
                f"{self.path}: the video could not be written completely ({readable} of "
                f"{self.frames_written} frames readable back; is the disk full?)"
            )
        commit_temp(tmp, self.path)

    def abort(self) -> None:
        """Drop a partial video."""
        from densepeds.io.mot import discard_temp

        if self._writer is not None:
            self._writer.kill()
            self._writer = None
        discard_temp(self._tmp)
        self._tmp = None

    def __enter__(self) -> AnnotatedVideoWriter:
        return self

    def __exit__(self, exc_type: object, *_: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def _readable_frames(path: Path) -> int:
    """Frames a just-written video holds, by its container's count (0 if it cannot be opened)."""
    try:
        if path.stat().st_size == 0:
            return 0
    except OSError:
        return 0
    with quiet_stderr():
        cap = cv2.VideoCapture(str(path))
        try:
            if not cap.isOpened():
                return 0
            count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            if count <= 0:
                count = 0
                while cap.grab():
                    count += 1
            return count
        finally:
            cap.release()
