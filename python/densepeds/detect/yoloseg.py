"""YOLOv8/YOLO11 instance segmentation (Ultralytics ONNX output contract) on CPU.

Outputs: predictions [B, 4 + nc + nm, A] (cx, cy, w, h; nc class scores; nm mask coefficients)
and prototypes [B, nm, Hp, Wp] or [B, Hp, Wp, nm]; a mask is sigmoid(proto @ coef) cropped to
its box. Input size and layout (NCHW or NHWC) are read from the model. All tiles of a frame go
through onnxruntime in one batched call; masks are rendered only inside each kept box.
``stage_seconds`` accumulates the time spent in preprocessing, inference, box decoding and
masks (for benchmarks).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import onnxruntime as ort

from densepeds.detect import anchor_grid, onnxutil, split_batch
from densepeds.detect.onnxutil import META_SOURCE, is_quantized_copy
from densepeds.detect.tiling import (
    PeopleTiles,
    SkipSchedule,
    Tile,
    TilesSpec,
    cut_flags,
    make_tiles,
    merge_views,
    parse_grid,
)
from densepeds.errors import ModelError, ParameterError
from densepeds.frames import check_frame
from densepeds.models.files import quantized_file_name
from densepeds.types import Detections

# Models whose non-finite output was reported (once each).
_NONFINITE_WARNED: set[object] = set()

LETTERBOX_GREY = 114
MIN_FOCUS_SIDE = 8  # pixels: a focus view cut smaller than this by the frame's edge is skipped
# Views per thread letterboxed, run in one onnxruntime call and reduced to their candidates at
# a time (YoloSegDetector.views_per_call): the frame's memory stays bounded however many views
# it has (focus views grow with the people lost); the outputs do not change.
VIEWS_PER_THREAD = 4
VIEWS_PER_GPU_CALL = 32  # on a GPU: a frame's views in one call (the default tiles: at most 24)
EXPECTED = (
    "a YOLOv8/YOLO11-seg ONNX model: one image input [1,3,H,W] or [1,H,W,3] (RGB in [0,1]) and "
    "outputs [1,4+classes+masks,anchors] and prototypes [1,masks,h,w] or [1,h,w,masks] "
    "(a re-ID model given as the detector? give the detector with --detector-model; "
    "`densepeds models` lists the known ones)"
)


@dataclass(frozen=True)
class _Picked:
    """Anchors above the score threshold: their view in the frame and raw prediction rows."""

    view_idx: npt.NDArray[np.intp]
    rows: np.ndarray  # [K, 4 + classes + masks]

    @staticmethod
    def join(parts: list[_Picked]) -> _Picked:
        """The parts of one frame (at least one: a frame has at least one view) as one."""
        return _Picked(
            np.concatenate([p.view_idx for p in parts]), np.concatenate([p.rows for p in parts])
        )


@dataclass(frozen=True)
class Candidates:
    """Detections kept after merging views: frame boxes, scores, mask coefficients, view."""

    boxes: npt.NDArray[np.float64]
    scores: npt.NDArray[np.float32]
    coefs: npt.NDArray[np.float32]
    view_idx: npt.NDArray[np.intp]

    @classmethod
    def empty(cls, num_masks: int) -> Candidates:
        return cls(
            np.zeros((0, 4)),
            np.zeros(0, np.float32),
            np.zeros((0, num_masks), np.float32),
            np.zeros(0, np.intp),
        )


@dataclass(frozen=True)
class _View:
    """A frame region letterboxed into the model input: input = (frame - origin) * scale."""

    tile: Tile
    scale: float
    is_tile: bool


class YoloSegDetector:
    """Person detector and segmenter; call it on a BGR frame to get Detections with masks.

    ``full_frame=False`` (default) leaves out the whole-frame view when the frame is tiled: it
    cost an extra inference and added mostly low-score duplicates of tiled people (tracking
    accuracy unchanged without it on MOT20-01-dev). ``dequantize=True`` (default) runs a float
    copy of a QDQ int8 export, made in memory at load time from the same weights (a float
    model is left as it is): about 2x faster here (onnxruntime cannot fuse this export's QDQ
    pattern into integer kernels), and its scores separate people from clutter better, which
    the pipeline's tracker preset relies on; ``dequantize=False`` runs the graph as shipped.
    benchmarks/results/realvideo.md and speed.md have the figures. ``quantized`` chooses the
    int8 copy made for this CPU by ``densepeds models quantize`` (:func:`choose_model`): None
    (default) runs it where one made from ``model`` is beside it or in the model folders, True
    requires it, False never runs it; ``path`` is the file run, ``quantized`` (attribute)
    whether it is such a copy (benchmarks/results/int8.md has its speed and accuracy). A frame
    too small for tiles is always seen whole.

    ``tiles="auto"`` (default) chooses each frame's tiles from the people found in the last
    frames (``densepeds.detect.tiling.PeopleTiles``; ``auto_grid``'s fixed grid until enough
    are seen): bands of square tiles sized so that a person there spans ``person_share`` of
    the input, magnified at most ``max_scale``, at most ``max_tiles`` views a frame and at most
    twice the fixed grid's (``tiling.GRID_MULTIPLE``); a fixed grid is given as "CxR", or
    ``"grid"`` for the one ``tiling.auto_grid`` chooses for the frame size.
    ``full_scan_every=k`` (default 1: every frame) runs all of those tiles (or the fixed
    grid's) on every k-th frame only, and on the frames between just views of the people found
    in the last k frames (``tiling.SkipSchedule``): windows of the tiles' sizes placed over
    them where that takes fewer views (``tiling.sliding_windows``; on the people's bands a
    person goes in a window the size of a tile that shows them whole), else the tiles that
    show them whole (``tiling.occupied_tiles``); the whole frame in one view when nobody was
    found. The people who enter or were missed are looked for at least every k frames: fewer
    views, but the tracks change (see benchmarks/results/detector-recall.md and fast.md).
    ``benchmarks/detector_recall.py`` measures recall and views per choice.

    ``fit_input=True`` (default) runs the model, on a fixed grid (or the whole frame, untiled),
    with its input cut to the shape of the grid's tiles (:func:`fitted_input`: the same scale,
    each side rounded up to whole cells of the coarsest level), so that less grey padding goes
    through the network: a 2x2 grid of a 4:3 frame runs 320x256 instead of 320x320, about 20%
    less work a view. Its anchor grid is rebuilt for that size (``anchor_grid``); a model whose
    anchor grid is in a form not known runs at its own size. The people-following tiles are
    square and always run the model's own size. Boxes move by up to about a pixel (the rebuilt
    anchors are exact where the shipped graph's are rounded, and the padding's border differs);
    ``fit_input=False`` runs the model's own size everywhere.

    ``focus_scale`` (default 2.5; 0: off) adds, on the next frame, one view per box given to
    :meth:`focus` (``Pipeline`` gives the tracks it reports without a detection: people lost
    behind others), a region of the input's shape centred on the box, its longer side
    ``focus_scale`` times the box's height (a square for a square input), so
    that the people there are seen magnified; their detections merge with the tiles' in the
    same cross-view suppression, and the tile choice learns only from the detections kept from
    the tiles' views. Nothing changes until :meth:`focus` is called. The default was chosen
    leave-one-out on the four video cells (benchmarks/results/decisions.md).

    ``device`` (``densepeds.detect.DEVICES``; :mod:`densepeds.detect.onnxutil`)
    chooses where the model runs; on a GPU a frame's views run in one call (at most
    ``VIEWS_PER_GPU_CALL``) and ``threads`` only sets the CPU's share; ``openvino`` runs each
    batch in one call on ``threads`` (None: every CPU). ``device`` (attribute) is where it runs.
    """

    def __init__(
        self,
        model: Path,
        *,
        tiles: TilesSpec = "auto",
        score_threshold: float = 0.15,
        iou_threshold: float = 0.6,
        full_frame: bool = False,
        batch_views: bool = True,
        with_masks: bool = True,
        threads: int | None = None,
        person_class: int = 0,
        dequantize: bool = True,
        quantized: bool | None = None,
        person_share: float = 0.25,
        max_tiles: int = 12,
        max_scale: float = 3.0,
        full_scan_every: int = 1,
        focus_scale: float = 2.5,
        fit_input: bool = True,
        device: str = "auto",
    ) -> None:
        if not 0.0 <= focus_scale < float("inf"):
            raise ParameterError(f"focus_scale must be >= 0 and finite, got {focus_scale}")
        if not 0.0 <= score_threshold <= 1.0:
            raise ParameterError(f"score_threshold must be in [0, 1], got {score_threshold}")
        if not 0.0 < iou_threshold <= 1.0:
            raise ParameterError(f"iou_threshold must be in (0, 1], got {iou_threshold}")
        self.tiles = tiles
        self.focus_scale = focus_scale
        self._focus = np.zeros((0, 4))  # boxes to look at magnified on the next frame
        self.score_threshold = score_threshold
        self.iou_threshold = iou_threshold
        self.full_frame = full_frame
        self.with_masks = with_masks
        self.person_class = person_class
        self.source = model
        self.path = choose_model(model, quantized)
        self.quantized = is_quantized_copy(self.path)
        self.threads = threads
        self.dequantize = dequantize and not self.quantized
        # threads=None: views split one part per CPU, each on one thread (split_batch), where
        # they divide evenly; other batches run as one call on every CPU (_wide, made when
        # first needed).
        self.fit_input = fit_input
        self._input_size: tuple[int, int] | None = None  # None: the model's own
        self._unfit: set[tuple[int, int]] = set()  # sizes the model cannot be given
        self.session, self.rewritten = onnxutil.batched_session(
            self.path,
            onnxutil.session_threads(threads, device),
            dequantize=self.dequantize,
            device=device,
        )
        self.device = onnxutil.session_device(self.session)  # later sessions: the same
        self._wide: ort.InferenceSession | None = None
        self.batch_views = batch_views
        # Seconds spent per stage (preprocess, inference, boxes, masks), for benchmarks.
        self.stage_seconds: dict[str, float] = {}
        self.last_views = 0  # views (tiles) of the last frame
        self._read_contract()
        self.model_h, self.model_w = self.input_h, self.input_w  # the model's own input size
        self.people_tiles = PeopleTiles(
            max(self.input_w, self.input_h), person_share, max_tiles, max_scale, full_scan_every
        )
        self.grid_schedule = SkipSchedule(full_scan_every)  # a fixed grid's tiles per frame

    # --- model contract -------------------------------------------------------------------
    def _read_contract(self) -> None:
        inputs = onnxutil.specs(self.session.get_inputs())
        outputs = onnxutil.specs(self.session.get_outputs())
        if len(inputs) != 1 or len(inputs[0].shape) != 4 or len(outputs) != 2:
            raise ModelError(
                f"{self.path}: expected {EXPECTED}; got inputs {inputs}, outputs {outputs}"
            )
        shape = inputs[0].shape
        if shape[3] == 3:
            self.nhwc, hw = True, shape[1:3]
        elif shape[1] == 3:
            self.nhwc, hw = False, shape[2:4]
        else:
            raise ModelError(f"{self.path}: input shape {shape} is neither NCHW nor NHWC RGB")
        if not all(isinstance(v, int) for v in hw):
            raise ModelError(f"{self.path}: input size must be fixed, got {shape}")
        self.input_h, self.input_w = int(hw[0]), int(hw[1])  # type: ignore[arg-type]
        self.input_name = inputs[0].name
        ranks = [len(o.shape) for o in outputs]
        if sorted(ranks) != [3, 4]:
            raise ModelError(f"{self.path}: expected {EXPECTED}; got outputs {outputs}")
        self.pred_index = ranks.index(3)
        self.proto_index = ranks.index(4)
        self._probe()

    def _probe(self) -> None:
        """Run a grey image once: fixes the output layouts and whether boxes are normalised."""
        preds, protos = self._infer(
            np.full((1, self.input_h, self.input_w, 3), LETTERBOX_GREY, np.uint8)
        )
        self.proto_nhwc = protos.shape[3] < protos.shape[1]
        self.num_masks = protos.shape[3] if self.proto_nhwc else protos.shape[1]
        if preds.shape[1] > preds.shape[2]:  # [1, A, C] exports: channels last
            self.pred_transposed = True
            channels = preds.shape[2]
        else:
            self.pred_transposed = False
            channels = preds.shape[1]
        self.num_classes = channels - 4 - self.num_masks
        if self.num_classes <= self.person_class:
            raise ModelError(
                f"{self.path}: {channels} prediction channels leave {self.num_classes} classes "
                f"for {self.num_masks} mask coefficients; expected {EXPECTED}"
            )
        centres = preds[0, :, :2] if self.pred_transposed else preds[0, :2, :].T
        # Normalised exports put every anchor centre in [0, 1]; pixel exports reach the size.
        self.box_scale = (
            np.array([self.input_w, self.input_h], np.float64)
            if float(np.abs(centres).max()) <= 1.5
            else np.ones(2)
        )

    def prepare(self, batch_u8: npt.NDArray[np.uint8]) -> npt.NDArray[np.float32]:
        """BGR uint8 [B, H, W, 3] letterboxed views -> the model's input (RGB in [0, 1])."""
        # OpenCV swaps the channels of the views stacked as one tall image (one pass), then one
        # cast and an in-place scale.
        views = np.ascontiguousarray(batch_u8)
        rgb = cv2.cvtColor(views.reshape(-1, views.shape[2], 3), cv2.COLOR_BGR2RGB)
        x = rgb.reshape(views.shape).astype(np.float32)
        x *= np.float32(1 / 255)
        if not self.nhwc:
            x = x.transpose(0, 3, 1, 2)
        return np.ascontiguousarray(x)

    def _infer(self, batch_u8: npt.NDArray[np.uint8]) -> tuple[np.ndarray, np.ndarray]:
        """batch_u8: BGR uint8 [B, H, W, 3] letterboxed views -> (predictions, prototypes)."""
        x = self.prepare(batch_u8)
        if self.batch_views:
            out = self._run_views(x)
            return out[self.pred_index], out[self.proto_index]
        session = self._wide_session()
        parts = [session.run(None, {self.input_name: x[i : i + 1]}) for i in range(len(x))]
        preds = np.concatenate([p[self.pred_index] for p in parts])
        protos = np.concatenate([p[self.proto_index] for p in parts])
        return preds, protos

    def views_per_call(self) -> int:
        """Views letterboxed, run and reduced to their candidates at a time: at most
        ``VIEWS_PER_THREAD`` per thread, so that the frame's memory stays bounded however
        many views it has (the input, the activations and the raw predictions of one part);
        on a GPU ``VIEWS_PER_GPU_CALL``."""
        if self.device == "cuda":
            return VIEWS_PER_GPU_CALL
        return VIEWS_PER_THREAD * (self.threads or onnxutil.available_cpus())

    def _run_views(self, x: npt.NDArray[np.float32]) -> list[np.ndarray]:
        """The model on a batch of views: with ``threads`` None split one part per CPU where
        the views divide evenly, else one call on every CPU; with ``threads`` one call on that
        many threads; on a GPU or with OpenVINO one call."""
        feed = {self.input_name: x}
        if self.threads is not None or self.device != "cpu":
            return list(self.session.run(None, feed))
        if len(x) % onnxutil.available_cpus():
            return list(self._wide_session().run(None, feed))
        return split_batch.run_split(self.session, feed)

    def _wide_session(self) -> ort.InferenceSession:
        """The model on every CPU in one call (``threads`` None: batches that do not split);
        the session as it is where ``threads`` is given, on one CPU or on a GPU."""
        if self.threads is not None or onnxutil.available_cpus() == 1 or self.device != "cpu":
            return self.session
        if self._wide is None:
            self._wide, _ = onnxutil.batched_session(
                self.path,
                None,
                dequantize=self.dequantize,
                input_size=self._input_size,
                anchors=True,
                device=self.device,
            )
        return self._wide

    def _fit_input(self, tiles: list[Tile]) -> None:
        """``fit_input``: the model's input cut to the fixed layout's views (see the class
        docstring); the model's own size where it cannot be given that size."""
        tile_w = max(t.x1 - t.x0 for t in tiles)
        tile_h = max(t.y1 - t.y0 for t in tiles)
        size = fitted_input(tile_w, tile_h, self.model_h, self.model_w)
        if not self.fit_input or size == (self.input_h, self.input_w) or size in self._unfit:
            return
        wanted = None if size == (self.model_h, self.model_w) else size
        try:
            session, self.rewritten = onnxutil.batched_session(
                self.path,
                onnxutil.session_threads(self.threads, self.device),
                dequantize=self.dequantize,
                input_size=wanted,
                anchors=True,
                device=self.device,
            )
        except ModelError:  # e.g. an anchor grid in a form it does not know: runs as it is
            self._unfit.add(size)
            return
        self.session, self._wide, self._input_size = session, None, wanted
        self._read_contract()

    # --- detection --------------------------------------------------------------------------
    def views(self, width: int, height: int) -> list[_View]:
        whole = Tile(0, 0, width, height, (False, False, False, False))
        if self.tiles == "auto":
            tiles = self.people_tiles.tiles(width, height)
        else:
            cols, rows = parse_grid(self.tiles, width, height, max(self.model_w, self.model_h))
            grid = make_tiles(width, height, cols, rows) if cols * rows > 1 else []
            self._fit_input(grid or [whole])
            tiles = self.grid_schedule.tiles(grid)
        regions = [(t, True) for t in tiles]
        if not tiles or self.full_frame:
            regions.append((whole, False))
        return [self._view(t, is_tile) for t, is_tile in regions]

    def _view(self, tile: Tile, is_tile: bool) -> _View:
        """``tile`` letterboxed into the model input at the largest scale that fits."""
        scale = min(self.input_w / (tile.x1 - tile.x0), self.input_h / (tile.y1 - tile.y0))
        return _View(tile, scale, is_tile)

    def letterbox(self, frame: npt.NDArray[np.uint8], views: list[_View]) -> np.ndarray:
        """The views of ``frame`` resized into one uint8 batch [V, H, W, 3], grey padded."""
        batch = np.full((len(views), self.input_h, self.input_w, 3), LETTERBOX_GREY, np.uint8)
        for k, v in enumerate(views):
            t = v.tile
            w = min(self.input_w, max(1, round((t.x1 - t.x0) * v.scale)))
            h = min(self.input_h, max(1, round((t.y1 - t.y0) * v.scale)))
            batch[k, :h, :w] = cv2.resize(
                frame[t.y0 : t.y1, t.x0 : t.x1], (w, h), interpolation=cv2.INTER_LINEAR
            )
        return batch

    def reset(self) -> None:
        """Forget the people seen (another video starts): its first frames get the fixed grid."""
        self.people_tiles.reset()
        self.grid_schedule.reset()
        self._focus = np.zeros((0, 4))

    def focus(self, boxes: npt.ArrayLike) -> None:
        """Boxes ``[x1, y1, x2, y2]`` to look at closer on the next frame (see ``focus_scale``
        in the class docstring)."""
        self._focus = np.asarray(boxes, np.float64).reshape(-1, 4)

    def focus_views(self, width: int, height: int) -> list[_View]:
        """The views of the boxes given to :meth:`focus` (none with ``focus_scale`` 0)."""
        out = []
        for b in self._focus if self.focus_scale > 0 else []:
            # The input's shape, its longer side focus_scale times the box's height.
            side = self.focus_scale * (b[3] - b[1]) / max(self.input_w, self.input_h)
            half_w, half_h = side * self.input_w / 2, side * self.input_h / 2
            cx, cy = (b[0] + b[2]) / 2, (b[1] + b[3]) / 2
            x0, y0 = int(max(0, cx - half_w)), int(max(0, cy - half_h))
            x1, y1 = int(min(width, cx + half_w)), int(min(height, cy + half_h))
            if x1 - x0 < MIN_FOCUS_SIDE or y1 - y0 < MIN_FOCUS_SIDE:
                continue
            tile = Tile(x0, y0, x1, y1, (x0 > 0, y0 > 0, x1 < width, y1 < height))
            out.append(self._view(tile, True))
        return out

    def __call__(self, frame: npt.NDArray[np.uint8]) -> Detections:
        check_frame(frame)
        height, width = frame.shape[:2]
        clock = time.perf_counter()
        views = self.views(width, height)
        tiles = len(views)
        views += self.focus_views(width, height)
        self._focus = np.zeros((0, 4))
        self.last_views = len(views)
        picked: list[_Picked] = []
        protos: list[np.ndarray] = []  # per view
        most = self.views_per_call()
        for start in range(0, len(views), most):
            batch = self.letterbox(frame, views[start : start + most])
            clock = self._tick("preprocess", clock)
            preds, part_protos = self._infer(batch)
            clock = self._tick("inference", clock)
            picked.append(self._pick(preds, start))
            protos.extend(part_protos)
            clock = self._tick("boxes", clock)
        found = self._merge(_Picked.join(picked), views, width, height)
        # The tile choice learns from the detections kept from the tiles, not the focus views.
        seen = found.view_idx < tiles
        if self.tiles == "auto":
            self.people_tiles.observe(found.boxes[seen], found.scores[seen], width, height)
        else:
            self.grid_schedule.observe(found.boxes[seen])
        dets = Detections(found.boxes.astype(np.float32), found.scores)
        clock = self._tick("boxes", clock)
        if self.with_masks and len(found.boxes):
            dets.masks, dets.mask_boxes = self._masks(
                found.boxes, found.coefs, found.view_idx, views, protos, width, height
            )
            self._tick("masks", clock)
        return dets

    def _tick(self, stage: str, since: float) -> float:
        now = time.perf_counter()
        self.stage_seconds[stage] = self.stage_seconds.get(stage, 0.0) + now - since
        return now

    def candidates(
        self, preds: np.ndarray, views: list[_View], width: int, height: int
    ) -> Candidates:
        """The detections kept from the views' raw predictions, in frame coordinates."""
        return self._merge(self._pick(preds, 0), views, width, height)

    def _pick(self, preds: np.ndarray, first_view: int) -> _Picked:
        """The person anchors above ``score_threshold`` in a batch of views' raw predictions
        (the batch's first view is view ``first_view`` of the frame)."""
        if self.pred_transposed:
            preds = preds.transpose(0, 2, 1)
        view_idx, anchor_idx = np.nonzero(preds[:, 4 + self.person_class, :] > self.score_threshold)
        rows = preds[view_idx, :, anchor_idx]
        ok = onnxutil.finite_rows(rows, self.path, _NONFINITE_WARNED)
        return _Picked(view_idx[ok] + first_view, rows[ok])

    def _merge(self, picked: _Picked, views: list[_View], width: int, height: int) -> Candidates:
        """The picked anchors as frame boxes, merged across the views."""
        view_idx, cand = picked.view_idx, picked.rows
        if len(view_idx) == 0:
            return Candidates.empty(self.num_masks)
        scores = cand[:, 4 + self.person_class]
        cxcy = cand[:, 0:2] * self.box_scale
        half = cand[:, 2:4] * self.box_scale / 2
        scale = np.array([views[i].scale for i in range(len(views))])[view_idx, None]
        origin = np.array([[v.tile.x0, v.tile.y0] for v in views], np.float64)[view_idx]
        boxes = np.concatenate([cxcy - half, cxcy + half], axis=1) / scale
        boxes += np.tile(origin, 2)
        np.clip(boxes, 0, [width, height, width, height], out=boxes)
        cut = np.zeros(len(boxes), bool)
        for k, v in enumerate(views):
            if v.is_tile:
                sel = view_idx == k
                cut[sel] = cut_flags(boxes[sel], v.tile)
        valid = (boxes[:, 2] - boxes[:, 0] >= 1) & (boxes[:, 3] - boxes[:, 1] >= 1)
        idx = np.flatnonzero(valid)
        merged = merge_views(boxes[idx], scores[idx], view_idx[idx], cut[idx], self.iou_threshold)
        keep = idx[merged]
        return Candidates(
            boxes[keep], scores[keep], cand[keep, 4 + self.num_classes :], view_idx[keep]
        )

    def masks(
        self,
        found: Candidates,
        views: list[_View],
        protos: Sequence[np.ndarray],
        width: int,
        height: int,
    ) -> tuple[list[npt.NDArray[np.bool_]], npt.NDArray[np.int32]]:
        """Box-local masks of ``found`` (see ``_masks``)."""
        return self._masks(found.boxes, found.coefs, found.view_idx, views, protos, width, height)

    def _masks(
        self,
        boxes: np.ndarray,
        coefs: np.ndarray,
        view_idx: np.ndarray,
        views: list[_View],
        protos: Sequence[np.ndarray],
        width: int,
        height: int,
    ) -> tuple[list[npt.NDArray[np.bool_]], npt.NDArray[np.int32]]:
        """Box-local masks: the prototype logits of each box's view, warped onto its box only."""
        mask_boxes = np.empty((len(boxes), 4), np.int32)
        mask_boxes[:, :2] = np.floor(boxes[:, :2])
        mask_boxes[:, 2:] = np.ceil(boxes[:, 2:])
        np.clip(mask_boxes, 0, [width, height, width, height], out=mask_boxes)
        masks: list[npt.NDArray[np.bool_]] = [np.zeros((0, 0), bool)] * len(boxes)
        for k in sorted(set(view_idx.tolist())):  # np.unique would import numpy.ma at start-up
            proto = protos[k] if self.proto_nhwc else protos[k].transpose(1, 2, 0)
            ph, pw = proto.shape[:2]
            v = views[k]
            ax = self.input_w / pw / v.scale  # frame px per prototype cell
            ay = self.input_h / ph / v.scale
            for i in np.flatnonzero(view_idx == k):
                x0, y0, x1, y1 = (int(c) for c in mask_boxes[i])
                # Prototype cell centre u maps to frame pixel index (u + 0.5) * a - 0.5 + origin;
                # only the cells under the box (plus a margin for interpolation) are evaluated.
                px0, px1 = _cell_span(x0, x1, v.tile.x0, ax, pw)
                py0, py1 = _cell_span(y0, y1, v.tile.y0, ay, ph)
                # einsum, not BLAS: tiny products with BLAS threads stall under onnxruntime load.
                logits = np.einsum("hwc,c->hw", proto[py0:py1, px0:px1], coefs[i])
                warp = np.array(
                    [
                        [ax, 0.0, (px0 + 0.5) * ax - 0.5 + v.tile.x0 - x0],
                        [0.0, ay, (py0 + 0.5) * ay - 0.5 + v.tile.y0 - y0],
                    ]
                )
                local = cv2.warpAffine(
                    np.ascontiguousarray(logits, dtype=np.float32),
                    warp,
                    (x1 - x0, y1 - y0),
                    flags=cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE,
                )
                masks[i] = local.reshape(y1 - y0, x1 - x0) > 0
        return masks, mask_boxes


