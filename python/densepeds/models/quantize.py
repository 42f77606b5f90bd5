"""An int8 copy of the segmenter made with onnxruntime's own static quantisation, for CPUs with
integer dot-product instructions (x86 AVX-512 VNNI / AVX-VNNI, ARM dot product).

The shipped detector is a QDQ export that onnxruntime cannot fuse into integer kernels, so the
package runs its float copy (:func:`densepeds.detect.onnxutil.dequantized`). This module
quantises that float copy again, this time in a form onnxruntime does fuse:

1. the float copy (int8 weights folded to float, batch made dynamic);
2. ``onnxruntime.quantization.shape_inference.quant_pre_process`` (shape inference, graph
   optimisation);
3. ``onnxruntime.quantization.quantize_static`` with :class:`QuantOptions` (by default:
   unsigned 8-bit activations, signed 8-bit weights per output channel (U8S8), min/max
   calibration on the letterboxed tiles of the frames given, QDQ format). The head (its output
   convolutions, the box distribution, score sigmoid, final concatenations and prototype
   activation) and the first convolution are left out of quantisation (:func:`float_nodes`):
   quantised, they cost tracking accuracy. (onnxruntime still runs the first convolution on
   integers, weights quantised at load time, because its input is the quantised image.)

The result records where it came from in its metadata (:data:`META_SOURCE` and the others): the
source model's sha256, the calibration frames, the format and onnxruntime's version. The same
model, frames, options and onnxruntime version give the same bytes. The detector uses it in place
of the float copy when it is found beside the model or in the model folders under
:func:`densepeds.models.files.quantized_file_name` (``densepeds models quantize`` writes it into
the user cache); :func:`check` compares its detections with the float copy's on frames it was
not calibrated on.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from densepeds.boxes import iou_matrix
from densepeds.detect.onnxutil import META_SOURCE
from densepeds.errors import ModelError, ParameterError
from densepeds.io.video import FrameRange, open_source, parse_frame_range

FORMATS = ("qdq", "qoperator")
ACTIVATIONS = ("u8", "s8")
CALIBRATIONS = ("minmax", "percentile")
PERCENTILE = 99.999  # of |activation|, for ``calibration="percentile"``

if TYPE_CHECKING:
    import onnx
# CPU flags (Linux /proc/cpuinfo) of the integer dot-product instructions that onnxruntime's
# U8S8 kernels are made for: x86 AVX-512 VNNI and AVX-VNNI, ARM's dot product.
DOT_PRODUCT_FLAGS = ("avx512_vnni", "avx_vnni", "asimddp")
META_CALIBRATION = "densepeds.calibration"
META_FORMAT = "densepeds.quant_format"
META_ORT = "densepeds.onnxruntime"


def metadata(path: Path) -> dict[str, str]:
    """The model's metadata properties (empty for a model without), read without its graph."""
    from densepeds.detect import onnxutil

    return onnxutil.model_metadata(path)


def integer_dot_product(cpuinfo: str | None = None) -> bool | None:
    """Whether the CPU has one of :data:`DOT_PRODUCT_FLAGS` (``cpuinfo``: the text of
    /proc/cpuinfo, read when not given); None where that cannot be told."""
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text()
        except OSError:
            return None
    flags: set[str] = set()
    for line in cpuinfo.splitlines():
        key, _, value = line.partition(":")
        if key.strip() in ("flags", "Features"):
            flags.update(value.split())
    if not flags:
        return None
    return any(f in flags for f in DOT_PRODUCT_FLAGS)


def float_copy(path: Path) -> onnx.ModelProto:
    """The float model the detector runs by default: QDQ folded away, batch dynamic."""
    from densepeds.detect import onnxutil

    model = onnxutil.dequantized(onnxutil.load_model(path))
    return onnxutil.with_dynamic_batch(model) if onnxutil.has_fixed_batch(model) else model


def float_nodes(model: onnx.ModelProto) -> list[str]:
    """Names of the nodes left in float: the head and the first convolution.

    The head is found by walking back from the graph outputs to the convolutions fed by an
    activation (the head's output convolutions, included): the reshapes, concatenations, the
    box distribution's softmax and its fixed convolution, the score sigmoid and the prototype
    activation. The first convolution takes the image.
    """
    producer = {out: node for node in model.graph.node for out in node.output}
    seen: set[int] = set()
    names: list[str] = []
    stack = [o.name for o in model.graph.output]
    while stack:
        node = producer.get(stack.pop())
        if node is None or id(node) in seen:
            continue
        seen.add(id(node))
        names.append(node.name)
        feeder = producer.get(node.input[0]) if node.input else None
        if node.op_type != "Conv" or feeder is None or feeder.op_type not in ("Mul", "Relu"):
            stack.extend(node.input)
    names += [n.name for n in model.graph.node if n.op_type == "Conv"][:1]
    if any(not name for name in names):
        raise ModelError("the model has unnamed nodes; cannot leave them out by name")
    return names


