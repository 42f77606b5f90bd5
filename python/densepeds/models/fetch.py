"""Putting model files into the user cache: ``fetch`` (download, resumable, sha256-verified) and
``install`` (copy a local file or folder, verified). Behind ``densepeds models fetch|install``.

Plain :mod:`urllib` rather than a download library (pooch, requests): each rule below is a few
lines here, and pooch has neither HTTP Range resumption nor a cap on what a server sends.

- Sources: a model's published URLs in order (first host, then its mirror), each tried when the
  one before fails; ``--url BASE`` / ``$DENSEPEDS_MODEL_URL`` replace them with ``BASE/<file>``;
  ``$DENSEPEDS_MODEL_HOSTS=BASE`` keeps them but fetches ``https://HOST/PATH`` from
  ``BASE/HOST/PATH`` (a mirror laid out like the hosts).
- Nothing unverified lands in the cache: bytes go to ``<file>.part`` beside the destination and
  are renamed into place only when size and sha256 match the pinned ones.
- Resumable: a connection dropped mid-file keeps ``<file>.part`` and the next attempt (the
  mirror, or the same command again) asks for the rest with an HTTP Range request; a server that
  ignores the range sends the whole file again, which replaces the partial one.
- Capped: no more than the pinned size is ever read. A server announcing another size
  (Content-Length, Content-Range) is refused before its body is read; one sending past the
  pinned size without announcing it is refused after one byte more.
- Redirects: followed (the published hosts redirect to their CDNs) up to ``MAX_REDIRECTS``, to
  http(s) only and never from https down to http.
- One at a time: a fetch locks the destination folder; a second one waits, then finds the file.
"""

from __future__ import annotations

import os
import re
import shutil
import sys
import tempfile
import urllib.error
import urllib.request
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from http.client import HTTPException, HTTPResponse
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from densepeds.errors import ModelError
from densepeds.models.files import (
    BY_FILE,
    DEFAULT_SET,
    HOSTS_ENV_VAR,
    MODELS,
    URL_ENV_VAR,
    ModelInfo,
    cache_dir,
    model_info,
    sha256_of,
)

__all__ = ["default_names", "fetch", "fetchable", "install", "source_urls"]

CHUNK = 1 << 16
TIMEOUT_S = 30.0
MAX_REDIRECTS = 5
SCHEMES = ("http", "https")


def fetchable() -> list[ModelInfo]:
    """Models with a pinned checksum (the ones ``fetch`` can verify)."""
    return [m for m in MODELS.values() if m.sha256 is not None]


def default_names() -> list[str]:
    """What ``densepeds models fetch`` gets with no names (modelfiles.DEFAULT_SET)."""
    return list(DEFAULT_SET)


def source_urls(info: ModelInfo, base_url: str | None = None) -> list[str]:
    """Where ``info`` is downloaded from, in order: ``base_url``/$DENSEPEDS_MODEL_URL + file,
    else its published URLs (on the hosts of $DENSEPEDS_MODEL_HOSTS where set); ModelError
    (saying why and what to do) where there is none."""
    base = base_url or os.environ.get(URL_ENV_VAR)
    if base:
        urls = [base.rstrip("/") + "/" + info.file]
    elif info.urls:
        hosts = os.environ.get(HOSTS_ENV_VAR)
        urls = [_rehost(u, hosts) for u in info.urls] if hosts else list(info.urls)
    else:
        raise ModelError(
            f"{info.name}: {info.source}; fetch it from a mirror (`densepeds models fetch "
            f"{info.name} --url BASE`, or set {URL_ENV_VAR}=BASE, to download BASE/{info.file}) "
            f"or install a copy you have (`densepeds models install PATH/TO/{info.file}`)"
        )
    for url in urls:
        if urlsplit(url).scheme not in SCHEMES:
            raise ModelError(
                f"{url}: only http and https downloads are supported (for a local copy use "
                "`densepeds models install FILE`)"
            )
    return urls


