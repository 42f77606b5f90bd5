"""`densepeds run` against the reference pipeline, whole processes, interleaved in one run.

    OPENBLAS_NUM_THREADS=1 python benchmarks/pipeline_speed.py \
        [--seq MOT20-01-dev,PETS09-S2L1-dev] [--frames 1:60,1:100] [--repeats 2] [--threads 2] \
        [--profile] [--reuse] [--memory] [--write benchmarks/results/speed.md]

For each sequence, each repeat runs both as separate processes (niced, ``--nice``), model
loading included (after one untimed 1-frame run of each, which fills onnxruntime's cache of
optimised graphs and Python's bytecode cache as a user's first start does), alternating which
goes first: ours (`python -m densepeds run SEQ --detector yoloseg --frames A:B`, the package
defaults; beside it, and in every other setting timed, `--focus-lost 0`: no closer look at the
people the tracker lost) and `benchmarks/reference_pipeline.py` (the straightforward pipeline,
on the tiles ours picks for the frame size). onnxruntime gets ``--threads`` intra-op threads in
both (by CPU affinity for ours: the command is started under ``taskset`` with that many CPUs
when the machine has more; else it is the machine's count; ours splits the detector's views and
the re-ID crops one part per CPU, each part on one thread: ``densepeds.detect.split_batch``).
Prints each run's wall and CPU seconds, per-stage ms/frame and the load average, then the
medians, re-ID's share of our frame and the ratio reference / ours. ``--profile`` adds an
in-process pass of our pipeline that splits detection into preprocessing, inference, box
decoding and masks. ``--reuse`` adds `densepeds run --reid-reuse` (re-ID reuse, off by default;
see densepeds.reid.ReusePolicy): in the fastest setting timed (``--skip K``'s) where there is one,
else at the defaults. ``--int8 FILE`` adds `densepeds run --detector-model FILE`, the
detector's int8 copy made by `densepeds models quantize` (densepeds.models.quantize), on the default
tiles and on the grid; ``--skip K`` adds a full scan every K-th frame only (`densepeds run
--full-scan-every K`) to the float copy and to the int8 copy on the default tiles, and to the
int8 copy on the grid. ``--only NAME...`` times only those pipelines
beside the reference; ``--seq``/``--frames`` one video alone. ``--wait-quiet S`` starts each timed
run once other processes leave the CPUs (waiting at most S seconds; on a shared machine).
``--memory`` appends `benchmarks/memory.py`'s table; ``--write`` writes the whole report as
Markdown. Figures only: nothing is asserted.
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
DETECTOR_INPUT = 320  # the shared segmenter's input size, which sets the automatic tiles
NO_FOCUS = "ours, no focus views"


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


def child_env(pycache: Path) -> dict[str, str]:
    """The timed processes' environment: Python's compiled bytecode cached in ``pycache`` (an
    installed package has its .pyc files; a source checkout run with PYTHONDONTWRITEBYTECODE
    would compile every module at every start), one OpenBLAS thread."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONUNBUFFERED="1")
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPYCACHEPREFIX"] = str(pycache)
    return env


def run_once(cmd: list[str], marker: str, env: dict[str, str]) -> Run:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=REPO)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    if "int8 copy" in proc.stdout and "--detector-model" not in cmd:
        # `densepeds run` takes an int8 copy from the model folders in place of the float one;
        # the rows without --detector-model are meant to time the float copy.
        raise SystemExit(
            f"{' '.join(cmd)} ran an int8 copy found in the model folders "
            f"({proc.stdout.split('int8 copy', 1)[1].split()[0]}); time without it "
            "($DENSEPEDS_MODEL_DIR naming its folder, or the user cache) so that `ours` is the "
            "float copy, and pass the copy with --int8"
        )
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return Run(wall, cpu, _stages(proc.stdout, marker))


def _default_features() -> str:
    """The features `densepeds run` uses on frames, so that the reference embeds the same."""
    from densepeds import pipeline

    choose = getattr(pipeline, "default_features", None)
    return str(choose(True)) if choose else "segmented"


def profile(seq_dir: Path, frames: str, threads: int) -> dict[str, float]:
    """Our pipeline in-process (package defaults): ms/frame per stage, detection split up."""
    from densepeds.io.video import SequenceSource
    from densepeds.pipeline import Pipeline

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