@dataclass(frozen=True)
class QuantOptions:
    """onnxruntime static quantisation settings; the defaults are what ``densepeds models
    quantize`` makes (``benchmarks/int8_speed.py`` measures the others).

    ``quant_format``: QDQ (Quantize/Dequantize pairs that onnxruntime fuses into integer
    kernels) or QOperator (QLinearConv and friends in the file). ``activations``: unsigned
    ("u8": U8S8 with the signed weights, the form of x86 VNNI instructions) or signed ("s8").
    ``per_channel``: one weight scale per output channel. ``reduce_range``: 7-bit weights.
    ``symmetric_activations``: activation ranges centred on zero. ``calibration``: each
    activation's range from its min/max over the calibration tiles, or from the
    :data:`PERCENTILE` percentile of its magnitude (histograms; clips rare outliers).
    """

    quant_format: str = "qdq"
    activations: str = "u8"
    per_channel: bool = True
    reduce_range: bool = False
    symmetric_activations: bool = False
    calibration: str = "minmax"

    def __post_init__(self) -> None:
        for name, allowed in (
            ("quant_format", FORMATS),
            ("activations", ACTIVATIONS),
            ("calibration", CALIBRATIONS),
        ):
            if getattr(self, name) not in allowed:
                raise ParameterError(
                    f"{name} must be one of {allowed}, got {getattr(self, name)!r}"
                )

    def describe(self) -> str:
        kinds = "U8S8" if self.activations == "u8" else "S8S8"
        parts = [self.quant_format, kinds, "per-channel" if self.per_channel else "per-tensor"]
        parts += ["reduce-range"] if self.reduce_range else []
        parts += ["symmetric-activations"] if self.symmetric_activations else []
        parts += [self.calibration if self.calibration == "minmax" else f"percentile-{PERCENTILE}"]
        return " ".join(parts)


@dataclass(frozen=True)
class Calibration:
    """Frames to calibrate on: every ``step``-th frame of ``frames`` in the video ``path``."""

    path: Path
    frames: FrameRange
    step: int = 1

    def describe(self) -> str:
        last = "end" if self.frames.last is None else self.frames.last
        return f"{self.path.name} frames {self.frames.first}:{last} every {self.step}"


def parse_calibration(text: str) -> Calibration:
    """``VIDEO[@A:B[/STEP]]``, e.g. ``crowd.mp4@215:429/8``."""
    path_text, _, spec = text.partition("@")
    rng, _, step_text = spec.partition("/")
    try:
        step = int(step_text) if step_text else 1
    except ValueError:
        raise ParameterError(
            f"calibration {text!r}: the step after '/' must be an integer"
        ) from None
    if step < 1:
        raise ParameterError(f"calibration {text!r}: the step must be >= 1")
    path = Path(path_text).expanduser()
    if not path.exists():
        raise ParameterError(f"calibration input {path} does not exist")
    return Calibration(path, parse_frame_range(rng or None), step)


def calibration_batches(
    detector: Any, inputs: Sequence[Calibration], offset: int = 0
) -> Iterator[npt.NDArray[np.float32]]:
    """The detector's input batches (its tiles of one frame, letterboxed) for each frame taken.

    ``offset`` shifts the frames taken within each step (0: the calibration frames; another
    value: frames between them, for :func:`check`).
    """
    for item in inputs:
        source = open_source(item.path)
        for k, (_, image) in enumerate(source.frames(item.frames)):
            if image is None or (k - offset) % item.step:
                continue
            height, width = image.shape[:2]
            batch = detector.letterbox(image, detector.views(width, height))
            yield detector.prepare(batch)


