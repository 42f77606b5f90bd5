"""One batch job, as a worker runs it: ``densepeds run``'s own code on one input, with models
that reach each node once and stay loaded in the worker for its next inputs.

The job builds the run of its input (a densepeds.runner.RunSpec) and calls the same functions as
``densepeds run`` (``runner.open_run`` then ``runner.track_source``), so its tracks are those of
``densepeds run INPUT --out NAME.txt`` with the same options. Only the thread counts differ:
onnxruntime, OpenCV and the motion step use the worker's CPU share (:func:`use_cpus`), which
leaves the results unchanged.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import resource
import socket
import stat
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from densepeds.batch.plan import Job, JobRecord, Settings, new_record, write_record
from densepeds.batch.plan import remove_partial_outputs as _remove_partial_outputs
from densepeds.errors import DensePedsError, ModelError
from densepeds.runner import RunSpec, one_line, open_run, track_source

DETECTOR_ROLE = "detector"
REID_ROLE = "reid"


@dataclass(frozen=True)
class ShippedModel:
    """A model file resolved by the driver: its contents travel once per node.

    ``ref`` holds the Ray object reference of the file's bytes (in a list, so that Ray hands it
    over unresolved and a node that has the file already fetches nothing); None uses ``path``.
    """

    name: str
    sha256: str
    size: int
    path: str
    ref: list[Any] | None = None


# Models loaded in this worker process, kept for its next inputs.
_LOADED: dict[tuple[Any, ...], Any] = {}


def node_cache_dir() -> Path:
    """Where shipped models are kept on this node: one folder per Ray node in the temporary
    folder (a local Ray's is removed when the batch ends), made if needed and checked to be
    this user's alone (:class:`ModelError` if not)."""
    path = node_cache_path()
    _private_dir(path.parent)
    return _private_dir(path)


def node_cache_path() -> Path:
    """:func:`node_cache_dir`'s path, neither made nor checked."""
    node = "local"
    try:
        import ray

        if ray.is_initialized():
            node = ray.get_runtime_context().get_node_id()[:16]
    except ImportError:
        pass
    return Path(tempfile.gettempdir()) / f"densepeds-batch-models-{os.getuid()}" / node


def _private_dir(path: Path) -> Path:
    """``path`` as a folder of this user's alone (made with mode 0700, or set to it): a folder
    in the shared temporary folder that is a link, or owned by someone else, is refused."""
    with contextlib.suppress(FileExistsError):
        path.mkdir(mode=0o700)
    st = os.lstat(path)
    if not stat.S_ISDIR(st.st_mode):
        raise ModelError(f"{path}: not a plain folder; refusing to keep models there")
    if st.st_uid != os.getuid():
        raise ModelError(
            f"{path}: owned by uid {st.st_uid}, not by this user ({os.getuid()}); refusing to "
            "use models kept there"
        )
    if stat.S_IMODE(st.st_mode) != 0o700:
        os.chmod(path, 0o700)
    return path


# Files of the node cache whose sha256 this process checked: path -> (inode, size, mtime).
_VERIFIED: dict[Path, tuple[int, int, int]] = {}


def _has_model(local: Path, model: ShippedModel) -> bool:
    """Whether ``local`` is a plain file of this user holding exactly ``model`` (its sha256),
    checked once per process while the file stays unchanged."""
    try:
        st = os.lstat(local)
    except FileNotFoundError:
        return False
    if not stat.S_ISREG(st.st_mode) or st.st_uid != os.getuid() or st.st_size != model.size:
        return False
    key = (st.st_ino, st.st_size, st.st_mtime_ns)
    if _VERIFIED.get(local) == key:
        return True
    digest = hashlib.sha256()
    with open(local, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    if digest.hexdigest() != model.sha256:
        return False
    _VERIFIED[local] = key
    return True


def use_cpus(threads: int) -> None:
    """Size this worker's threads for the ``threads`` CPUs it was given, as ``densepeds run``
    sizes them for a machine with that many: onnxruntime splits each batch in one part per CPU
    (``densepeds.detect.split_batch``; Ray's ``OMP_NUM_THREADS=1`` does not reach onnxruntime's
    own thread pools), and OpenCV runs that many threads."""
    import cv2

    from densepeds.detect import onnxutil

    onnxutil.limit_cpus(threads)
    cv2.setNumThreads(threads)


class WorkerModels:
    """The ``models`` argument of ``runner.open_run``: loads each model once per worker process
    (sized for its CPUs by :func:`use_cpus`), from the node's copy of the driver's file."""

    def __init__(
        self, shipped: dict[str, ShippedModel], threads: int | None, device: str = "auto"
    ) -> None:
        self.shipped = shipped
        self.threads = threads
        self.device = device
        self.load_seconds = 0.0
        self.fetched: list[str] = []

    def _file(self, role: str, given: str | None) -> str | None:
        model = self.shipped.get(role)
        if model is None:
            return given  # not resolved by the driver: looked up here as `run` would
        if model.ref is None:
            return model.path
        local = node_cache_dir() / f"{model.sha256[:16]}-{model.name}"
        # One worker of the node copies the file; the others wait for it (a lock per model).
        with open(local.with_name(f".{local.name}.lock"), "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            if not _has_model(local, model):
                import ray

                data = ray.get(model.ref[0])
                if hashlib.sha256(data).hexdigest() != model.sha256:
                    raise ModelError(f"{model.name}: the copy shipped to this node is damaged")
                fd, tmp = tempfile.mkstemp(dir=local.parent, prefix=f".{local.name}.")
                with os.fdopen(fd, "wb") as fh:
                    fh.write(data)
                os.replace(tmp, local)
                _VERIFIED.pop(local, None)
                self.fetched.append(model.name)
        return str(local)

    def _load(self, key: tuple[Any, ...], make: Any) -> Any:
        if key not in _LOADED:
            start = time.perf_counter()
            _LOADED[key] = make()
            self.load_seconds += time.perf_counter() - start
        return _LOADED[key]

    def detector(self, kind: str, given: str | None, **options: Any) -> Any:
        from densepeds.detect import make_detector

        path = self._file(DETECTOR_ROLE, given)
        return self._load(
            (DETECTOR_ROLE, kind, path, self.threads, self.device, *sorted(options.items())),
            lambda: make_detector(kind, path, device=self.device, **options),
        )

    def reid(self, given: str | None, reuse: bool = False) -> Any:
        from densepeds.reid import ReID

        path = self._file(REID_ROLE, given)
        model = self._load(
            (REID_ROLE, path, self.threads, self.device, reuse),
            lambda: ReID(path, device=self.device, reuse=reuse),
        )
        model.reset()  # nothing carries over from the previous input
        return model


def run_args(settings: Settings, job: Job, threads: int | None) -> RunSpec:
    """The run ``densepeds run INPUT`` makes of this job's input with the batch's settings."""
    params = list(settings.params)
    if threads is not None and "threads" not in dict(settings.params):
        params.append(("threads", threads))  # the motion step's threads: same results
    return RunSpec.for_input(
        settings,
        job.input,
        params=tuple(params),
        out=job.tracks,
        video=job.video_file,
        quiet=True,
    )


def run_job(
    job: Job,
    settings: Settings,
    settings_hash: str,
    shipped: dict[str, ShippedModel],
    threads: int | None = None,
    device: str = "auto",
) -> JobRecord:
    """Track one input into its outputs and write its record; a bad input gives a ``failed``
    record with the one-line error (never an exception)."""
    start = time.perf_counter()
    cpu_start = _cpu_seconds()
    record = new_record(job, settings_hash, "running")
    record.node = _node_name()
    record.pid = os.getpid()
    job.out_dir.mkdir(parents=True, exist_ok=True)
    _remove_partial_outputs(job)
    write_record(job, record)
    if threads is not None:
        use_cpus(threads)
    models = WorkerModels(shipped, threads, device)
    try:
        spec = run_args(settings, job, threads)
        src, pipe, dets, out, rng = open_run(spec, models)
        record.open_seconds = time.perf_counter() - start
        record.frames, record.tracks = track_source(spec, pipe, src, out, dets, rng)
        record.fps = pipe.times.fps
        record.status = "done"
        record.tracks_file = job.tracks.name
        record.video_file = job.video_file.name if job.video_file is not None else None
    except DensePedsError as err:
        record.status, record.error = "failed", one_line(err)
    except Exception as err:  # a bug or an unexpected library error: this input fails alone
        record.status, record.error = "failed", f"{type(err).__name__}: {one_line(err)}"
    record.load_seconds = models.load_seconds
    record.fetched_models = models.fetched
    record.seconds = time.perf_counter() - start
    record.cpu_seconds = _cpu_seconds() - cpu_start
    record.max_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    write_record(job, record)
    return record


def _node_name() -> str:
    try:
        import ray

        if ray.is_initialized():
            return ray.get_runtime_context().get_node_id()[:12]
    except ImportError:
        pass
    return socket.gethostname()


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime
