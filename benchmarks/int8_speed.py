"""The segmenter's int8 copy (`densepeds models quantize`) against its float copy, printed as
Markdown (`benchmarks/results/int8.md`):

1. inference time per view for each quantisation setting
   (:class:`densepeds.models.quantize.QuantOptions`) and onnxruntime graph optimisation level, all
   sessions timed interleaved in one process on the same batches (the package's own tiles of
   MOT20-01 frames, captured from the float detector), wall and CPU time, with the load average
   printed;
2. where the time goes: per operator type, the float copy and the default int8 copy (onnxruntime's
   profiler; each node's median over the runs, per view);
3. each setting's detections against the float copy's on the frames after the calibration frames
   (:func:`densepeds.models.quantize.check`).

    OPENBLAS_NUM_THREADS=1 python benchmarks/int8_speed.py [--frames 1:60] [--every 6] \\
        [--rounds 5] [--threads 2] [--skip-agreement] [--smoke]

``--smoke`` checks that the script runs (seconds, figures meaningless): the float copy and the
default int8 copy only, calibrated on two frames.

Every variant is calibrated on the frames int8.md's command uses (MOT20-01 215-429 every 8th,
PETS09-S2L1 398-795 every 16th); variants sharing a calibration method share its ranges.
"""

from __future__ import annotations

import argparse
import bisect
import contextlib
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import onnxruntime as ort
from densepeds.detect import onnxutil
from densepeds.detect.yoloseg import YoloSegDetector
from densepeds.io.video import open_source, parse_frame_range
from densepeds.models import quantize

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("DENSEPEDS_SHARED", REPO.parent / "shared"))
MODEL = SHARED / "models" / "yolov8n-seg-320-int8.onnx"
MOT20 = SHARED / "data" / "MOT20-01-dev" / "MOT20-01-raw.mp4"
PETS = SHARED / "data" / "PETS09-S2L1-dev" / "vtest.avi"
CALIBRATION = (f"{MOT20}@215:429/8", f"{PETS}@398:795/16")
SMOKE_CALIBRATION = (f"{MOT20}@215:215", f"{PETS}@398:398")
LEVELS = {
    "all": ort.GraphOptimizationLevel.ORT_ENABLE_ALL,
    "extended": ort.GraphOptimizationLevel.ORT_ENABLE_EXTENDED,
    "basic": ort.GraphOptimizationLevel.ORT_ENABLE_BASIC,
}
DEFAULT = quantize.QuantOptions()


@dataclass(frozen=True)
class Variant:
    name: str
    options: quantize.QuantOptions | None  # None: the float copy
    level: str = "all"  # the package's sessions: onnxruntime's default, all optimisations


VARIANTS = [
    Variant("float copy (the package's default)", None),
    Variant(f"int8: {DEFAULT.describe()} (`densepeds models quantize`)", DEFAULT),
    Variant("int8, graph optimisation extended (no NHWC/NCHWc layouts)", DEFAULT, "extended"),
    Variant("int8, graph optimisation basic (Q/DQ not fused)", DEFAULT, "basic"),
    Variant("int8: QOperator", replace(DEFAULT, quant_format="qoperator")),
    Variant("int8: per-tensor weights", replace(DEFAULT, per_channel=False)),
    Variant("int8: reduce_range (7-bit weights)", replace(DEFAULT, reduce_range=True)),
    Variant("int8: symmetric activations", replace(DEFAULT, symmetric_activations=True)),
    Variant("int8: S8S8 (signed activations)", replace(DEFAULT, activations="s8")),
    Variant("int8: percentile calibration", replace(DEFAULT, calibration="percentile")),
]


def load() -> str:
    return "/".join(f"{v:.1f}" for v in os.getloadavg())


