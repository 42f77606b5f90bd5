"""Person re-identification embeddings through onnxruntime: crops in, L2-normalised rows out.

Each supported model contract is a row of MODEL_KINDS (layout, dtype, colour order,
normalisation); the input size and the embedding's width (512 for OSNet, 768 for YoutuReID,
anything) are read from the model. Crops are resized and sent in batches of ``batch_size`` per
onnxruntime call; a model with a fixed batch of 1 is rewritten to a dynamic batch once at load
time, and where that copy does not give one row per crop (a reshape to batch 1 the rewrite cannot
see) the model runs as published, one crop per call. A model that claims any batch but ignores
it is refused with one clear error.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import onnxruntime as ort

from densepeds.detect import onnxutil, split_batch
from densepeds.errors import ModelError, ParameterError
from densepeds.frames import check_frame
from densepeds.models.files import default_reid_file, find_model
from densepeds.segment import bbox_crop, crops_for, person_masks
from densepeds.types import Detections

DEFAULT_MODEL = "osnet_x0_25_msmt17.onnx"
POOL_FLOOR = 0.1  # weight of a background cell in mask-weighted pooling (person cells: 1)
# Crops a thread embeds in one onnxruntime call: memory stays bounded however many people a frame
# has; the embeddings do not change.
CROPS_PER_THREAD = 16
CROPS_PER_GPU_CALL = 128  # on a GPU: a frame's crops in one call


@dataclass(frozen=True)
class ModelKind:
    """How a re-ID model wants its input."""

    layout: str  # "NCHW" or "NHWC"
    dtype: type  # np.float32 or np.uint8
    rgb: bool  # channel order RGB (else BGR, as OpenCV decodes)
    scale: float  # multiply pixels by this first
    mean: tuple[float, float, float]  # then subtract (in the model's channel order)
    std: tuple[float, float, float]  # and divide
    match_aspect: bool = False  # widen/narrow boxes about their centre to the input's w/h first


MODEL_KINDS: dict[str, ModelKind] = {
    # torchreid OSNet family: [N,3,256,128] RGB /255, ImageNet mean/std -> [N,512]; OpenCV Zoo's
    # YoutuReID has the same input ([1,3,256,128]) -> [1,768].
    "osnet": ModelKind(
        "NCHW", np.float32, True, 1 / 255, (0.485, 0.456, 0.406), (0.229, 0.224, 0.225)
    ),
    # DeepSORT mars-small128 (nwojke/deep_sort tools/generate_detections.py): [N,128,64,3] uint8
    # BGR as cv2.imread gives, raw pixels (the graph normalises) -> [N,128]; boxes first set to
    # the input's aspect ratio (width = 0.5 * height) about their centre, as DeepSORT does.
    "mars-small128": ModelKind(
        "NHWC", np.uint8, False, 1.0, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), match_aspect=True
    ),
}


def guess_kind(layout: str, dtype: str) -> str:
    if layout == "NHWC" and dtype == "tensor(uint8)":
        return "mars-small128"
    if layout == "NCHW" and dtype == "tensor(float)":
        return "osnet"
    raise ModelError(
        f"not a re-ID model densepeds can read: its input is {layout} {dtype}, while OSNet takes "
        "float NCHW and mars-small128 uint8 NHWC (a detector given as the re-ID model?); give "
        "a re-ID model with --reid-model (`densepeds models` lists them), or in Python name its "
        f"contract with ReID(kind=...) (one of {sorted(MODEL_KINDS)})"
    )


class ReID:
    """Appearance embedder. ``embed(frame, dets, features)`` -> float32 [N, D], unit rows.

    ``threads``: onnxruntime's threads per call; None (default) splits each batch into one part
    per CPU, each part run on one thread, all at once (:mod:`densepeds.detect.split_batch`; the
    same embeddings bitwise: tests/test_reid_threads.py). ``flip``: each row is the mean of the
    crop's and its mirror's embeddings (twice the work);
    ``context``: crops grow by this fraction of the box's width and height on each side. Both
    are off by default: neither raised the tracked HOTA on the real videos
    (``benchmarks/results/decisions.md``). ``device`` (``densepeds.detect.DEVICES``):
    where the model runs (as ``YoloSegDetector``'s); ``device`` (attribute) is where it runs.
    """

    def __init__(
        self,
        model: str | os.PathLike[str] | None = None,
        *,
        kind: str = "auto",
        threads: int | None = None,
        batch_size: int = 32,
        reuse: bool | ReusePolicy = False,
        input_size: tuple[int, int] | None = None,
        flip: bool = False,
        context: float = 0.0,
        device: str = "auto",
    ) -> None:
        if batch_size < 1:
            raise ParameterError(f"batch_size must be >= 1, got {batch_size}")
        if kind != "auto" and kind not in MODEL_KINDS:
            raise ParameterError(f"kind must be 'auto' or one of {sorted(MODEL_KINDS)}, got {kind}")
        if not 0.0 <= context <= 1.0:
            raise ParameterError(f"context must be in [0, 1], got {context}")
        self.flip = flip
        self.context = context
        path = find_model(default_reid_file()) if model is None else find_model(str(model))
        self.path: Path = path
        self.batch_size = batch_size
        self.input_size = input_size
        self.threads = threads
        self.session, self.rewritten = onnxutil.batched_session(
            path,
            onnxutil.session_threads(threads, device),
            input_size=input_size,
            device=device,
        )
        self.device = onnxutil.session_device(self.session)  # later sessions: the same
        inputs = onnxutil.specs(self.session.get_inputs())
        outputs = onnxutil.specs(self.session.get_outputs())
        if len(inputs) != 1 or len(inputs[0].shape) != 4 or len(outputs) < 1:
            raise ModelError(
                f"{path}: expected a re-ID model with one image input [N,3,H,W] or [N,H,W,3] "
                f"and an embedding output [N,D] (a detector given as the re-ID model? give "
                f"the re-ID model with --reid-model; `densepeds models` lists the known ones); "
                f"got inputs {inputs}, outputs {outputs}"
            )
        shape = inputs[0].shape
        if shape[1] == 3:
            layout, hw = "NCHW", shape[2:4]
        elif shape[3] == 3:
            layout, hw = "NHWC", shape[1:3]
        else:
            raise ModelError(
                f"{path}: input shape {shape} is neither NCHW nor NHWC with 3 channels"
            )
        if not all(isinstance(v, int) for v in hw):
            raise ModelError(f"{path}: input height and width must be fixed, got {shape}")
        try:
            self.kind_name = guess_kind(layout, inputs[0].dtype) if kind == "auto" else kind
        except ModelError as err:
            raise ModelError(f"{path}: {err}") from None
        self.kind = MODEL_KINDS[self.kind_name]
        if self.kind.layout != layout:
            raise ModelError(
                f"{path}: {self.kind_name} expects {self.kind.layout}, model is {layout}"
            )
        self.height, self.width = int(hw[0]), int(hw[1])  # type: ignore[arg-type]
        self.input_name = inputs[0].name
        self._raw_shape: tuple[int, ...] | None = None  # the network's last output shape
        self.one_at_a_time = False  # the model runs as published, one crop per call
        self.dim = self._probe_dim()
        self._probe_batch()
        self._pooled: tuple[ort.InferenceSession, tuple[int, int]] | None = None
        policy = ReusePolicy() if reuse is True else reuse or None
        self.reuse: ReusePolicy | None = policy
        self._previous: dict[str, _Previous] = {}  # per feature kind: the last frame's rows
        self.embedded = 0  # crops run through the network (with reuse, fewer than detections)
        self.reused = 0

    def _probe_dim(self) -> int:
        """The embedding size, from one blank crop; rejects a model whose output is not an
        embedding ([N, D] or [N, D, 1, 1], smaller than its input; e.g. an identity model)."""
        self._run(np.zeros((1, self.height, self.width, 3), np.uint8))
        shape = tuple(self._raw_shape or ())
        pixels = self.height * self.width * 3
        flat = shape[:2] if len(shape) == 4 and shape[2:] == (1, 1) else shape
        if len(flat) != 2 or flat[0] != 1 or not 1 <= flat[1] < pixels:
            raise ModelError(
                f"{self.path}: output {list(shape)} is not an embedding: a re-ID model gives "
                f"[N, D] (or [N, D, 1, 1]) with D below the input's {pixels} values"
            )
        return int(flat[1])

    def _probe_batch(self) -> None:
        """Two blank crops in one call must give two rows. A fixed-batch model whose
        dynamic-batch copy does not falls back to running as published, one crop per call; any
        other model that does not is refused (ModelError)."""
        feed = {self.input_name: self._input(np.zeros((2, self.height, self.width, 3), np.uint8))}
        quiet = ort.RunOptions()
        quiet.log_severity_level = 4  # a failing copy is expected here: no ORT error line
        try:
            shape = np.shape(self.session.run(None, feed, quiet)[0])
            error = None
        except Exception as err:  # noqa: BLE001 (onnxruntime fails in its own ways)
            shape, error = (), err
        if len(shape) > 0 and shape[0] == 2:
            return
        if self.rewritten:
            self.session = onnxutil.make_session(
                onnxutil.load_model(self.path), self.threads or 1, device=self.device
            )
            self.rewritten = False
            self.one_at_a_time = True
            return
        first_line = str(error).strip().splitlines()[0] if error is not None else ""
        got = f"output {list(shape)}" if error is None else f"an error ({first_line})"
        raise ModelError(
            f"{self.path}: the re-ID model gave {got} for a batch of 2 crops: its output "
            "ignores the batch size (export it with a dynamic batch, or with a fixed batch of 1)"
        )

    def reset(self) -> None:
        """Forget the previous frame (start of a new video): nothing is reused across it."""
        self._previous.clear()

    def _pooled_session(self) -> tuple[ort.InferenceSession, tuple[int, int]]:
        """The model with mask-weighted final pooling, built on first use."""
        if self._pooled is None:
            model = onnxutil.load_model(self.path)
            if self.input_size is not None:
                model = onnxutil.with_input_size(model, *self.input_size)
            if not self.one_at_a_time and (
                onnxutil.has_fixed_batch(model) or self.input_size is not None
            ):
                model = onnxutil.with_dynamic_batch(model)
            pooled, size = onnxutil.with_weighted_final_pool(model)
            threads = onnxutil.session_threads(self.threads, self.device)
            self._pooled = (onnxutil.make_session(pooled, threads, device=self.device), size)
        return self._pooled

    def _run(
        self, batch_bgr: npt.NDArray[np.uint8], weights: npt.NDArray[np.float32] | None = None
    ) -> npt.NDArray[np.float32]:
        """Embeddings of the crops, at most ``CROPS_PER_THREAD`` per thread (on a GPU
        ``CROPS_PER_GPU_CALL``) at a time."""
        if self.device == "cuda":
            most = CROPS_PER_GPU_CALL
        else:
            most = CROPS_PER_THREAD * (self.threads or onnxutil.available_cpus())
        if len(batch_bgr) > most:
            parts = [
                self._run(
                    batch_bgr[i : i + most], None if weights is None else weights[i : i + most]
                )
                for i in range(0, len(batch_bgr), most)
            ]
            return np.concatenate(parts)
        feed: dict[str, np.ndarray] = {self.input_name: self._input(batch_bgr)}
        session = self.session
        if weights is not None:
            session, _ = self._pooled_session()
            feed[onnxutil.POOL_WEIGHTS] = weights
        if self.one_at_a_time:  # each crop its own call; with threads=None, one per CPU at once

            def one(i: int) -> np.ndarray:
                return np.asarray(session.run(None, {k: v[i : i + 1] for k, v in feed.items()})[0])

            items = range(len(batch_bgr))
            if self.threads is None and self.device == "cpu" and len(batch_bgr) > 1:
                rows = list(split_batch.cpu_pool().map(one, items))
            else:
                rows = [one(i) for i in items]
            out = np.concatenate(rows)
        elif self.threads is None and self.device == "cpu":
            out = split_batch.run_split(session, feed)[0]
        else:
            out = session.run(None, feed)[0]
        self._raw_shape = np.shape(out)
        if len(self._raw_shape) == 0 or self._raw_shape[0] != len(batch_bgr):
            raise ModelError(
                f"{self.path}: the re-ID model gave output {list(self._raw_shape)} for "
                f"{len(batch_bgr)} crops: its output ignores the batch size (export it with a "
                "dynamic batch, or with a fixed batch of 1)"
            )
        return np.asarray(out, np.float32).reshape(len(batch_bgr), -1)

    def _input(self, batch_bgr: npt.NDArray[np.uint8]) -> np.ndarray:
        """The model's input tensor for BGR images [N, H, W, 3] of its input size."""
        k = self.kind
        x = batch_bgr[..., ::-1] if k.rgb else batch_bgr
        if k.dtype is np.uint8:
            inp = np.ascontiguousarray(x)
            return inp.transpose(0, 3, 1, 2).copy() if k.layout == "NCHW" else inp
        mul = np.float32(k.scale) / np.asarray(k.std, np.float32)
        sub = np.asarray(k.mean, np.float32) / np.asarray(k.std, np.float32)
        if k.layout == "NHWC":
            return np.ascontiguousarray(x * mul - sub, np.float32)
        # One pass per channel straight into the planar layout (the same float32 arithmetic
        # as x * mul - sub, without the full-size temporaries and the transposing copy).
        n, h, w, _ = x.shape
        out = np.empty((n, 3, h, w), np.float32)
        for c in range(3):
            np.multiply(x[..., c], mul[c], out=out[:, c], dtype=np.float32)
            out[:, c] -= sub[c]
        return out

    def embed_crops(
        self,
        crops: list[npt.NDArray[np.uint8]],
        person: list[npt.NDArray[np.bool_]] | None = None,
    ) -> npt.NDArray[np.float32]:
        """BGR crops of any size -> float32 [N, D] with unit L2 rows.

        ``person`` (one mask per crop) switches to mask-weighted pooling of the final features.
        With ``flip`` each row is the mean of the crop's and its mirror image's embeddings (the
        two run in one batch), so a crop and its mirror give the same row.
        """
        out = np.zeros((len(crops), getattr(self, "dim", 0)), np.float32)
        for start in range(0, len(crops), self.batch_size):
            chunk = crops[start : start + self.batch_size]
            batch = np.empty((len(chunk), self.height, self.width, 3), np.uint8)
            for i, crop in enumerate(chunk):
                batch[i] = cv2.resize(
                    crop, (self.width, self.height), interpolation=cv2.INTER_LINEAR
                )
            weights = None
            if person is not None:
                weights = self._pool_weights(person[start : start + len(chunk)])
            if self.flip:
                both = np.concatenate([batch, batch[:, :, ::-1]])
                pair = None if weights is None else np.concatenate([weights, weights[..., ::-1]])
                rows = self._run(both, pair)
                half = len(chunk)
                out[start : start + half] = _unit(rows[:half]) + _unit(rows[half:])
            else:
                out[start : start + len(chunk)] = self._run(batch, weights)
        bad = ~np.isfinite(out).all(axis=1)
        if bad.any():
            raise ModelError(
                f"{self.path}: the re-ID model gave non-finite embeddings (NaN or inf) for "
                f"{int(bad.sum())} of {len(out)} crops"
            )
        return _unit(out)

    def _pool_weights(self, masks: list[npt.NDArray[np.bool_]]) -> npt.NDArray[np.float32]:
        """Per feature cell: POOL_FLOOR + (1 - POOL_FLOOR) * the person's share of the cell."""
        _, (h, w) = self._pooled_session()
        out = np.empty((len(masks), 1, h, w), np.float32)
        for i, m in enumerate(masks):
            share = cv2.resize(m.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
            out[i, 0] = POOL_FLOOR + (1 - POOL_FLOOR) * share
        return out

    def embed(
        self, frame: npt.NDArray[np.uint8], dets: Detections, features: str = "segmented"
    ) -> npt.NDArray[np.float32]:
        """Embeddings of each detection's crop; ``features`` as in densepeds.segment.FEATURES.

        With ``reuse``, calls are taken as consecutive frames of one video: a detection that
        plainly continues one of the previous call's detections gets that embedding back
        instead of a new one (see ReusePolicy); call ``reset()`` between videos.
        """
        check_frame(frame)
        if len(dets) == 0:
            if self.reuse is not None:
                self._previous.pop(features, None)
            return np.zeros((0, self.dim), np.float32)
        if self.reuse is None:
            out = self._embed_all(frame, dets, features)
            self.embedded += len(dets)
            return out
        thumbs = thumbnails(frame, dets.boxes)
        prev = self._previous.get(features)
        source = np.full(len(dets), -1, np.intp)
        if prev is not None and prev.shape == frame.shape:
            source = reuse_sources(self.reuse, dets.boxes, thumbs, prev)
        fresh = np.flatnonzero(source < 0)
        out = np.empty((len(dets), self.dim), np.float32)
        ages = np.zeros(len(dets), np.int64)
        if len(fresh):
            out[fresh] = self._embed_all(frame, dets.subset(fresh), features)
        if prev is not None:
            kept = np.flatnonzero(source >= 0)
            out[kept] = prev.embeddings[source[kept]]
            ages[kept] = prev.ages[source[kept]] + 1
        self.embedded += len(fresh)
        self.reused += len(dets) - len(fresh)
        self._previous[features] = _Previous(
            frame.shape, dets.boxes.astype(np.float64), out.copy(), ages, thumbs
        )
        return out

    def _embed_all(
        self, frame: npt.NDArray[np.uint8], dets: Detections, features: str
    ) -> npt.NDArray[np.float32]:
        if self.context > 0:
            boxes = dets.boxes.astype(np.float64)
            pad_x = self.context * (boxes[:, 2] - boxes[:, 0])
            pad_y = self.context * (boxes[:, 3] - boxes[:, 1])
            boxes += np.c_[-pad_x, -pad_y, pad_x, pad_y]
            dets = Detections(boxes.astype(np.float32), dets.scores, dets.masks, dets.mask_boxes)
        if self.kind.match_aspect:
            boxes = dets.boxes.astype(np.float64)
            centre = (boxes[:, 0] + boxes[:, 2]) / 2
            half = (boxes[:, 3] - boxes[:, 1]) * (self.width / self.height) / 2
            boxes[:, 0], boxes[:, 2] = centre - half, centre + half
            dets = Detections(boxes.astype(np.float32), dets.scores, dets.masks, dets.mask_boxes)
        crops = crops_for(frame, dets, features)
        if features == "masked_pool":  # plain crops, the masks weight the final pooling
            return self.embed_crops(crops, person_masks(frame, dets))
        return self.embed_crops(crops)


def _unit(rows: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    norms = np.linalg.norm(rows, axis=1, keepdims=True)
    return (rows / np.maximum(norms, 1e-12)).astype(np.float32)


@dataclass(frozen=True)
class ReusePolicy:
    """When a detection keeps the previous frame's embedding instead of a new one.

    Only where IoU alone already decides who it is. Both rules need the box to overlap one
    previous detection by at least ``min_iou``, and that embedding to have been reused fewer
    than ``max_reuses`` frames in a row (appearance drifts: it is computed anew then). Then
    either rule lets it keep that embedding:

    - *isolated*: no other box, previous or current, overlaps the box or that previous
      detection by more than ``isolated_iou`` (nobody is near, so appearance cannot decide
      between candidates), and its thumbnail (below) differs by at most
      ``isolated_thumb_diff`` (a looser bound: only a different person in the box fails it);
      ``isolated_iou=None`` turns this rule off;
    - *unchanged*: no other box overlaps them by more than ``max_other_iou``, and the box's
      8x4 colour thumbnail differs from that detection's by at most ``max_thumb_diff`` grey
      levels on average (someone else stepped in front: embed again).
    """

    min_iou: float = 0.6
    isolated_iou: float | None = 0.0
    isolated_thumb_diff: float = 10.0
    max_other_iou: float = 0.3
    max_thumb_diff: float = 6.0
    max_reuses: int = 4

    def __post_init__(self) -> None:
        if not 0.0 < self.min_iou <= 1.0 or not 0.0 <= self.max_other_iou < self.min_iou:
            raise ParameterError(
                f"need 0 <= max_other_iou < min_iou <= 1, got {self.max_other_iou}, {self.min_iou}"
            )
        if self.isolated_iou is not None and not 0.0 <= self.isolated_iou < self.min_iou:
            raise ParameterError(
                f"need 0 <= isolated_iou < min_iou (or None), got {self.isolated_iou}"
            )
        if min(self.max_thumb_diff, self.isolated_thumb_diff, self.max_reuses) < 0:
            raise ParameterError("max_thumb_diff, isolated_thumb_diff and max_reuses must be >= 0")


THUMB_SIZE = (4, 8)  # (width, height): coarse colour layout of a person, cheap to compare


@dataclass(frozen=True)
class _Previous:
    shape: tuple[int, ...]
    boxes: npt.NDArray[np.float64]
    embeddings: npt.NDArray[np.float32]
    ages: npt.NDArray[np.int64]  # frames each embedding has been reused in a row
    thumbs: npt.NDArray[np.float32]


def thumbnails(frame: npt.NDArray[np.uint8], boxes: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """[N, 8, 4, 3] area-averaged colour thumbnails of the boxes' plain crops."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    out = np.empty((len(b), THUMB_SIZE[1], THUMB_SIZE[0], 3), np.float32)
    for i, box in enumerate(b):
        out[i] = cv2.resize(bbox_crop(frame, box), THUMB_SIZE, interpolation=cv2.INTER_AREA)
    return out


def reuse_sources(
    policy: ReusePolicy,
    boxes: npt.ArrayLike,
    thumbs: npt.NDArray[np.float32],
    prev: _Previous,
) -> npt.NDArray[np.intp]:
    """For each current box, the previous detection whose embedding it keeps, or -1."""
    from densepeds.boxes import iou_matrix

    cur = np.asarray(boxes, np.float64).reshape(-1, 4)
    source = np.full(len(cur), -1, np.intp)
    if len(cur) == 0 or len(prev.boxes) == 0:
        return source
    cross = iou_matrix(cur, prev.boxes)  # [current, previous]
    within = iou_matrix(cur, cur)
    np.fill_diagonal(within, 0.0)
    best = cross.argmax(axis=1)
    rows = np.arange(len(cur))
    best_iou = cross[rows, best]
    others = cross.copy()
    others[rows, best] = 0.0
    # Other current boxes on the chosen previous one: zero out this row's own share first.
    column = cross[:, best].copy()  # [current k, candidate i]: IoU of current k with best[i]
    column[rows, rows] = 0.0
    # The most any other box, previous or current, overlaps this box or its previous one.
    nearby = np.maximum.reduce([others.max(axis=1), column.max(axis=0), within.max(axis=1)])
    diff = np.abs(thumbs - prev.thumbs[best]).mean(axis=(1, 2, 3))
    allowed = (nearby <= policy.max_other_iou) & (diff <= policy.max_thumb_diff)
    if policy.isolated_iou is not None:
        allowed |= (nearby <= policy.isolated_iou) & (diff <= policy.isolated_thumb_diff)
    ok = (best_iou >= policy.min_iou) & (prev.ages[best] < policy.max_reuses) & allowed
    source[ok] = best[ok]
    return source


@dataclass(frozen=True)
class Separation:
    """How well embeddings tell people apart between two frames."""

    people: int  # people present in both frames
    nearest_correct: float  # fraction whose nearest embedding in the other frame is themselves
    p10_different: float  # 10th percentile of cosine distance between different people


def separation(
    emb_a: npt.NDArray[np.float32],
    ids_a: npt.ArrayLike,
    emb_b: npt.NDArray[np.float32],
    ids_b: npt.ArrayLike,
) -> tuple[int, int, npt.NDArray[np.float64]]:
    """(people in both, of whom nearest is self, distances between different people).

    Person p counts as correct when d(p_a, p_b) < d(p_a, q_b) for every other q in frame b.
    """
    a_ids = np.asarray(ids_a)
    b_ids = np.asarray(ids_b)
    dist = 1.0 - emb_a.astype(np.float64) @ emb_b.astype(np.float64).T
    same = a_ids[:, None] == b_ids[None, :]
    correct = 0
    people = 0
    for i in range(len(a_ids)):
        j = np.flatnonzero(same[i])
        if len(j) != 1:
            continue
        people += 1
        others = np.delete(dist[i], j[0])
        correct += int(len(others) == 0 or dist[i, j[0]] < others.min())
    return people, correct, dist[~same]


def summarise(results: list[tuple[int, int, npt.NDArray[np.float64]]]) -> Separation:
    people = sum(r[0] for r in results)
    correct = sum(r[1] for r in results)
    diffs = np.concatenate([r[2] for r in results]) if results else np.zeros(0)
    p10 = float(np.percentile(diffs, 10)) if len(diffs) else float("nan")
    return Separation(people, correct / max(people, 1), p10)
