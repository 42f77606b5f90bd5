"""End-to-end speed of the full pipeline on the real videos, split by stage.

    python benchmarks/pipeline_speed.py [--frames 1:50] [--features segmented,bbox,none]
                                        [--seq PETS09-S2L1-dev MOT20-01-dev] [--out FILE.md]

Runs detect (yoloseg) -> segmented boxes -> re-ID (OSNet) -> FRVO + association on each
sequence's video in ../shared/data and prints frames per second and milliseconds per frame for
decode, detection, re-ID, tracking and output (as `densepeds run` measures them), plus the
machine's CPU count. Figures only: nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

from densepeds.pipeline import STAGES, Pipeline
from densepeds.video import SequenceSource, parse_frame_range

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("DENSEPEDS_SHARED", REPO.parent / "shared"))


def measure(seq_dir: Path, frames: str, features: str, threads: int | None) -> dict[str, float]:
    src = SequenceSource(seq_dir)
    if not src.has_images:
        raise SystemExit(f"{seq_dir}: no video or images to run the detector on")
    opts = {"threads": threads} if threads else {}
    pipe = Pipeline("yoloseg", features=features, motion="frvo", detector_options=opts)
    pipe.detector()  # load models outside the timed loop
    if features != "none":
        pipe.reid()
    n_tracks = 0
    for _, tracks in pipe.run(src, frames, detections=None):
        n_tracks += len(tracks.ids)
    t = pipe.times
    row = {f"{k}_ms": v for k, v in t.per_frame_ms().items()}
    row.update(frames=t.frames, fps=t.fps, tracks_per_frame=n_tracks / max(t.frames, 1))
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seq", nargs="+", default=["PETS09-S2L1-dev", "MOT20-01-dev"])
    ap.add_argument("--frames", default="1:50")
    ap.add_argument("--features", default="segmented,bbox,none")
    ap.add_argument("--threads", type=int, default=None, help="onnxruntime threads")
    ap.add_argument("--out", type=Path, help="also write the table to this Markdown file")
    args = ap.parse_args()
    parse_frame_range(args.frames)
    header = ["sequence", "features", "frames", "fps", *(f"{s} ms" for s in STAGES), "tracks/frame"]
    lines = ["| " + " | ".join(header) + " |", "|---|---|" + "---:|" * (len(header) - 2)]
    for name in args.seq:
        for features in args.features.split(","):
            start = time.perf_counter()
            r = measure(SHARED / "data" / name, args.frames, features, args.threads)
            cells = [name, features, f"{r['frames']:.0f}", f"{r['fps']:.2f}"]
            cells += [f"{r[f'{s}_ms']:.1f}" for s in STAGES]
            cells.append(f"{r['tracks_per_frame']:.1f}")
            lines.append("| " + " | ".join(cells) + " |")
            print(lines[-1], f"  ({time.perf_counter() - start:.0f} s)", file=sys.stderr)
    cpus = os.cpu_count()
    note = (
        f"Frames {args.frames}; {cpus} CPUs visible; {platform.processor() or platform.machine()};"
        f" Python {platform.python_version()}. Stages as timed by densepeds.Pipeline.times."
    )
    table = "\n".join([*lines, "", note])
    print(table)
    if args.out:
        args.out.write_text(
            "# End-to-end pipeline speed\n\n"
            f"Command: `python benchmarks/pipeline_speed.py --frames {args.frames} "
            f"--features {args.features}`\n\n{table}\n",
            encoding="utf-8",
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
