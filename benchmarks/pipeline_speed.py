"""Issue 7's speed target: `densepeds run` against the reference pipeline, whole processes.

    OPENBLAS_NUM_THREADS=1 python benchmarks/pipeline_speed.py [--seq MOT20-01-dev] \
        [--frames 1:60] [--repeats 3] [--threads 2] [--profile]

Each repeat runs both as separate processes, model loading included, alternating which goes
first: ours (`python -m densepeds run SEQ --frames A:B`, the package defaults) and
`benchmarks/reference_pipeline.py` (the straightforward pipeline). onnxruntime gets
``--threads`` intra-op threads in both (by CPU affinity for ours: the command is started under
``taskset`` with that many CPUs when the machine has more; else it is the machine's count).
Prints each run's wall and CPU seconds and per-stage ms/frame, then the medians and the ratio
reference / ours. ``--profile`` adds an in-process pass of our pipeline that splits detection
into preprocessing, inference, box decoding and masks. ``--reuse`` adds a third process:
`densepeds run` with re-ID reuse switched on (``ReID(reuse=True)``, which the pipeline does not
do by default; see densepeds.reid.ReusePolicy). Figures only: nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("DENSEPEDS_SHARED", REPO.parent / "shared"))
# The shared models by bare name (an explicit DENSEPEDS_MODEL_DIR from the environment wins).
os.environ.setdefault("DENSEPEDS_MODEL_DIR", str(SHARED / "models"))
STAGE_RE = re.compile(r"([a-z]+) ([0-9.]+)")
REUSE_CHILD = "--child-run-with-reuse"


def _run_with_reuse(argv: list[str]) -> int:
    """`densepeds run ARGV` with every ReID built with reuse on (the pipeline's opt-in)."""
    from densepeds import reid
    from densepeds.cli import main as cli_main

    plain_init = reid.ReID.__init__

    def init(self: reid.ReID, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("reuse", True)
        plain_init(self, *args, **kwargs)  # type: ignore[arg-type]

    reid.ReID.__init__ = init  # type: ignore[method-assign]
    return cli_main(["run", *argv])


def _cpu_prefix(threads: int) -> list[str]:
    """Pin to ``threads`` CPUs where the machine has more (quieter, and sets our default)."""
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) <= threads:
        return []
    return ["taskset", "-c", ",".join(str(c) for c in cpus[:threads])]


def _stages(text: str, marker: str) -> dict[str, float]:
    """``decode 1.2, detection 60.3, ... ms/frame`` from the line holding ``marker``."""
    for line in text.splitlines():
        if marker in line and "ms/frame" in line:
            body = line[line.rfind("(") + 1 :] if "(" in line else line.split(";")[-1]
            body = body.split("ms/frame")[0]
            return {k: float(v) for k, v in STAGE_RE.findall(body) if k != "load"}
    raise RuntimeError(f"no per-stage line in the output:\n{text}")


@dataclass(frozen=True)
class Run:
    wall: float  # seconds, the whole process
    cpu: float  # user + system seconds of the process
    stages: dict[str, float]  # ms per frame, as the process printed them


def run_once(cmd: list[str], marker: str) -> Run:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONUNBUFFERED="1")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=REPO)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return Run(wall, cpu, _stages(proc.stdout, marker))


def _default_features() -> str:
    """The features `densepeds run` uses on frames, so that the reference embeds the same."""
    from densepeds import pipeline

    choose = getattr(pipeline, "default_features", None)
    return str(choose(True)) if choose else "segmented"


