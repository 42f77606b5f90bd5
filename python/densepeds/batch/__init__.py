"""Many inputs at once: ``densepeds batch INPUT... --out DIR``, or ``densepeds.batch.run``.

Each input (a video, an image folder or a MOTChallenge sequence; folders and globs expand to the
inputs inside) is one online tracking job, run on Ray: a local Ray on this machine by default,
an existing cluster with ``address`` (or ``$RAY_ADDRESS``). A job runs ``densepeds run``'s own
code, so its tracks equal ``densepeds run INPUT`` with the same options. Outputs per input
``NAME`` in the output folder: ``NAME.txt`` (tracks), ``NAME.mp4`` (with ``video``) and
``NAME.json`` (its record); ``batch.json`` sums up the batch. Rerunning a batch skips the inputs
done with the same settings and redoes the rest; a bad input fails alone.

    from densepeds import batch
    result = batch.run(["clips/", "cam7.mp4"], "out/", detector="yoloseg", workers=2)
    print(result.table())
"""

from __future__ import annotations

import argparse
import hashlib
import os
import signal
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from densepeds.batch.plan import (
    SUMMARY_FILE,
    JobRecord,
    PlanItem,
    Settings,
    expand_inputs,
    plan,
    write_json_atomic,
)
from densepeds.errors import ModelError, ParameterError
from densepeds.runner.spec import add_run_options, presets_help

__all__ = ["BatchResult", "JobRecord", "PlanItem", "Settings", "add_parser", "prepare", "run"]

EXIT_FAILED = 1


@dataclass
class BatchResult:
    """A finished batch: one record per input, in the inputs' order."""

    records: list[JobRecord]
    out_dir: Path
    settings_hash: str
    seconds: float  # wall time of the whole call, Ray's start included
    start_seconds: float  # starting or joining Ray and shipping the models
    workers: int | None
    threads: int | None  # None: nothing ran

    @property
    def failed(self) -> list[JobRecord]:
        return [r for r in self.records if r.status != "done"]

    @property
    def ran(self) -> list[JobRecord]:
        return [r for r in self.records if not r.skipped]

    @property
    def frames_per_second(self) -> float:
        """Frames tracked by this call per second of its wall time after Ray's start."""
        frames = sum(r.frames for r in self.ran)
        busy = self.seconds - self.start_seconds
        return frames / busy if busy > 0 else 0.0

    def to_json(self) -> dict[str, Any]:
        return {
            "settings": self.settings_hash,
            "seconds": round(self.seconds, 3),
            "start_seconds": round(self.start_seconds, 3),
            "workers": self.workers,
            "threads": self.threads,
            "frames_per_second": round(self.frames_per_second, 3),
            "failed": len(self.failed),
            "inputs": [{**r.to_json(), "skipped": r.skipped} for r in self.records],
        }

    def table(self) -> str:
        """The summary: per input frames, tracks, fps and status, then the totals."""
        rows = ["| input | status | frames | tracks | fps | seconds | note |", "|---" * 7 + "|"]
        for r in self.records:
            status = "done (before)" if r.skipped else r.status
            note = (r.error or "").replace("|", "/")
            rows.append(
                f"| {r.name} | {status} | {r.frames} | {r.tracks} | {r.fps:.1f} | "
                f"{r.seconds:.1f} | {note} |"
            )
        ran = self.ran
        done = sum(r.status == "done" for r in ran)
        rows.append(
            f"\n{len(self.records)} inputs: {done} done now, {len(self.records) - len(ran)} done "
            f"before, {len(self.failed)} failed; {sum(r.frames for r in ran)} frames in "
            f"{self.seconds:.1f} s ({self.start_seconds:.1f} s starting Ray), "
            f"{self.frames_per_second:.1f} frames/s overall -> {self.out_dir / SUMMARY_FILE}"
        )
        return "\n".join(rows)


@dataclass
class Prepared:
    """A batch ready to run: its plan, settings hash and the model files to ship."""

    items: list[PlanItem]
    out_dir: Path
    settings: Settings
    settings_hash: str
    models: dict[str, Path]