def choose_model(model: Path, quantized: bool | None) -> Path:
    """The file the detector runs for ``model``: its int8 copy or ``model`` itself.

    The int8 copy (``densepeds models quantize``, :mod:`densepeds.models.quantize`) is looked for
    beside ``model`` and then in the model folders; it is used when ``quantized`` is True
    (ModelError when there is none) or None (when there is one). A copy made from a different file
    than ``model`` (its recorded sha256 differs) is a ModelError either way, never used silently.
    """
    if quantized is False or is_quantized_copy(model):
        return model
    from densepeds.models.files import locate, sha256_of

    name = quantized_file_name(model)
    found = model.with_name(name) if model.with_name(name).is_file() else locate(name)
    if found is None:
        if quantized:
            raise ModelError(
                f"no int8 copy of {model.name} ({name}) beside it or in the model folders; make "
                "one with `densepeds models quantize --calibrate VIDEO`"
            )
        return model
    recorded = onnxutil.model_metadata(found).get(META_SOURCE)
    if recorded != sha256_of(model):
        raise ModelError(
            f"{found} was not made from {model} (sha256 differs); remake it with "
            "`densepeds models quantize --calibrate VIDEO`, or delete it"
        )
    return found


def fitted_input(tile_w: int, tile_h: int, model_h: int, model_w: int) -> tuple[int, int]:
    """(height, width) of an input that shows a ``tile_w`` x ``tile_h`` view at the scale the
    model's own ``model_h`` x ``model_w`` input does, with less padding: each side the view's
    at that scale, rounded up to whole cells of the coarsest level, at most the model's."""
    scale = min(model_w / tile_w, model_h / tile_h)
    cell = anchor_grid.STRIDES[-1]

    def side(view: float, most: int) -> int:
        return min(most, math.ceil(view * scale / cell - 1e-9) * cell)

    return side(tile_h, model_h), side(tile_w, model_w)


def _cell_span(lo: int, hi: int, origin: int, step: float, cells: int) -> tuple[int, int]:
    """Prototype cells [c0, c1) whose centres cover frame pixels [lo, hi), with a 1-cell margin."""
    c0 = int(np.floor((lo + 0.5 - origin) / step - 0.5)) - 1
    c1 = int(np.ceil((hi - 0.5 - origin) / step - 0.5)) + 2
    c0 = min(max(c0, 0), cells - 1)
    return c0, min(max(c1, c0 + 1), cells)
