"""The end-to-end tracker for downstream code: frames (or detections) in, tracks out.

    pipe = Pipeline(detector="yoloseg", motion="frvo", features="segmented")
    for frame_no, tracks in pipe.run("video.mp4"):
        ...

Each stage (decode, detection, re-ID, tracking, output) is timed so that callers can report
where the time goes (``Pipeline.times``).
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, cast, overload

import numpy as np
import numpy.typing as npt

from densepeds.boxes import box_area, intersections, iou_matrix
from densepeds.errors import InputError, ParameterError, warn_input
from densepeds.frames import check_frame
from densepeds.io.video import FrameRange, FrameSource, open_source, parse_frame_range
from densepeds.presets import Preset, get_preset, preset_for
from densepeds.segment import FEATURES as CROP_FEATURES
from densepeds.sv_adapter import is_sv_detections
from densepeds.types import Detections

if TYPE_CHECKING:
    from supervision import Detections as SvDetections

    from densepeds.sv_adapter import SvTracks
    from densepeds.tracking import Tracks

__all__ = [
    "FEATURES",
    "MOTIONS",
    "STAGES",
    "FrameResult",
    "Pipeline",
    "StageTimes",
    "default_features",
    "suppress_duplicates",
    "track_rows",
]

MOTIONS = ("frvo", "rvo", "sf", "cv")
# The appearance features of densepeds.segment (segmented: the method's white fill outside the
# mask; bbox: the plain crop; masked_*: other maskings), or none: motion only.
FEATURES = (*CROP_FEATURES, "none")
# The method's segmented boxes (white fill outside the mask): no other kind is shown better on
# the dev grid's video cells, so the method's form is the default
# (benchmarks/results/accuracy-claims.md, realvideo.md; docs/method.md).
DEFAULT_FEATURES = "segmented"
DETECTORS = ("yoloseg", "maskrcnn")
# Pipeline-level options (the rest of the keyword arguments go to the tracker), applied to the
# detections before tracking; the presets (densepeds.presets) set them for CNN detectors.
DETECTION_OPTIONS = ("min_score", "min_height", "nms_iou", "nms_containment", "nms_mask_overlap")
STAGES = ("decode", "detection", "reid", "tracking", "output")
Image = npt.NDArray[np.uint8]


class Embedder(Protocol):
    def embed(
        self, frame: Image, dets: Detections, features: str = "segmented"
    ) -> npt.NDArray[np.float32]: ...


@dataclass
class StageTimes:
    """Wall-clock seconds spent in each stage, and the frames processed."""

    seconds: dict[str, float] = field(default_factory=lambda: dict.fromkeys(STAGES, 0.0))
    frames: int = 0

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start

    @property
    def total(self) -> float:
        return sum(self.seconds.values())

    @property
    def fps(self) -> float:
        return self.frames / self.total if self.total > 0 else 0.0

    def per_frame_ms(self) -> dict[str, float]:
        n = max(self.frames, 1)
        return {k: 1000.0 * v / n for k, v in self.seconds.items()}

    def breakdown(self) -> str:
        """E.g. ``decode 1.2, detection 60.3, reid 20.1, tracking 0.8, output 0.1 ms/frame``."""
        parts = [f"{k} {v:.1f}" for k, v in self.per_frame_ms().items()]
        return ", ".join(parts) + " ms/frame"


@dataclass
class FrameResult:
    """One frame of ``Pipeline.run_frames``: its tracks, its image (None without images) and the
    detections of the frame as the detector found them or the caller gave them, before the
    pipeline's filter (``tracks.det_index`` refers to these)."""

    frame_no: int
    tracks: Tracks
    image: Image | None
    detections: Detections


def track_rows(frame_no: int, tracks: Tracks) -> list[tuple[float, ...]]:
    """Rows (frame, id, x1, y1, x2, y2, score) for ``motio.write_tracks``."""
    return [
        (frame_no, int(i), *map(float, b), float(s))
        for i, b, s in zip(tracks.ids, tracks.boxes, tracks.scores, strict=True)
    ]


