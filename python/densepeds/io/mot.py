"""MOTChallenge text files: sequence info, detections, ground truth and tracker output.

Layouts (one object per line, comma separated):
  det.txt     frame, -1, left, top, width, height, score[, x, y, z]   (score: any range; read
              into [0, 1] by default, see score_scale)
  gt.txt      frame, id, left, top, width, height, flag, class, visibility   (MOT16/17/20)
              frame, id, left, top, width, height, flag, x, y, z             (MOT15)
  tracks.txt  frame, id, left, top, width, height, conf, -1, -1, -1
Frames are numbered from 1. Every parse error names the file and the 1-based line.
"""

from __future__ import annotations

import configparser
import contextlib
import errno
import os
import re
import secrets
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import numpy.typing as npt

from densepeds.errors import DetFileError, InputError, OutputError
from densepeds.types import Detections

__all__ = [
    "SCORE_MAPPINGS",
    "ScoreMapping",
    "SeqInfo",
    "atomic_output",
    "commit_temp",
    "discard_temp",
    "probe_output",
    "read_detections",
    "read_gt",
    "read_mot_rows",
    "read_seqinfo",
    "read_tracks",
    "rescale_scores",
    "reserve_temp",
    "safe_name",
    "score_scale",
    "write_bytes",
    "write_text",
    "write_tracks",
]

FloatArray = npt.NDArray[np.float64]

# Largest frame count a seqinfo.ini may declare (frame numbers fit a 32-bit integer).
MAX_SEQ_LENGTH = 2**31 - 1
# Largest track id a tracks file may hold (ids fit a 32-bit integer, as MOTChallenge tools assume).
MAX_TRACK_ID = 2**31 - 1
# Largest image width or height a seqinfo.ini may declare (pixels: 16K, above any camera).
MAX_IMAGE_SIDE = 16384
# Largest magnitude of a box coordinate or size in a MOTChallenge file (pixels): beyond it the
# value is no position in any image (1e300 would overflow the tracker's float32 boxes).
MAX_BOX_VALUE = 1e7
# Largest magnitude of a detection score: min-max rescaling would squash every other score of
# the file towards 0 under one absurd value (1e308).
MAX_SCORE = 1e6


@dataclass(frozen=True)
class SeqInfo:
    """The [Sequence] section of a MOTChallenge ``seqinfo.ini``."""

    name: str
    length: int
    width: int
    height: int
    fps: float
    im_dir: str
    im_ext: str
    path: Path

    @property
    def image_dir(self) -> Path:
        return self.path / self.im_dir

    def frame_path(self, frame: int) -> Path:
        """The image of a 1-based frame number (MOTChallenge names images 000001.jpg, ...)."""
        return self.image_dir / f"{frame:06d}{self.im_ext}"


