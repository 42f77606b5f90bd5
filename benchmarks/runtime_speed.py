"""onnxruntime against OpenVINO on this CPU, for the models the pipeline runs, printed as Markdown:

- the segmenter's float copy (the shipped int8 export dequantised, as the package runs it by
  default: ``onnxutil.dequantized``), one 320-px view of a MOT20-01 frame;
- the segmenter as shipped (QDQ int8), and ``--int8 PATH`` (a ``densepeds models quantize``
  copy), each where OpenVINO accepts it (else the reason is printed);
- OSNet x0.25 on 16 crops of people-sized patches of the same frame.

Each model is compiled once per runtime, with the same thread count (``--threads``, default
every usable CPU) and OpenVINO's precision held at f32; then ``--rounds`` rounds each run both
runtimes ``--repeats`` times, the order alternating, and the median per call is printed with the
load average around. Outputs are compared on the same input: the largest absolute difference of
each raw output (OpenVINO against onnxruntime). onnxruntime's own OpenVINO execution provider is
timed too where this onnxruntime has it.

    OPENBLAS_NUM_THREADS=1 python benchmarks/runtime_speed.py [--rounds 7] [--repeats 5] \\
        [--threads 2] [--int8 out/models/yolov8n-seg-320-int8-ortq.onnx]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import onnxruntime as ort
from densepeds.detect import onnxutil
from densepeds.reid import ReID

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("DENSEPEDS_SHARED", REPO.parent / "shared"))
DETECTOR = SHARED / "models" / "yolov8n-seg-320-int8.onnx"
OSNET = SHARED / "models" / "osnet_x0_25_msmt17.onnx"
FRAME = SHARED / "data" / "MOT20-01-dev" / "MOT20-01-raw.mp4"
CROPS = 16


@dataclass
class Case:
    name: str
    model: Path  # an ONNX file both runtimes load
    feed: dict[str, np.ndarray]


Runner = Callable[[], list[np.ndarray]]


def first_frame() -> np.ndarray:
    capture = cv2.VideoCapture(str(FRAME))
    ok, frame = capture.read()
    capture.release()
    if not ok:
        sys.exit(f"cannot read {FRAME}")
    return np.asarray(frame, np.uint8)


def detector_view(frame: np.ndarray) -> np.ndarray:
    """One 320x320 view (NHWC RGB in [0, 1], as the detector feeds it) of the frame's middle."""
    h, w = frame.shape[:2]
    side = min(h, w) * 3 // 4
    y, x = (h - side) // 2, (w - side) // 2
    view = cv2.resize(frame[y : y + side, x : x + side], (320, 320))
    return (cv2.cvtColor(view, cv2.COLOR_BGR2RGB).astype(np.float32) / 255)[None]


def reid_crops(frame: np.ndarray, reid: ReID) -> np.ndarray:
    """``CROPS`` person-shaped patches along the frame, as OSNet's input tensor."""
    h, w = frame.shape[:2]
    crops = []
    for k in range(CROPS):
        x = (w - 60) * k // (CROPS - 1)
        y = (h - 150) * (k % 4) // 3
        crops.append(cv2.resize(frame[y : y + 150, x : x + 60], (reid.width, reid.height)))
    return reid._input(np.stack(crops))


def ort_runner(model: Path, feed: dict[str, np.ndarray], threads: int, ep: str | None) -> Runner:
    opts = onnxutil.session_options(threads)
    providers: list[str] = [ep, onnxutil.CPU_PROVIDER] if ep else [onnxutil.CPU_PROVIDER]
    session = ort.InferenceSession(str(model), sess_options=opts, providers=providers)
    return lambda: [np.asarray(o) for o in session.run(None, feed)]


def ov_runner(model: Path, feed: dict[str, np.ndarray], threads: int) -> Runner:
    """OpenVINO's runtime as ``densepeds run --device openvino`` runs it (f32, a request per
    call: ``onnxutil.OpenVinoSession``)."""
    session = onnxutil.OpenVinoSession(str(model), threads)
    return lambda: session.run(None, feed)


def timed(run: Runner, repeats: int) -> float:
    start = time.perf_counter()
    for _ in range(repeats):
        run()
    return (time.perf_counter() - start) / repeats * 1000


def load() -> str:
    return "/".join(f"{v:.1f}" for v in os.getloadavg())