def quantize_detector(
    model: Path,
    dest: Path,
    inputs: Sequence[Calibration],
    *,
    options: QuantOptions | None = None,
    tiles: str = "auto",
    threads: int | None = None,
    calibration_cache: Path | None = None,
) -> Path:
    """Write the int8 copy of yoloseg ``model`` to ``dest`` (see the module doc); returns dest.

    ``calibration_cache``: a file keeping the calibrated activation ranges (onnxruntime's); when
    it exists, its ranges are used instead of running the float copy on the frames again (valid
    only for the same model, frames, tiles and calibration method).
    """
    import onnx
    from onnxruntime import __version__ as ort_version
    from onnxruntime.quantization import (
        CalibrationDataReader,
        CalibrationMethod,
        QuantFormat,
        QuantType,
        quantize_static,
    )
    from onnxruntime.quantization.shape_inference import quant_pre_process

    from densepeds.detect.yoloseg import YoloSegDetector
    from densepeds.models.files import sha256_of

    opts = options or QuantOptions()
    if not inputs:
        raise ParameterError("quantisation needs at least one calibration video or folder")
    detector = YoloSegDetector(model, tiles=tiles, threads=threads, quantized=False)
    batches = calibration_batches(detector, inputs)

    # Histogram calibration stacks its batches, so they must have one shape: one view each.
    single = opts.calibration != "minmax"
    pending: list[npt.NDArray[np.float32]] = []

    class Reader(CalibrationDataReader):  # type: ignore[misc]
        count = 0  # frames read

        def get_next(self) -> dict[str, npt.NDArray[np.float32]] | None:
            if not pending:
                batch = next(batches, None)
                if batch is None:
                    return None
                self.count += 1
                pending.extend(np.split(batch, len(batch)) if single else [batch])
            return {detector.input_name: pending.pop(0)}

    reader = Reader()
    with tempfile.TemporaryDirectory(prefix="densepeds-quantize-") as tmp_name:
        tmp = Path(tmp_name)
        plain = float_copy(model)
        onnx.save(plain, str(tmp / "float.onnx"))
        quant_pre_process(str(tmp / "float.onnx"), str(tmp / "pre.onnx"), skip_symbolic_shape=True)
        pre = onnx.load(str(tmp / "pre.onnx"))
        quantize_static(
            str(tmp / "pre.onnx"),
            str(tmp / "int8.onnx"),
            reader,
            quant_format=QuantFormat.QDQ if opts.quant_format == "qdq" else QuantFormat.QOperator,
            per_channel=opts.per_channel,
            reduce_range=opts.reduce_range,
            activation_type=QuantType.QUInt8 if opts.activations == "u8" else QuantType.QInt8,
            weight_type=QuantType.QInt8,
            calibrate_method=CalibrationMethod.MinMax
            if opts.calibration == "minmax"
            else CalibrationMethod.Percentile,
            nodes_to_exclude=float_nodes(pre),
            extra_options={
                "ActivationSymmetric": opts.symmetric_activations,
                **({"CalibPercentile": PERCENTILE} if single else {}),
            },
            calibration_cache_path=calibration_cache,
        )
        # With the ranges from the cache no frame was read; count them for the record.
        reader.count = reader.count or sum(1 for _ in batches)
        if reader.count == 0:
            raise ParameterError("no calibration frames were read (check the frame ranges)")
        out = onnx.load(str(tmp / "int8.onnx"))
    props = {p.key: p.value for p in out.metadata_props}
    props[META_SOURCE] = sha256_of(model)
    described = "; ".join(c.describe() for c in inputs)
    props[META_CALIBRATION] = f"{described}; {reader.count} frames; tiles {tiles}"
    props[META_FORMAT] = opts.describe()
    props[META_ORT] = ort_version
    onnx.helper.set_model_props(out, props)
    dest.parent.mkdir(parents=True, exist_ok=True)
    part = dest.with_name(dest.name + ".part")
    onnx.save(out, str(part))
    part.replace(dest)
    return dest


@dataclass(frozen=True)
class Agreement:
    """Detections of the int8 copy against the float copy's on the same frames."""

    frames: int
    float_dets: int
    int8_dets: int
    matched: int  # float detections with an int8 one at IoU >= the threshold

    @property
    def recall(self) -> float:
        return self.matched / self.float_dets if self.float_dets else 1.0


def check(
    model: Path,
    quantized: Path,
    inputs: Sequence[Calibration],
    *,
    min_score: float = 0.3,
    min_iou: float = 0.5,
    offset: int = 1,
    threads: int | None = None,
) -> Agreement:
    """How many of the float copy's detections (score >= ``min_score``) the int8 copy finds
    (any of its detections overlapping by ``min_iou``; ``int8_dets`` counts its own above
    ``min_score``).

    Runs on frames ``offset`` past each calibration frame (not calibrated on, where the step is
    larger than 1), with the detectors' own tiling.
    """
    from densepeds.detect.yoloseg import YoloSegDetector

    ref = YoloSegDetector(model, threads=threads, with_masks=False, quantized=False)
    low = YoloSegDetector(quantized, threads=threads, with_masks=False)
    frames = float_dets = int8_dets = matched = 0
    for item in inputs:
        source = open_source(item.path)
        for k, (_, image) in enumerate(source.frames(item.frames)):
            if image is None or (k - offset) % item.step:
                continue
            a, b = ref(image), low(image)
            a_boxes = a.boxes[a.scores >= min_score]
            frames += 1
            float_dets += len(a_boxes)
            int8_dets += int((b.scores >= min_score).sum())
            if len(a_boxes) and len(b.boxes):
                matched += int((iou_matrix(a_boxes, b.boxes).max(axis=1) >= min_iou).sum())
    return Agreement(frames, float_dets, int8_dets, matched)