def read_seqinfo(seq_dir: str | os.PathLike[str]) -> SeqInfo:
    """Read ``seq_dir/seqinfo.ini`` (``seq_dir`` may also be the ini file itself)."""
    path = Path(seq_dir)
    ini = path if path.suffix == ".ini" else path / "seqinfo.ini"
    seq_path = ini.parent
    if not ini.is_file():
        raise InputError(f"{ini}: no seqinfo.ini (is {seq_path} a MOTChallenge sequence folder?)")
    # No interpolation: a '%' in a value is a character, not a reference.
    parser = configparser.ConfigParser(interpolation=None)
    try:
        parser.read(ini, encoding="utf-8")
    except configparser.Error as err:
        raise InputError(f"{ini}: not a valid ini file ({_one_line(err.message)})") from err
    except UnicodeDecodeError as err:
        raise InputError(f"{ini}: not UTF-8 text (byte {err.start})") from err
    except OSError as err:
        raise InputError(f"{ini}: cannot read ({err.strerror})") from err
    if "Sequence" not in parser:
        raise InputError(f"{ini}: missing the [Sequence] section")
    sec = parser["Sequence"]

    def field(key: str, kind: type, default: object = None) -> object:
        if key not in sec:
            if default is not None:
                return default
            raise InputError(f"{ini}: [Sequence] has no {key}=")
        raw = sec[key].strip()
        try:
            value = kind(raw)
        except ValueError as err:
            raise InputError(f"{where(key)}: {key}={raw!r} is not a valid {kind.__name__}") from err
        if kind in (int, float) and not (np.isfinite(float(value)) and value > 0):
            raise InputError(f"{where(key)}: {key}={raw!r} must be positive")
        if kind is int and value > MAX_SEQ_LENGTH:
            raise InputError(f"{where(key)}: {key}={raw} is too large (at most {MAX_SEQ_LENGTH})")
        if key in ("imWidth", "imHeight") and value > MAX_IMAGE_SIDE:
            raise InputError(f"{where(key)}: {key}={raw} is too large (at most {MAX_IMAGE_SIDE})")
        return value

    def where(key: str) -> str:
        return f"{ini}:{_ini_line(ini, key)}" if _ini_line(ini, key) else str(ini)

    im_dir = str(field("imDir", str, "img1")).strip()
    im_ext = str(field("imExt", str, ".jpg")).strip()
    _confine_im_dir(seq_path, im_dir, where("imDir"))
    if not re.fullmatch(r"\.?[A-Za-z0-9]{1,8}", im_ext):
        raise InputError(f"{where('imExt')}: imExt={im_ext!r} is not a file extension like .jpg")
    return SeqInfo(
        # The name names output files (out/<name>.txt): never a path.
        name=safe_name(str(field("name", str, seq_path.name)), seq_path.name),
        length=int(field("seqLength", int)),  # type: ignore[call-overload]
        width=int(field("imWidth", int)),  # type: ignore[call-overload]
        height=int(field("imHeight", int)),  # type: ignore[call-overload]
        fps=float(field("frameRate", float)),  # type: ignore[arg-type]
        im_dir=im_dir,
        im_ext=im_ext,
        path=seq_path,
    )


def _ini_line(ini: Path, key: str) -> int | None:
    """The 1-based line of ``key=`` in an ini file (the last one, as configparser keeps), if any."""
    try:
        lines = ini.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return None
    found = None
    for no, line in enumerate(lines, 1):
        m = re.match(r"\s*([^=:]+?)\s*[=:]", line)
        if m and m.group(1).lower() == key.lower():
            found = no
    return found


def _confine_im_dir(seq_path: Path, im_dir: str, where: str) -> None:
    """Refuse an ``imDir`` that leaves the sequence folder: absolute, with ``..``, or a link out.

    Images are read into the detector and the annotated video: a sequence may only show its own.
    """
    rel = Path(im_dir)
    if not im_dir or rel.is_absolute() or im_dir.startswith(("/", "\\")) or ".." in rel.parts:
        raise InputError(
            f"{where}: imDir={im_dir!r} must be a folder inside the sequence folder "
            "(relative, without '..')"
        )
    target = seq_path / rel
    if target.exists():
        root = seq_path.resolve()
        if not target.resolve().is_relative_to(root):
            raise InputError(
                f"{where}: imDir={im_dir!r} leads out of the sequence folder "
                f"(to {target.resolve()})"
            )


def _locate_bad_line(path: Path, lines: list[str], line_nos: list[int], ncols: int) -> DetFileError:
    """Scan line by line for the first unparsable row (the slow path, only after a failure)."""
    for text, no in zip(lines, line_nos, strict=True):
        fields = text.split(",")
        if len(fields) != ncols:
            return DetFileError(f"{path}:{no}: expected {ncols} columns, found {len(fields)}")
        for col, value in enumerate(fields):
            try:
                float(value)
            except ValueError:
                return DetFileError(
                    f"{path}:{no}: column {col + 1} is not a number: {value.strip()!r}"
                )
    return DetFileError(f"{path}: cannot parse as comma-separated numbers")


