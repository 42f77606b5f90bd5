"""Putting model files into the user cache: ``fetch`` (download, resumable, sha256-verified) and
``install`` (copy a local file or folder, verified). Behind ``densepeds models fetch|install``.

A download goes to ``<file>.part`` beside its destination; a later ``fetch`` resumes it with an
HTTP Range request (a server that ignores the range sends the whole file again, which is fine).
The file is renamed into place only when its size and sha256 match the pinned ones; a mismatch
deletes the partial file and raises ModelError.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import urllib.error
import urllib.request
from collections.abc import Iterable
from http.client import HTTPException
from pathlib import Path

from densepeds.errors import ModelError
from densepeds.modelfiles import (
    BY_FILE,
    MODELS,
    URL_ENV_VAR,
    ModelInfo,
    cache_dir,
    model_info,
    sha256_of,
)

__all__ = ["fetch", "fetchable", "install", "model_url"]

CHUNK = 1 << 16
TIMEOUT_S = 30.0


def fetchable() -> list[ModelInfo]:
    """Models with a pinned checksum (the ones ``fetch`` can verify)."""
    return [m for m in MODELS.values() if m.sha256 is not None]


def model_url(info: ModelInfo, base_url: str | None = None) -> str:
    """Where ``info`` is downloaded from: ``base_url``/$DENSEPEDS_MODEL_URL + file, else its
    published URL; ModelError (saying why and what to do) where there is none."""
    base = base_url or os.environ.get(URL_ENV_VAR)
    if base:
        return base.rstrip("/") + "/" + info.file
    if info.url:
        return info.url
    raise ModelError(
        f"{info.name}: {info.source}; fetch it from a mirror (`densepeds models fetch "
        f"{info.name} --url BASE`, or set {URL_ENV_VAR}=BASE, to download BASE/{info.file}) or "
        f"install a copy you have (`densepeds models install PATH/TO/{info.file}`)"
    )


def _check(path: Path, info: ModelInfo, origin: str) -> None:
    """ModelError unless ``path`` is exactly the pinned file (no-op for unpinned models)."""
    if info.size is not None:
        size = path.stat().st_size
        if size != info.size:
            raise ModelError(
                f"{origin}: {size} bytes, expected {info.size} for {info.file} (wrong or "
                "truncated file; nothing was installed)"
            )
    if info.sha256 is not None:
        digest = sha256_of(path)
        if digest != info.sha256:
            raise ModelError(
                f"{origin}: sha256 {digest} does not match {info.file}'s pinned {info.sha256} "
                "(corrupt or different file; nothing was installed)"
            )


def _progress(total: int | None, initial: int, desc: str, quiet: bool):  # type: ignore[no-untyped-def]
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        desc=desc,
        unit="B",
        unit_scale=True,
        unit_divisor=1024,
        file=sys.stderr,
        disable=True if quiet else None,  # None: shown on a terminal only
        leave=False,
    )


def fetch(
    name: str,
    *,
    base_url: str | None = None,
    dest_dir: str | os.PathLike[str] | None = None,
    quiet: bool = False,
) -> Path:
    """Download model ``name`` into ``dest_dir`` (default: the user cache) and verify it.

    Returns the installed path. An already installed, verified file is kept as it is.
    """
    info = model_info(name)
    if info.sha256 is None:
        raise ModelError(f"{info.name} has no pinned download: {info.source}")
    dest = Path(dest_dir).expanduser() if dest_dir is not None else cache_dir()
    target = dest / info.file
    if target.is_file():
        try:
            _check(target, info, str(target))
            return target
        except ModelError:
            pass  # replaced below
    url = model_url(info, base_url)
    _make_dir(dest)
    part = target.with_name(target.name + ".part")
    have = part.stat().st_size if part.is_file() else 0
    if info.size is not None and have > info.size:
        part.unlink()
        have = 0
    if info.size is None or have < info.size:
        _download(url, part, have, info, quiet)
    try:
        _check(part, info, url)
    except ModelError:
        part.unlink(missing_ok=True)
        raise
    os.replace(part, target)
    return target


def _download(url: str, part: Path, have: int, info: ModelInfo, quiet: bool) -> None:
    request = urllib.request.Request(url, headers={"User-Agent": "densepeds"})
    if have:
        request.add_header("Range", f"bytes={have}-")
    try:
        response = urllib.request.urlopen(request, timeout=TIMEOUT_S)
    except urllib.error.HTTPError as err:
        if err.code == 416 and have:  # range past the end: what we have may be the whole file
            return
        raise ModelError(f"{url}: HTTP {err.code} {err.reason}") from err
    except (urllib.error.URLError, OSError) as err:
        reason = getattr(err, "reason", err)
        raise ModelError(f"{url}: cannot download ({reason})") from err
    with response:
        if have and response.status != 206:
            have = 0  # the server sent the whole file: start again
        mode = "ab" if have else "wb"
        if not os.access(part.parent, os.W_OK):
            raise ModelError(f"cannot write into the model folder {part.parent}")
        length = response.headers.get("Content-Length")
        total = have + int(length) if length is not None else info.size
        bar = _progress(total, have, info.file, quiet)
        try:
            with part.open(mode) as out:
                while True:
                    block = response.read(CHUNK)
                    if not block:
                        break
                    out.write(block)
                    bar.update(len(block))
        except (OSError, HTTPException) as err:
            raise ModelError(
                f"{url}: download interrupted after {part.stat().st_size} bytes ({err}); run "
                "the same command again to resume"
            ) from err
        finally:
            bar.close()
    got = part.stat().st_size
    if info.size is not None and got < info.size:
        raise ModelError(
            f"{url}: download stopped after {got} of {info.size} bytes; run the same command "
            "again to resume"
        )


def install(
    source: str | os.PathLike[str],
    *,
    dest_dir: str | os.PathLike[str] | None = None,
    names: Iterable[str] | None = None,
) -> list[Path]:
    """Copy model files into ``dest_dir`` (default: the user cache), verified where pinned.

    ``source`` is a model file (recognised by its file name, else by its sha256) or a folder, from
    which every known model file present is installed (``names`` limits which). Returns the
    installed paths; ModelError if a file does not verify or nothing was found.
    """
    src = Path(source).expanduser()
    dest = Path(dest_dir).expanduser() if dest_dir is not None else cache_dir()
    wanted = [model_info(n) for n in names] if names else None
    if src.is_dir():
        candidates = wanted or list(MODELS.values())
        pairs = [(src / m.file, m) for m in candidates if (src / m.file).is_file()]
        if not pairs:
            files = ", ".join(m.file for m in candidates)
            raise ModelError(f"{src}: none of the model files ({files}) is in this folder")
    elif src.is_file():
        info = BY_FILE.get(src.name) or _by_digest(src)
        if info is None:
            known = ", ".join(m.file for m in MODELS.values())
            raise ModelError(
                f"{src}: not a model densepeds knows (neither its name nor its sha256 matches "
                f"{known}); pass it with --detector-model/--reid-model instead"
            )
        pairs = [(src, info)]
    else:
        raise ModelError(f"{src}: no such file or folder")
    installed = []
    _make_dir(dest)
    for path, info in pairs:
        _check(path, info, str(path))
        try:
            installed.append(_copy_into(path, dest / info.file))
        except OSError as err:
            raise ModelError(f"cannot install {path} into {dest}: {err.strerror or err}") from err
    return installed


def _make_dir(dest: Path) -> None:
    try:
        dest.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ModelError(f"cannot create the model folder {dest}: {err.strerror or err}") from err


def _by_digest(path: Path) -> ModelInfo | None:
    digest = sha256_of(path)
    return next((m for m in MODELS.values() if m.sha256 == digest), None)


def _copy_into(src: Path, target: Path) -> Path:
    """Copy atomically (temporary file in the destination folder, then rename)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    if target.exists() and target.resolve() == src.resolve():
        return target
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as out, src.open("rb") as inp:
            shutil.copyfileobj(inp, out)
        os.chmod(tmp, 0o644 & ~_umask())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
