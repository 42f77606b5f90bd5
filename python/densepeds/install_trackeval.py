"""Install TrackEval (the scorer behind ``densepeds eval``) so that ``pip check`` stays clean.

    python -m densepeds.install_trackeval

TrackEval's wheels declare ``opencv-python``: a second OpenCV beside the
``opencv-python-headless`` that DensePeds depends on (both install the same ``cv2`` module, the
later overwriting the other). Installed with ``--no-deps`` it leaves a requirement that ``pip
check`` (and every later ``pip install``) reports for good. Here the pinned wheel is downloaded
by pip (its sha256 checked), its metadata rewritten to require ``opencv-python-headless``
instead -- the same ``cv2`` module, which TrackEval imports -- under the local version
``1.3.0+headless`` (so it is not taken for the published file), and installed by pip with its
other declared dependencies. Nothing else in the wheel changes.
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import re
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Sequence
from pathlib import Path

from densepeds.errors import InputError

__all__ = ["LOCAL", "PIN", "headless_wheel", "main"]

PIN = "trackeval==1.3.0"
SHA256 = "bf5ed90f7b5a3eafc6dcfce36fb900259a587e8f3b2438ef23d72e7d4ab94efb"
LOCAL = "headless"
_REQUIREMENT = re.compile(r"^(Requires-Dist:\s*)opencv-python(?=$|[\s<>=!~;\[(])", re.M)


def _record_hash(data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=")
    return f"sha256={digest.decode()}"


def headless_wheel(wheel: Path, out_dir: Path) -> Path:
    """A copy of ``wheel`` (in ``out_dir``) whose metadata requires ``opencv-python-headless``
    where it required ``opencv-python``, with the local version ``+headless`` (file name,
    ``.dist-info`` folder, ``Version``) and its RECORD's hashes to match. Raises InputError
    for a wheel that is not one, or that requires no ``opencv-python``."""
    try:
        name, version, rest = wheel.name.split("-", 2)
    except ValueError:
        raise InputError(f"{wheel.name}: not a wheel file name") from None
    old_info, new_version = f"{name}-{version}.dist-info/", f"{version}+{LOCAL}"
    new_info = f"{name}-{new_version}.dist-info/"
    out = out_dir / f"{name}-{new_version}-{rest}"
    with zipfile.ZipFile(wheel) as src:
        files = {info.filename: src.read(info) for info in src.infolist() if not info.is_dir()}
    if old_info + "METADATA" not in files or old_info + "RECORD" not in files:
        raise InputError(f"{wheel.name}: no {old_info}METADATA and RECORD")
    meta = files[old_info + "METADATA"].decode("utf-8")
    meta, count = _REQUIREMENT.subn(r"\1opencv-python-headless", meta)
    if count == 0:
        raise InputError(f"{wheel.name}: its metadata requires no opencv-python")
    meta = re.sub(r"^Version:.*$", f"Version: {new_version}", meta, count=1, flags=re.M)
    files[old_info + "METADATA"] = meta.encode("utf-8")
    renamed = {
        (new_info + path[len(old_info) :] if path.startswith(old_info) else path): data
        for path, data in files.items()
    }
    record = new_info + "RECORD"
    lines = [f"{path},{_record_hash(data)},{len(data)}" for path, data in renamed.items()]
    lines = [line for line in lines if not line.startswith(record + ",")] + [f"{record},,"]
    renamed[record] = ("\n".join(lines) + "\n").encode("utf-8")
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as dst:
        for path, data in renamed.items():
            dst.writestr(path, data)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m densepeds.install_trackeval",
        description=f"Install {PIN} with metadata that requires opencv-python-headless.",
    )
    parser.add_argument("--quiet", "-q", action="store_true", help="pip's quiet mode")
    args = parser.parse_args(argv)
    pip = [sys.executable, "-m", "pip"]
    quiet = ["-q"] if args.quiet else []
    with tempfile.TemporaryDirectory(prefix="densepeds-trackeval-") as tmp:
        req = Path(tmp) / "requirements.txt"
        req.write_text(f"{PIN} --hash=sha256:{SHA256}\n")
        got = Path(tmp) / "got"
        subprocess.run(
            [*pip, "download", *quiet, "--no-deps", "--only-binary=:all:", "-r", str(req)]
            + ["-d", str(got)],
            check=True,
        )
        (wheel,) = got.glob("*.whl")
        made = headless_wheel(wheel, Path(tmp))
        subprocess.run([*pip, "install", *quiet, str(made)], check=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
