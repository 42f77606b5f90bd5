"""The straightforward pipeline that issue 7's speed target is measured against.

    OPENBLAS_NUM_THREADS=1 python benchmarks/reference_pipeline.py SEQ_OR_VIDEO --frames 1:60 \
        --out tracks.txt [--features segmented] [--threads 2] [--tiles 3x2]

Same models and settings as ``densepeds run``, done the plain way: the shipped int8 segmenter on
the 3x2 tiles (``--tiles``: ours on other frame sizes), each tile its own batch-1 onnxruntime
call on the model file as shipped (no rewrite, no float copy, no whole-frame view); a mask for
every detection; every detection cropped and embedded by OSNet every frame (one batched call
per frame); the tracker; the tracks file. onnxruntime with its default session options but
``intra_op_num_threads`` = ``--threads`` (2).

Every setting is pinned here, so that a later change of the package's defaults does not move the
reference. The box and mask decoding, merging of tiles, crops, tracker and output writer are the
package's own (they are the same work in both pipelines); the loop and its timing are this
script's. Prints one line: frames, wall time and the per-stage breakdown in ms per frame.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # numpy's BLAS threads fight onnxruntime's
# The shared models by bare name (an explicit DENSEPEDS_MODEL_DIR from the environment wins).
os.environ.setdefault(
    "DENSEPEDS_MODEL_DIR",
    str(Path(os.environ.get("DENSEPEDS_SHARED", Path(__file__).parents[2] / "shared")) / "models"),
)

import numpy as np
import onnxruntime as ort
from densepeds.detect.yoloseg import YoloSegDetector
from densepeds.io.mot import write_tracks
from densepeds.io.video import open_source, parse_frame_range
from densepeds.models.files import find_model
from densepeds.pipeline import StageTimes, track_rows
from densepeds.reid import ReID
from densepeds.tracking import Tracker
from densepeds.types import Detections

STAGES = ("load", "decode", "detection", "masks", "reid", "tracking", "output")
DETECTOR_MODEL = "yolov8n-seg-320-int8.onnx"
REID_MODEL = "osnet_x0_25_msmt17.onnx"


def plain_session(path: Path, threads: int) -> ort.InferenceSession:
    """onnxruntime's defaults but for the intra-op thread count (the reference's only setting)."""
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = threads
    return ort.InferenceSession(str(path), sess_options=opts, providers=["CPUExecutionProvider"])


class ReferenceDetector:
    """3x2 tiles, a batch-1 call per tile on the shipped model, masks for every detection."""

    def __init__(self, threads: int, tiles: tuple[int, int] = (3, 2)) -> None:
        path = find_model(DETECTOR_MODEL)
        # The package's decoder, used for letterboxing and decoding only; inference runs on a
        # session of the file as shipped (fixed batch 1), once per tile.
        self.decoder = YoloSegDetector(
            path, tiles=tiles, full_frame=False, threads=1, dequantize=False
        )
        self.session = plain_session(path, threads)
        self.input_name = self.session.get_inputs()[0].name

    def __call__(self, frame: np.ndarray, timer: StageTimes) -> Detections:
        d = self.decoder
        height, width = frame.shape[:2]
        with timer.stage("detection"):
            views = d.views(width, height)
            preds, protos = [], []
            for view in views:
                image = d.letterbox(frame, [view])[..., ::-1].astype(np.float32) / 255
                if not d.nhwc:
                    image = image.transpose(0, 3, 1, 2)
                out = self.session.run(None, {self.input_name: np.ascontiguousarray(image)})
                preds.append(out[d.pred_index])
                protos.append(out[d.proto_index])
            found = d.candidates(np.concatenate(preds), views, width, height)
            dets = Detections(found.boxes.astype(np.float32), found.scores)
        with timer.stage("masks"):
            if len(dets):
                dets.masks, dets.mask_boxes = d.masks(
                    found, views, np.concatenate(protos), width, height
                )
        return dets


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("input", help="video, image folder or MOTChallenge sequence folder")
    ap.add_argument("--frames", default=None, metavar="A:B")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--features", default="segmented", help="re-ID crops (segment.FEATURES)")
    ap.add_argument("--motion", default="frvo")
    ap.add_argument("--threads", type=int, default=2, help="onnxruntime intra-op threads")
    ap.add_argument("--tiles", default="3x2", help="COLUMNSxROWS tiles of the segmenter")
    args = ap.parse_args(argv)
    cols, rows_ = (int(v) for v in args.tiles.lower().split("x"))
    start = time.perf_counter()
    timer = StageTimes(seconds=dict.fromkeys(STAGES, 0.0))
    with timer.stage("load"):
        ort.set_default_logger_severity(3)
        detector = ReferenceDetector(args.threads, (cols, rows_))
        reid = ReID(find_model(REID_MODEL), threads=args.threads, batch_size=64)
        if reid.rewritten:
            raise SystemExit("the reference expects the shipped OSNet (dynamic batch)")
        reid.session = plain_session(reid.path, args.threads)
        tracker = Tracker(motion=args.motion)
        src = open_source(args.input)
    rows: list[tuple[float, ...]] = []
    frames = 0
    it = src.frames(parse_frame_range(args.frames))
    while True:
        with timer.stage("decode"):
            item = next(it, None)
        if item is None:
            break
        frame_no, image = item
        if image is None:
            raise SystemExit(f"{args.input}: the reference needs frames")
        dets = detector(image, timer)
        with timer.stage("reid"):
            emb = None
            if len(dets):
                emb = reid.embed(image, dets, args.features)
        with timer.stage("tracking"):
            tracks = tracker.update(dets.boxes.astype(np.float64), dets.scores, emb)
        with timer.stage("output"):
            rows.extend(track_rows(frame_no, tracks))
        frames += 1
    with timer.stage("output"):
        write_tracks(args.out, rows)
    wall = time.perf_counter() - start
    per = {k: 1000 * v / max(frames, 1) for k, v in timer.seconds.items() if k != "load"}
    parts = ", ".join(f"{k} {v:.1f}" for k, v in per.items())
    print(
        f"reference: {frames} frames in {wall:.2f} s (load {timer.seconds['load']:.2f} s); "
        f"{parts} ms/frame"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
