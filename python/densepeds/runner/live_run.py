"""``densepeds run`` on a live camera (:mod:`densepeds.io.live`): each frame's tracks are written
and flushed as it is tracked; the run ends with one line and exit code ``EXIT_DISCONNECTED`` when
the stream ends or disconnects, and Ctrl-C keeps what was written."""

from __future__ import annotations

import sys

from densepeds.errors import ParameterError
from densepeds.io.live import EXIT_DISCONNECTED, LiveSource, shown
from densepeds.runner.control import Interrupted, ctrl_c_after_block
from densepeds.runner.engine import open_run, summary
from densepeds.runner.spec import RunSpec


def _lines(rows: list[tuple[float, ...]]) -> str:
    """MOTChallenge lines, as ``densepeds.io.mot.write_tracks`` writes them."""
    return "".join(
        f"{int(f)},{int(i)},{x1:.3f},{y1:.3f},{x2 - x1:.3f},{y2 - y1:.3f},{s:.6g},-1,-1,-1\n"
        for f, i, x1, y1, x2, y2, s in rows
    )


def run_live(spec: RunSpec) -> int:
    """``densepeds run`` on a live source (see the module docstring); the exit code."""
    from densepeds.io.mot import probe_output
    from densepeds.io.video import AnnotatedVideoWriter
    from densepeds.pipeline import track_rows

    for flag, value in (("--detections", spec.detections), ("--fill-gaps", spec.fill_gaps)):
        if value:
            raise ParameterError(
                f"{flag} does not go with a live source ({shown(str(spec.input))})"
            )
    src, pipe, _, out, rng = open_run(spec)
    assert isinstance(src, LiveSource)
    src.reconnect = spec.reconnect
    if src.reconnect < 0:
        raise ParameterError(f"--reconnect must be >= 0, got {src.reconnect}")
    probe_output(out)
    writer = AnnotatedVideoWriter(spec.video, fps=src.fps) if spec.video else None
    if spec.video:
        probe_output(spec.video)
    ids: set[int] = set()
    frames = 0
    interrupted = False
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        with open(out, "w", encoding="utf-8") as f:
            try:
                for res in pipe.run_frames(src, rng):
                    with ctrl_c_after_block(), pipe.times.stage("output"):
                        f.write(_lines(track_rows(res.frame_no, res.tracks)))
                        f.flush()
                        ids.update(res.tracks.ids.tolist())
                        if writer is not None:
                            writer.write(
                                res.image, res.tracks.ids, res.tracks.boxes, frame_no=res.frame_no
                            )
                        frames += 1
            except KeyboardInterrupt:
                interrupted = True
        if writer is not None:
            writer.close()
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    finally:
        src.close()
    kept = f"their tracks are in {out}" + (f" and {spec.video}" if writer is not None else "")
    if interrupted:
        raise Interrupted(f"interrupted after {frames} frames; {kept}")
    print(summary(src.name, frames, len(ids), out, pipe, spec.video))
    if src.ended is None:
        return 0
    sys.stderr.write(
        f"densepeds run: {shown(str(spec.input))}: {src.ended} after {frames} frames; {kept}\n"
    )
    return EXIT_DISCONNECTED
