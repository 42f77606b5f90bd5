"""Ray as a batch's engine: a local Ray on this machine, or an existing cluster by address.

Each input is one Ray task that asks for ``threads`` CPUs (and, for a GPU device, a share of the
cluster's GPUs: :func:`gpu_share`), so Ray runs as many at once as the nodes have CPUs for; a
task is never retried by Ray (a worker that dies fails its input, which the next run of the batch
redoes).
"""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import signal
import socket
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from densepeds.batch.plan import Job, JobRecord, Settings, new_record, read_record, write_record
from densepeds.batch.worker import ShippedModel, node_cache_path, run_job
from densepeds.errors import ParameterError

ADDRESS_ENV = "RAY_ADDRESS"
INSTALL_HINT = "densepeds batch needs Ray: pip install 'densepeds[ray]'"


# The termination signals a batch handles: noted while Ray runs (Ray's own handler would end the
# driver with a crash dump, and an exception raised inside a Ray call is a SystemError).
STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)
# Signals received during the current session, in order.
_RECEIVED: list[int] = []


def received_signal() -> int | None:
    """The first termination signal noted in the last session, if any."""
    return _RECEIVED[0] if _RECEIVED else None


class StopSignalError(Exception):
    """A termination signal reached the driver: the jobs still running were cancelled and their
    records say so. ``records``: every record of the jobs that ended (cancelled ones included)."""

    def __init__(self, signum: int, records: list[JobRecord]) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.records = records


def import_ray() -> Any:
    try:
        import ray
    except ImportError as err:
        raise ParameterError(INSTALL_HINT) from err
    return ray


@contextmanager
def session(address: str | None, num_cpus: int | None) -> Any:
    """Ray, connected: to ``address`` (or ``$RAY_ADDRESS``), else a new local Ray with
    ``num_cpus`` CPUs that is shut down afterwards. An already connected Ray is used as it is."""
    ray = import_ray()
    if ray.is_initialized():
        yield ray
        return
    address = address or os.environ.get(ADDRESS_ENV) or None
    saved = {sig: signal.getsignal(sig) for sig in STOP_SIGNALS}  # restored when Ray is gone
    kwargs: dict[str, Any] = {
        "include_dashboard": False,
        "logging_level": logging.ERROR,
        "log_to_driver": False,
    }
    try:
        if address:
            check_reachable(address)
            ray.init(address=address, **kwargs)
        else:
            ray.init(address="local", num_cpus=num_cpus, **kwargs)
    except (ConnectionError, RuntimeError, ValueError) as err:
        where = f"the Ray cluster at {address}" if address else "a local Ray"
        raise ParameterError(f"cannot start or join {where}: {err}") from err
    # After ray.init (which installs Ray's own handlers): note the signal, stop at the next poll.
    _RECEIVED.clear()
    for sig in STOP_SIGNALS:
        signal.signal(sig, lambda signum, _frame: _RECEIVED.append(signum))
    try:
        yield ray
    finally:
        if not address:  # this machine's copies of the models go with the local Ray
            shutil.rmtree(node_cache_path(), ignore_errors=True)
        ray.shutdown()
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def check_reachable(address: str, timeout: float = 10.0) -> None:
    """Fail at once, in one line, where nothing listens at a cluster's HOST:PORT (Ray itself
    retries for many minutes)."""
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not port.isdigit():
        raise ParameterError(f"--address {address}: expected HOST:PORT")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout).close()
    except OSError as err:
        raise ParameterError(f"cannot reach a Ray cluster at {address}: {err}") from err


def ship_models(ray: Any, files: dict[str, Path]) -> dict[str, ShippedModel]:
    """Put each model file's bytes in Ray's object store once; workers copy them to their node."""
    shipped = {}
    for role, path in files.items():
        data = path.read_bytes()
        shipped[role] = ShippedModel(
            name=path.name,
            sha256=hashlib.sha256(data).hexdigest(),
            size=len(data),
            path=str(path),
            ref=[ray.put(data)],
        )
    return shipped


