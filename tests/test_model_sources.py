"""`densepeds models fetch` with no options, from local servers laid out like the published
hosts ($DENSEPEDS_MODEL_HOSTS): the default set, the mirror after a failing first host, the
download cap, redirects, and nothing unverified in the cache. The real files are not here: the
default set's pins are replaced by those of generated graphs with the same contracts
(tests/contract_models.py), everything else (names, URLs, layout) is the published one."""

from __future__ import annotations

import dataclasses
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from contract_models import youtu_reid, zoo_maskrcnn
from densepeds.cli import main
from densepeds.errors import ModelError
from densepeds.models import fetch as modelfetch
from densepeds.models.files import (
    BY_FILE,
    DEFAULT_SET,
    ENV_VAR,
    HOSTS_ENV_VAR,
    MODELS,
    URL_ENV_VAR,
    ModelInfo,
    sha256_of,
)
from modelserver import serve

PUBLISHED = {  # the pins from the published Git LFS pointers (issue 39)
    "maskrcnn-zoo-int8": (
        "4409935e855719fd6cd986f7ec2a3de840d0bd9c9cf7a0cba84ce95377f5b476",
        45769352,
    ),
    "maskrcnn-zoo": ("5bf940c124d9117f6fae350c4e0d46df180cbb01981832b35fdbed148078b946", 177970010),
    "youtureid-int8": (
        "4757c4cb759b79030a9870abf29c064c2ee51e079a05700690800c81b16cf245",
        26763574,
    ),
    "youtureid": ("0579683334d4b9440221606dcb461656dd0dc64143b18f48faedaced9b4f580d", 106878407),
}


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    for var in (ENV_VAR, URL_ENV_VAR, HOSTS_ENV_VAR):
        monkeypatch.delenv(var, raising=False)
    return tmp_path / "xdg" / "densepeds" / "models"


@pytest.fixture
def graphs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, Path]:
    """Stand-ins for the default set, pinned in place of the real files."""
    made = tmp_path / "made"
    made.mkdir()
    files = {
        "maskrcnn-zoo-int8": zoo_maskrcnn(made / "zoo.onnx"),
        "youtureid-int8": youtu_reid(made / "youtu.onnx"),
    }
    for name, path in files.items():
        _pin(monkeypatch, name, path)
    return files


def _pin(monkeypatch: pytest.MonkeyPatch, name: str, path: Path) -> ModelInfo:
    info = dataclasses.replace(MODELS[name], sha256=sha256_of(path), size=path.stat().st_size)
    monkeypatch.setitem(MODELS, name, info)
    monkeypatch.setitem(BY_FILE, info.file, info)
    return info


def _lay_out(root: Path, name: str, data: bytes, which: tuple[int, ...] = (0, 1)) -> None:
    """``data`` at the published URLs' paths (host/path) of the sources numbered ``which``."""
    for k in which:
        parts = urlsplit(MODELS[name].urls[k])
        target = root / parts.netloc / parts.path.lstrip("/")
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)


def _rel(name: str, k: int) -> str:
    parts = urlsplit(MODELS[name].urls[k])
    return f"/{parts.netloc}{parts.path}"


@pytest.fixture
def hosts(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[Path, str]]:
    root = tmp_path / "hosts"
    root.mkdir()
    yield root, HOSTS_ENV_VAR


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def _leftovers(cache: Path) -> list[str]:
    return sorted(p.name for p in cache.iterdir()) if cache.is_dir() else []


