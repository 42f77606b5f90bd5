"""Faults at the file and process edges (issue 19): a full disk, truncated input, hostile
``seqinfo.ini`` names, unwritable outputs, signals. Each test names the finding it covers.

A full disk is simulated portably: the command runs in a child process whose file size limit
(``RLIMIT_FSIZE``) is a few KiB, with ``SIGXFSZ`` ignored, so that a write past it fails with
``EFBIG`` as a write to a full disk fails with ``ENOSPC``.
"""

from __future__ import annotations

import os
import re
import resource
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import onnx
import pytest
from conftest import shared_path
from densepeds.cli import main
from densepeds.errors import ModelError
from densepeds.io.mot import read_tracks, safe_name
from densepeds.scene import make_scene
from onnx import TensorProto, helper
from test_reid import fixed_batch_mars_like

# --- helpers ---------------------------------------------------------------------------------


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def _one_line(rc: int, err: str, *needles: str, code: int = 2) -> str:
    assert rc == code, err
    assert "Traceback" not in err, err
    lines = [line for line in err.strip().splitlines() if line.startswith("densepeds")]
    assert len(lines) == 1, err
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def _file_limit(limit: int) -> Callable[[], None]:
    def apply() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


def _cli(
    *argv: str, limit: int | None = None, cwd: Path | None = None, timeout: float = 300
) -> subprocess.CompletedProcess[str]:
    """``python -m densepeds ARGV`` in a child process (optionally on a 'full disk')."""
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    return subprocess.run(
        [sys.executable, "-m", "densepeds", *argv],
        capture_output=True,
        text=True,
        env=env,
        cwd=cwd,
        timeout=timeout,
        preexec_fn=_file_limit(limit) if limit is not None else None,
    )


def _hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob(".*"))


def _sequence(tmp_path: Path, frames: int = 30, images: bool = False) -> Path:
    """The built-in scene written as a MOTChallenge sequence (det + gt, optional images)."""
    return make_scene(seed=3, frames=frames).write(tmp_path / "seqs", images=images)


def _set_seqinfo(seq: Path, **fields: str) -> None:
    ini = seq / "seqinfo.ini"
    lines = []
    for line in ini.read_text().splitlines():
        key = line.partition("=")[0]
        lines.append(f"{key}={fields.pop(key)}" if key in fields else line)
    ini.write_text("\n".join(lines + [f"{k}={v}" for k, v in fields.items()]) + "\n")


def _unwritable_dir(tmp_path: Path) -> Path:
    """A folder this process cannot create files in (a read-only folder; as root, sysfs)."""
    if os.geteuid() != 0:
        ro = tmp_path / "read-only"
        ro.mkdir()
        ro.chmod(0o555)
        return ro
    sysfs = Path("/sys")
    try:
        (sysfs / "densepeds-probe").touch()
    except OSError:
        return sysfs
    (sysfs / "densepeds-probe").unlink()
    pytest.skip("running as root with no read-only folder to write into")


# --- finding 1: a full disk, exit 0 ------------------------------------------------------------


def test_finding1_video_on_a_full_disk_fails_and_leaves_nothing(tmp_path: Path) -> None:
    seq = _sequence(tmp_path, frames=40)
    out, video = tmp_path / "out" / "t.txt", tmp_path / "out" / "v.mp4"
    proc = _cli("run", str(seq), "--out", str(out), "--video", str(video), "-q", limit=48 * 1024)
    line = _one_line(proc.returncode, proc.stderr, str(video), "could not be written")
    # FFmpeg stops at the failed write; OpenCV's writer is found out by reading the file back.
    assert re.search(r"stopped after \d+ frames|of 40 frames", line), line
    assert not video.exists() and not out.exists()
    assert _hidden(tmp_path / "out") == []


def test_finding1_tracks_on_a_full_disk_fail(tmp_path: Path) -> None:
    seq = _sequence(tmp_path, frames=40)
    out = tmp_path / "t.txt"
    proc = _cli("run", str(seq), "--out", str(out), "-q", limit=4 * 1024)
    _one_line(proc.returncode, proc.stderr, str(out), "cannot write")
    assert not out.exists() and _hidden(tmp_path) == []


def test_finding1_scene_on_a_full_disk_is_not_a_sequence(tmp_path: Path) -> None:
    proc = _cli("scene", str(tmp_path / "s"), "--frames", "20", limit=16 * 1024)
    _one_line(proc.returncode, proc.stderr, "cannot write")
    assert "wrote" not in proc.stdout
    # What was written is not a sequence that `run` would track as if complete.
    assert not list(tmp_path.rglob("seqinfo.ini"))
    assert not [p for p in tmp_path.rglob("*") if p.name.startswith(".")]