def suppress_duplicates(
    dets: Detections,
    iou: float = 1.0,
    containment: float = 1.0,
    mask_overlap: float = 1.0,
    mask_min_iou: float = 0.3,
) -> npt.NDArray[np.intp]:
    """Indices (ascending) of the detections kept by greedy suppression, best score first.

    A box is a duplicate of a kept one when their IoU > ``iou``, when more than ``containment``
    of its area lies inside the kept box (a person cut at a tile's edge inside the whole-frame
    box of the same person), or, with masks, when the boxes overlap by IoU > ``mask_min_iou``
    and more than ``mask_overlap`` of the smaller mask lies on the kept one's mask: in a crowd
    two people's boxes overlap a lot while their masks (occluder, occluded) barely do. 1.0
    keeps everything a test would remove.
    """
    n = len(dets)
    use_masks = mask_overlap < 1.0 and dets.masks is not None and dets.mask_boxes is not None
    if n < 2 or (iou >= 1.0 and containment >= 1.0 and not use_masks):
        return np.arange(n)
    b = dets.boxes.astype(np.float64)
    overlap = iou_matrix(b, b)
    inside = intersections(b, b) / np.maximum(box_area(b)[None, :], 1e-9)  # [i, j]: j in i
    duplicate = (overlap > iou) | (inside > containment)  # [i, j]: i kept suppresses j
    if use_masks:
        for i, j in zip(*np.nonzero(np.triu(overlap > mask_min_iou, 1)), strict=True):
            if not duplicate[i, j] and _mask_share(dets, int(i), int(j)) > mask_overlap:
                duplicate[i, j] = duplicate[j, i] = True
    keep = np.zeros(n, bool)
    suppressed = np.zeros(n, bool)
    for i in np.argsort(-dets.scores, kind="stable"):
        if not suppressed[i]:
            keep[i] = True
            suppressed |= duplicate[i]
    return np.flatnonzero(keep)


def _mask_share(dets: Detections, i: int, j: int) -> float:
    """Share of the smaller of masks i and j that lies on the other (0 for empty masks)."""
    assert dets.masks is not None and dets.mask_boxes is not None
    bi, bj = dets.mask_boxes[i], dets.mask_boxes[j]
    x0, y0 = max(bi[0], bj[0]), max(bi[1], bj[1])
    x1, y1 = min(bi[2], bj[2]), min(bi[3], bj[3])
    smaller = min(int(dets.masks[i].sum()), int(dets.masks[j].sum()))
    if x1 <= x0 or y1 <= y0 or smaller == 0:
        return 0.0
    mi = dets.masks[i][y0 - bi[1] : y1 - bi[1], x0 - bi[0] : x1 - bi[0]]
    mj = dets.masks[j][y0 - bj[1] : y1 - bj[1], x0 - bj[0] : x1 - bj[0]]
    return float(np.count_nonzero(mi & mj)) / smaller


def default_features(has_images: bool) -> str:
    """The appearance features used where there are frames; motion only where there are none."""
    return DEFAULT_FEATURES if has_images else "none"


