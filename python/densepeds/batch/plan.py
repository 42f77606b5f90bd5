"""A batch's plan: the inputs a list of paths and globs expands to, their output names, the
settings every input is tracked with, and the per-input JSON records that make a batch resumable.

Per input NAME the output folder holds ``NAME.txt`` (MOTChallenge tracks), ``NAME.mp4`` (with
``video``) and ``NAME.json``: the input's path, size and modification time, the settings hash,
the status (``running``, ``done`` or ``failed``), frames, tracks and speed. Every file is written
to a temporary name and moved into place, the record last, so an input counts as done only when
its outputs are complete.
"""

from __future__ import annotations

import glob
import hashlib
import json
import os
import re
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from densepeds.errors import InputError, ParameterError
from densepeds.io.video import IMAGE_EXTS, VIDEO_EXTS, parse_frame_range
from densepeds.pipeline import DETECTORS, FEATURES, MOTIONS
from densepeds.runner.spec import RunOptions, params_tuple

RECORD_VERSION = 1
SUMMARY_FILE = "batch.json"
_GLOB_CHARS = re.compile(r"[*?\[]")


@dataclass(frozen=True, kw_only=True)
class Settings(RunOptions):
    """The ``densepeds run`` options every input of a batch is tracked with (see ``run --help``
    and densepeds.runner.RunOptions), and ``video``: also write an annotated ``NAME.mp4`` per
    input.
    """

    video: bool = False

    @classmethod
    def make(cls, **options: Any) -> Settings:
        """Settings from keywords: the field names, ``params`` any mapping (or pairs) of tracker
        parameters, model paths as str or path; an unknown name is a ParameterError."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(options) - names)
        if unknown:
            raise ParameterError(
                f"unknown batch option(s) {', '.join(unknown)}; expected some of "
                f"{', '.join(sorted(names))}"
            )
        for key in ("detector_model", "reid_model"):
            if options.get(key) is not None:
                options[key] = str(options[key])
        options["params"] = params_tuple(options.get("params"))
        return cls(**options)

    def check(self) -> None:
        """Raise ParameterError for a value ``run`` would refuse (before any input is opened)."""
        from densepeds.pipeline import Pipeline

        if self.detector is not None and self.detector not in DETECTORS:
            raise ParameterError(f"detector {self.detector!r}: expected one of {DETECTORS}")
        if self.features is not None and self.features not in FEATURES:
            raise ParameterError(f"features {self.features!r}: expected one of {FEATURES}")
        if self.motion not in MOTIONS:
            raise ParameterError(f"motion {self.motion!r}: expected one of {MOTIONS}")
        if self.fill_gaps < 0:
            raise ParameterError(f"fill_gaps must be >= 0 frames, got {self.fill_gaps}")
        if self.reid_reuse and self.features == "none":
            raise ParameterError(
                "reid_reuse keeps re-ID embeddings, and these settings compute none (features none)"
            )
        parse_frame_range(self.frames)
        # Builds the tracker only (models load lazily): rejects an unknown preset and unknown or
        # bad tracker values.
        Pipeline(
            self.detector,
            motion=self.motion,
            features="none",
            preset=self.preset,
            **dict(self.params),
        )

    def digest(self, model_digests: dict[str, str]) -> str:
        """A hash of everything that decides the outputs: the options, the model files' contents
        (``model_digests``: role -> sha256) and the package version."""
        from densepeds import __version__

        text = json.dumps(
            {
                "settings": asdict(self),
                "models": model_digests,
                "version": __version__,
                "record": RECORD_VERSION,
            },
            sort_keys=True,
            default=str,
        )
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Job:
    """One input and where its outputs go."""

    name: str
    input: Path
    out_dir: Path
    video: bool

    @property
    def tracks(self) -> Path:
        return self.out_dir / f"{self.name}.txt"

    @property
    def video_file(self) -> Path | None:
        return self.out_dir / f"{self.name}.mp4" if self.video else None

    @property
    def record_file(self) -> Path:
        return self.out_dir / f"{self.name}.json"


@dataclass
class JobRecord:
    """What a job left in ``NAME.json`` (and in the batch summary)."""

    name: str
    input: str
    input_size: int
    input_mtime_ns: int
    settings: str
    status: str  # running | done | failed
    error: str | None = None
    frames: int = 0
    tracks: int = 0
    fps: float = 0.0  # tracking frames per second, as `densepeds run` reports it
    seconds: float = 0.0  # the job's wall time: opening, model loading and tracking
    open_seconds: float = 0.0  # opening the input and getting the models
    load_seconds: float = 0.0  # loading models (0 when this worker had them already)
    cpu_seconds: float = 0.0  # CPU time of the worker process (all its threads) on this job
    fetched_models: list[str] = field(default_factory=list)  # copied to this node by this job
    tracks_file: str | None = None
    video_file: str | None = None
    node: str | None = None
    pid: int | None = None
    max_rss_mb: float = 0.0  # the worker process's peak resident memory so far
    skipped: bool = False  # done by an earlier batch with the same settings (not saved)
    version: int = RECORD_VERSION

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        del data["skipped"]
        return data

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> JobRecord:
        known = {k: v for k, v in data.items() if k in cls.__dataclass_fields__}
        return cls(**known)


@dataclass(frozen=True)
class PlanItem:
    job: Job
    action: str  # run | skip
    reason: str  # why: "new", "done", "settings changed", "input changed", "failed", ...
    record: JobRecord | None  # the existing record, if any


# --- inputs ----------------------------------------------------------------------------------


def is_input_folder(path: Path) -> bool:
    """A folder tracked as one input: a MOTChallenge sequence or a folder of images."""
    if (path / "seqinfo.ini").is_file():
        return True
    return any(p.suffix.lower() in IMAGE_EXTS for p in path.iterdir() if p.is_file())


def expand_inputs(items: Iterable[str | os.PathLike[str]]) -> list[Path]:
    """The inputs named by ``items`` (absolute paths): videos, image folders and sequence folders
    as they are; a folder of those (searched recursively, hidden entries skipped) and a glob
    expand to every input inside. Order: as given, folders and globs sorted; an input reached
    twice (also through a link) counts once."""
    found: list[Path] = []
    for item in items:
        text = os.fspath(item)
        if _GLOB_CHARS.search(text):
            matches = sorted(glob.glob(os.path.expanduser(text), recursive=True))
            if not matches:
                raise InputError(f"{text}: no file or folder matches")
            for m in matches:
                found.extend(_expand_path(Path(m), explicit=False, seen=set()))
            continue
        path = Path(text).expanduser()
        if not path.exists():
            raise InputError(f"{path}: no such file or folder")
        found.extend(_expand_path(path, explicit=True, seen=set()))
    unique: dict[Path, Path] = {}  # by the file it is; named as given (a link keeps its name)
    for p in found:
        unique.setdefault(p.resolve(), Path(os.path.abspath(p)))
    if not unique:
        raise InputError("no inputs: no videos, image folders or sequence folders found")
    return list(unique.values())


def _expand_path(path: Path, explicit: bool, seen: set[Path]) -> list[Path]:
    """The inputs at ``path``; ``seen``: the folders (resolved) already searched, so that a link
    back to a folder above (a loop) is searched once, not forever."""
    if path.is_file():
        if path.name == "seqinfo.ini":
            return [path.parent]
        # A file named on the command line is an input (a corrupt one fails its own job); a
        # file found in a folder or by a glob is one only if it looks like a video.
        return [path] if explicit or path.suffix.lower() in VIDEO_EXTS else []
    if not path.is_dir():
        return []
    if is_input_folder(path):
        return [path]
    real = path.resolve()
    if real in seen:
        return []
    seen.add(real)
    inside: list[Path] = []
    for child in sorted(path.iterdir(), key=lambda p: p.name):
        if not child.name.startswith("."):
            inside.extend(_expand_path(child, explicit=False, seen=seen))
    if explicit and not inside:
        raise InputError(f"{path}: no videos, image folders or sequence folders inside")
    return inside


# Longest output name (bytes): NAME.json's temporary (``.NAME.json.XXXXXXXX.tmp``) and every
# other file of the job then fit the 255-byte file names of common file systems.
MAX_NAME_BYTES = 160


def _own_name(path: Path) -> str:
    """The input's own output name: its stem or folder name, shortened (with a hash of its path)
    past :data:`MAX_NAME_BYTES`, and never the summary's name (``batch.json``)."""
    name = path.stem if path.is_file() else path.name
    tag = hashlib.sha256(str(path).encode()).hexdigest()[:8]
    if len(name.encode()) > MAX_NAME_BYTES:
        cut = name.encode()[: MAX_NAME_BYTES - 9].decode(errors="ignore")
        name = f"{cut}-{tag}"
    if name.lower() == Path(SUMMARY_FILE).stem.lower():
        name = f"{name}-{tag}"
    return name