# --- finding 2: truncated input tracked silently -------------------------------------------------


def _det_file(path: Path, frames: int) -> Path:
    rows = [f"{k},-1,{20 + k % 5},{20},30,60,0.9,-1,-1,-1\n" for k in range(1, frames + 1)]
    path.write_text("".join(rows))
    return path


def test_finding2_truncated_video_is_reported(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    full = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(full), cv2.VideoWriter.fourcc(*"MJPG"), 10.0, (160, 120))
    rng = np.random.default_rng(0)
    for _ in range(60):
        writer.write(rng.integers(0, 256, (120, 160, 3), np.uint8))
    writer.release()
    cut = tmp_path / "cut.avi"
    data = full.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.3)])
    dets = _det_file(tmp_path / "det.txt", 60)
    out = tmp_path / "t.txt"
    args = ["run", str(cut), "--detections", str(dets), "--features", "none", "--out", str(out)]
    rc, _, err = _run(capsys, *args, "-q")
    line = _one_line(rc, err, "of 60 frames", "--allow-partial")
    decoded = int(line.split("decoded ")[1].split()[0])
    assert 0 < decoded < 60
    assert not out.exists()
    rc, _, err = _run(capsys, *args, "-q", "--allow-partial")
    assert rc == 0 and f"decoded {decoded} of 60" in err
    assert read_tracks(out)[:, 0].max() <= decoded