def _task(
    job: Job,
    settings: Settings,
    settings_hash: str,
    shipped: dict[str, ShippedModel],
    threads: int,
    device: str,
) -> JobRecord:
    return run_job(job, settings, settings_hash, shipped, threads, device)


def gpu_share(device: str, gpus: float, tasks: int) -> float:
    """The GPUs each task asks Ray for: a GPU device's share of the cluster's ``gpus`` among
    the ``tasks`` run at once (Ray hides the GPUs from a task that asks for none), else none.
    ``cuda`` on a cluster without GPUs is a ParameterError."""
    if device in ("cpu", "openvino") or gpus <= 0:
        if device == "cuda":
            raise ParameterError("device cuda: the Ray cluster has no GPU")
        return 0.0
    return min(1.0, gpus / max(1, tasks))


def execute(
    ray: Any,
    jobs: Sequence[Job],
    settings: Settings,
    settings_hash: str,
    models: dict[str, Path],
    threads: int,
    workers: int | None,
    on_done: Callable[[JobRecord], None],
    device: str = "auto",
) -> list[JobRecord]:
    """Run every job on Ray, at most ``workers`` at once (None: as many as the CPUs allow), its
    models on ``device``; ``on_done`` is called as each finishes. Records come back in the
    jobs' order."""
    gpus = gpu_share(device, ray.cluster_resources().get("GPU", 0), workers or len(jobs))
    shipped = ship_models(ray, models)
    task = ray.remote(num_cpus=threads, num_gpus=gpus, max_retries=0)(_task)
    waiting = list(jobs)
    running: dict[Any, Job] = {}
    done: dict[Path, JobRecord] = {}
    limit = workers or len(jobs)
    try:
        while waiting or running:
            if _RECEIVED:
                raise StopSignalError(_RECEIVED[0], list(done.values()))
            while waiting and len(running) < limit:
                job = waiting.pop(0)
                ref = task.remote(job, settings, settings_hash, shipped, threads, device)
                running[ref] = job
            # Polled, so that a noted signal stops the batch within a fraction of a second.
            ready, _ = ray.wait(list(running), num_returns=1, timeout=0.25)
            for ref in ready:
                job = running.pop(ref)
                try:
                    record = ray.get(ref)
                except ray.exceptions.RayError as err:
                    record = _lost(job, settings_hash, err)
                done[job.input] = record
                on_done(record)
    except StopSignalError as stop:
        stop.records.extend(_cancel(ray, running, settings_hash, stop))
        raise
    except BaseException:
        for ref in running:
            ray.cancel(ref, force=True)
        raise
    return [done[j.input] for j in jobs]


def _cancel(
    ray: Any, running: dict[Any, Job], settings_hash: str, stop: StopSignalError
) -> list[JobRecord]:
    """Cancel the running jobs, wait for their workers to end, and leave each a consistent
    record: ``done`` where it finished first, else ``failed`` naming the signal (redone by the
    next run) - never ``running``."""
    for ref in running:
        ray.cancel(ref, force=True)
    if running:
        ray.wait(list(running), num_returns=len(running), timeout=10.0)
    records = []
    for job in running.values():
        record = read_record(job)
        if record is None or record.status != "done":
            record = new_record(job, settings_hash, "failed")
            record.error = f"interrupted ({stop})"
            write_record(job, record)
        records.append(record)
    return records


def _lost(job: Job, settings_hash: str, err: Exception) -> JobRecord:
    """The record of a job whose worker died or could not run it (the next run redoes it)."""
    record = new_record(job, settings_hash, "failed")
    first = str(err).strip().splitlines()[0] if str(err).strip() else ""
    record.error = f"worker lost ({type(err).__name__}): {first}".rstrip(": ")
    write_record(job, record)
    return record