def reference_tiles(seq_dir: Path) -> str:
    """The fixed grid of tiles the reference runs on for the sequence's frame size (`ours on the
    grid` gets the same), as ``densepeds run --tiles`` takes it."""
    from densepeds.detect.tiling import auto_grid
    from densepeds.io.mot import read_seqinfo

    info = read_seqinfo(seq_dir)
    cols, rows = auto_grid(info.width, info.height, DETECTOR_INPUT)
    return f"{cols}x{rows}"


def compare(
    seq: str, frames: str, args: argparse.Namespace, names: list[str], tmp: str
) -> list[str]:
    """Interleaved runs of one sequence; returns the report's lines (also printed)."""
    seq_dir = SHARED / "data" / seq
    if not seq_dir.is_dir():
        raise SystemExit(f"{seq_dir}: missing (set DENSEPEDS_SHARED to the shared data folder)")
    pin = _cpu_prefix(args.threads)
    features = _default_features()
    tiles = reference_tiles(seq_dir)
    nice = ["nice", "-n", str(args.nice)] if args.nice else []
    run = [*nice, *pin, sys.executable, "-m", "densepeds", "run", str(seq_dir)]
    run += ["--detector", "yoloseg", "--frames", frames, "-q"]
    ours = [*run, "--out", f"{tmp}/ours.txt"]
    # Every other setting runs without the focus views, as fast.md measures its accuracy.
    run += ["--focus-lost", "0"]
    cmds = {
        "ours": ours,
        NO_FOCUS: [*run, "--out", f"{tmp}/no-focus.txt"],
        "reference": [
            *nice,
            *pin,
            sys.executable,
            str(REPO / "benchmarks" / "reference_pipeline.py"),
            str(seq_dir),
            *("--frames", frames, "--out", f"{tmp}/reference.txt"),
            *("--threads", str(args.threads), "--features", features, "--tiles", tiles),
        ],
        "ours on the grid": [*run, "--tiles", tiles, "--out", f"{tmp}/grid.txt"],
        "ours+reuse": [*run, "--reid-reuse", "--out", f"{tmp}/reuse.txt"],
    }
    if args.int8 is not None:
        int8 = ["--detector-model", str(args.int8.resolve()), "--out", f"{tmp}/int8.txt"]
        cmds["ours+int8"] = [*run, *int8]
        grid_int8 = ["--detector-model", str(args.int8.resolve()), "--tiles", tiles]
        cmds["ours+int8 on the grid"] = [*run, *grid_int8, "--out", f"{tmp}/int8-grid.txt"]
        if args.skip:
            skip = ["--full-scan-every", str(args.skip), "--out", f"{tmp}/int8-skip.txt"]
            cmds[skip_name(args.skip)] = [*run, *grid_int8, *skip]
            reuse = ["--full-scan-every", str(args.skip), "--reid-reuse"]
            cmds[reuse_name(args.skip)] = [*run, *grid_int8, *reuse, "--out", f"{tmp}/reuse.txt"]
            on_people = ["--full-scan-every", str(args.skip), "--out", f"{tmp}/int8-people.txt"]
            cmds[people_skip_name(args.skip, True)] = [*run, *int8[:2], *on_people]
    if args.skip:
        skip = ["--full-scan-every", str(args.skip), "--out", f"{tmp}/people-skip.txt"]
        cmds[people_skip_name(args.skip, False)] = [*run, *skip]
    # `densepeds run` ends with "... N frames/s for the whole pipeline; timed: ... ms/frame)".
    markers = {name: "frames/s" for name in cmds} | {"reference": "reference:"}
    runs: dict[str, list[Run]] = {name: [] for name in names}
    lines = [
        f"### {seq}, frames {frames} (the reference and `ours on the grid` on {tiles} tiles; "
        "`ours` on its default tiles, which follow the people)",
        "",
        "```",
    ]

    def say(line: str) -> None:
        print(line, flush=True)
        lines.append(line)

    say(f"load average before: {_load()}")
    # Each pipeline once on one frame, untimed: onnxruntime's optimised graphs (see
    # densepeds.detect.onnxutil) and Python's bytecode are then cached, as every start but a
    # user's first finds them.
    env = child_env(Path(tmp) / "pycache")
    first = frames.split(":")[0]
    for name in names:
        cmd = cmds[name]
        if "--frames" in cmd:
            at = cmd.index("--frames") + 1
            run_once([*cmd[:at], f"{first}:{first}", *cmd[at + 1 :]], markers[name], env)
    for rep in range(args.repeats):
        order = names if rep % 2 == 0 else names[::-1]
        for name in order:
            waited = wait_quiet(args.wait_quiet) if args.wait_quiet else None
            r = run_once(cmds[name], markers[name], env)
            runs[name].append(r)
            stages = ", ".join(f"{k} {v:.1f}" for k, v in r.stages.items())
            say(
                f"repeat {rep + 1} {name:9s}: wall {r.wall:.1f} s, cpu {r.cpu:.1f} s "
                f"({stages} ms/frame); load {_load()}" + _waited(waited)
            )
    say("```")
    med = {
        name: {
            "wall": statistics.median(r.wall for r in rs),
            "cpu": statistics.median(r.cpu for r in rs),
        }
        for name, rs in runs.items()
    }
    say("")
    say(f"| pipeline | wall s (median of {args.repeats}) | CPU s | ms/frame by stage (median) |")
    say("|---|---:|---:|---|")
    for name, rs in runs.items():
        stage_med = {k: statistics.median(r.stages[k] for r in rs) for k in rs[0].stages}
        cells = ", ".join(f"{k} {v:.1f}" for k, v in stage_med.items())
        share = stage_med.get("reid", 0.0) / max(sum(stage_med.values()), 1e-9)
        cells += f" (re-ID {100 * share:.0f}% of the frame)"
        say(f"| {name} | {med[name]['wall']:.1f} | {med[name]['cpu']:.1f} | {cells} |")
    say("")
    for name in names[1:]:
        ratio = med["reference"]["wall"] / med[name]["wall"]
        cpu_ratio = med["reference"]["cpu"] / med[name]["cpu"]
        say(f"Speed-up, reference / {name}: **{ratio:.2f}x wall**, {cpu_ratio:.2f}x CPU time.")
    say("")
    say(
        f"Features {features}; onnxruntime threads {args.threads} (ours: views and crops split "
        "one part per CPU, each on one thread); "
        f"{'pinned with ' + ' '.join(pin) if pin else 'not pinned'}; "
        f"{len(os.sched_getaffinity(0))} CPUs; load average after {_load()}."
    )
    say("")
    if args.profile:
        say("Ours in-process, ms/frame:")
        say("")
        for k, v in profile(seq_dir, frames, args.threads).items():
            say(f"- {k}: {v:.1f}")
        say("")
    return lines