def capture_batches(frames: str, every: int, threads: int) -> list[np.ndarray]:
    """The float detector's input batches (its own tiles) for every ``every``-th frame."""
    det = YoloSegDetector(MODEL, threads=threads, quantized=False, with_masks=False)
    taken: list[np.ndarray] = []
    prepare = det.prepare

    def keep(batch_u8: np.ndarray) -> np.ndarray:
        x = prepare(batch_u8)
        taken.append(x)
        return x

    det.prepare = keep  # type: ignore[method-assign]
    out = []
    for k, (_, image) in enumerate(open_source(MOT20).frames(parse_frame_range(frames))):
        det(image)  # every frame, so that the tiles follow the people as in a run
        if k % every == 0:
            out.append(taken[-1])
    return out


def make_variants(
    tmp: Path, threads: int, variants: list[Variant], calibration: tuple[str, ...]
) -> dict[str, Path]:
    inputs = [quantize.parse_calibration(c) for c in calibration]
    made: dict[str, Path] = {}
    for k, v in enumerate(variants):
        if v.options is None:
            continue
        key = v.options.describe()
        if key not in made:
            cache = tmp / f"ranges-{v.options.calibration}.json"
            made[key] = quantize.quantize_detector(
                MODEL,
                tmp / f"variant{k}.onnx",
                inputs,
                options=v.options,
                threads=threads,
                calibration_cache=cache,
            )
    return made


def session(path: Path | None, level: str, threads: int, profile: str | None = None) -> Any:
    opts = onnxutil.session_options(threads)
    opts.graph_optimization_level = LEVELS[level]
    if profile is not None:
        opts.enable_profiling = True
        opts.profile_file_prefix = profile
    ort.set_default_logger_severity(3)
    data = quantize.float_copy(MODEL).SerializeToString() if path is None else str(path)
    return ort.InferenceSession(data, sess_options=opts, providers=["CPUExecutionProvider"])


def time_interleaved(
    sessions: dict[str, Any], batches: list[np.ndarray], rounds: int
) -> dict[str, tuple[float, float]]:
    """name -> (median wall ms per view, median CPU ms per view), rounds alternating order."""
    views = sum(len(b) for b in batches)
    wall: dict[str, list[float]] = defaultdict(list)
    cpu: dict[str, list[float]] = defaultdict(list)
    names = list(sessions)
    for r in range(rounds):
        for name in names if r % 2 == 0 else names[::-1]:
            s = sessions[name]
            feed = s.get_inputs()[0].name
            t, c = time.perf_counter(), time.process_time()
            for b in batches:
                s.run(None, {feed: b})
            wall[name].append(time.perf_counter() - t)
            cpu[name].append(time.process_time() - c)
    return {
        n: (1e3 * statistics.median(wall[n]) / views, 1e3 * statistics.median(cpu[n]) / views)
        for n in names
    }