def _check_choice(what: str, value: str, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise ParameterError(f"{what} {value!r}: expected one of {', '.join(allowed)}")
    return value


class Pipeline:
    """Detection, segmented-box re-ID features, motion prediction and association, per frame.

    detector: None (detections are given to ``step``/``run``, or read from a sequence's det.txt),
        "yoloseg" / "maskrcnn" (built with ``detector_model`` or the default model file), or any
        callable ``frame -> Detections``.
    reid: None (the default OSNet model, loaded the first time a frame needs features), a model
        path, or any object with ``embed(frame, dets, features) -> float32 [N, D]``.
    motion: frvo | rvo | sf | cv. features: segmented | bbox | none (appearance is used only when
        a frame is given). Other keyword arguments go to ``densepeds.tracking.Tracker``;
    tracker: instead, any object with ``update(boxes, scores, embeddings) -> Tracks`` and
        ``reset()`` (e.g. another tracker to compare with).
    preset: a name in ``densepeds.presets.PRESETS`` (default: the detector's own, ``detfile``
        for detections given or read from a file); the caller's values win over it. ``preset``
        and ``params`` show what is in use.
    device: where the models the pipeline loads run: ``auto`` (default: a GPU where one is
        usable, else the CPU), ``cpu`` or ``cuda`` (``densepeds.detect.onnxutil.providers``);
        models given loaded keep their own.
    """

    def __init__(
        self,
        detector: None | str | Any = None,
        reid: None | str | os.PathLike[str] | Embedder = None,
        motion: str = "frvo",
        features: str = DEFAULT_FEATURES,
        *,
        detector_model: str | os.PathLike[str] | None = None,
        detector_options: Mapping[str, Any] | None = None,
        tracker: Any = None,
        preset: str | None = None,
        device: str = "auto",
        **tracker_params: Any,
    ) -> None:
        from densepeds.detect import DEVICES

        self.device = _check_choice("device", device, DEVICES)
        self.motion = _check_choice("motion", motion, MOTIONS)
        self.features = _check_choice("features", features, FEATURES)
        if isinstance(detector, str):
            _check_choice("detector", detector, DETECTORS)
        elif detector is not None and not callable(detector):
            raise ParameterError("detector must be None, 'yoloseg', 'maskrcnn' or a callable")
        self._detector_spec = detector
        self._detector: Any = None if isinstance(detector, str) else detector
        if self._detector is not None and hasattr(self._detector, "reset"):
            self._detector.reset()  # a loaded detector shared by a batch starts a new sequence
        self._detector_model = detector_model
        self._detector_options = dict(detector_options or {})
        self._frame_detections = Detections.empty()  # the last frame's, for run_frames
        self._capped_frames = 0  # frames whose detector output was cut to the tracker's bound
        self._reid_spec = reid
        self._reid: Embedder | None = reid if hasattr(reid, "embed") else None  # type: ignore[assignment]
        options = {k: tracker_params.pop(k) for k in DETECTION_OPTIONS if k in tracker_params}
        # The preset (the detector's own unless named), then the caller's values over it.
        self.preset: Preset = preset_for(detector) if preset is None else get_preset(preset)
        options = {**self.preset.detection, **options}
        if isinstance(detector, str) and self.preset.score_floor is not None:
            self._detector_options = {
                "score_threshold": self.preset.score_floor,
                **self._detector_options,
            }
        if tracker is None:
            tracker_params = {**self.preset.tracker, **tracker_params}
        self.detection_options = options
        self.tracker_params = tracker_params
        if tracker is None:
            from densepeds.tracking import Tracker

            tracker = Tracker(motion=motion, **tracker_params)
        elif tracker_params:
            raise ParameterError("give tracker parameters or a tracker object, not both")
        self.tracker = tracker
        self.times = StageTimes()
        self._sv: SvTracks | None = None  # made by the first supervision Detections

    @property
    def params(self) -> dict[str, Any]:
        """Every setting in use: the preset's name, the detector's score floor (None: the
        detections as given), the detection filter and the tracker's parameters."""
        floor = self._detector_options.get("score_threshold") if self.has_detector else None
        tracker_params = getattr(self.tracker, "params", {})
        return {
            "preset": self.preset.name,
            "score_floor": floor,
            **self.detection_options,
            **dict(tracker_params),
        }

    # --- lazily built models -------------------------------------------------------------------

    @property
    def has_detector(self) -> bool:
        return self._detector_spec is not None

    def detector(self) -> Any:
        if self._detector is None:
            if self._detector_spec is None:
                raise InputError("no detections given and no detector chosen")
            from densepeds.detect import make_detector

            model = None if self._detector_model is None else Path(self._detector_model)
            self._detector = make_detector(
                self._detector_spec, model, device=self.device, **self._detector_options
            )
        return self._detector

    def reid(self) -> Embedder:
        if self._reid is None:
            from densepeds.reid import ReID

            model = None if self._reid_spec is None else Path(self._reid_spec)  # type: ignore[arg-type]
            self._reid = ReID(model, device=self.device)
        return self._reid

    # --- one frame ------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget all tracks (start a new sequence); the models stay loaded, the detector forgets
        what it learnt of the last sequence (e.g. where its people are)."""
        self.tracker.reset()
        if self._sv is not None:
            self._sv.reset()
        if self._detector is not None and hasattr(self._detector, "reset"):
            self._detector.reset()
        self.times = StageTimes()

    def _at_most_tracked(self, detections: Detections) -> Detections:
        """A detector's output cut to the most confident ``MAX_DETECTIONS_PER_FRAME`` (the most
        the tracker takes in a frame), with a warning the first time."""
        from densepeds._core import MAX_DETECTIONS_PER_FRAME

        most = MAX_DETECTIONS_PER_FRAME
        if len(detections) <= most:
            return detections
        if self._capped_frames == 0:
            warn_input(
                f"the detector found {len(detections)} people in one frame; the {most} most "
                "confident are tracked (said once)"
            )
        self._capped_frames += 1
        top = np.argsort(-detections.scores, kind="stable")[:most]
        return detections.subset(np.sort(top))

    def process(
        self,
        frame: Image | None = None,
        detections: Detections | None = None,
        embeddings: npt.NDArray[np.float32] | None = None,
    ) -> Tracks:
        """``step`` without the frame counter (used by ``run`` which counts itself)."""
        if frame is not None:
            check_frame(frame)
            self.set_image_size(frame.shape[1], frame.shape[0])
        if detections is None:
            if frame is None:
                raise InputError("step() needs a frame, detections, or both")
            with self.times.stage("detection"):
                detections = self._at_most_tracked(self.detector()(frame))
        elif not isinstance(detections, Detections):
            raise InputError(f"detections must be densepeds.Detections, got {type(detections)}")
        self._frame_detections = detections  # as found or given, before the pipeline's filter
        if embeddings is not None:
            embeddings = np.asarray(embeddings, np.float32)
            if embeddings.ndim != 2 or len(embeddings) != len(detections):
                raise InputError(
                    f"embeddings must be [N, D] for {len(detections)} detections, "
                    f"got {embeddings.shape}"
                )
        kept = None
        if self.detection_options:
            with self.times.stage("detection"):
                kept = self._kept(detections)
                if len(kept) < len(detections):
                    detections = detections.subset(kept)
                    embeddings = None if embeddings is None else embeddings[kept]
                else:
                    kept = None
        if embeddings is None and frame is not None and self.features != "none" and len(detections):
            with self.times.stage("reid"):
                embeddings = self.reid().embed(frame, detections, features=self.features)
        with self.times.stage("tracking"):
            tracks = self.tracker.update(
                detections.boxes.astype(np.float64), detections.scores, embeddings
            )
        if kept is not None:  # det_index refers to the detections as given
            matched = tracks.det_index >= 0
            index = tracks.det_index.copy()
            index[matched] = kept[index[matched]]
            tracks = tracks._replace(det_index=index)
        if self._detector is not None and hasattr(self._detector, "focus"):
            # The people reported without a detection, for a closer look (focus_scale).
            self._detector.focus(tracks.boxes[tracks.det_index < 0])
        return tracks

    def set_image_size(self, width: int, height: int) -> None:
        """Tells the tracker the image size (so that it can tell people who left the image from
        hidden ones); ``step`` does it from the frame, ``run`` from the source."""
        set_size = getattr(self.tracker, "set_image_size", None)
        if set_size is not None:
            set_size(width, height)

    def _kept(self, dets: Detections) -> npt.NDArray[np.intp]:
        """Indices of the detections tracked: score floor, then duplicate suppression."""
        opt = self.detection_options
        index = np.arange(len(dets))
        min_score = opt.get("min_score")
        if min_score is not None:
            index = index[dets.scores[index] >= min_score]
        min_height = opt.get("min_height")
        if min_height is not None:
            heights = dets.boxes[index, 3] - dets.boxes[index, 1]
            index = index[heights >= min_height]
        return index[
            suppress_duplicates(
                dets.subset(index),
                opt.get("nms_iou", 1.0),
                opt.get("nms_containment", 1.0),
                opt.get("nms_mask_overlap", 1.0),
            )
        ]

    @overload
    def step(
        self,
        frame: Image | None = None,
        detections: Detections | None = None,
        embeddings: npt.NDArray[np.float32] | None = None,
    ) -> Tracks: ...

    @overload
    def step(
        self,
        frame: Image | None,
        detections: SvDetections,
        embeddings: npt.NDArray[np.float32] | None = None,
    ) -> SvDetections: ...

    def step(
        self,
        frame: Image | None = None,
        detections: Detections | SvDetections | None = None,
        embeddings: npt.NDArray[np.float32] | None = None,
    ) -> Tracks | SvDetections:
        """Track one frame. Give the frame, its detections, or both (detections win over the
        detector; appearance features need the frame, or precomputed ``embeddings``).

        ``detections`` may be a ``supervision.Detections`` (from any detector; its masks, where
        it has them, shape the segmented re-ID crops): the result is then a new
        ``sv.Detections`` with ``tracker_id`` and the coasted people (``densepeds.sv_adapter``).
        """
        if is_sv_detections(detections):
            from densepeds.sv_adapter import SvTracks, to_detections

            if self._sv is None:
                max_age = dict(getattr(self.tracker, "params", {})).get("max_age")
                self._sv = SvTracks(None if max_age is None else int(max_age))
            tracks = self.process(frame, to_detections(detections), embeddings)
            self.times.frames += 1
            return self._sv.result(detections, tracks)
        tracks = self.process(frame, cast("Detections | None", detections), embeddings)
        self.times.frames += 1
        return tracks

    # --- whole sources --------------------------------------------------------------------------

    def run(
        self,
        source: str | os.PathLike[str] | FrameSource,
        frames: str | FrameRange | None = None,
        detections: str | os.PathLike[str] | Mapping[int, Detections] | None = None,
    ) -> Iterator[tuple[int, Tracks]]:
        """Track a video, image folder, MOT sequence or FrameSource; yield (frame_no, tracks)."""
        for result in self.run_frames(source, frames, detections):
            yield result.frame_no, result.tracks

    def run_frames(
        self,
        source: str | os.PathLike[str] | FrameSource,
        frames: str | FrameRange | None = None,
        detections: str | os.PathLike[str] | Mapping[int, Detections] | None = None,
    ) -> Iterator[FrameResult]:
        """Like ``run``, also yielding each frame's image and detections (for drawing)."""
        src = source if isinstance(source, FrameSource) else open_source(source)
        rng = parse_frame_range(frames)
        dets = self.source_detections(src, detections)
        size = getattr(src, "size", None)
        if size is not None:
            self.set_image_size(*size)
        it = src.frames(rng)
        while True:
            with self.times.stage("decode"):
                item = next(it, None)
            if item is None:
                break
            frame_no, image = item
            frame_dets = None
            if dets is not None:
                frame_dets = dets.get(frame_no) or Detections.empty()
            tracks = self.process(image, frame_dets)
            self.times.frames += 1
            yield FrameResult(frame_no, tracks, image, self._frame_detections)

    def source_detections(
        self,
        src: FrameSource,
        detections: str | os.PathLike[str] | Mapping[int, Detections] | None,
    ) -> Mapping[int, Detections] | None:
        """Where a run's detections come from: given > detector > the source's own (det.txt)."""
        from densepeds.io.mot import read_detections

        if detections is not None:
            if isinstance(detections, Mapping):
                return detections
            return _checked_against(src, read_detections(detections), detections)
        if self.has_detector:
            if not getattr(src, "has_images", True):
                raise InputError(f"{src.name}: has no images to run a detector on")
            return None
        own = getattr(src, "detections", None)
        if isinstance(own, Mapping):
            return own
        det_path = getattr(src, "det_path", None)
        if det_path is not None:
            return _checked_against(src, read_detections(det_path), det_path)
        raise InputError(
            f"{src.name}: no detections: give a det file (--detections) or a detector (--detector)"
        )


