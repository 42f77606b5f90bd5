"""The file readers (det, gt, tracks, seqinfo) fuzzed with hypothesis (issue 19).

For any content, each reader either returns data that keeps its documented guarantees or
raises a :class:`~densepeds.errors.DensePedsError` (one line for the CLI); never another
exception. Inputs are drawn from a grammar of near-valid MOTChallenge rows (numbers, NaN, inf,
overflowing and malformed tokens, wrong column counts, blank lines) and from raw bytes. Example
counts are bounded so that the suite stays quick.
"""

from __future__ import annotations

import string
from pathlib import Path

import numpy as np
import pytest
from densepeds.errors import DensePedsError
from densepeds.io import mot as motio
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

EXAMPLES = settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

_NUMBER = st.one_of(
    st.integers(-5, 3000).map(str),
    st.floats(allow_nan=True, allow_infinity=True, width=64).map(repr),
    st.floats(-1e4, 1e4).map(lambda x: f"{x:.3f}"),
    st.sampled_from(
        ["nan", "inf", "-inf", "1e400", "-1e400", "99999999999999999999", "0x10", "1_0", ""]
    ),
    st.sampled_from([" 7 ", "+3", "-0", "1e-320", "abc", "1,2", "\t5", "١٢"]),
)


@st.composite
def _mot_text(draw: st.DrawFn) -> str:
    ncols = draw(st.integers(1, 11))
    rows = []
    for _ in range(draw(st.integers(0, 12))):
        if draw(st.integers(0, 9)) == 0:
            odd = ["", "   ", "#x", ",,,", "1,2,3,4,5,6,7,8,9,10,11,12"]
            rows.append(draw(st.sampled_from(odd)))
            continue
        k = ncols if draw(st.integers(0, 5)) else draw(st.integers(1, 11))
        frame = draw(st.integers(-2, 50).map(str) | _NUMBER)
        rest = [draw(_NUMBER) for _ in range(k - 1)]
        rows.append(",".join([frame, *rest]) + draw(st.sampled_from(["", ",", " ", "\r"])))
    return "\n".join(rows) + draw(st.sampled_from(["", "\n", "\n\n"]))


_CONTENT = st.one_of(
    _mot_text().map(lambda t: t.encode("utf-8")),
    st.binary(max_size=300),
    _mot_text().map(lambda t: t.encode("utf-8") + b"\xff\xfe"),
)


def _write(folder: Path, name: str, data: bytes) -> Path:
    path = folder / name
    path.write_bytes(data)
    return path


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


@EXAMPLES
@given(data=_CONTENT)
def test_read_detections_is_valid_or_one_error(folder: Path, data: bytes) -> None:
    path = _write(folder, "det.txt", data)
    try:
        dets = motio.read_detections(path)
    except DensePedsError:
        return
    for frame, d in dets.items():
        assert isinstance(frame, int) and frame >= 1
        assert len(d) > 0
        assert np.isfinite(d.boxes).all() and np.isfinite(d.scores).all()
        assert (d.boxes[:, 2] >= d.boxes[:, 0]).all() and (d.boxes[:, 3] >= d.boxes[:, 1]).all()
        assert ((d.scores >= 0) & (d.scores <= 1)).all()


@EXAMPLES
@given(data=_CONTENT)
def test_read_gt_is_valid_or_one_error(folder: Path, data: bytes) -> None:
    path = _write(folder, "gt.txt", data)
    try:
        gt = motio.read_gt(path)
    except DensePedsError:
        return
    assert gt.ndim == 2 and gt.shape[1] >= 7 and np.isfinite(gt).all()
    if len(gt):
        assert (gt[:, 0] >= 1).all() and (gt[:, 0] == np.round(gt[:, 0])).all()
        assert (gt[:, 4] > 0).all() and (gt[:, 5] > 0).all()


@EXAMPLES
@given(data=_CONTENT)
def test_read_tracks_is_valid_or_one_error(folder: Path, data: bytes) -> None:
    path = _write(folder, "tracks.txt", data)
    try:
        tracks = motio.read_tracks(path)
    except DensePedsError:
        return
    assert tracks.shape[1] == 7 and np.isfinite(tracks).all()
    ids = tracks[:, 1]
    assert ((ids >= 0) & (ids <= motio.MAX_TRACK_ID) & (ids == np.round(ids))).all()
    assert (tracks[:, 4] >= tracks[:, 2]).all() and (tracks[:, 5] >= tracks[:, 3]).all()
    # What was read writes back and reads again to the same rows (to the written precision).
    again = folder / "again.txt"
    motio.write_tracks(again, tracks)
    back = motio.read_tracks(again)
    order = np.lexsort((tracks[:, 1], tracks[:, 0]))
    np.testing.assert_allclose(back[:, :2], tracks[order, :2])


_KEYS = ["name", "imDir", "frameRate", "seqLength", "imWidth", "imHeight", "imExt", "other"]
_VALUE = st.one_of(
    _NUMBER,
    st.text(alphabet=string.printable + "%é/\\.\x00", max_size=20),
    st.sampled_from(["../../../tmp/x", "/etc/passwd", "..", "%(x)s", "50%", "a\nb"]),
)


@st.composite
def _seqinfo(draw: st.DrawFn) -> bytes:
    header = draw(st.sampled_from(["[Sequence]", "[sequence]", "[Sequence", "", "[Other]"]))
    lines = [header]
    for key in draw(st.lists(st.sampled_from(_KEYS), max_size=10)):
        sep = draw(st.sampled_from(["=", " = ", ":", ""]))
        lines.append(f"{key}{sep}{draw(_VALUE)}")
    text = "\n".join(lines).encode("utf-8", "surrogatepass")
    return text + draw(st.sampled_from([b"", b"\n", b"\xff"]))


@EXAMPLES
@given(data=st.one_of(_seqinfo(), st.binary(max_size=200)))
def test_read_seqinfo_is_valid_or_one_error(folder: Path, data: bytes) -> None:
    seq = folder / "seq"
    seq.mkdir(exist_ok=True)
    _write(seq, "seqinfo.ini", data)
    try:
        info = motio.read_seqinfo(seq)
    except DensePedsError:
        return
    assert 1 <= info.length <= motio.MAX_SEQ_LENGTH
    assert info.width >= 1 and info.height >= 1 and np.isfinite(info.fps) and info.fps > 0
    # The name becomes a file name: never a path, never hidden.
    assert info.name and info.name == motio.safe_name(info.name)
    assert "/" not in info.name and "\\" not in info.name and not info.name.startswith(".")