def _rehost(url: str, base: str) -> str:
    parts = urlsplit(url)
    return f"{base.rstrip('/')}/{parts.netloc}{parts.path}"


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

    Returns the installed path. An already installed, verified file is kept as it is. Each
    source is tried in turn; ModelError (every source's reason) when none gives the pinned file.
    """
    info = model_info(name)
    if info.sha256 is None or info.size is None:
        raise ModelError(f"{info.name} has no pinned download: {info.source}")
    dest = Path(dest_dir).expanduser() if dest_dir is not None else cache_dir()
    target = dest / info.file
    if _verified(target, info):
        return target
    urls = source_urls(info, base_url)
    make_dir(dest)
    with _folder_lock(dest):  # one download at a time into a folder: no interleaved .part
        if _verified(target, info):  # another fetch got it while this one waited
            return target
        part = target.with_name(target.name + ".part")
        failures: list[str] = []
        for url in urls:
            try:
                _fetch_from(url, part, info, quiet)
            except ModelError as err:
                failures.append(str(err))
                continue
            os.replace(part, target)
            return target
    if len(failures) == 1:
        raise ModelError(failures[0])
    raise ModelError(f"{info.file}: no source gave the pinned file ({'; '.join(failures)})")


def _verified(target: Path, info: ModelInfo) -> bool:
    """``target`` is there and is the pinned file (one that is not is replaced by the fetch)."""
    if not target.is_file():
        return False
    try:
        _check(target, info, str(target))
    except ModelError:
        return False
    return True


@contextmanager
def _folder_lock(folder: Path) -> Iterator[None]:
    """An exclusive lock on ``folder`` (flock on the folder itself: no lock file is left); a
    second fetch into it waits, then finds the verified file. No-op where flock is missing."""
    try:
        import fcntl
    except ImportError:  # not POSIX
        yield
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _fetch_from(url: str, part: Path, info: ModelInfo, quiet: bool) -> None:
    """``part`` completed from ``url`` and verified; ModelError otherwise (the partial file
    kept only where the connection dropped, for a resume)."""
    assert info.size is not None
    have = part.stat().st_size if part.is_file() else 0
    if have > info.size:
        part.unlink()
        have = 0
    if have < info.size:
        _download(url, part, have, info, quiet)
    try:
        _check(part, info, url)
    except ModelError:
        part.unlink(missing_ok=True)
        if have == 0:
            raise
        # The bytes kept from an earlier attempt may be another file's: once more from scratch.
        _download(url, part, 0, info, quiet)
        try:
            _check(part, info, url)
        except ModelError:
            part.unlink(missing_ok=True)
            raise


class _Redirects(urllib.request.HTTPRedirectHandler):
    """Redirects to http(s) only, never from https down to http, at most MAX_REDIRECTS."""

    max_redirections = MAX_REDIRECTS

    def redirect_request(  # type: ignore[override]
        self, req: urllib.request.Request, fp: Any, code: int, msg: str, headers: Any, newurl: str
    ) -> urllib.request.Request | None:
        old, new = urlsplit(req.full_url).scheme, urlsplit(newurl).scheme
        if new not in SCHEMES:
            raise ModelError(f"{req.full_url}: redirected to {newurl}, not an http(s) URL; refused")
        if old == "https" and new != "https":
            raise ModelError(
                f"{req.full_url}: redirected from https to {newurl} (unencrypted); refused"
            )
        return super().redirect_request(req, fp, code, msg, headers, newurl)


def _open(url: str, have: int) -> HTTPResponse:
    request = urllib.request.Request(url, headers={"User-Agent": "densepeds"})
    if have:
        request.add_header("Range", f"bytes={have}-")
    opener = urllib.request.build_opener(_Redirects())
    response: HTTPResponse = opener.open(request, timeout=TIMEOUT_S)
    return response


CONTENT_RANGE = re.compile(r"bytes (\d+)-(\d+)/(\d+|\*)")


def _download(url: str, part: Path, have: int, info: ModelInfo, quiet: bool) -> None:
    """Append the rest of the file (from byte ``have``) to ``part``, reading no more than the
    pinned size."""
    assert info.size is not None
    try:
        response = _open(url, have)
    except urllib.error.HTTPError as err:
        if err.code == 416 and have:  # range past the end: what we have may be the whole file
            return
        raise ModelError(f"{url}: HTTP {err.code} {err.reason}") from err
    except (urllib.error.URLError, OSError, HTTPException) as err:
        reason = getattr(err, "reason", err)
        raise ModelError(f"{url}: cannot download ({reason})") from err
    with response:
        start = _start_of(response, url, have, info)
        length_header = response.headers.get("Content-Length")
        length = int(length_header) if length_header and length_header.isdigit() else None
        if length is not None and start + length != info.size:
            part.unlink(missing_ok=True)
            raise ModelError(
                f"{url}: the server's file is {start + length} bytes, not the {info.size} of "
                f"{info.file} (wrong, truncated or oversized file; refused before reading it)"
            )
        if not os.access(part.parent, os.W_OK):
            raise ModelError(f"cannot write into the model folder {part.parent}")
        want = info.size - start
        bar = _progress(info.size, start, info.file, quiet)
        got = 0
        try:
            with part.open("ab" if start else "wb") as out:
                while got < want:
                    block = response.read(min(CHUNK, want - got))
                    if not block:
                        break
                    out.write(block)
                    got += len(block)
                    bar.update(len(block))
                extra = response.read(1) if got == want else b""
        except (OSError, HTTPException) as err:
            raise ModelError(
                f"{url}: download interrupted after {start + got} bytes ({err}); run "
                "the same command again to resume"
            ) from err
        finally:
            bar.close()
    if extra:
        part.unlink(missing_ok=True)
        raise ModelError(
            f"{url}: the server sends more than the {info.size} bytes of {info.file} (wrong or "
            "oversized file; stopped reading, nothing was kept)"
        )
    if got < want:
        raise ModelError(
            f"{url}: download stopped after {start + got} of {info.size} bytes; run the same "
            "command again to resume"
        )


def _start_of(response: HTTPResponse, url: str, have: int, info: ModelInfo) -> int:
    """The byte offset the response's body starts at: ``have`` for a partial response that
    continues the file, 0 for a whole one; ModelError for a partial one that does not fit."""
    if response.status != 206:
        return 0
    m = CONTENT_RANGE.fullmatch((response.headers.get("Content-Range") or "").strip())
    if m is None or int(m.group(1)) != have:
        raise ModelError(
            f"{url}: the server answered the range request from byte {have} with "
            f"{response.headers.get('Content-Range')!r}; refused"
        )
    if m.group(3) != "*" and int(m.group(3)) != info.size:
        raise ModelError(
            f"{url}: the server's file is {m.group(3)} bytes, not the {info.size} of "
            f"{info.file} (wrong or oversized file; refused before reading it)"
        )
    return have


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
    make_dir(dest)
    for path, info in pairs:
        _check(path, info, str(path))
        try:
            installed.append(copy_into(path, dest / info.file))
        except OSError as err:
            raise ModelError(f"cannot install {path} into {dest}: {err.strerror or err}") from err
    return installed


def make_dir(dest: Path) -> None:
    try:
        dest.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ModelError(f"cannot create the model folder {dest}: {err.strerror or err}") from err


def _by_digest(path: Path) -> ModelInfo | None:
    digest = sha256_of(path)
    return next((m for m in MODELS.values() if m.sha256 == digest), None)


def copy_into(src: Path, target: Path) -> Path:
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
