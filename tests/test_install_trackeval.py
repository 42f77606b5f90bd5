"""densepeds.install_trackeval: TrackEval's wheel re-labelled to require opencv-python-headless
(so that pip check stays clean), tested on a wheel made here (no download)."""

from __future__ import annotations

import base64
import hashlib
import subprocess
import sys
import zipfile
from importlib.metadata import distributions
from pathlib import Path

import pytest
from densepeds.errors import InputError
from densepeds.install_trackeval import headless_wheel

METADATA = """Metadata-Version: 2.4
Name: trackeval
Version: 1.3.0
Requires-Dist: numpy>=2.2.6; python_version == "3.10"
Requires-Dist: opencv-python>=4.11.0.86
Requires-Dist: opencv-python-rolling>=1; extra == "x"
Requires-Dist: tabulate>=0.9.0

TrackEval.
"""


def _wheel(tmp: Path, metadata: str = METADATA) -> Path:
    info = "trackeval-1.3.0.dist-info/"
    files = {
        "trackeval/__init__.py": b"VALUE = 42\n",
        info + "METADATA": metadata.encode(),
        info + "WHEEL": b"Wheel-Version: 1.0\nRoot-Is-Purelib: true\nTag: py3-none-any\n",
    }
    record = "".join(f"{p},{_hash(d)},{len(d)}\n" for p, d in files.items()) + info + "RECORD,,\n"
    files[info + "RECORD"] = record.encode()
    path = tmp / "trackeval-1.3.0-py3-none-any.whl"
    with zipfile.ZipFile(path, "w") as z:
        for p, d in files.items():
            z.writestr(p, d)
    return path


def _hash(data: bytes) -> str:
    return "sha256=" + base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()


def test_the_wheel_requires_the_headless_opencv_and_installs(tmp_path: Path) -> None:
    out = headless_wheel(_wheel(tmp_path), tmp_path)
    assert out.name == "trackeval-1.3.0+headless-py3-none-any.whl"
    info = "trackeval-1.3.0+headless.dist-info/"
    with zipfile.ZipFile(out) as z:
        names = set(z.namelist())
        assert names == {
            "trackeval/__init__.py",
            info + "METADATA",
            info + "WHEEL",
            info + "RECORD",
        }
        # every RECORD row's hash and size, recomputed
        rows = [line.split(",") for line in z.read(info + "RECORD").decode().splitlines()]
        assert {r[0] for r in rows} == names
        for path, digest, size in rows:
            if path != info + "RECORD":
                data = z.read(path)
                assert (digest, size) == (_hash(data), str(len(data))), path
    # pip installs it, and the installed metadata says what pip check will read
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-index"]
        + ["--target", str(target), str(out)],
        check=True,
    )
    (dist,) = [d for d in distributions(path=[str(target)]) if d.metadata["Name"] == "trackeval"]
    assert dist.version == "1.3.0+headless"
    assert dist.requires == [
        'numpy>=2.2.6; python_version == "3.10"',
        "opencv-python-headless>=4.11.0.86",
        'opencv-python-rolling>=1; extra == "x"',
        "tabulate>=0.9.0",
    ]
    assert (target / "trackeval" / "__init__.py").read_text() == "VALUE = 42\n"


def test_a_wheel_without_the_requirement_is_refused(tmp_path: Path) -> None:
    wheel = _wheel(tmp_path, METADATA.replace("opencv-python>=4.11.0.86", "scipy"))
    with pytest.raises(InputError, match="requires no opencv-python"):
        headless_wheel(wheel, tmp_path / "out")
