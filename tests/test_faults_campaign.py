"""The fault campaign of issue 40: one class of defect per section, each with more cases than its
reproducer. Every failure is one line naming the file (and line) at exit 2, every drop or
reinterpretation of input a warning line on stderr, and memory follows what the files hold."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from densepeds import _core
from densepeds.errors import InputError, ModelError, ParameterError
from densepeds.io.mot import read_detections, read_seqinfo, read_tracks, reserve_temp
from densepeds.scene import make_scene
from test_faults import _cli, _one_line, _run, _sequence, _set_seqinfo

MAX_DETS = _core.MAX_DETECTIONS_PER_FRAME


def _limited_cli(*argv: str, gib: float, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """``python -m densepeds ARGV`` with its address space capped at ``gib`` GiB."""

    def cap() -> None:
        limit = int(gib * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    return subprocess.run(
        [sys.executable, "-m", "densepeds", *argv],
        capture_output=True,
        text=True,
        env=env,
        timeout=timeout,
        preexec_fn=cap,
    )


def _one_error_line(proc: subprocess.CompletedProcess[str], *needles: str) -> str:
    assert proc.returncode == 2, (proc.returncode, proc.stderr[-2000:])
    assert "Traceback" not in proc.stderr, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr[-2000:]
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def _rows(frame: int, boxes: np.ndarray, score: float = 0.9) -> str:
    return "".join(
        f"{frame},-1,{x:.2f},{y:.2f},{w:.2f},{h:.2f},{score},-1,-1,-1\n" for x, y, w, h in boxes
    )


# --- crash: a frame of very many overlapping detections -------------------------------------------


@pytest.mark.parametrize(("count", "spread"), [(30_000, 1500.0), (100_000, 3000.0)])
def test_crowded_frame_is_one_error_in_bounded_memory(
    tmp_path: Path, count: int, spread: float
) -> None:
    # A chain of overlapping boxes: one matching component of every detection (on 216e707 its
    # dense matrix needs tens of GB: the process aborts).
    rng = np.random.default_rng(0)
    xy = rng.uniform(0, spread, (count, 2))
    boxes = np.c_[xy, np.full(count, 40.0), np.full(count, 100.0)]
    seq = _long_sequence(tmp_path, "crowd", 2)
    det = seq / "det" / "det.txt"
    det.write_text(_rows(1, boxes) + _rows(2, boxes + 1.0))
    start = time.monotonic()
    proc = _limited_cli("run", str(seq), "--out", str(tmp_path / "t.txt"), gib=3)
    line = _one_error_line(proc, f"{det}:{MAX_DETS + 1}:", f"at most {MAX_DETS}")
    assert "frame 1" in line
    assert time.monotonic() - start < 60
    assert not (tmp_path / "t.txt").exists()


def test_crowded_frame_from_python_is_an_input_error() -> None:
    boxes = np.tile([0.0, 0.0, 40.0, 100.0], (MAX_DETS + 1, 1)) + np.arange(MAX_DETS + 1.0)[:, None]
    tracker = _core.Tracker()
    with pytest.raises(InputError, match=f"at most {MAX_DETS}"):
        tracker.update(boxes, np.full(MAX_DETS + 1, 0.9))
    assert tracker.frame_count == 0
    # The bound itself is tracked, overlapping boxes and all.
    boxes = boxes[:MAX_DETS] * 0.01 + [0.0, 0.0, 40.0, 100.0]
    for _ in range(2):
        tracker.update(boxes, np.full(MAX_DETS, 0.9))


def test_detector_crowd_past_the_bound_keeps_the_most_confident() -> None:
    from densepeds.pipeline import Pipeline
    from densepeds.types import Detections

    n = MAX_DETS + 500
    rng = np.random.default_rng(2)
    xy = rng.uniform(0, 600, (n, 2))
    boxes = np.c_[xy, xy + [20.0, 50.0]].astype(np.float32)
    scores = rng.uniform(0.3, 1.0, n).astype(np.float32)

    def detector(frame: np.ndarray) -> Detections:
        return Detections(boxes, scores)

    pipe = Pipeline(detector, features="none")
    frame = np.zeros((480, 640, 3), np.uint8)
    with pytest.warns(UserWarning, match=f"found {n} people in one frame; the {MAX_DETS} most"):
        pipe.process(frame)
    kept = pipe._frame_detections
    assert len(kept) == MAX_DETS
    assert kept.scores.min() >= np.sort(scores)[-MAX_DETS]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pipe.process(frame)  # said once


# --- unbounded memory: eval by seqLength, a gt row at frame 2e9, scene --frames -------------------


@pytest.fixture(scope="module")
def scored_sequence(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    pytest.importorskip("trackeval")
    tmp = tmp_path_factory.mktemp("eval")
    seq = _sequence(tmp, frames=40)
    tracks = tmp / "tracks.txt"
    assert _cli("run", str(seq), "--out", str(tracks), "-q").returncode == 0
    return seq, tracks


def _eval_json(seq: Path, tracks: Path, gib: float = 3) -> dict[str, float]:
    proc = _limited_cli(
        "eval", "--gt", str(seq), "--tracks", str(tracks), "--format", "json", gib=gib
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout)["combined"]


@pytest.mark.parametrize("length", ["5000000", str(2**31 - 1)])
def test_eval_memory_follows_the_files_not_seqlength(
    scored_sequence: tuple[Path, Path], tmp_path: Path, length: str
) -> None:
    seq, tracks = scored_sequence
    expected = _eval_json(seq, tracks)
    long = tmp_path / seq.name
    long.mkdir()
    (long / "gt").mkdir()
    (long / "gt" / "gt.txt").write_text((seq / "gt" / "gt.txt").read_text())
    (long / "seqinfo.ini").write_text((seq / "seqinfo.ini").read_text())
    _set_seqinfo(long, seqLength=length)
    assert _eval_json(long, tracks) == expected


def test_eval_of_far_frames_equals_eval_of_near_ones(
    scored_sequence: tuple[Path, Path], tmp_path: Path
) -> None:
    # The same rows spread over frames k * 10^7 (no seqinfo: the last row sets the length, up to
    # 4e8): every metric is unchanged, in bounded memory.
    seq, tracks = scored_sequence
    expected = _eval_json(seq, tracks)
    far = tmp_path / seq.name
    (far / "gt").mkdir(parents=True)
    gt = np.loadtxt(seq / "gt" / "gt.txt", delimiter=",", ndmin=2)
    gt[:, 0] *= 10_000_000
    np.savetxt(far / "gt" / "gt.txt", gt, delimiter=",", fmt="%.10g")
    rows = np.loadtxt(tracks, delimiter=",", ndmin=2)
    rows[:, 0] *= 10_000_000
    far_tracks = tmp_path / "far.txt"
    np.savetxt(far_tracks, rows, delimiter=",", fmt="%.10g")
    got = _eval_json(far, far_tracks)
    assert got.keys() == expected.keys()
    for key, value in expected.items():
        assert got[key] == pytest.approx(value, abs=1e-9), key


def test_eval_gt_row_at_frame_2e9(scored_sequence: tuple[Path, Path], tmp_path: Path) -> None:
    seq, tracks = scored_sequence
    far = tmp_path / seq.name
    (far / "gt").mkdir(parents=True)
    text = (seq / "gt" / "gt.txt").read_text()
    last = text.strip().splitlines()[-1].split(",")
    (far / "gt" / "gt.txt").write_text(text + ",".join(["2000000000", *last[1:]]) + "\n")
    proc = _limited_cli(
        "eval", "--gt", str(far), "--tracks", str(tracks), "--format", "json", gib=3
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads(proc.stdout)["combined"]["FN"] > 0


@pytest.mark.parametrize(
    "argv",
    [
        ["scene", "{tmp}/out", "--frames", "100000000"],
        ["scene", "{tmp}/out", "--frames", "100001", "--no-images"],
        ["run", "--scene-frames", "100000000", "--features", "none"],
    ],
)
def test_absurd_scene_lengths_are_refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, argv: list[str]
) -> None:
    rc, _, err = _run(capsys, *(a.replace("{tmp}", str(tmp_path)) for a in argv))
    _one_line(rc, err, "frames is too many")
    assert not (tmp_path / "out").exists()


# --- hang: input expansion through link loops ----------------------------------------------------


def test_batch_dry_run_with_link_loops_returns(tmp_path: Path) -> None:
    root = tmp_path / "inputs"
    root.mkdir()
    seq = _sequence(root, frames=5)  # inputs/seqs/<name>
    (root / "self1").symlink_to(root, target_is_directory=True)
    (root / "self2").symlink_to(root, target_is_directory=True)
    (root / "seqs" / "up").symlink_to(root, target_is_directory=True)
    (root / "a" / "b").mkdir(parents=True)
    (root / "a" / "b" / "back").symlink_to(root / "a", target_is_directory=True)
    try:
        proc = _cli("batch", str(root), "--out", str(tmp_path / "out"), "--dry-run", timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail("batch --dry-run never returned on a folder with links to itself")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count(f"| {seq.name} |") == 1, proc.stdout


# --- paths: imDir confined to the sequence folder -------------------------------------------------


def _images(folder: Path, frames: int = 3, size: tuple[int, int] = (64, 48)) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for k in range(1, frames + 1):
        cv2.imwrite(str(folder / f"{k:06d}.jpg"), np.full((size[1], size[0], 3), 90, np.uint8))


@pytest.mark.parametrize("im_dir", ["{outside}", "../../..", "img1/../../x", "{link}", "/etc"])
def test_imdir_outside_the_sequence_is_refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, im_dir: str
) -> None:
    seq = _sequence(tmp_path, frames=3)
    outside = tmp_path / "elsewhere"
    _images(outside)
    (seq / "link").symlink_to(outside, target_is_directory=True)
    _set_seqinfo(seq, imDir=im_dir.format(outside=outside, link="link"))
    line_no = (
        (seq / "seqinfo.ini")
        .read_text()
        .splitlines()
        .index(f"imDir={im_dir.format(outside=outside, link='link')}")
    )
    with pytest.raises(InputError, match="imDir"):
        read_seqinfo(seq)
    rc, _, err = _run(capsys, "run", str(seq), "--out", str(tmp_path / "t.txt"), "-q")
    _one_line(rc, err, f"seqinfo.ini:{line_no + 1}:", "imDir")


def test_imdir_inside_the_sequence_is_read(tmp_path: Path) -> None:
    seq = _sequence(tmp_path, frames=3)
    _images(seq / "frames" / "left")
    _set_seqinfo(seq, imDir="frames/left")
    assert read_seqinfo(seq).image_dir == seq / "frames" / "left"
    _set_seqinfo(seq, imExt="/../../x.jpg")
    with pytest.raises(InputError, match="imExt"):
        read_seqinfo(seq)


# --- caches: the batch workers' model folder ------------------------------------------------------


def _shipped(path: Path) -> object:
    import hashlib

    from densepeds.batch.worker import ShippedModel

    data = path.read_bytes()
    return ShippedModel(path.name, hashlib.sha256(data).hexdigest(), len(data), str(path))


def test_model_cache_is_private_and_checked(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from densepeds.batch import worker as batch_worker

    monkeypatch.setattr(batch_worker.tempfile, "gettempdir", lambda: str(tmp_path))
    folder = batch_worker.node_cache_dir()
    for f in (folder, folder.parent):
        st = f.lstat()
        assert st.st_uid == os.getuid() and (st.st_mode & 0o777) == 0o700, oct(st.st_mode)
    folder.chmod(0o777)  # loosened by someone: tightened again
    assert batch_worker.node_cache_dir() == folder and (folder.stat().st_mode & 0o777) == 0o700

    model = tmp_path / "model.onnx"
    model.write_bytes(b"the real model" * 100)
    shipped = _shipped(model)
    local = folder / "copy.onnx"
    local.write_bytes(b"a planted file" * 100)  # same size, other bytes
    assert not batch_worker._has_model(local, shipped)  # type: ignore[arg-type]
    local.write_bytes(model.read_bytes())
    assert batch_worker._has_model(local, shipped)  # type: ignore[arg-type]
    local.unlink()
    local.symlink_to(model)  # a link, even to the right bytes, is not the node's copy
    assert not batch_worker._has_model(local, shipped)  # type: ignore[arg-type]


def test_model_cache_of_another_owner_or_a_link_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from densepeds.batch import worker as batch_worker

    monkeypatch.setattr(batch_worker.tempfile, "gettempdir", lambda: str(tmp_path))
    top = tmp_path / f"densepeds-batch-models-{os.getuid()}"
    elsewhere = tmp_path / "planted"
    elsewhere.mkdir()
    top.symlink_to(elsewhere, target_is_directory=True)
    with pytest.raises(ModelError, match="not a plain folder"):
        batch_worker.node_cache_dir()
    top.unlink()
    if os.geteuid() != 0:
        pytest.skip("making a folder owned by someone else needs root")
    top.mkdir(mode=0o700)
    os.chown(top, 65534, 65534)
    with pytest.raises(ModelError, match="owned by uid 65534"):
        batch_worker.node_cache_dir()


# --- signals: batch on SIGTERM / SIGHUP -----------------------------------------------------------


def _long_sequence(root: Path, name: str, frames: int) -> Path:
    seq = root / name
    (seq / "det").mkdir(parents=True)
    (seq / "seqinfo.ini").write_text(
        f"[Sequence]\nname={name}\nimDir=img1\nframeRate=25\nseqLength={frames}\n"
        "imWidth=640\nimHeight=480\nimExt=.jpg\n"
    )
    k = np.arange(1, frames + 1)
    rows = [
        np.c_[
            k,
            -np.ones(frames),
            40 * j + 2 * np.sin(k / 9),
            100 + k % 3,
            np.full(frames, 30),
            np.full(frames, 80),
            np.full(frames, 0.9),
        ]
        for j in range(12)
    ]
    np.savetxt(seq / "det" / "det.txt", np.concatenate(rows), delimiter=",", fmt="%g")
    return seq


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_batch_on_a_termination_signal(tmp_path: Path, sig: signal.Signals) -> None:
    pytest.importorskip("ray")
    inputs = tmp_path / "in"
    for k in range(3):
        _long_sequence(inputs, f"clip{k}", 20_000)
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "densepeds",
            "batch",
            str(inputs),
            "--out",
            str(out),
            "-q",
            "--workers",
            "1",
            "--features",
            "none",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline and not list(out.glob("clip*.json")):
        time.sleep(0.2)
    assert list(out.glob("clip*.json")), "no job started"
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + sig, (proc.returncode, err)
    assert "Traceback" not in err and "ray" not in err.lower(), err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and sig.name in lines[0], err
    summary = json.loads((out / "batch.json").read_text())
    statuses = [json.loads(p.read_text())["status"] for p in out.glob("clip*.json")]
    assert statuses and "running" not in statuses, statuses
    assert summary["inputs"] and all(r["status"] != "running" for r in summary["inputs"]), summary


# --- names: record names that cannot collide or overflow ----------------------------------------


def test_job_names_never_collide_with_the_summary_or_overflow(tmp_path: Path) -> None:
    from densepeds.batch.plan import MAX_NAME_BYTES, SUMMARY_FILE, job_names

    files = []
    for name in ["batch.avi", "Batch.mp4", "b" * 245 + ".mp4", "é" * 120 + ".avi", "a.mp4"]:
        (tmp_path / name).write_bytes(b"x")
        files.append(tmp_path / name)
    names = job_names(files)
    assert len(set(names)) == len(names)
    assert all(f"{n}.json".lower() != SUMMARY_FILE for n in names), names
    assert all(len(n.encode()) <= MAX_NAME_BYTES for n in names), names
    assert names[-1] == "a"
    # Two long names that share their first 200 characters stay apart.
    (tmp_path / "d1").mkdir()
    (tmp_path / "d2").mkdir()
    long = "c" * 240
    pair = [tmp_path / "d1" / f"{long}.mp4", tmp_path / "d2" / f"{long}.mp4"]
    for p in pair:
        p.write_bytes(b"x")
    a, b = job_names(pair)
    assert a != b and max(len(a.encode()), len(b.encode())) < 200


def test_batch_plan_writes_records_for_long_and_reserved_names(tmp_path: Path) -> None:
    from densepeds.batch.plan import Job, expand_inputs, job_names, new_record, write_record

    inputs = tmp_path / "in"
    inputs.mkdir()
    for name in ["batch.avi", "v" * 245 + ".mp4"]:
        (inputs / name).write_bytes(b"not a video")
    out = tmp_path / "out"
    paths = expand_inputs([inputs])
    for name, path in zip(job_names(paths), paths, strict=True):
        job = Job(name, path, out, False)
        write_record(job, new_record(job, "hash", "failed"))
    assert sorted(p.name for p in out.iterdir() if p.name.startswith("batch"))[0] != "batch.json"
    assert len(list(out.glob("*.json"))) == 2


def test_longest_legal_out_name_is_accepted(tmp_path: Path) -> None:
    seq = _sequence(tmp_path, frames=5)
    out = tmp_path / ("t" * 250 + ".txt")  # 254 bytes: a legal file name
    proc = _cli("run", str(seq), "--out", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    assert len(read_tracks(out)) > 0
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    tmp = reserve_temp(tmp_path / ("é" * 125 + ".txt"))  # 254 bytes, two to a character
    assert len(tmp.name.encode()) <= 255
    tmp.unlink()


# --- non-finite and absurd values -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("row", "needle"),
    [
        ("100,10,20,40,inf", "NaN or infinite"),
        ("100,10,20,40,+inf", "NaN or infinite"),
        ("100,10,20,40,nan", "NaN or infinite"),
        ("100,10,20,40,1e309", "NaN or infinite"),
        ("100,10,20,40,1e308", "score 1e+308"),
        ("100,10,20,40,-5e7", "score -5e+07"),
        ("100,10,1e300,40,0.5", "box value"),
        ("100,10,20,1e30,0.5", "box value"),
        ("-1e12,10,20,40,0.5", "box value"),
    ],
)
def test_absurd_det_values_are_refused_with_file_and_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, row: str, needle: str
) -> None:
    seq = _sequence(tmp_path, frames=10)
    det = seq / "det" / "det.txt"
    lines = det.read_text().splitlines()
    lines.insert(3, f"2,-1,{row},-1,-1,-1")
    det.write_text("\n".join(lines) + "\n")
    rc, _, err = _run(capsys, "run", str(seq), "--out", str(tmp_path / "t.txt"), "-q")
    _one_line(rc, err, f"{det}:4:", needle)
    with pytest.raises(InputError, match=f"{det}:4:"):
        read_detections(det)


def test_frame_past_the_largest_frame_number_is_refused(tmp_path: Path) -> None:
    det = tmp_path / "det.txt"
    det.write_text("1,-1,10,10,20,40,0.9\n3000000000,-1,10,10,20,40,0.9\n")
    with pytest.raises(InputError, match=f"{det}:2: frame 3e\\+09"):
        read_detections(det)


@pytest.mark.parametrize("bad", [np.inf, -np.inf, np.nan])
def test_non_finite_scores_from_python_are_refused(bad: float) -> None:
    from densepeds.tracking import Tracker

    tracker = Tracker()
    with pytest.raises(InputError, match="score 1"):
        tracker.update(np.array([[0, 0, 10, 20], [50, 0, 60, 20]], np.float32), [0.9, bad])


def _fake_yolo_output(detector: object, boxes: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """Raw predictions [1, 4 + classes + masks, anchors] holding ``boxes`` (cx, cy, w, h)."""
    cls = detector.person_class  # type: ignore[attr-defined]
    width = 4 + cls + 1 + 32
    preds = np.zeros((1, width, len(boxes)), np.float32)
    preds[0, :4] = boxes.T
    preds[0, 4 + cls] = scores
    return preds


def test_detector_nan_boxes_are_dropped_with_a_warning() -> None:
    from densepeds.detect import onnxutil

    rows = np.array([[1, 2, 3, 4, 0.9], [np.nan, 2, 3, 4, 0.9], [1, 2, np.inf, 4, 0.9]])
    warned: set[object] = set()
    with pytest.warns(UserWarning, match="2 of 3 detections with NaN or infinite"):
        ok = onnxutil.finite_rows(rows, "model.onnx", warned)
    assert ok.tolist() == [True, False, False]
    assert warned == {"model.onnx"}
    assert onnxutil.finite_rows(np.zeros((0, 38), np.float32), "m", set()).shape == (0,)


def test_yoloseg_pick_drops_non_finite_rows() -> None:
    from densepeds.detect import yoloseg

    det = object.__new__(yoloseg.YoloSegDetector)
    det.pred_transposed = False  # type: ignore[attr-defined]
    det.person_class = 0  # type: ignore[attr-defined]
    det.score_threshold = 0.25  # type: ignore[attr-defined]
    det.path = Path("nan-model.onnx")  # type: ignore[attr-defined]
    boxes = np.array([[50, 50, 20, 40], [np.nan, 50, 20, 40], [80, 50, 20, 40]], np.float32)
    preds = _fake_yolo_output(det, boxes, np.array([0.9, 0.9, 0.9], np.float32))
    yoloseg._NONFINITE_WARNED.discard(det.path)  # type: ignore[attr-defined]
    with pytest.warns(UserWarning, match="nan-model.onnx"):
        picked = det._pick(preds, 0)
    assert len(picked.rows) == 2 and np.isfinite(picked.rows).all()


# --- silent drops: a warning on stderr, exit 0 ----------------------------------------------------


def test_detections_past_seqlength_are_a_warning(tmp_path: Path) -> None:
    seq = _sequence(tmp_path, frames=30)
    _set_seqinfo(seq, seqLength="10")
    proc = _cli("run", str(seq), "--out", str(tmp_path / "t.txt"), "-q")
    assert proc.returncode == 0, proc.stderr
    warning = [line for line in proc.stderr.splitlines() if "warning" in line]
    assert len(warning) == 1 and "frames 11-30" in warning[0] and "seqLength" in warning[0]


def test_detections_outside_the_declared_image_are_a_warning(tmp_path: Path) -> None:
    seq = _sequence(tmp_path, frames=10)
    _set_seqinfo(seq, imWidth="200", imHeight="150")
    proc = _cli("run", str(seq), "--out", str(tmp_path / "t.txt"), "-q")
    assert proc.returncode == 0, proc.stderr
    assert "centred outside the 200x150 image" in proc.stderr, proc.stderr
    _set_seqinfo(seq, imWidth="640", imHeight="480")
    proc = _cli("run", str(seq), "--out", str(tmp_path / "t.txt"), "-q")
    assert "warning" not in proc.stderr, proc.stderr


def test_image_folder_of_mixed_sizes_is_a_warning(tmp_path: Path) -> None:
    from densepeds.io.video import ImageFolderSource

    folder = tmp_path / "frames"
    _images(folder, frames=2, size=(64, 48))
    cv2.imwrite(str(folder / "000003.jpg"), np.zeros((96, 128, 3), np.uint8))
    with pytest.warns(UserWarning, match="000003.jpg: 128x96, but the frames before it are 64x48"):
        shapes = [img.shape for _, img in ImageFolderSource(folder).frames()]  # type: ignore[union-attr]
    assert shapes[-1] == (96, 128, 3)


# --- tracebacks: absurd image sizes ---------------------------------------------------------------


@pytest.mark.parametrize(("key", "value"), [("imWidth", str(2**31 - 1)), ("imHeight", "100000")])
def test_absurd_image_size_is_refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, key: str, value: str
) -> None:
    seq = _sequence(tmp_path, frames=5)
    _set_seqinfo(seq, **{key: value})
    rc, _, err = _run(
        capsys,
        "run",
        str(seq),
        "--out",
        str(tmp_path / "t.txt"),
        "--video",
        str(tmp_path / "v.mp4"),
        "-q",
    )
    _one_line(rc, err, "seqinfo.ini:", key, "too large")
    assert not (tmp_path / "v.mp4").exists()


# --- native library noise -------------------------------------------------------------------------


def test_damaged_video_is_our_one_line_only(tmp_path: Path) -> None:
    video = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter.fourcc(*"MJPG"), 10, (160, 120))
    rng = np.random.default_rng(1)
    for _ in range(30):
        writer.write(rng.integers(0, 255, (120, 160, 3), np.uint8))
    writer.release()
    data = bytearray(video.read_bytes())
    data[len(data) // 3 : len(data) // 3 + 4000] = bytes(4000)  # a damaged stretch
    video.write_bytes(bytes(data[: 2 * len(data) // 3]))
    det = tmp_path / "det.txt"
    det.write_text("".join(f"{k},-1,10,10,20,40,0.9\n" for k in range(1, 31)))
    proc = _cli(
        "run",
        str(video),
        "--detections",
        str(det),
        "--out",
        str(tmp_path / "t.txt"),
        "--features",
        "none",
        "-q",
    )
    lines = proc.stderr.strip().splitlines()
    assert all(line.startswith("densepeds") for line in lines), proc.stderr


def test_scene_config_refuses_absurd_sizes() -> None:
    with pytest.raises(ParameterError, match="image size"):
        make_scene(frames=5, width=1_000_000)
