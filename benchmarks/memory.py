"""Issue 7's memory target: a long run must not grow (peak RSS after 400 frames within 10% of
the peak after 100).

    OPENBLAS_NUM_THREADS=1 python benchmarks/memory.py [--input VIDEO] [--frames 1:400] \
        [--at 100,200,300,400] [--repeats 3] [--write benchmarks/results/memory.md] \
        [densepeds run's options: --tiles, --preset, --param KEY=VALUE, ...]

Runs the pipeline that `densepeds run` sets up (densepeds.runner.open_run: the yoloseg
detector, re-ID and tracker with run's defaults, or the run options given; every frame's tracks
kept as output rows), over a video (default: the whole
MOT20-01 video, 429 frames; the dev sequence stops at 214), and prints the
process's peak and current resident memory after the given numbers of frames, with the
growth of the last checkpoint over the first, for each of ``--repeats`` runs (each a fresh
process: the figures vary from process to process) and their median. Figures only: nothing is
asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("DENSEPEDS_SHARED", REPO.parent / "shared"))
# The shared models by bare name (an explicit DENSEPEDS_MODEL_DIR from the environment wins).
os.environ.setdefault("DENSEPEDS_MODEL_DIR", str(SHARED / "models"))


def current_rss_mib() -> float:
    """Resident set size now (Linux /proc; the peak where that is unavailable)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return peak_rss_mib()


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """One run in this process: the checkpoints' (frames, peak, now, output rows), the frame
    rate and the stage breakdown."""
    checkpoints = sorted({int(v) for v in args.at.split(",")})

    from densepeds.pipeline import track_rows
    from densepeds.runner import RunOptions, RunSpec, open_run

    if not args.input.exists():
        raise SystemExit(f"{args.input}: missing (set DENSEPEDS_SHARED to the shared data folder)")
    start = time.perf_counter()
    spec = RunSpec.for_input(RunOptions.from_args(args), args.input, quiet=True)
    src, pipe, dets, _, rng = open_run(spec)  # loads the models, as `densepeds run` does
    print(
        f"models loaded: peak {peak_rss_mib():.0f} MiB, now {current_rss_mib():.0f} MiB",
        file=sys.stderr,
    )
    rows: list[tuple[float, ...]] = []  # `densepeds run` keeps these to write at the end
    table: list[tuple[int, float, float, int]] = []
    frames = 0
    for res in pipe.run_frames(src, rng, dets):
        rows.extend(track_rows(res.frame_no, res.tracks))
        frames += 1
        if frames in checkpoints:
            table.append((frames, peak_rss_mib(), current_rss_mib(), len(rows)))
            print(
                f"after {frames} frames: peak {table[-1][1]:.0f} MiB, now {table[-1][2]:.0f} MiB "
                f"({time.perf_counter() - start:.0f} s)",
                file=sys.stderr,
                flush=True,
            )
    if frames < max(checkpoints):
        print(f"note: the range held only {frames} frames", file=sys.stderr)
    return {"table": table, "fps": pipe.times.fps, "breakdown": pipe.times.breakdown()}


def growth(table: list[list[float]]) -> float:
    """Peak RSS at the last checkpoint over the first, percent."""
    return 100 * (table[-1][1] / table[0][1] - 1)


def main() -> int:
    from densepeds.runner import RunOptions
    from densepeds.runner.spec import add_run_options

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--input", type=Path, default=SHARED / "data" / "MOT20-01-dev" / "MOT20-01-raw.mp4"
    )
    ap.add_argument("--at", default="100,200,300,400", help="frame counts to report after")
    # The run's settings: `densepeds run`'s own options (its defaults, but the yoloseg detector
    # and frames 1:400).
    add_run_options(ap, shared_only=True)
    ap.set_defaults(detector="yoloseg", frames="1:400")
    ap.add_argument(
        "--repeats", type=int, default=3, help="runs, each in a fresh process (default 3)"
    )
    ap.add_argument("--one", action="store_true", help=argparse.SUPPRESS)  # a repeat's process
    ap.add_argument("--write", type=Path, help="also write the figures to this markdown file")
    args = ap.parse_args()
    if args.one:
        print(json.dumps(measure(args)))
        return 0
    if args.repeats < 1:
        raise SystemExit(f"--repeats must be >= 1, got {args.repeats}")
    load_before = os.getloadavg()
    own = [a for a in sys.argv[1:] if a != "--write" and not a.startswith("--write=")]
    if args.write is not None and str(args.write) in own:
        own.remove(str(args.write))
    runs = []
    for k in range(args.repeats):
        print(f"repeat {k + 1} of {args.repeats}", file=sys.stderr)
        done = subprocess.run(
            [sys.executable, __file__, *own, "--one"], stdout=subprocess.PIPE, text=True
        )
        if done.returncode:
            raise SystemExit(f"repeat {k + 1} failed (exit {done.returncode})")
        runs.append(json.loads(done.stdout))
    checkpoints = [int(row[0]) for row in runs[0]["table"]]
    lines = [
        "| frames | "
        + " | ".join(f"run {k + 1} peak / now MiB" for k in range(len(runs)))
        + " | output rows |",
        "|---:|" + "---:|" * (len(runs) + 1),
    ]
    for i, n in enumerate(checkpoints):
        cells = " | ".join(f"{r['table'][i][1]:.0f} / {r['table'][i][2]:.0f}" for r in runs)
        lines.append(f"| {n} | {cells} | {runs[0]['table'][i][3]} |")
    settings = {
        k: v
        for k, v in vars(RunOptions.from_args(args)).items()
        if v != getattr(RunOptions(), k) and k != "frames"
    }
    if len(checkpoints) >= 2:
        grown = [growth(r["table"]) for r in runs]
        lines += [
            "",
            f"Peak RSS after {checkpoints[-1]} frames over the peak after {checkpoints[0]}: "
            + ", ".join(f"{g:+.1f}%" for g in grown)
            + f" (median **{statistics.median(grown):+.1f}%**; {args.input.name}, run settings "
            f"{settings}; run 1 at {runs[0]['fps']:.2f} fps: "
            f"{runs[0]['breakdown']}).",
        ]
    print("\n" + "\n".join(lines))
    if args.write:
        command = " ".join(["OPENBLAS_NUM_THREADS=1 python benchmarks/memory.py", *sys.argv[1:]])
        header = [
            "# Memory over a long run",
            "",
            "Written by this command (do not edit; rerun it):",
            "",
            f"    {command}",
            "",
            f"Machine: {os.cpu_count()} CPUs, load average before the runs "
            f"{'/'.join(f'{v:.1f}' for v in load_before)}, after them "
            f"{'/'.join(f'{v:.1f}' for v in os.getloadavg())} (the frame rate depends on it, "
            f"the memory does not); Python {sys.version.split()[0]}. Each run is a fresh "
            "process; the same run's memory differs from process to process (how the C "
            "allocator's heaps fragment depends on the threads' timing), so every run is shown.",
            "",
        ]
        args.write.write_text("\n".join(header + lines) + "\n")
        print(f"wrote {args.write}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