def prepare(
    inputs: Iterable[str | os.PathLike[str]],
    out_dir: str | os.PathLike[str],
    settings: Settings,
) -> Prepared:
    """Expand the inputs, check the settings, find the models and plan what to run or skip."""
    settings.check()
    paths = expand_inputs(inputs)
    models = _model_files(settings)
    digests = {role: hashlib.sha256(p.read_bytes()).hexdigest() for role, p in models.items()}
    settings_hash = settings.digest(digests)
    out = Path(out_dir).expanduser().resolve()
    if out.exists() and not out.is_dir():
        raise ParameterError(f"--out {out}: exists and is not a folder")
    return Prepared(plan(paths, out, settings, settings_hash), out, settings, settings_hash, models)


def _model_files(settings: Settings) -> dict[str, Path]:
    """The model files the jobs may load, found here; an explicitly chosen one must exist, a
    default one that is missing is left for the jobs that need it to report."""
    from densepeds.batch.worker import DETECTOR_ROLE, REID_ROLE
    from densepeds.models.files import (
        default_detector,
        default_model_file,
        default_reid_file,
        find_model,
    )

    files: dict[str, Path] = {}
    kind = settings.detector or default_detector(settings.detector_model)
    wanted = [
        (
            DETECTOR_ROLE,
            settings.detector_model or default_model_file(kind),
            settings.detector is not None or settings.detector_model is not None,
        )
    ]
    if settings.features != "none":
        wanted.append(
            (
                REID_ROLE,
                settings.reid_model or default_reid_file(),
                settings.reid_model is not None or settings.features is not None,
            )
        )
    for role, name, required in wanted:
        try:
            files[role] = find_model(name).resolve()
        except ModelError:
            if required:
                raise
    return files


def run(
    inputs: Iterable[str | os.PathLike[str]],
    out_dir: str | os.PathLike[str],
    settings: Settings | None = None,
    *,
    workers: int | None = None,
    threads: int | None = None,
    address: str | None = None,
    progress: Callable[[JobRecord, int, int, float], None] | None = None,
    **options: Any,
) -> BatchResult:
    """Track every input on Ray and return the records (see the module's docstring).

    The tracking options are ``densepeds run``'s: ``settings``, or as keywords ``options`` the
    fields of :class:`densepeds.batch.plan.Settings` (those of densepeds.runner.RunOptions,
    ``device`` included: where the models run, as ``run --device``, with a GPU the workers share
    the cluster's GPUs; ``params`` a mapping of tracker parameters, and ``video``).
    ``workers``: inputs tracked at once (default: this machine's CPUs / ``threads`` for a local
    Ray, at most one per input; as many as the cluster's CPUs allow with an address);
    ``threads``: CPUs per worker (onnxruntime, OpenCV and motion threads; default: this
    machine's CPUs / the workers, so that a single worker runs as ``densepeds run`` does and
    more share the CPUs). ``progress(record, done, total, frames_per_second)`` is called as
    each input finishes. Raises DensePedsError for a bad option or input list before any job
    runs; a failing input only fails its own record.
    """
    if settings is None:
        settings = Settings.make(**options)
    elif options:
        raise ParameterError("give settings or options, not both")
    from densepeds.detect.onnxutil import check_device

    check_device(settings.device)
    if threads is not None and threads < 1:
        raise ParameterError(f"threads must be >= 1, got {threads}")
    if workers is not None and workers < 1:
        raise ParameterError(f"workers must be >= 1, got {workers}")
    start = time.perf_counter()
    prep = prepare(inputs, out_dir, settings)
    try:  # an output folder that cannot be written fails the batch before any job
        prep.out_dir.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=prep.out_dir).close()
    except OSError as err:
        raise ParameterError(f"--out {prep.out_dir}: cannot write there ({err})") from err
    todo = [item.job for item in prep.items if item.action == "run"]
    records = {item.job.input: item.record for item in prep.items if item.action == "skip"}
    start_seconds = 0.0
    stopped_by: int | None = None
    if todo:
        from densepeds.batch.on_ray import StopSignalError, execute, received_signal, session
        from densepeds.detect.onnxutil import available_cpus

        local_workers, threads = worker_shape(available_cpus(), len(todo), workers, threads)
        counter = {"done": 0, "frames": 0}
        with session(address, local_workers * threads) as ray:
            start_seconds = time.perf_counter() - start
            begin = time.perf_counter()

            def on_done(record: JobRecord) -> None:
                counter["done"] += 1
                counter["frames"] += record.frames
                if progress is not None:
                    rate = counter["frames"] / max(time.perf_counter() - begin, 1e-9)
                    progress(record, counter["done"], len(todo), rate)

            try:
                for record in execute(
                    ray,
                    todo,
                    settings,
                    prep.settings_hash,
                    prep.models,
                    threads,
                    workers,
                    on_done,
                    settings.device,
                ):
                    records[Path(record.input)] = record
            except StopSignalError as stop:
                records.update({Path(r.input): r for r in stop.records})
                stopped_by = stop.signum
        if stopped_by is None:  # a signal noted after the last job ended
            stopped_by = received_signal()
    result = BatchResult(
        records=[r for r in (records.get(item.job.input) for item in prep.items) if r is not None],
        out_dir=prep.out_dir,
        settings_hash=prep.settings_hash,
        seconds=time.perf_counter() - start,
        start_seconds=start_seconds,
        workers=workers,
        threads=threads,
    )
    write_json_atomic(prep.out_dir / SUMMARY_FILE, result.to_json())
    if stopped_by is not None:
        # Ray is gone and the summary written: the signal now acts as it would have (for the
        # command, exit 128 + the signal; by default, the end of the process).
        signal.raise_signal(stopped_by)
    return result