def test_published_pins_and_sources() -> None:
    for name, (sha, size) in PUBLISHED.items():
        info = MODELS[name]
        assert (info.sha256, info.size) == (sha, size)
        assert len(info.urls) == 2 and all(u.startswith("https://") for u in info.urls)
        assert all(u.endswith("/" + info.file) for u in info.urls)
    zoo = "validated/vision/object_detection_segmentation/mask-rcnn/model/MaskRCNN-12-int8.onnx"
    assert MODELS["maskrcnn-zoo-int8"].urls == (
        f"https://huggingface.co/onnxmodelzoo/legacy_models/resolve/main/{zoo}",
        f"https://media.githubusercontent.com/media/onnx/models/main/{zoo}",
    )
    reid = "models/person_reid_youtureid/person_reid_youtu_2021nov_int8.onnx"
    assert MODELS["youtureid-int8"].urls == (
        f"https://media.githubusercontent.com/media/opencv/opencv_zoo/main/{reid}",
        f"https://huggingface.co/opencv/opencv_zoo/resolve/main/{reid}",
    )
    assert DEFAULT_SET == ("maskrcnn-zoo-int8", "youtureid-int8")


def test_fetch_with_no_options_gets_the_default_set(
    cache: Path,
    graphs: dict[str, Path],
    hosts: tuple[Path, str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    root, var = hosts
    for name, path in graphs.items():
        _lay_out(root, name, path.read_bytes(), which=(0,))
    paths: list[str] = []
    with serve(root, paths=paths) as (base, _):
        monkeypatch.setenv(var, base)
        rc, out, err = _run(capsys, "models", "fetch", "-q")
    assert rc == 0, err
    assert paths == [_rel(n, 0) for n in DEFAULT_SET]  # first hosts only, one request each
    for name, path in graphs.items():
        assert sha256_of(cache / MODELS[name].file) == sha256_of(path)
    assert _leftovers(cache) == sorted(MODELS[n].file for n in DEFAULT_SET)


@pytest.mark.parametrize("first", ["missing", "corrupt", "truncated", "oversized"])
def test_the_mirror_after_a_failing_first_host(
    first: str,
    cache: Path,
    graphs: dict[str, Path],
    hosts: tuple[Path, str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    root, var = hosts
    name = "youtureid-int8"
    good = graphs[name].read_bytes()
    _lay_out(root, name, good, which=(1,))
    bad = {
        "missing": None,
        "corrupt": good[:100] + bytes([good[100] ^ 0xFF]) + good[101:],
        "truncated": good[:-10],
        "oversized": good + b"\0" * 4096,
    }[first]
    if bad is not None:
        _lay_out(root, name, bad, which=(0,))
    paths: list[str] = []
    with serve(root, paths=paths) as (base, _):
        monkeypatch.setenv(var, base)
        rc, out, err = _run(capsys, "models", "fetch", name, "-q")
    assert rc == 0, err
    assert paths == [_rel(name, 0), _rel(name, 1)]
    assert (cache / MODELS[name].file).read_bytes() == good
    assert _leftovers(cache) == [MODELS[name].file]


def test_every_source_failing_is_one_line_and_leaves_nothing(
    cache: Path,
    graphs: dict[str, Path],
    hosts: tuple[Path, str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    root, var = hosts
    name = "maskrcnn-zoo-int8"
    good = graphs[name].read_bytes()
    _lay_out(root, name, good[:-1] + bytes([good[-1] ^ 1]), which=(0,))  # corrupt
    with serve(root) as (base, _):  # and nothing on the mirror
        monkeypatch.setenv(var, base)
        rc, _, err = _run(capsys, "models", "fetch", name, "-q")
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert "no source gave the pinned file" in err and "does not match" in err and "404" in err
    assert _leftovers(cache) == []


def test_a_server_announcing_too_much_is_refused_before_reading(
    cache: Path, graphs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    name = "youtureid-int8"
    file = MODELS[name].file
    with serve(tmp_path, special={f"/{file}": ("announce", 64 << 20)}) as (base, _):
        rc, _, err = _run(capsys, "models", "fetch", name, "--url", base, "-q")
    assert rc == 2 and "refused before reading" in err and str(64 << 20) in err, err
    assert _leftovers(cache) == []


def test_a_server_streaming_past_the_size_is_cut_off(
    cache: Path, graphs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """No Content-Length: the download stops one byte past the pinned size (issue 40: 64 MiB
    were read for an 891,579-byte model)."""
    name = "youtureid-int8"
    file = MODELS[name].file
    sent: dict[str, int] = {}
    stream = 64 << 20
    with serve(tmp_path, special={f"/{file}": ("stream", stream)}, sent=sent) as (base, _):
        rc, _, err = _run(capsys, "models", "fetch", name, "--url", base, "-q")
    assert rc == 2 and "sends more than" in err, err
    assert _leftovers(cache) == []
    # What the server got into the socket before the client hung up: the pinned size plus
    # what the kernel buffers, far from the 64 MiB offered.
    assert sent[f"/{file}"] < stream // 2


def test_redirects_followed_to_the_file(
    cache: Path, graphs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    name = "youtureid-int8"
    file = MODELS[name].file
    (tmp_path / "cdn").mkdir()
    (tmp_path / "cdn" / file).write_bytes(graphs[name].read_bytes())
    special = {f"/{file}": ("redirect", f"/cdn/{file}")}
    with serve(tmp_path, special=special) as (base, _):
        rc, _, err = _run(capsys, "models", "fetch", name, "--url", base, "-q")
    assert rc == 0, err
    assert _leftovers(cache) == [file]


@pytest.mark.parametrize("where", ["wrong file", "loop", "file scheme", "ftp scheme"])
def test_bad_redirects_are_refused(
    where: str,
    cache: Path,
    graphs: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    name = "youtureid-int8"
    file = MODELS[name].file
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / file).write_bytes(b"\0" * graphs[name].stat().st_size)
    location = {
        "wrong file": f"/other/{file}",
        "loop": f"/{file}",
        "file scheme": f"file://{graphs[name]}",
        "ftp scheme": f"ftp://127.0.0.1/{file}",
    }[where]
    with serve(tmp_path, special={f"/{file}": ("redirect", location)}) as (base, _):
        rc, _, err = _run(capsys, "models", "fetch", name, "--url", base, "-q")
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert _leftovers(cache) == []


def test_no_redirect_from_https_down_to_http() -> None:
    handler = modelfetch._Redirects()
    request = urllib.request.Request("https://huggingface.co/x.onnx")
    with pytest.raises(ModelError, match="from https"):
        handler.redirect_request(request, None, 302, "Found", {}, "http://cdn.example/x.onnx")
    upgraded = handler.redirect_request(
        urllib.request.Request("http://a.example/x"), None, 302, "Found", {}, "https://b/x"
    )
    assert upgraded is not None and upgraded.full_url == "https://b/x"


def test_hosts_base_replaces_each_host(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(URL_ENV_VAR, raising=False)
    monkeypatch.setenv(HOSTS_ENV_VAR, "http://127.0.0.1:9/mirror/")
    info = MODELS["maskrcnn-zoo"]
    assert modelfetch.source_urls(info) == [
        "http://127.0.0.1:9/mirror/" + u.removeprefix("https://") for u in info.urls
    ]
    monkeypatch.setenv(URL_ENV_VAR, "http://127.0.0.1:9/flat")
    assert modelfetch.source_urls(info) == ["http://127.0.0.1:9/flat/MaskRCNN-12.onnx"]
    with pytest.raises(ModelError, match="only http and https"):
        modelfetch.source_urls(info, "file:///tmp")


def test_concurrent_fetches_download_once(
    cache: Path, graphs: dict[str, Path], tmp_path: Path
) -> None:
    """Two fetches of one model at once: the second waits for the first and finds the verified
    file, instead of both writing into one partial file."""
    import threading

    name = "youtureid-int8"
    file = MODELS[name].file
    (tmp_path / file).write_bytes(graphs[name].read_bytes())
    paths: list[str] = []
    errors: list[BaseException] = []
    with serve(tmp_path, special={f"/{file}": ("slow", 0.5)}, paths=paths) as (base, _):

        def one() -> None:
            try:
                modelfetch.fetch(name, base_url=base, quiet=True)
            except BaseException as err:  # noqa: BLE001
                errors.append(err)

        threads = [threading.Thread(target=one) for _ in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    assert not errors and paths == [f"/{file}"]
    assert _leftovers(cache) == [file]