def read_mot_rows(
    path: str | os.PathLike[str], *, min_cols: int, what: str = "MOT"
) -> tuple[FloatArray, npt.NDArray[np.int64]]:
    """Parse a MOTChallenge text file into a float64 [K, C] array and the 1-based line of each row.

    Blank lines are skipped. Raises DetFileError naming ``file:line`` for a wrong column count, a
    non-number, NaN/inf, or a frame number that is not a positive integer.
    """
    p = Path(path)
    if not p.is_file():
        raise DetFileError(f"{p}: {what} file not found")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise DetFileError(f"{p}: cannot read {what} file ({err})") from err
    raw_lines = text.splitlines()
    line_nos = [i + 1 for i, line in enumerate(raw_lines) if line.strip()]
    lines = [raw_lines[i - 1].strip().rstrip(",") for i in line_nos]
    if not lines:
        return np.zeros((0, min_cols)), np.zeros(0, np.int64)
    ncols = len(lines[0].split(","))
    if ncols < min_cols:
        raise DetFileError(
            f"{p}:{line_nos[0]}: {what} rows need at least {min_cols} columns, found {ncols}"
        )
    try:
        data = np.loadtxt(lines, delimiter=",", dtype=np.float64, ndmin=2)
    except ValueError:
        raise _locate_bad_line(p, lines, line_nos, ncols) from None
    if data.shape[1] != ncols:  # loadtxt accepts no ragged rows, but be explicit
        raise _locate_bad_line(p, lines, line_nos, ncols)
    nos = np.asarray(line_nos, dtype=np.int64)
    bad = ~np.isfinite(data).all(axis=1)
    if bad.any():
        no = nos[np.argmax(bad)]
        raise DetFileError(f"{p}:{no}: NaN or infinite value")
    boxes = data[:, 2:6]
    bad = (np.abs(boxes) > MAX_BOX_VALUE).any(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise DetFileError(
            f"{p}:{nos[i]}: box value beyond {MAX_BOX_VALUE:g} pixels in magnitude: "
            f"{', '.join(f'{v:g}' for v in boxes[i])}"
        )
    frames = data[:, 0]
    bad = (frames < 1) | (frames != np.round(frames)) | (frames > MAX_SEQ_LENGTH)
    if bad.any():
        i = int(np.argmax(bad))
        raise DetFileError(
            f"{p}:{nos[i]}: frame {frames[i]:g} is not an integer in 1..{MAX_SEQ_LENGTH}"
        )
    return data, nos


MIN_BOX_SIZE = 1e-3  # px: the smallest box side a MOTChallenge file of ours can hold


def _check_sizes(
    path: str | os.PathLike[str], data: FloatArray, nos: npt.NDArray[np.int64]
) -> None:
    # At least the written precision (write_tracks: 3 decimals), so what is read writes back.
    bad = (data[:, 4] < MIN_BOX_SIZE) | (data[:, 5] < MIN_BOX_SIZE)
    if bad.any():
        i = int(np.argmax(bad))
        raise DetFileError(
            f"{path}:{nos[i]}: box width and height must be positive (at least "
            f"{MIN_BOX_SIZE:g} px), got {data[i, 4]:g} x {data[i, 5]:g}"
        )


ScoreMapping = Literal["auto", "minmax", "none"]
SCORE_MAPPINGS: tuple[str, ...] = ("auto", "minmax", "none")


def score_scale(
    scores: npt.ArrayLike, normalize: ScoreMapping = "auto"
) -> tuple[float, float] | None:
    """The ``(lo, hi)`` that :func:`read_detections` maps to ``[0, 1]``, or None for no mapping.

    This is the project's one rule for detection score ranges (the tracker's score thresholds
    are numbers in ``[0, 1]``):

    - ``"auto"`` (default): scores already within ``[0, 1]`` (MOT16/17/20 files, our detectors)
      are kept; any other file (MOT15 holds e.g. -0.7 .. 139) is min-max rescaled per file.
    - ``"minmax"``: always min-max rescale per file.
    - ``"none"``: keep the file's scores as they are.

    Min-max (not a rank/percentile mapping) because it keeps the detector's own spacing of
    confidences: on the MOT15 files the 99th percentile sits at 0.8-0.95 of the maximum, so one
    outlier does not squash the rest, while a rank mapping would force every file to the same
    uniform distribution whatever its detector's quality. A file whose scores are all equal (and
    outside [0, 1]) carries no confidence information and maps to 1.
    """
    if normalize not in SCORE_MAPPINGS:
        raise InputError(f"normalize must be one of {', '.join(SCORE_MAPPINGS)}, got {normalize!r}")
    s = np.asarray(scores, dtype=np.float64)
    if normalize == "none" or s.size == 0:
        return None
    lo, hi = float(s.min()), float(s.max())
    if normalize == "auto" and lo >= 0.0 and hi <= 1.0:
        return None
    return lo, hi


def rescale_scores(scores: npt.ArrayLike, scale: tuple[float, float] | None) -> FloatArray:
    """Apply a :func:`score_scale` result: ``(s - lo) / (hi - lo)``; all ones when ``hi == lo``."""
    s = np.asarray(scores, dtype=np.float64)
    if scale is None:
        return s
    lo, hi = scale
    if hi <= lo:
        return np.ones_like(s)
    return np.clip((s - lo) / (hi - lo), 0.0, 1.0)


def read_detections(
    path: str | os.PathLike[str],
    *,
    min_score: float | None = None,
    normalize: ScoreMapping = "auto",
) -> dict[int, Detections]:
    """Read a det.txt into {frame: Detections}; frames without detections are absent.

    Scores are mapped into ``[0, 1]`` by ``normalize`` (see :func:`score_scale`: by default a
    file already in ``[0, 1]`` is untouched and any other range is min-max rescaled over the whole
    file). ``min_score`` then drops detections scoring below it, in the mapped scale.
    An empty file gives ``{}``.
    """
    data, nos = read_mot_rows(path, min_cols=7, what="detections")
    if len(data) == 0:
        score_scale(data[:, 6], normalize)  # still reject a bad ``normalize``
        return {}
    _check_sizes(path, data, nos)
    bad = np.abs(data[:, 6]) > MAX_SCORE
    if bad.any():
        i = int(np.argmax(bad))
        raise DetFileError(
            f"{path}:{nos[i]}: score {data[i, 6]:g} is beyond {MAX_SCORE:g} in magnitude"
        )
    _check_frame_counts(path, data[:, 0], nos)
    data[:, 6] = rescale_scores(data[:, 6], score_scale(data[:, 6], normalize))
    if min_score is not None:
        data = data[data[:, 6] >= min_score]
    order = np.argsort(data[:, 0], kind="stable")
    data = data[order]
    boxes = np.empty((len(data), 4), np.float32)
    boxes[:, :2] = data[:, 2:4]
    boxes[:, 2:] = data[:, 2:4] + data[:, 4:6]
    scores = data[:, 6].astype(np.float32)
    frames = data[:, 0].astype(np.int64)
    starts = np.flatnonzero(np.r_[True, frames[1:] != frames[:-1]])
    ends = np.r_[starts[1:], len(frames)]
    return {
        int(frames[s]): Detections(boxes[s:e], scores[s:e])
        for s, e in zip(starts, ends, strict=True)
    }


def _check_frame_counts(
    path: str | os.PathLike[str], frames: FloatArray, nos: npt.NDArray[np.int64]
) -> None:
    """DetFileError at the first row past the tracker's bound on detections in one frame."""
    from densepeds._core import MAX_DETECTIONS_PER_FRAME

    if len(frames) <= MAX_DETECTIONS_PER_FRAME:
        return
    uniq, counts = np.unique(frames, return_counts=True)
    if counts.max() <= MAX_DETECTIONS_PER_FRAME:
        return
    frame = uniq[np.argmax(counts)]
    rows = np.flatnonzero(frames == frame)
    raise DetFileError(
        f"{path}:{nos[rows[MAX_DETECTIONS_PER_FRAME]]}: frame {frame:.0f} has {len(rows)} "
        f"detections; at most {MAX_DETECTIONS_PER_FRAME} a frame are tracked"
    )


def read_gt(path: str | os.PathLike[str]) -> FloatArray:
    """Read a gt.txt as float64 [K, C] in the file's own columns (C >= 7; see module docstring)."""
    data, nos = read_mot_rows(path, min_cols=7, what="ground-truth")
    if len(data):
        _check_sizes(path, data, nos)
    return data


def read_tracks(path: str | os.PathLike[str]) -> FloatArray:
    """Read tracker output as float64 [K, 7]: frame, id, x1, y1, x2, y2, score.

    The same layout that :func:`write_tracks` takes, so a round trip is the identity (to the
    written precision). Files with only 6 columns get score 1.
    """
    data, nos = read_mot_rows(path, min_cols=6, what="tracks")
    out = np.zeros((len(data), 7))
    if len(data) == 0:
        return out
    _check_sizes(path, data, nos)
    ids = data[:, 1]
    bad = (ids != np.round(ids)) | (ids < 0) | (ids > MAX_TRACK_ID)
    if bad.any():
        i = int(np.argmax(bad))
        raise DetFileError(
            f"{path}:{nos[i]}: track id {ids[i]:g} is not an integer in 0..{MAX_TRACK_ID}"
        )
    out[:, :2] = data[:, :2]
    out[:, 2:4] = data[:, 2:4]
    out[:, 4:6] = data[:, 2:4] + data[:, 4:6]
    out[:, 6] = data[:, 6] if data.shape[1] > 6 else 1.0
    return out


def _rows_array(rows: Iterable[tuple[float, ...]] | npt.ArrayLike) -> FloatArray:
    arr = np.asarray(rows if isinstance(rows, np.ndarray) else list(rows), dtype=np.float64)  # type: ignore[arg-type]
    if arr.size == 0:
        return np.zeros((0, 7))
    if arr.ndim != 2 or arr.shape[1] != 7:
        raise InputError(
            f"track rows must be (frame, id, x1, y1, x2, y2, score), got shape {arr.shape}"
        )
    if not np.isfinite(arr).all():
        raise InputError("track rows contain NaN or infinite values")
    frames, ids = arr[:, 0], arr[:, 1]
    if ((frames < 1) | (frames != np.round(frames))).any():
        raise InputError("track frames must be integers >= 1")
    if (ids != np.round(ids)).any():
        raise InputError("track ids must be integers")
    if ((arr[:, 4] < arr[:, 2]) | (arr[:, 5] < arr[:, 3])).any():
        raise InputError("track boxes must have x2 >= x1 and y2 >= y1")
    return arr


def write_tracks(
    path: str | os.PathLike[str], rows: Iterable[tuple[float, ...]] | npt.ArrayLike
) -> int:
    """Write tracks in MOTChallenge format, sorted by frame then id. Returns the row count.

    ``rows``: (frame, id, x1, y1, x2, y2, score) tuples or a [K, 7] array. Written through
    :func:`write_text`: complete or not at all, mode following the umask; a failed write raises
    :class:`~densepeds.errors.OutputError`.
    """
    arr = _rows_array(rows)
    arr = arr[np.lexsort((arr[:, 1], arr[:, 0]))]
    lines = [
        f"{int(f)},{int(i)},{x1:.3f},{y1:.3f},{x2 - x1:.3f},{y2 - y1:.3f},{s:.6g},-1,-1,-1\n"
        for f, i, x1, y1, x2, y2, s in arr.tolist()
    ]
    write_text(path, "".join(lines))
    return len(lines)


# --- checked, atomic output files -----------------------------------------------------------------

_TEMP_TAG = "densepeds"


def safe_name(name: str, fallback: str = "output") -> str:
    """``name`` (taken from an input: a sequence name, a file stem) made safe as a file name.

    Anything but letters, digits, ``-``, ``_``, ``.``, ``+`` and spaces becomes ``_`` (so no path
    separator, drive or control character survives), leading dots and spaces are dropped (no
    ``..``, no hidden file), and the result is at most 200 characters; ``fallback`` (made safe
    the same way) when nothing is left.
    """
    cleaned = re.sub(r"[^\w\-+. ]", "_", name, flags=re.ASCII).lstrip(". ").rstrip(" ")[:200]
    if cleaned:
        return cleaned
    return safe_name(fallback) if fallback and fallback != name else "output"


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _os_reason(err: OSError) -> str:
    if err.errno == errno.EFBIG:
        return "file too large (or the file size limit was reached)"
    return err.strerror or type(err).__name__


def _output_error(path: Path, err: OSError) -> OutputError:
    return OutputError(f"{path}: cannot write ({_os_reason(err)})")


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # e.g. EPERM: it exists
        return True
    return True


def _remove_stale_temps(path: Path) -> None:
    """Remove temporaries for ``path`` left by a process that was killed (``kill -9``)."""
    pattern = re.compile(
        rf"\.{re.escape(_temp_stem(path))}\.{_TEMP_TAG}-(\d+)-[0-9a-f]+{re.escape(path.suffix)}"
    )
    try:
        entries = list(path.parent.iterdir())
    except OSError:
        return
    for entry in entries:
        m = pattern.fullmatch(entry.name)
        if m and int(m.group(1)) != os.getpid() and not _pid_alive(int(m.group(1))):
            with contextlib.suppress(OSError):
                entry.unlink()


# Longest file name (bytes) on common file systems (ext4, XFS, APFS, NTFS in UTF-16 units).
_NAME_MAX = 255


def _temp_stem(path: Path) -> str:
    """``path``'s name as its temporaries carry it: shortened so that the temporary's name fits
    :data:`_NAME_MAX` bytes whenever ``path``'s own name does."""
    room = _NAME_MAX - len(f"..{_TEMP_TAG}-{2**32}-{'0' * 8}{path.suffix}".encode())
    return path.name.encode()[: max(room, 1)].decode(errors="ignore")


def reserve_temp(path: str | os.PathLike[str]) -> Path:
    """Create an empty hidden temporary file beside ``path`` and return its name.

    The file is created with mode ``0o666`` less the umask (what ``open()`` gives), so the output
    moved into place by :func:`commit_temp` follows the umask. Its name carries this process's
    id, so that temporaries of a killed process are found and removed by the next call for the
    same ``path``. Raises :class:`OutputError` when the folder cannot be made or written, or
    ``path`` is a folder.
    """
    out = Path(path)
    try:
        if out.is_dir():
            raise OutputError(f"{out}: is a folder, not a file")
        for parent in out.parents:
            if parent.exists():
                if not parent.is_dir():
                    raise OutputError(f"{out}: {parent} is a file, not a folder")
                break
        out.parent.mkdir(parents=True, exist_ok=True)
        _remove_stale_temps(out)
        while True:
            tmp = out.parent / (
                f".{_temp_stem(out)}.{_TEMP_TAG}-{os.getpid()}-{secrets.token_hex(4)}{out.suffix}"
            )
            try:
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
            except FileExistsError:
                continue
            os.close(fd)
            return tmp
    except OSError as err:
        raise _output_error(out, err) from err


def commit_temp(tmp: Path, path: str | os.PathLike[str]) -> None:
    """Move a finished temporary over ``path`` (atomic on one file system)."""
    out = Path(path)
    try:
        os.replace(tmp, out)
    except OSError as err:
        discard_temp(tmp)
        raise _output_error(out, err) from err
    except BaseException:
        discard_temp(tmp)
        raise


def discard_temp(tmp: Path | None) -> None:
    """Remove a temporary (if any); never raises."""
    if tmp is not None:
        with contextlib.suppress(OSError):
            tmp.unlink()


def probe_output(path: str | os.PathLike[str]) -> None:
    """Check, before a long run, that ``path`` can be written (folder made, a file created and
    removed there); raises :class:`OutputError` saying why not."""
    discard_temp(reserve_temp(path))


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary name beside ``path`` to write; it is moved over ``path`` when the block
    ends normally and removed on any exception (interrupts included). An ``OSError`` inside the
    block becomes :class:`OutputError` naming ``path``."""
    out = Path(path)
    tmp = reserve_temp(out)
    try:
        yield tmp
    except OSError as err:
        discard_temp(tmp)
        raise _output_error(out, err) from err
    except BaseException:
        discard_temp(tmp)
        raise
    commit_temp(tmp, out)


def write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` completely or not at all: through a temporary beside it,
    flushed and synced before it is moved into place. Raises :class:`OutputError` on any failed
    write (a full disk, permissions, a path under a file)."""
    with atomic_output(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """:func:`write_bytes` of ``text`` in UTF-8."""
    write_bytes(path, text.encode("utf-8"))