def profile(seq_dir: Path, frames: str, threads: int) -> dict[str, float]:
    """Our pipeline in-process (package defaults): ms/frame per stage, detection split up."""
    from densepeds.pipeline import Pipeline
    from densepeds.video import SequenceSource

    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) > threads:
        os.sched_setaffinity(0, cpus[:threads])
    pipe = Pipeline("yoloseg")
    det = pipe.detector()
    pipe.reid()
    n = sum(1 for _ in pipe.run(SequenceSource(seq_dir), frames))
    out = pipe.times.per_frame_ms()
    for k, v in getattr(det, "stage_seconds", {}).items():
        out[f"detection.{k}"] = 1000 * v / max(n, 1)
    reid = pipe.reid()
    embedded, reused = getattr(reid, "embedded", 0), getattr(reid, "reused", 0)
    out["crops embedded/frame"] = embedded / max(n, 1)
    out["crops reused/frame"] = reused / max(n, 1)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seq", default="MOT20-01-dev")
    ap.add_argument("--frames", default="1:60")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--reuse", action="store_true", help="also time ours with re-ID reuse on")
    args = ap.parse_args()
    seq_dir = SHARED / "data" / args.seq
    if not seq_dir.is_dir():
        raise SystemExit(f"{seq_dir}: missing (set DENSEPEDS_SHARED to the shared data folder)")
    pin = _cpu_prefix(args.threads)
    features = _default_features()
    names = ["reference", "ours", *(["ours+reuse"] if args.reuse else [])]
    runs: dict[str, list[Run]] = {name: [] for name in names}
    with tempfile.TemporaryDirectory(prefix="densepeds-speed-") as tmp:
        cmds = {
            "ours": [
                *pin,
                sys.executable,
                "-m",
                "densepeds",
                "run",
                str(seq_dir),
                "--frames",
                args.frames,
                "--out",
                f"{tmp}/ours.txt",
                "-q",
            ],
            "reference": [
                *pin,
                sys.executable,
                str(REPO / "benchmarks" / "reference_pipeline.py"),
                str(seq_dir),
                "--frames",
                args.frames,
                "--out",
                f"{tmp}/reference.txt",
                "--threads",
                str(args.threads),
                "--features",
                features,
            ],
        }
        cmds["ours+reuse"] = [
            *pin,
            sys.executable,
            __file__,
            REUSE_CHILD,
            *cmds["ours"][cmds["ours"].index("run") + 1 :],
        ]
        cmds["ours+reuse"][cmds["ours+reuse"].index("--out") + 1] = f"{tmp}/reuse.txt"
        markers = {"ours": "fps (", "ours+reuse": "fps (", "reference": "reference:"}
        for rep in range(args.repeats):
            order = names if rep % 2 == 0 else names[::-1]
            for name in order:
                r = run_once(cmds[name], markers[name])
                runs[name].append(r)
                stages = ", ".join(f"{k} {v:.1f}" for k, v in r.stages.items())
                print(
                    f"repeat {rep + 1} {name:9s}: wall {r.wall:.1f} s, cpu {r.cpu:.1f} s "
                    f"({stages} ms/frame)",
                    flush=True,
                )
    med = {
        name: {
            "wall": statistics.median(r.wall for r in rs),
            "cpu": statistics.median(r.cpu for r in rs),
        }
        for name, rs in runs.items()
    }
    print()
    print(f"| pipeline | wall s (median of {args.repeats}) | CPU s | ms/frame by stage (median) |")
    print("|---|---:|---:|---|")
    for name, rs in runs.items():
        stage_med = {k: statistics.median(r.stages[k] for r in rs) for k in rs[0].stages}
        cells = ", ".join(f"{k} {v:.1f}" for k, v in stage_med.items())
        print(f"| {name} | {med[name]['wall']:.1f} | {med[name]['cpu']:.1f} | {cells} |")
    print()
    for name in names[1:]:
        ratio = med["reference"]["wall"] / med[name]["wall"]
        cpu_ratio = med["reference"]["cpu"] / med[name]["cpu"]
        print(f"speed-up, reference / {name}: {ratio:.2f}x wall, {cpu_ratio:.2f}x CPU time")
    print(
        f"{args.seq} frames {args.frames}; features {features}; "
        f"onnxruntime threads {args.threads}; "
        f"{'pinned with ' + ' '.join(pin) if pin else 'not pinned'}; "
        f"{len(os.sched_getaffinity(0))} CPUs; load average {os.getloadavg()[0]:.1f} at the end; "
        f"{platform.processor() or platform.machine()}; Python {platform.python_version()}"
    )
    if args.profile:
        print("\nours in-process, ms/frame:")
        for k, v in profile(seq_dir, args.frames, args.threads).items():
            print(f"  {k}: {v:.1f}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == REUSE_CHILD:
        sys.exit(_run_with_reuse(sys.argv[2:]))
    sys.exit(main())