def op_profile(path: Path | None, batches: list[np.ndarray], threads: int, tmp: Path) -> dict:
    """Operator type -> ms per view: each node's median over the runs of its time per view."""
    s = session(path, "all", threads, profile=str(tmp / "profile"))
    feed = s.get_inputs()[0].name
    for b in batches:
        s.run(None, {feed: b})
    events = json.loads(Path(s.end_profiling()).read_text())
    runs = sorted(e["ts"] for e in events if e.get("name") == "model_run")
    per_node: dict[str, list[float]] = defaultdict(list)
    kind: dict[str, str] = {}
    for e in events:
        if e.get("cat") == "Node" and e["name"].endswith("_kernel_time"):
            run = bisect.bisect_right(runs, e["ts"]) - 1
            per_node[e["name"]].append(e["dur"] / 1e3 / len(batches[max(run, 0)]))
            kind[e["name"]] = e["args"].get("op_name", "?")
    by_op: dict[str, float] = defaultdict(float)
    for node, per_view in per_node.items():
        by_op[kind[node]] += statistics.median(per_view)
    return dict(sorted(by_op.items(), key=lambda kv: -kv[1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", default="1:60", help="MOT20-01 frames whose tiles are timed")
    ap.add_argument("--every", type=int, default=6, help="time every N-th of them")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--skip-agreement", action="store_true")
    ap.add_argument("--smoke", action="store_true", help="check that it runs (seconds)")
    args = ap.parse_args()
    variants = VARIANTS[:2] if args.smoke else VARIANTS
    calibration = SMOKE_CALIBRATION if args.smoke else CALIBRATION
    for path in (MODEL, MOT20, PETS):
        if not path.exists():
            raise SystemExit(f"{path}: missing (the shared data beside the repo; DENSEPEDS_SHARED)")
    with tempfile.TemporaryDirectory(prefix="int8-speed-") as tmp_name:
        tmp = Path(tmp_name)
        batches = capture_batches(args.frames, args.every, args.threads)
        with contextlib.redirect_stdout(sys.stderr):  # onnxruntime's calibration prints
            made = make_variants(tmp, args.threads, variants, calibration)
        files = {v.name: made[v.options.describe()] if v.options else None for v in variants}
        sessions = {v.name: session(files[v.name], v.level, args.threads) for v in variants}
        for s in sessions.values():  # warm up
            s.run(None, {s.get_inputs()[0].name: batches[0]})
        before = load()
        timed = time_interleaved(sessions, batches, args.rounds)
        after = load()
        default = files[variants[1].name]
        profiles = {
            "float copy": op_profile(None, batches, args.threads, tmp),
            "int8 copy": op_profile(default, batches, args.threads, tmp),
        }
        inputs = [quantize.parse_calibration(c) for c in calibration]
        agreement = {}
        if not args.skip_agreement:
            for v in variants[1:]:
                path = files[v.name]
                if v.level == "all" and path is not None:
                    agreement[v.name] = quantize.check(MODEL, path, inputs, threads=args.threads)
    views = sum(len(b) for b in batches)
    print(
        f"MOT20-01 frames {args.frames}, every {args.every}-th frame: {len(batches)} batches, "
        f"{views} views (the package's tiles); {args.rounds} rounds interleaved; onnxruntime "
        f"{ort.__version__}, {args.threads} threads, the package's session options; "
        f"{onnxutil.available_cpus()} CPUs ({platform.processor() or platform.machine()}); "
        f"load average before {before}, after {after}.\n"
    )
    ref_wall, ref_cpu = timed[variants[0].name]
    print("| setting | wall ms/view | CPU ms/view | float copy / this (wall) | (CPU) |")
    print("|---|---:|---:|---:|---:|")
    for v in variants:
        w, c = timed[v.name]
        print(f"| {v.name} | {w:.2f} | {c:.2f} | {ref_wall / w:.2f}x | {ref_cpu / c:.2f}x |")
    print(
        f"\nWhere the time goes: kernel ms per view by operator (onnxruntime's profiler, "
        f"{args.threads} threads, each node's median over the batches; share of the total):\n"
    )
    names = list(profiles)
    print("| operator | " + " | ".join(names) + " |")
    print("|---|" + "---:|" * len(names))
    ops = sorted(
        {o for p in profiles.values() for o in p},
        key=lambda o: -max(p.get(o, 0) for p in profiles.values()),
    )
    totals = {n: sum(p.values()) for n, p in profiles.items()}
    for o in ops:
        cells = [
            f"{profiles[n].get(o, 0):.2f} ({100 * profiles[n].get(o, 0) / totals[n]:.0f}%)"
            if o in profiles[n]
            else ""
            for n in names
        ]
        print(f"| {o} | " + " | ".join(cells) + " |")
    print("| total | " + " | ".join(f"{totals[n]:.2f}" for n in names) + " |")
    if agreement:
        print(
            "\nDetections against the float copy's (score >= 0.3, IoU >= 0.5) on the "
            f"{next(iter(agreement.values())).frames} frames after the calibration frames:\n"
        )
        print("| setting | float copy's found | recall | int8 detections |")
        print("|---|---:|---:|---:|")
        for name, a in agreement.items():
            print(f"| {name} | {a.matched}/{a.float_dets} | {a.recall:.3f} | {a.int8_dets} |")


if __name__ == "__main__":
    main()