def job_names(inputs: Sequence[Path]) -> list[str]:
    """Output names: the video's stem or the folder's name (see :func:`_own_name`); inputs that
    share one are told apart by their parent folder's name, then by a hash of their path."""
    names = [_own_name(p) for p in inputs]
    for attempt in range(2):
        counts: dict[str, int] = {}
        for n in names:
            counts[n] = counts.get(n, 0) + 1
        if all(c == 1 for c in counts.values()):
            break
        for i, (n, p) in enumerate(zip(names, inputs, strict=True)):
            if counts[n] > 1:
                if attempt == 0 and len(f"{p.parent.name}-{n}".encode()) <= MAX_NAME_BYTES:
                    names[i] = f"{p.parent.name}-{n}"
                else:
                    names[i] = f"{n}-{hashlib.sha256(str(p).encode()).hexdigest()[:8]}"
    return names


def input_stat(path: Path) -> tuple[int, int]:
    """(total size in bytes, latest modification time in ns) of a file or a folder's files."""
    if path.is_file():
        st = path.stat()
        return st.st_size, st.st_mtime_ns
    size = mtime = 0
    for root, _, files in os.walk(path):
        for f in files:
            st = Path(root, f).stat()
            size += st.st_size
            mtime = max(mtime, st.st_mtime_ns)
    return size, mtime


