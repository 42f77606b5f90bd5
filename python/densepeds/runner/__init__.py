"""The run layer: what a tracking run is (:class:`RunSpec`, built from the command-line options
declared in :mod:`densepeds.runner.spec`) and the engine that carries it out
(:mod:`densepeds.runner.engine`), used by ``densepeds run``, every ``densepeds batch`` job and
the benchmarks.

    from densepeds.runner import RunSpec, open_run, track_source
    spec = RunSpec(input="crowd.mp4", frames="1:100", out=Path("crowd.txt"), quiet=True)
    src, pipe, dets, out, rng = open_run(spec)
    frames, tracks = track_source(spec, pipe, src, out, dets, rng)
"""

from __future__ import annotations

from densepeds.runner.control import Interrupted, Terminated, one_line, termination_raises
from densepeds.runner.engine import open_run, run_scene, summary, track_source
from densepeds.runner.spec import RunOptions, RunSpec

__all__ = [
    "Interrupted",
    "RunOptions",
    "RunSpec",
    "Terminated",
    "one_line",
    "open_run",
    "run_scene",
    "summary",
    "termination_raises",
    "track_source",
]