def skip_name(every: int) -> str:
    return f"ours+int8 on the grid, full scan every {every}"


def people_skip_name(every: int, int8: bool) -> str:
    """Ours on the default tiles (which follow the people) with a full scan every K-th frame."""
    return f"ours{'+int8' if int8 else ''}, full scan every {every}"


def reuse_name(every: int | None) -> str:
    return f"{skip_name(every)}, re-ID reuse" if every else "ours+reuse"


# Vector instruction sets onnxruntime's kernels choose between (int8 most of all: VNNI).
ISA_FLAGS = ("avx2", "avx512f", "avx512_vnni", "avx_vnni", "amx_int8")


def _cpu_name() -> str:
    """The CPU's model name and which of ``ISA_FLAGS`` it exposes (the ratios depend on them)."""
    try:
        info = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return platform.processor() or platform.machine()
    name = next((ln.split(":", 1)[1].strip() for ln in info if ln.startswith("model name")), "")
    flags = next((ln.split(":", 1)[1].split() for ln in info if ln.startswith("flags")), [])
    shown = [f for f in ISA_FLAGS if f in flags]
    return f"{name or platform.machine()} ({' '.join(shown) or 'none of ' + ', '.join(ISA_FLAGS)})"


def _runnable_others(seconds: float = 2.0, samples: int = 10) -> float:
    """Mean count of other runnable processes over ``seconds`` (/proc/loadavg's running
    count, less this one)."""
    total = 0
    for _ in range(samples):
        with open("/proc/loadavg", encoding="ascii") as f:
            total += int(f.read().split()[3].split("/")[0]) - 1
        time.sleep(seconds / samples)
    return total / samples


def wait_quiet(limit: float, threshold: float = 0.5) -> tuple[float, float]:
    """Waits (at most ``limit`` seconds) until fewer than ``threshold`` other processes are
    runnable on average over 2 s; (seconds waited, that average at the start of the run)."""
    start = time.perf_counter()
    while True:
        others = _runnable_others()
        waited = time.perf_counter() - start
        if others < threshold or waited >= limit:
            return waited, others


def _waited(waited: tuple[float, float] | None) -> str:
    if waited is None:
        return ""
    return f"; started after {waited[0]:.0f} s, {waited[1]:.1f} other processes runnable"


