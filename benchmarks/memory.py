"""Issue 7's memory target: a long run must not grow (peak RSS after 400 frames within 10% of
the peak after 100).

    OPENBLAS_NUM_THREADS=1 python benchmarks/memory.py [--input VIDEO] [--frames 1:400] \
        [--at 100,200,300,400] [--write benchmarks/results/memory.md]

Runs the package's pipeline with its defaults, as `densepeds run` does (detector, re-ID,
tracker, every frame's tracks kept as output rows), over a video (default: the whole
MOT20-01 video, 429 frames; the dev sequence stops at 214), and prints the
process's peak and current resident memory after the given numbers of frames, with the
growth of the last checkpoint over the first. Figures only: nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path

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


def _option(text: str) -> tuple[str, object]:
    key, _, raw = text.partition("=")
    low = raw.lower()
    if low in ("true", "false"):
        return key, low == "true"
    try:
        return key, float(raw) if "." in raw else int(raw)
    except ValueError:
        return key, raw


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--input", type=Path, default=SHARED / "data" / "MOT20-01-dev" / "MOT20-01-raw.mp4"
    )
    ap.add_argument("--frames", default="1:400")
    ap.add_argument("--at", default="100,200,300,400", help="frame counts to report after")
    ap.add_argument(
        "--detector-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a detector default (e.g. dequantize=true)",
    )
    ap.add_argument("--write", type=Path, help="also write the figures to this markdown file")
    args = ap.parse_args()
    options = dict(_option(text) for text in args.detector_option)
    checkpoints = sorted({int(v) for v in args.at.split(",")})

    from densepeds.pipeline import Pipeline, track_rows
    from densepeds.video import open_source

    if not args.input.exists():
        raise SystemExit(f"{args.input}: missing (set DENSEPEDS_SHARED to the shared data folder)")
    load_before = os.getloadavg()
    src = open_source(args.input)
    start = time.perf_counter()
    pipe = Pipeline("yoloseg", detector_options=options)
    pipe.detector()
    pipe.reid()
    print(f"models loaded: peak {peak_rss_mib():.0f} MiB, now {current_rss_mib():.0f} MiB")
    rows: list[tuple[float, ...]] = []  # `densepeds run` keeps these to write at the end
    table: list[tuple[int, float, float, int]] = []
    frames = 0
    for frame_no, tracks in pipe.run(src, args.frames):
        rows.extend(track_rows(frame_no, tracks))
        frames += 1
        if frames in checkpoints:
            table.append((frames, peak_rss_mib(), current_rss_mib(), len(rows)))
            print(
                f"after {frames} frames: peak {table[-1][1]:.0f} MiB, now {table[-1][2]:.0f} MiB "
                f"({time.perf_counter() - start:.0f} s)",
                flush=True,
            )
    if frames < max(checkpoints):
        print(f"note: the range held only {frames} frames", file=sys.stderr)
    lines = ["| frames | peak RSS MiB | RSS now MiB | output rows |", "|---:|---:|---:|---:|"]
    lines += [f"| {n} | {peak:.0f} | {now:.0f} | {nrows} |" for n, peak, now, nrows in table]
    if len(table) >= 2:
        first, last = table[0], table[-1]
        growth = 100 * (last[1] / first[1] - 1)
        lines += [
            "",
            f"Peak RSS after {last[0]} frames is {growth:+.1f}% of the peak after {first[0]} "
            f"({args.input.name}, detector options {options or 'default'}, "
            f"{pipe.times.fps:.2f} fps; {pipe.times.breakdown()}).",
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
            f"Machine: {os.cpu_count()} CPUs, load average before the run "
            f"{'/'.join(f'{v:.1f}' for v in load_before)}, after it "
            f"{'/'.join(f'{v:.1f}' for v in os.getloadavg())} (the frame rate depends on it, "
            f"the memory does not); Python {sys.version.split()[0]}.",
            "",
        ]
        args.write.write_text("\n".join(header + lines) + "\n")
        print(f"wrote {args.write}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
