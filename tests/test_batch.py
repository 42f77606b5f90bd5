"""densepeds batch: inputs, plans and records without Ray; then, on one local Ray shared by the
module, results equal to `densepeds run`, a corrupt input failing alone, and a batch whose
worker is killed resuming with only the unfinished input."""

from __future__ import annotations

import json
import logging
import os
import shutil
import signal
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import shared_path
from densepeds import batch
from densepeds.batch.on_ray import check_reachable
from densepeds.batch.plan import Settings, expand_inputs, job_names
from densepeds.batch.worker import node_cache_dir
from densepeds.cli import main
from densepeds.errors import InputError, ParameterError
from densepeds.scene import make_scene

# --- without Ray: inputs, names, plans ---------------------------------------------------------


def _scene_seq(root: Path, seed: int, frames: int, images: bool = True) -> Path:
    return Path(make_scene(seed=seed, frames=frames).write(root / f"s{seed}", images=images))


def test_inputs_expand_folders_and_globs(tmp_path: Path) -> None:
    seq = _scene_seq(tmp_path / "archive", 0, 3, images=False)
    cams = tmp_path / "archive" / "cams"
    (cams / "north").mkdir(parents=True)
    (cams / "south").mkdir(parents=True)
    for name in ("north/cam.mp4", "south/cam.mp4", "south/b.avi"):
        (cams / name).write_bytes(b"not decoded here")
    (cams / "notes.txt").write_text("not an input")
    frames = tmp_path / "archive" / "frames"
    frames.mkdir()
    (frames / "000001.jpg").write_bytes(b"")
    (tmp_path / "archive" / ".hidden").mkdir()
    (tmp_path / "archive" / ".hidden" / "x.mp4").write_bytes(b"")

    found = expand_inputs([tmp_path / "archive"])
    assert found == [
        (cams / "north/cam.mp4").resolve(),
        (cams / "south/b.avi").resolve(),
        (cams / "south/cam.mp4").resolve(),
        frames.resolve(),
        seq.resolve(),
    ]
    # A glob expands like a folder; an input named twice counts once.
    assert expand_inputs([str(cams / "*" / "*.mp4"), cams / "north" / "cam.mp4"]) == [
        (cams / "north/cam.mp4").resolve(),
        (cams / "south/cam.mp4").resolve(),
    ]
    # A link is named as given, and counts once with what it points to.
    (tmp_path / "cam7").symlink_to(seq)
    assert expand_inputs([tmp_path / "cam7", seq]) == [tmp_path / "cam7"]
    # Inputs that share a name are told apart by their folder.
    assert job_names(found) == ["north-cam", "b", "south-cam", "frames", seq.name]
    with pytest.raises(InputError, match="no such file"):
        expand_inputs([tmp_path / "missing"])
    with pytest.raises(InputError, match="no file or folder matches"):
        expand_inputs([str(tmp_path / "*.mkv")])
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no videos"):
        expand_inputs([tmp_path / "empty"])


def test_settings_are_checked_before_any_input(tmp_path: Path) -> None:
    with pytest.raises(ParameterError):
        Settings(params=(("no_such_parameter", 1),)).check()
    with pytest.raises(ParameterError):
        Settings(frames="9:3").check()
    a = Settings(features="none").digest({})
    assert a == Settings(features="none").digest({})
    assert a != Settings(features="none", params=(("max_age", 30),)).digest({})
    assert a != Settings(features="none").digest({"reid": "0" * 64})
    assert a != Settings(features="none", fill_gaps=40).digest({})
    with pytest.raises(ParameterError, match="fill_gaps"):
        Settings(fill_gaps=-1).check()


def test_a_job_gets_runs_options(tmp_path: Path) -> None:
    """The batch settings reach the `run` options of each job, --fill-gaps included."""
    from types import SimpleNamespace

    from densepeds.batch.worker import run_args

    job = SimpleNamespace(input=tmp_path / "a.mp4", tracks=tmp_path / "a.txt", video_file=None)
    args = run_args(Settings(motion="cv", frames="1:9", fill_gaps=40), job, None)  # type: ignore[arg-type]
    assert (args.motion, args.frames, args.fill_gaps, args.out) == ("cv", "1:9", 40, job.tracks)
    assert run_args(Settings(), job, None).fill_gaps == 0  # type: ignore[arg-type]