def compare(case: Case, runners: dict[str, Runner], rounds: int, repeats: int) -> list[str]:
    """Timing lines and the output differences of each runtime against onnxruntime's."""
    reference = runners["onnxruntime"]()
    diffs = {}
    for name, run in runners.items():
        out = run()  # also the warm-up
        if len(out) != len(reference):
            diffs[name] = "outputs differ in number"
            continue
        diffs[name] = ", ".join(
            f"{float(np.max(np.abs(a.astype(np.float64) - b))):.2e}"
            for a, b in zip(out, reference, strict=True)
        )
    times: dict[str, list[float]] = {name: [] for name in runners}
    order = list(runners)
    for r in range(rounds):
        for name in order if r % 2 == 0 else order[::-1]:
            times[name].append(timed(runners[name], repeats))
    base = statistics.median(times["onnxruntime"])
    lines = []
    for name, values in times.items():
        ms = statistics.median(values)
        lines.append(
            f"| {case.name} | {name} | {ms:.1f} | {base / ms:.2f}x | "
            f"{min(values):.1f}-{max(values):.1f} | {diffs[name]} |"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--repeats", type=int, default=5, help="calls per round and runtime")
    parser.add_argument("--threads", type=int, default=onnxutil.available_cpus())
    parser.add_argument("--int8", type=Path, help="also time this int8 copy of the segmenter")
    args = parser.parse_args(argv)
    for path in (DETECTOR, OSNET, FRAME):
        if not path.exists():
            sys.exit(f"needs {path} (set DENSEPEDS_SHARED)")
    try:
        import openvino as ov
    except ImportError:
        sys.exit("needs OpenVINO: pip install openvino")

    frame = first_frame()
    reid = ReID(OSNET, device="cpu")
    tmp = Path(tempfile.mkdtemp(prefix="runtime-speed-"))
    floated = tmp / "yolov8n-seg-320-float.onnx"
    floated.write_bytes(onnxutil.dequantized(onnxutil.load_model(DETECTOR)).SerializeToString())
    det_input = ort.InferenceSession(str(DETECTOR)).get_inputs()[0].name
    view = {det_input: detector_view(frame)}
    cases = [
        Case("segmenter, float copy, 1 view", floated, view),
        Case("segmenter as shipped (QDQ int8), 1 view", DETECTOR, view),
    ]
    if args.int8 is not None:
        cases.append(Case(f"segmenter, int8 copy {args.int8.name}, 1 view", args.int8, view))
    cases.append(
        Case(f"OSNet x0.25, {CROPS} crops", OSNET, {reid.input_name: reid_crops(frame, reid)})
    )

    ov_ep = "OpenVINOExecutionProvider"
    has_ep = ov_ep in ort.get_available_providers()
    print("# Runtimes: onnxruntime against OpenVINO on this CPU\n")
    print("Written by this command (do not edit; rerun it):\n")
    print(
        "    OPENBLAS_NUM_THREADS=1 python benchmarks/runtime_speed.py "
        + " ".join(argv or sys.argv[1:])
    )
    print()
    cpu = platform.processor() or platform.machine()
    print(
        f"Machine: {cpu}, {onnxutil.available_cpus()} CPUs usable; Python "
        f"{platform.python_version()}; onnxruntime {ort.__version__}, OpenVINO "
        f"{ov.get_version()}; {args.threads} threads each; onnxruntime's OpenVINO execution "
        f"provider: {'timed' if has_ep else 'not in this onnxruntime'}. Median ms per call over "
        f"{args.rounds} rounds of {args.repeats} calls, the runtimes alternating; `max abs diff`: "
        "each raw output against onnxruntime's on the same input.\n"
    )
    print(f"load average before: {load()}\n")
    print("| model | runtime | ms per call | speed-up | range ms | max abs diff per output |")
    print("|---|---|---:|---:|---|---|")
    for case in cases:
        runners: dict[str, Runner] = {
            "onnxruntime": ort_runner(case.model, case.feed, args.threads, None)
        }
        try:
            runners["OpenVINO"] = ov_runner(case.model, case.feed, args.threads)
        except Exception as err:  # OpenVINO refuses some graphs: said, not timed
            first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            print(f"| {case.name} | OpenVINO | refused: {first[:120]} | | | |")
        if has_ep:
            runners["onnxruntime + OpenVINO EP"] = ort_runner(
                case.model, case.feed, args.threads, ov_ep
            )
        for line in compare(case, runners, args.rounds, args.repeats):
            print(line, flush=True)
    print(f"\nload average after: {load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