def _checked_against(
    src: FrameSource, dets: dict[int, Detections], path: str | os.PathLike[str]
) -> dict[int, Detections]:
    """``dets`` of a det file, with a warning (never silently) for what the source drops or
    reinterprets: detections past its last frame, and detections centred well outside its
    image (a declared image size smaller than the detections' frame)."""
    length = getattr(src, "length", None)
    if length is not None:
        late = [k for k in dets if k > length]
        if late:
            count = sum(len(dets[k]) for k in late)
            warn_input(
                f"{path}: {count} detections in frames {min(late)}-{max(late)} lie past the "
                f"sequence's {length} frames (seqLength) and are not tracked"
            )
    size = getattr(src, "size", None)
    if size is not None:
        width, height = size
        outside = 0
        for d in dets.values():
            cx = 0.5 * (d.boxes[:, 0] + d.boxes[:, 2])
            cy = 0.5 * (d.boxes[:, 1] + d.boxes[:, 3])
            # People walking out are centred just past the border; a tenth of the image beyond
            # it, the declared size is not the detections' frame.
            far_x = (cx < -0.1 * width) | (cx > 1.1 * width)
            far_y = (cy < -0.1 * height) | (cy > 1.1 * height)
            outside += int(np.count_nonzero(far_x | far_y))
        if outside:
            warn_input(
                f"{path}: {outside} detections are centred outside the {width}x{height} image "
                "(imWidth x imHeight) by more than a tenth of it; tracks there are reported as "
                "leaving the image"
            )
    return dets
