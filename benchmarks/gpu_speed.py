"""The whole pipeline's frames per second on a GPU, as Markdown (``benchmarks/results/gpu.md``):
``densepeds run --device DEVICE`` on MOT20-01-dev and PETS09-S2L1-dev, with the package's
defaults and each ``--speed`` profile (``fast`` where an int8 copy of the detector is found).

Each run is a whole process; its frames per second are the summary line's (decode, detection,
re-ID, tracking and output; model loading and the GPU's start are not in it), after
``--warm`` frames run once beforehand in the same way so that TensorRT's engines and onnxruntime's
caches exist. The card is named from ``nvidia-smi``.

    python benchmarks/gpu_speed.py [--device cuda] [--repeats 2] [--write benchmarks/results/gpu.md]
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("DENSEPEDS_SHARED", REPO.parent / "shared"))
CLIPS = {
    "MOT20-01-dev": (SHARED / "data" / "MOT20-01-dev" / "MOT20-01-raw.mp4", "1:214"),
    "PETS09-S2L1-dev": (SHARED / "data" / "PETS09-S2L1-dev" / "vtest.avi", "1:397"),
}
SETTINGS = {
    "defaults": [],
    "--speed accurate": ["--speed", "accurate"],
    "--speed balanced": ["--speed", "balanced"],
    "--speed fast": ["--speed", "fast"],
}
SUMMARY = re.compile(r"([0-9.]+) frames/s for the whole pipeline.*\((.*)\)")


def card() -> str:
    if shutil.which("nvidia-smi") is None:
        return "no nvidia-smi (no NVIDIA GPU visible)"
    out = subprocess.run(
        ["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
        capture_output=True,
        text=True,
        check=False,
    )
    return out.stdout.strip() or out.stderr.strip()


def run(video: Path, frames: str, device: str, extra: list[str], out: Path) -> tuple[float, str]:
    """(frames per second, ms per frame by stage) of one ``densepeds run``; raises with its
    error line where it fails."""
    cmd = [sys.executable, "-m", "densepeds", "run", str(video), "--frames", frames, "-q"]
    cmd += ["--device", device, *extra, "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        lines = (done.stderr or done.stdout).strip().splitlines()
        raise RuntimeError(lines[-1] if lines else f"exit status {done.returncode}")
    found = SUMMARY.search(done.stdout)
    if found is None:
        raise RuntimeError(f"no frames/s in: {done.stdout.strip()}")
    return float(found.group(1)), found.group(2)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda", help="densepeds run --device (default cuda)")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--warm", default="1:5", metavar="A:B", help="frames run first, untimed")
    parser.add_argument("--frames", metavar="A:B", help="instead of each clip's dev frames")
    parser.add_argument("--write", type=Path, help="also write the Markdown here")
    args = parser.parse_args(argv)
    for video, _ in CLIPS.values():
        if not video.exists():
            sys.exit(f"needs {video} (set DENSEPEDS_SHARED)")
    lines = [
        "# The whole pipeline on a GPU",
        "",
        "Written by this command (do not edit; rerun it):",
        "",
        "    python benchmarks/gpu_speed.py "
        + " ".join(argv if argv is not None else sys.argv[1:]),
        "",
        f"Card: {card()}; `densepeds run --device {args.device}`; load average before "
        f"{'/'.join(f'{v:.1f}' for v in os.getloadavg())}. Frames per second of the whole "
        f"pipeline (the run's summary line: model loading excluded), median of {args.repeats} "
        "runs, each a whole process.",
        "",
        "| clip | frames | settings | frames/s | ms/frame by stage (last run) |",
        "|---|---|---|---:|---|",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "tracks.txt"
        for clip, (video, dev_frames) in CLIPS.items():
            frames = args.frames or dev_frames
            for name, extra in SETTINGS.items():
                try:
                    run(video, args.warm, args.device, extra, out)
                    results = [
                        run(video, frames, args.device, extra, out) for _ in range(args.repeats)
                    ]
                except RuntimeError as err:
                    row = f"| {clip} | {frames} | {name} | - | not run: {err} |"
                else:
                    fps = statistics.median(r[0] for r in results)
                    row = f"| {clip} | {frames} | {name} | {fps:.1f} | {results[-1][1]} |"
                print(row, flush=True)
                lines.append(row)
    lines.append("")
    lines.append(f"Load average after: {'/'.join(f'{v:.1f}' for v in os.getloadavg())}.")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write is not None:
        args.write.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