def worker_shape(
    cpus: int, inputs: int, workers: int | None, threads: int | None
) -> tuple[int, int]:
    """(workers, CPUs per worker) on a machine with ``cpus`` for ``inputs`` inputs, each given
    or chosen so that the workers use every CPU: as many workers as inputs up to the CPUs /
    ``threads``, then the CPUs shared among them."""
    workers = workers or max(1, min(inputs, cpus // (threads or 1)))
    return workers, threads or max(1, cpus // workers)


# --- command line ---------------------------------------------------------------------------


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Add ``batch`` to the ``densepeds`` command's subparsers."""
    p = sub.add_parser(
        "batch",
        help="track many inputs in parallel on Ray (resumable)",
        description=textwrap.fill(
            "Track every input (videos, image folders, MOTChallenge sequences; a folder "
            "or a glob expands to the inputs inside) in parallel on Ray, each as `densepeds run` "
            "would. Writes NAME.txt, NAME.json (and NAME.mp4 with --video) per input and "
            "batch.json; a rerun skips the inputs done with the same settings. Exit status 1 if "
            "any input failed.",
            79,
        ),
        epilog=presets_help(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="video, folder or glob")
    p.add_argument("--out", required=True, metavar="DIR", type=Path, help="output folder")
    add_run_options(p, shared_only=True)
    p.add_argument("--video", action="store_true", help="also write NAME.mp4 (annotated)")
    p.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="inputs at once (default: CPUs / --threads locally; the cluster's CPUs with "
        "--address)",
    )
    p.add_argument(
        "--threads",
        type=int,
        metavar="N",
        help="CPUs per worker (default: this machine's CPUs / the workers)",
    )
    p.add_argument(
        "--address",
        metavar="HOST:PORT",
        help="join this Ray cluster (default: $RAY_ADDRESS, else a local Ray)",
    )
    p.add_argument("--dry-run", action="store_true", help="list what would run and stop")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress lines")
    return p


def cmd_batch(args: argparse.Namespace) -> int:
    """``densepeds batch``: exit 0 when every input is done, 1 when any failed."""
    settings = Settings.from_args(args)
    if args.dry_run:
        prep = prepare(args.inputs, args.out, settings)
        print(format_plan(prep.items))
        return 0
    progress = None if args.quiet else _print_progress
    result = run(
        args.inputs,
        args.out,
        settings,
        workers=args.workers,
        threads=args.threads,
        address=args.address,
        progress=progress,
    )
    print(result.table())
    return EXIT_FAILED if result.failed else 0


def format_plan(items: list[PlanItem]) -> str:
    rows = ["| input | action | why | path |", "|---|---|---|---|"]
    for item in items:
        rows.append(f"| {item.job.name} | {item.action} | {item.reason} | {item.job.input} |")
    runs = sum(item.action == "run" for item in items)
    rows.append(f"\n{len(items)} inputs: {runs} to run, {len(items) - runs} done before")
    return "\n".join(rows)


def _print_progress(record: JobRecord, done: int, total: int, rate: float) -> None:
    what = (
        f"{record.frames} frames, {record.tracks} tracks, {record.fps:.1f} fps"
        if record.status == "done"
        else f"failed: {record.error}"
    )
    sys.stderr.write(f"batch: [{done}/{total}] {record.name} {what}; {rate:.1f} frames/s overall\n")
    sys.stderr.flush()