def test_bad_batch_command_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    rc = main(["batch", str(tmp_path / "nope"), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "no such file" in err[0], err
    rc = main(["batch", str(tmp_path), "--out", str(tmp_path / "o"), "--param", "bogus=1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "bogus" in err[0], err
    # Nothing listens at the address: one line at once (Ray alone would retry for minutes).
    ray = pytest.importorskip("ray", reason="needs Ray: pip install 'densepeds[ray]'")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # closed again: nothing listens there
    with pytest.raises(ParameterError, match=f"cannot reach a Ray cluster at 127.0.0.1:{port}"):
        check_reachable(f"127.0.0.1:{port}")
    with pytest.raises(ParameterError, match="expected HOST:PORT"):
        check_reachable("head-node")
    if not ray.is_initialized():  # else batch.run would use the Ray already joined
        seq = _scene_seq(tmp_path / "in", 0, 2, images=False)
        argv = ["batch", str(seq), "--out", str(tmp_path / "o"), "--address", f"127.0.0.1:{port}"]
        rc = main(argv)
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and "cannot reach a Ray cluster" in err[0], err


# --- on a local Ray ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def ray_session() -> Iterator[Any]:
    """One local Ray for the module (starting one takes seconds); batch.run joins it."""
    ray = pytest.importorskip("ray", reason="needs Ray: pip install 'densepeds[ray]'")
    try:
        ray.init(
            address="local",
            num_cpus=2,
            include_dashboard=False,
            log_to_driver=False,
            logging_level=logging.WARNING,
        )
    except Exception as err:  # the one place Ray tests may skip: Ray cannot start here
        pytest.skip(f"a local Ray cannot start here: {err}")
    yield ray
    shutil.rmtree(node_cache_dir(), ignore_errors=True)  # this Ray node's copies of the models
    ray.shutdown()


def _run_tracks(capsys: pytest.CaptureFixture[str], out: Path, *argv: str) -> tuple[int, str]:
    rc = main(["run", *argv, "--out", str(out), "--quiet"])
    return rc, capsys.readouterr().err.strip()


def test_batch_equals_run_and_a_corrupt_input_fails_alone(
    ray_session: Any, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    pets = shared_path("data", "PETS09-S2L1-dev")
    shared_path("models", "yolov8n-seg-320-int8.onnx")
    scene = _scene_seq(tmp_path / "in", 3, 8)
    bad = tmp_path / "in" / "broken.avi"
    bad.write_bytes(b"RIFF" + bytes(range(256)) * 20)
    # A sequence (its det.txt, OSNet features), the same video as a file (YOLOv8-seg + OSNet),
    # the built-in scene with images, and a corrupt video.
    inputs = [str(pets), str(pets / "vtest.avi"), str(scene), str(bad)]
    out = tmp_path / "out"
    rc = main(["batch", *inputs, "--out", str(out), "--frames", "1:8", "--video", "--quiet"])
    table = capsys.readouterr().out
    assert rc == 1, table  # one input failed
    summary = json.loads((out / "batch.json").read_text())
    by_name = {r["name"]: r for r in summary["inputs"]}
    assert set(by_name) == {"PETS09-S2L1-dev", "vtest", scene.name, "broken"}

    for name, source in [
        ("PETS09-S2L1-dev", pets),
        ("vtest", pets / "vtest.avi"),
        (scene.name, scene),
    ]:
        rec = by_name[name]
        assert rec["status"] == "done" and rec["frames"] == 8 and rec["tracks"] > 0, rec
        rc, _ = _run_tracks(
            capsys, tmp_path / "run" / f"{name}.txt", str(source), "--frames", "1:8"
        )
        assert rc == 0
        ours = (out / f"{name}.txt").read_text()
        assert ours == (tmp_path / "run" / f"{name}.txt").read_text(), name
        assert len({line.split(",")[1] for line in ours.splitlines()}) == rec["tracks"]
        video = out / f"{name}.mp4"
        assert rec["video_file"] == video.name and video.stat().st_size > 0
        assert f"| {name} | done | 8 | {rec['tracks']} |" in table

    # The corrupt input fails with `run`'s own one-line message; nothing else is written for it.
    rc, err = _run_tracks(capsys, tmp_path / "run" / "broken.txt", str(bad))
    assert rc == 2
    assert by_name["broken"]["status"] == "failed"
    assert err == f"densepeds run: error: {by_name['broken']['error']}"
    assert not (out / "broken.txt").exists() and not (out / "broken.mp4").exists()
    assert "| broken | failed |" in table
    # Each model file reached this (single) node once.
    fetched = [m for r in summary["inputs"] for m in r["fetched_models"]]
    assert sorted(fetched) == sorted(set(fetched)) and "osnet_x0_25_msmt17.onnx" in fetched


def _wait_running(record: Path, timeout: float = 120.0) -> int:
    """The pid of the worker once the job's record says it is running."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            data = json.loads(record.read_text())
            if data["status"] == "running" and data["pid"]:
                return int(data["pid"])
        except (OSError, ValueError):
            pass
        time.sleep(0.02)
    raise AssertionError(f"{record} never said running")


def test_killed_worker_loses_only_its_input_and_the_rerun_completes_it(
    ray_session: Any, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    seqs = [_scene_seq(tmp_path / "in", seed, 6) for seed in (0, 1, 2)]
    out = tmp_path / "out"
    options: dict[str, Any] = {"features": "segmented", "workers": 1}
    victim = out / f"{seqs[1].name}.json"
    results: list[batch.BatchResult] = []
    worker = threading.Thread(target=lambda: results.append(batch.run(seqs, out, **options)))
    worker.start()
    os.kill(_wait_running(victim), signal.SIGKILL)
    worker.join(timeout=300)
    first = results[0]
    status = [r.status for r in first.records]
    assert status == ["done", "failed", "done"], [r.error for r in first.records]
    assert "worker lost" in (first.records[1].error or "")
    assert not (out / f"{seqs[1].name}.txt").exists()

    # The rerun redoes only the killed input; the others keep their files untouched, and what
    # an interrupted job leaves in temporary files is removed.
    kept = {s.name: (out / f"{s.name}.txt").stat().st_mtime_ns for s in (seqs[0], seqs[2])}
    leftover = out / f".{seqs[1].name}.txt.k1ll3d.tmp"
    leftover.write_text("partial")
    second = batch.run(seqs, out, **options)
    assert not leftover.exists()
    assert [r.skipped for r in second.records] == [True, False, True]
    assert [r.status for r in second.records] == ["done"] * 3
    assert kept == {s.name: (out / f"{s.name}.txt").stat().st_mtime_ns for s in (seqs[0], seqs[2])}
    # The completed input equals a single run of it.
    rc = main(["run", str(seqs[1]), "--out", str(tmp_path / "single.txt"), "--quiet"])
    assert rc == 0
    assert (out / f"{seqs[1].name}.txt").read_text() == (tmp_path / "single.txt").read_text()

    # Now all is done for these settings; other settings redo every input.
    plan = batch.prepare(seqs, out, Settings(features="segmented")).items
    assert [(i.action, i.reason) for i in plan] == [("skip", "done")] * 3
    rc = main(["batch", *map(str, seqs), "--out", str(out), "--features", "segmented", "--dry-run"])
    assert rc == 0 and capsys.readouterr().out.count("| skip | done |") == 3
    plan = batch.prepare(seqs, out, Settings(features="none")).items
    assert [(i.action, i.reason) for i in plan] == [("run", "settings changed")] * 3
    # A changed input is redone.
    det = seqs[2] / "det" / "det.txt"
    det.write_text(det.read_text() + "\n")
    plan = batch.prepare(seqs, out, Settings(features="segmented")).items
    assert [i.reason for i in plan] == ["done", "done", "input changed"]


def test_readme_batch_commands_parse() -> None:
    """Every `python -m densepeds batch ...` line in docs/usage.md's batch section parses."""
    import re

    from conftest import REPO
    from densepeds.cli import build_parser

    text = (REPO / "docs" / "usage.md").read_text(encoding="utf-8")
    section = re.search(
        r"^## Many inputs at once: `densepeds batch`\n(.*?)(?=^## |\Z)", text, re.S | re.M
    )
    assert section, "docs/usage.md has no batch section"
    commands = re.findall(r"^python -m densepeds (batch .*)$", section.group(1), re.M)
    assert len(commands) >= 3
    for line in commands:
        args = build_parser().parse_args(line.split("#")[0].split())
        assert args.command == "batch" and args.out is not None
