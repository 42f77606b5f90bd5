"""`densepeds models`: the listing, `fetch` from a mirror on 127.0.0.1 (pinned, verified,
resumable) and `install` of local copies; and the missing-model error naming the command."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from conftest import shared_path
from densepeds.cli import main
from densepeds.errors import ModelError
from densepeds.models import fetch as modelfetch
from densepeds.models.files import ENV_VAR, MODELS, URL_ENV_VAR, cache_dir, find_model, sha256_of
from modelserver import serve

OSNET = MODELS["osnet"]
YOLO = MODELS["yoloseg"]


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty user cache (XDG_CACHE_HOME) and no model dir or mirror from the environment."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.delenv(ENV_VAR, raising=False)
    monkeypatch.delenv(URL_ENV_VAR, raising=False)
    return tmp_path / "xdg" / "densepeds" / "models"


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def test_pinned_checksums_are_the_shared_files() -> None:
    for info in (YOLO, OSNET):
        path = shared_path("models", info.file)
        assert path.stat().st_size == info.size
        assert sha256_of(path) == info.sha256


def test_listing_shows_contracts_and_what_was_found(
    cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc, out, _ = _run(capsys, "models")
    assert rc == 0
    for info in MODELS.values():
        assert info.file in out and info.licence in out and info.contract in out
        assert info.source in out and info.role in out
        assert all(url in out for url in info.urls)
    assert f"sha256: {OSNET.sha256}" in out and f"{OSNET.size} bytes" in out
    assert "45.8 MB, 45769352 bytes" in out  # the default detector's download
    assert str(cache) in out and "found: no" in out
    assert "no published ONNX" in out  # neither shipped model has a published ONNX URL
    assert "AGPL-3.0 (Ultralytics" in out
    assert "`densepeds models fetch` gets maskrcnn-zoo-int8 + youtureid-int8 (72.5 MB)" in out
    assert "`densepeds run` uses now: detector maskrcnn (MaskRCNN-12-int8.onnx)" in out
    cache.mkdir(parents=True)
    shutil.copy(shared_path("models", OSNET.file), cache / OSNET.file)
    rc, out, _ = _run(capsys, "models", "list")
    assert f"found: {cache / OSNET.file}" in out


def test_missing_model_error_names_the_command(
    cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.raises(ModelError) as err:
        find_model(OSNET.file)
    message = str(err.value)
    assert str(cache) in message
    assert f"densepeds models install PATH/TO/{OSNET.file}" in message
    assert "densepeds models fetch osnet --url MIRROR" in message
    assert "no published ONNX" in message
    monkeypatch.setenv(URL_ENV_VAR, "http://127.0.0.1:9")
    with pytest.raises(ModelError, match="run `densepeds models fetch osnet`"):
        find_model(OSNET.file)
    with pytest.raises(ModelError, match="export_maskrcnn.py"):
        find_model("maskrcnn_resnet50_fpn.onnx")


def test_fetch_without_a_url_says_why(cache: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc, _, err = _run(capsys, "models", "fetch", "osnet")
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert "no published ONNX" in err and "--url" in err and "models install" in err
    assert not cache.exists() or not any(cache.iterdir())


def test_fetch_from_a_mirror_then_find(cache: Path, capsys: pytest.CaptureFixture[str]) -> None:
    models = shared_path("models")
    with serve(models) as (base, ranges):
        rc, out, _ = _run(capsys, "models", "fetch", "yoloseg", "osnet", "--url", base, "-q")
        assert rc == 0, out
        assert ranges == [None, None]  # one whole download per model
        for info in (YOLO, OSNET):
            assert f"{cache / info.file} (sha256 verified)" in out
            assert sha256_of(cache / info.file) == info.sha256
        assert find_model(OSNET.file) == cache / OSNET.file
        # Already there and verified: nothing is downloaded again.
        rc, _, _ = _run(capsys, "models", "fetch", "osnet", "--url", base)
        assert rc == 0 and len(ranges) == 2
    assert not list(cache.glob("*.part"))


def test_fetch_honours_the_mirror_env_var(
    cache: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    with serve(shared_path("models")) as (base, _):
        monkeypatch.setenv(URL_ENV_VAR, base + "/")
        rc, out, _ = _run(capsys, "models", "fetch", OSNET.file, "-q")
    assert rc == 0 and (cache / OSNET.file).is_file(), out


def test_corrupted_download_is_refused(
    cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    data = bytearray(shared_path("models", OSNET.file).read_bytes())
    data[len(data) // 2] ^= 0xFF  # same size, one byte flipped
    (mirror / OSNET.file).write_bytes(bytes(data))
    with serve(mirror) as (base, _):
        rc, _, err = _run(capsys, "models", "fetch", "osnet", "--url", base, "-q")
    assert rc == 2 and "sha256" in err and "does not match" in err
    assert not (cache / OSNET.file).exists()
    assert not list(cache.glob("*.part"))  # the bad bytes are not kept for a resume
    (mirror / OSNET.file).write_bytes(bytes(data[:1000]))  # truncated
    with serve(mirror) as (base, _):
        rc, _, err = _run(capsys, "models", "fetch", "osnet", "--url", base, "-q")
    assert rc == 2 and "file is 1000 bytes" in err and not (cache / OSNET.file).exists()
    assert not list(cache.glob("*.part"))


def test_interrupted_download_resumes_with_a_range_request(
    cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cut = 300_000
    with serve(shared_path("models"), cut_after=cut) as (base, ranges):
        rc, _, err = _run(capsys, "models", "fetch", "osnet", "--url", base, "-q")
        assert rc == 2 and "run the same command again to resume" in err, err
        part = cache / (OSNET.file + ".part")
        assert part.stat().st_size == cut and not (cache / OSNET.file).exists()
        rc, out, _ = _run(capsys, "models", "fetch", "osnet", "--url", base, "-q")
        assert rc == 0, out
        assert ranges == [None, f"bytes={cut}-"]
    assert sha256_of(cache / OSNET.file) == OSNET.sha256 and not part.exists()


def test_fetch_restarts_when_the_server_ignores_the_range(cache: Path, tmp_path: Path) -> None:
    """A stale partial file and a plain http.server (no Range support: 200, whole file)."""
    import functools
    import http.server
    import threading

    cache.mkdir(parents=True)
    (cache / (OSNET.file + ".part")).write_bytes(b"garbage" * 100)
    handler = functools.partial(
        http.server.SimpleHTTPRequestHandler, directory=str(shared_path("models"))
    )
    handler.log_message = lambda *a: None  # type: ignore[attr-defined]
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        path = modelfetch.fetch(
            "osnet", base_url=f"http://127.0.0.1:{server.server_address[1]}", quiet=True
        )
    finally:
        server.shutdown()
        server.server_close()
    assert sha256_of(path) == OSNET.sha256


def test_install_file_and_folder(
    cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    models = shared_path("models")
    renamed = tmp_path / "reid.onnx"  # recognised by its sha256 whatever its name
    shutil.copy(models / OSNET.file, renamed)
    rc, out, _ = _run(capsys, "models", "install", str(renamed))
    assert rc == 0 and str(cache / OSNET.file) in out
    assert sha256_of(cache / OSNET.file) == OSNET.sha256
    rc, out, _ = _run(capsys, "models", "install", str(models))
    assert rc == 0 and str(cache / YOLO.file) in out
    assert find_model(YOLO.file) == cache / YOLO.file
    assert (cache / YOLO.file).stat().st_mode & 0o777 == 0o644 & ~_umask()


def test_install_refuses_wrong_files(
    cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / OSNET.file
    data = bytearray(shared_path("models", OSNET.file).read_bytes())
    data[-1] ^= 1
    bad.write_bytes(bytes(data))
    rc, _, err = _run(capsys, "models", "install", str(bad))
    assert rc == 2 and "does not match" in err and not (cache / OSNET.file).exists()
    other = tmp_path / "mine.onnx"
    other.write_bytes(b"not a model we know")
    rc, _, err = _run(capsys, "models", "install", str(other))
    assert rc == 2 and "not a model densepeds knows" in err
    rc, _, err = _run(capsys, "models", "install", str(tmp_path / "empty"))
    assert rc == 2 and "no such file" in err
    (tmp_path / "empty").mkdir()
    rc, _, err = _run(capsys, "models", "install", str(tmp_path / "empty"))
    assert rc == 2 and "none of the model files" in err


def test_cache_follows_xdg(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert cache_dir() == tmp_path / "densepeds" / "models"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert cache_dir() == Path("~/.cache/densepeds/models").expanduser()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def test_run_without_models_names_the_command(
    cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """With no model anywhere, run asks for the default set's detector and says how to get it."""
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    rc, _, err = _run(capsys, "run", str(video), "--frames", "1:2")
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert "model MaskRCNN-12-int8.onnx not found" in err and str(cache) in err
    assert "run `densepeds models fetch` (downloads maskrcnn-zoo-int8, youtureid-int8" in err
    rc, _, err = _run(capsys, "run", str(video), "--frames", "1:2", "--detector", "yoloseg")
    assert rc == 2 and f"densepeds models install PATH/TO/{YOLO.file}" in err


def test_unwritable_destination_is_one_line(
    cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "file"
    blocker.write_bytes(b"x")  # a file where the folder would go: mkdir fails for anyone
    rc, _, err = _run(
        capsys,
        "models",
        "install",
        str(shared_path("models", OSNET.file)),
        "--dir",
        str(blocker / "models"),
    )
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "cannot create" in err, err