def _load() -> str:
    return "/".join(f"{v:.1f}" for v in os.getloadavg())


def memory_lines() -> list[str]:
    """benchmarks/memory.py's table (the package's defaults over the MOT20-01 video)."""
    cmd = [sys.executable, str(REPO / "benchmarks" / "memory.py")]
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=REPO)
    if proc.returncode != 0:
        raise SystemExit(f"memory.py failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    print(proc.stdout, flush=True)
    return ["## Memory (`benchmarks/memory.py`)", "", proc.stdout.strip(), ""]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seq", default="MOT20-01-dev,PETS09-S2L1-dev", help="comma-separated")
    ap.add_argument("--frames", default="1:60,1:100", help="one range per sequence")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--nice", type=int, default=5, help="niceness of the timed processes")
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--reuse", action="store_true", help="also time ours with re-ID reuse on")
    ap.add_argument(
        "--int8",
        type=Path,
        metavar="FILE",
        help="also time ours with this int8 copy of the detector (`densepeds models quantize`)",
    )
    ap.add_argument(
        "--skip",
        type=int,
        metavar="K",
        help="with --int8: also time ours (float and int8 on the default tiles, int8 on the "
        "grid) with a full scan every K-th frame only (between, the views showing somebody; "
        "YoloSegDetector full_scan_every)",
    )
    ap.add_argument(
        "--wait-quiet",
        type=float,
        metavar="SECONDS",
        help="before each timed run, wait up to SECONDS until other processes leave the CPUs "
        "(fewer than 0.5 runnable on average over 2 s; the line says how long it waited)",
    )
    ap.add_argument("--memory", action="store_true", help="also run benchmarks/memory.py")
    ap.add_argument(
        "--only",
        nargs="+",
        metavar="NAME",
        help="time only these pipelines (names as printed) beside the reference",
    )
    ap.add_argument("--write", type=Path, help="write the report to this file")
    args = ap.parse_args()
    seqs, ranges = args.seq.split(","), args.frames.split(",")
    if len(ranges) != len(seqs):
        raise SystemExit(f"give one frame range per sequence: {len(seqs)} vs {len(ranges)}")
    names = ["reference", "ours", NO_FOCUS, "ours on the grid"]
    names += ["ours+reuse"] if args.reuse and not args.skip else []
    names += ["ours+int8", "ours+int8 on the grid"] if args.int8 is not None else []
    if args.skip:
        if args.int8 is None or args.skip < 1:
            raise SystemExit("--skip K needs --int8 FILE and K >= 1")
        names += [people_skip_name(args.skip, False), people_skip_name(args.skip, True)]
        names.append(skip_name(args.skip))
        names += [reuse_name(args.skip)] if args.reuse else []
    if args.only:
        names = ["reference", *(n for n in names[1:] if n in args.only)]
    command = "OPENBLAS_NUM_THREADS=1 python benchmarks/pipeline_speed.py " + " ".join(sys.argv[1:])
    lines = [
        "# Speed: `densepeds run` against the reference pipeline",
        "",
        "Written by this command (do not edit; rerun it):",
        "",
        f"    {command}",
        "",
        f"Machine: {_cpu_name()}, "
        f"{len(os.sched_getaffinity(0))} CPUs usable, shared with other jobs; Python "
        f"{platform.python_version()}. Each repeat runs every pipeline as a whole process "
        "(model loading included), the order alternating; the load average is printed "
        "around each run. `reference` is `benchmarks/reference_pipeline.py` (the shipped int8 "
        "segmenter, a batch-1 call per tile, OSNet on every crop); `ours` is `densepeds run` "
        "with the package's defaults; `ours, no focus views` the same with `--focus-lost 0` (no "
        "closer look at the people the tracker lost: `benchmarks/results/decisions.md`), as every "
        "other row runs (`results/fast.md` measures their accuracy without it); `ours on the "
        "grid` is that on the reference's fixed grid of tiles "
        "(`densepeds.detect.tiling.auto_grid`), where the detector runs its input cut to the "
        "tiles' shape (`YoloSegDetector`'s default `fit_input`: the same views at the same scale, "
        "less padding).",
        "",
    ]
    with tempfile.TemporaryDirectory(prefix="densepeds-speed-") as tmp:
        for seq, frames in zip(seqs, ranges, strict=True):
            lines += compare(seq, frames, args, names, tmp)
    if args.memory:
        lines += memory_lines()
    if args.write:
        args.write.write_text("\n".join(lines).rstrip() + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