# --- records ---------------------------------------------------------------------------------


def write_json_atomic(path: Path, data: Any) -> None:
    """Write JSON to a temporary file beside ``path`` and move it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(data, fh, indent=1)
            fh.write("\n")
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_record(job: Job, record: JobRecord) -> None:
    write_json_atomic(job.record_file, record.to_json())


def read_record(job: Job) -> JobRecord | None:
    """The job's record, or None where there is none or it cannot be read (then it is redone)."""
    try:
        data = json.loads(job.record_file.read_text(encoding="utf-8"))
        return JobRecord.from_json(data) if isinstance(data, dict) else None
    except (OSError, ValueError, TypeError):
        return None


def new_record(job: Job, settings_hash: str, status: str) -> JobRecord:
    size, mtime = input_stat(job.input)
    return JobRecord(
        name=job.name,
        input=str(job.input),
        input_size=size,
        input_mtime_ns=mtime,
        settings=settings_hash,
        status=status,
    )


def plan(
    inputs: Sequence[Path], out_dir: Path, settings: Settings, settings_hash: str
) -> list[PlanItem]:
    """Per input: run it, or skip it because an earlier batch completed it with the same
    settings (record ``done``, same input path, size and time, outputs present)."""
    out_dir = out_dir.expanduser().resolve()
    items = []
    for name, path in zip(job_names(inputs), inputs, strict=True):
        job = Job(name, path, out_dir, settings.video)
        record = read_record(job)
        action, reason = "run", "new"
        if record is not None:
            size, mtime = input_stat(path)
            if record.status != "done":
                reason = f"was {record.status}"
            elif record.settings != settings_hash:
                reason = "settings changed"
            elif record.input != str(path):
                reason = "other input"
            elif (record.input_size, record.input_mtime_ns) != (size, mtime):
                reason = "input changed"
            elif not job.tracks.is_file() or (
                job.video_file is not None and not job.video_file.is_file()
            ):
                reason = "outputs missing"
            else:
                action, reason = "skip", "done"
                record.skipped = True
        items.append(PlanItem(job, action, reason, record))
    return items


def remove_partial_outputs(job: Job) -> None:
    """Delete temporary files an interrupted job left behind (tracks, video, record)."""
    pattern = re.compile(
        rf"^\.{re.escape(job.name)}\.(txt\.[^.]+\.tmp|[^.]+\.mp4|json\.[^.]+\.tmp)$"
    )
    if job.out_dir.is_dir():
        for p in job.out_dir.iterdir():
            if pattern.match(p.name):
                p.unlink(missing_ok=True)