def test_finding2_image_folder_shorter_than_seqlength(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    seq = _sequence(tmp_path, frames=20, images=True)
    for k in range(9, 21):
        (seq / "img1" / f"{k:06d}.jpg").unlink()
    out = tmp_path / "t.txt"
    rc, _, err = _run(capsys, "run", str(seq), "--features", "none", "--out", str(out), "-q")
    _one_line(rc, err, "decoded 8 of 20")
    assert not out.exists()
    rc, _, err = _run(
        capsys, "run", str(seq), "--features", "none", "--out", str(out), "-q", "--allow-partial"
    )
    assert rc == 0 and "decoded 8 of 20" in err and out.is_file()


# --- finding 3: the output path steered by seqinfo.ini ------------------------------------------


@pytest.mark.parametrize("name", ["ABSOLUTE", "../../../densepeds-y", "..", "a/b\\c"])
def test_finding3_output_name_from_seqinfo_stays_in_out(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    name: str,
) -> None:
    seq = _sequence(tmp_path, frames=10)
    # An absolute name points inside tmp_path, so that a file written there is seen below.
    _set_seqinfo(seq, name=str(tmp_path / "elsewhere" / "x") if name == "ABSOLUTE" else name)
    work = tmp_path / "a" / "b" / "c"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    before = set(tmp_path.rglob("*"))
    rc, out, _ = _run(capsys, "run", str(seq), "-q")
    assert rc == 0
    made = {p for p in set(tmp_path.rglob("*")) - before if p.is_file()}
    assert len(made) == 1, made
    (path,) = made
    assert path.parent == work / "out", path
    assert not path.name.startswith(".")


def test_finding3_safe_name() -> None:
    assert safe_name("MOT17-02-FRCNN") == "MOT17-02-FRCNN"
    for hostile in ("/etc/passwd", "../../x", "..", "a/../b", "c:\\x", "\x00evil", ". .x"):
        clean = safe_name(hostile)
        assert "/" not in clean and "\\" not in clean and "\x00" not in clean
        assert clean and not clean.startswith(".") and clean not in ("..", ".")
    assert safe_name("...", "seq") == "seq"
    assert len(safe_name("x" * 1000)) == 200


# --- finding 4: tracebacks instead of one line ----------------------------------------------------


def test_finding4_unwritable_outputs(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    seq = _sequence(tmp_path, frames=10)
    a_file = tmp_path / "file.txt"
    a_file.write_text("x")
    ro = _unwritable_dir(tmp_path)
    cases = {
        str(ro / "t.txt"): "cannot write",
        str(tmp_path): "is a folder",
        str(a_file / "t.txt"): "is a file, not a folder",
        str(a_file / "deeper" / "t.txt"): "is a file, not a folder",
    }
    for out, why in cases.items():
        rc, _, err = _run(capsys, "run", str(seq), "--out", out, "-q")
        _one_line(rc, err, out, why)
    # A read-only video output fails before any frame is tracked.
    rc, _, err = _run(
        capsys, "run", str(seq), "--out", str(tmp_path / "t.txt"), "--video", str(ro / "v.mp4")
    )
    _one_line(rc, err, str(ro / "v.mp4"))
    assert not (tmp_path / "t.txt").exists()


@pytest.mark.parametrize(
    ("field", "value", "needle"),
    [
        ("name", "50%", None),
        ("frameRate", "25%", "frameRate"),
        ("seqLength", "99999999999999999999", "too large"),
        ("seqLength", "1e400", "seqLength"),
    ],
)
def test_finding4_hostile_seqinfo_values(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    field: str,
    value: str,
    needle: str | None,
) -> None:
    seq = _sequence(tmp_path, frames=10)
    _set_seqinfo(seq, **{field: value})
    rc, _, err = _run(capsys, "run", str(seq), "--out", str(tmp_path / "t.txt"), "-q")
    if needle is None:  # a '%' in the name is just a character
        assert rc == 0, err
    else:
        _one_line(rc, err, "seqinfo.ini", needle)


def test_finding4_non_utf8_seqinfo(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    seq = _sequence(tmp_path, frames=10)
    ini = seq / "seqinfo.ini"
    ini.write_bytes(ini.read_bytes().replace(b"name=", b"name=\xff\xfe"))
    rc, _, err = _run(capsys, "run", str(seq), "--out", str(tmp_path / "t.txt"), "-q")
    _one_line(rc, err, "seqinfo.ini", "UTF-8")


@pytest.mark.parametrize("track_id", ["-3", "12345678901234567890"])
def test_finding4_eval_on_bad_track_ids(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, track_id: str
) -> None:
    seq = _sequence(tmp_path, frames=10)
    tracks = tmp_path / "t.txt"
    tracks.write_text(f"1,1,10,10,20,40,1,-1,-1,-1\n2,{track_id},10,10,20,40,1,-1,-1,-1\n")
    rc, _, err = _run(capsys, "eval", "--gt", str(seq), "--tracks", str(tracks))
    _one_line(rc, err, f"{tracks}:2", "track id")


def test_finding4_scene_into_unwritable_places(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    a_file = tmp_path / "file"
    a_file.write_text("x")
    for where, why in ((_unwritable_dir(tmp_path), "cannot write"), (a_file, "not a folder")):
        rc, out, err = _run(capsys, "scene", str(where / "s"), "--frames", "3", "--no-images")
        _one_line(rc, err, why)
        assert "wrote" not in out


def _wait_until_loaded(proc: subprocess.Popen[str], library: str, timeout: float = 60) -> None:
    """Wait until the child has mapped ``library`` (Linux: /proc/PID/maps)."""
    maps = Path(f"/proc/{proc.pid}/maps")
    if not maps.exists():
        pytest.skip("needs /proc/PID/maps to see when the command has started")
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            if library in maps.read_text():
                return
        except OSError:
            pass
        time.sleep(0.002)


@pytest.mark.parametrize("delay", [0.02, 0.1, 0.3, 0.6])
def test_finding4_ctrl_c_early_is_one_line(tmp_path: Path, delay: float) -> None:
    """Ctrl-C from the moment the package starts loading (before that, the interpreter's own
    start-up is not ours) while the modules load and the scene is made: one line, 130."""
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "densepeds", "scene", str(tmp_path / "s"), "--frames", "400"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    _wait_until_loaded(proc, "_core")
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    if proc.returncode == 0:
        pytest.skip("finished before the interrupt")  # a very fast machine
    # A process ended by SIGINT after its one line is status 130 to the shell as well.
    rc = 130 if proc.returncode == -signal.SIGINT else proc.returncode
    _one_line(rc, err, "interrupted", code=130)
    assert not [p for p in tmp_path.rglob("*") if p.name.startswith(".")]


# --- finding 5: a one-line edit runs for hours ----------------------------------------------


def test_finding5_seqlength_far_past_the_detections(tmp_path: Path) -> None:
    seq = _sequence(tmp_path, frames=30)
    normal = tmp_path / "normal.txt"
    assert _cli("run", str(seq), "--out", str(normal), "-q").returncode == 0
    _set_seqinfo(seq, seqLength="1000000000")
    long = tmp_path / "long.txt"
    try:  # the plain run of 10^9 frames takes hours
        proc = _cli("run", str(seq), "--out", str(long), "-q", timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail("a seqLength of 10^9 frames past 30 frames of detections ran for minutes")
    assert proc.returncode == 0 and "detections end at frame 30" in proc.stderr, proc.stderr
    a, b = read_tracks(normal), read_tracks(long)
    np.testing.assert_array_equal(b[b[:, 0] <= 30], a)  # the same tracks where both ran
    assert b[:, 0].max() <= 30 + 5  # then at most the lost-track output window


# --- finding 6: temporary files, re-ID model output, ablate's frame range ------------------------


def test_finding6_sigterm_during_video_removes_the_temporary(tmp_path: Path) -> None:
    seq = _sequence(tmp_path, frames=150)
    outdir = tmp_path / "out"
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "densepeds", "run", str(seq), "-q"]
        + ["--out", str(outdir / "t.txt"), "--video", str(outdir / "v.mp4")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    deadline = time.monotonic() + 120
    while not (outdir.is_dir() and _hidden(outdir)) and time.monotonic() < deadline:
        if proc.poll() is not None:
            break
        time.sleep(0.02)
    assert proc.poll() is None, "the run ended before it could be terminated"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    _one_line(proc.returncode, err, "terminated", code=128 + signal.SIGTERM)
    assert sorted(p.name for p in outdir.iterdir()) == []


def test_finding6_temporaries_of_a_killed_run_are_removed(tmp_path: Path) -> None:
    from densepeds.io.mot import write_text

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".v.mp4.densepeds-{dead.pid}-0a1b2c3d.mp4"
    stale.write_bytes(b"half a video")
    alive = tmp_path / f".v.mp4.densepeds-{os.getpid()}-0a1b2c3d.mp4"  # ours: kept
    alive.write_bytes(b"in progress")
    other = tmp_path / ".v.mp4.something-else.mp4"
    other.write_bytes(b"not ours")
    write_text(tmp_path / "v.mp4", "x")
    assert not stale.exists() and alive.exists() and other.exists()


def _identity_model(path: Path) -> Path:
    graph = helper.make_graph(
        [helper.make_node("Identity", ["images"], ["out"])],
        "identity",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, ["N", 3, 256, 128])],
        [helper.make_tensor_value_info("out", TensorProto.FLOAT, ["N", 3, 256, 128])],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    onnx.save(model, str(path))
    return path


def _nan_model(path: Path) -> Path:
    """[N,3,256,128] -> [N,3]: channel means times NaN."""
    nan = onnx.numpy_helper.from_array(np.array([np.nan], np.float32), "nan")
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["m"], axes=[2, 3], keepdims=0),
        helper.make_node("Mul", ["m", "nan"], ["out"]),
    ]
    graph = helper.make_graph(
        nodes,
        "nan",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, ["N", 3, 256, 128])],
        [helper.make_tensor_value_info("out", TensorProto.FLOAT, ["N", 3])],
        initializer=[nan],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    onnx.save(model, str(path))
    return path


def test_finding6_reid_model_that_is_not_an_embedder(tmp_path: Path) -> None:
    from densepeds.reid import ReID

    path = _identity_model(tmp_path / "identity.onnx")
    with pytest.raises(ModelError, match="not an embedding") as exc:
        ReID(path, threads=1)
    assert str(path) in str(exc.value)
    # A real embedder still loads.
    assert ReID(fixed_batch_mars_like(tmp_path / "m.onnx"), threads=1).dim == 128


def test_finding6_non_finite_embeddings_name_the_model(tmp_path: Path) -> None:
    from densepeds.reid import ReID

    path = _nan_model(tmp_path / "nan.onnx")
    reid = ReID(path, threads=1)
    crops = [np.full((60, 30, 3), 100, np.uint8)]
    with pytest.raises(ModelError, match="non-finite") as exc:
        reid.embed_crops(crops)
    assert str(path) in str(exc.value)


def test_finding6_ablate_frames_out_of_range(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    seq = _sequence(tmp_path, frames=20)
    rc, _, err = _run(capsys, "ablate", str(seq), "--motion", "cv", "--frames", "500:600", "-q")
    line = _one_line(rc, err, "500", "20")
    assert "densepeds-ablate-" not in line and "/tmp" not in line.split(":", 2)[-1]
    rc, _, err = _run(capsys, "ablate", "--motion", "cv", "--frames", "500:", "-q")
    _one_line(rc, err, "500")


def test_finding6_ablate_frames_out_of_range_real(capsys: pytest.CaptureFixture[str]) -> None:
    seq = shared_path("data", "TUD-Stadtmitte")
    rc, _, err = _run(capsys, "ablate", str(seq), "--motion", "cv", "--frames", "500:600", "-q")
    line = _one_line(rc, err, "TUD-Stadtmitte", "179")
    assert "densepeds-ablate-" not in line
