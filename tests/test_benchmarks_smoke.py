"""Every kept benchmark suite runs end to end on a few frames, so that none rots unseen.

The figures these runs print mean nothing (a handful of frames on a shared machine); each test
checks only that the suite runs and prints or writes its report's shape. The suites whose
``main`` takes ``argv`` run in this process, with the real videos cut to a few frames; the
others run as the command a maintainer types, with tiny arguments or ``--smoke``.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import REPO, shared_path

BENCH = REPO / "benchmarks"
sys.path.insert(0, str(BENCH))

FEW = "1:3"  # frames of each real video in the in-process runs


def _script(name: str, *args: str, timeout: float = 120) -> str:
    """``python benchmarks/NAME.py ARGS`` as a maintainer runs it; its stdout."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}  # the installed package, as a user has it
    done = subprocess.run(
        [sys.executable, str(BENCH / f"{name}.py"), *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=timeout,
    )
    assert done.returncode == 0, f"{name}.py {' '.join(args)}:\n{done.stdout}\n{done.stderr}"
    return done.stdout


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One cache of the few frames' detections and embeddings for the in-process suites."""
    return tmp_path_factory.mktemp("bench-cache")


@pytest.fixture
def few_frames(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The real videos cut to FEW frames wherever the suites read their frame ranges."""
    shared_path("data", "MOT20-01-dev")
    shared_path("data", "PETS09-S2L1-dev")
    shared_path("models")
    import accuracy_grid
    import realvideo

    videos = tuple((seq, FEW) for seq, _ in realvideo.VIDEOS)
    monkeypatch.setattr(realvideo, "VIDEOS", videos)
    monkeypatch.setattr(accuracy_grid, "VIDEOS", dict(videos))
    yield


def test_accuracy_grid(few_frames: None, cache: Path, tmp_path: Path, capsys: Any) -> None:
    shared_path("data", "TUD-Stadtmitte")
    import accuracy_grid

    out = tmp_path / "grid.json"
    cells = ["TUD-Stadtmitte/det", "PETS09-S2L1-dev/float"]
    argv = ["--cache", str(cache), "--cells", *cells, "--json", str(out), "-q"]
    assert accuracy_grid.main(argv) == 0
    result = json.loads(out.read_text())["cells"]
    assert sorted(result) == sorted(cells)
    assert all(0 <= m["HOTA"] <= 100 for m in result.values())
    assert "mean HOTA" in capsys.readouterr().out


def test_accuracy_tables(
    few_frames: None, cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``accuracy_grid.py --write`` into a temporary folder (the committed results stay as they
    are): the leave-one-out table on two cells, with three of its candidates."""
    import accuracy_grid
    import accuracy_tables

    monkeypatch.setattr(
        accuracy_tables, "CANDIDATES", dict(list(accuracy_tables.CANDIDATES.items())[:3])
    )

    argv = ["--cache", str(cache), "--cells", "TUD-Stadtmitte/det", "PETS09-S2L1-dev/float"]
    argv += ["--write", "--results", str(tmp_path), "--tables", "loo", "-q"]
    assert accuracy_grid.main(argv) == 0
    written = {p.name for p in tmp_path.glob("*.md")}
    assert written == {"accuracy-loo.md"}, written


def test_accuracy_grid_peers(few_frames: None, cache: Path, tmp_path: Path) -> None:
    """``accuracy_grid.py --write --tables peers``: every peer on the same inputs."""
    for module in ("trackforge", "trackers", "deep_sort_realtime", "motpy"):
        pytest.importorskip(module, reason="the peers extra: pip install -e '.[peers]'")
    import accuracy_grid

    argv = ["--cache", str(cache), "--cells", "TUD-Stadtmitte/det", "PETS09-S2L1-dev/float"]
    argv += ["--write", "--results", str(tmp_path), "--tables", "peers", "-q"]
    assert accuracy_grid.main(argv) == 0
    assert "roboflow-sort" in (tmp_path / "accuracy.md").read_text()


def test_realvideo(few_frames: None, cache: Path, tmp_path: Path, capsys: Any) -> None:
    import realvideo

    out = tmp_path / "realvideo.md"
    argv = ["--cache", str(cache), "--rows", "frvo:segmented,cv:none", "-q", "--write", str(out)]
    assert realvideo.main(argv) == 0
    text = out.read_text()
    assert "frvo" in text and "MOT20-01-dev" in text and "PETS09-S2L1-dev" in text


def test_detector_recall(few_frames: None, tmp_path: Path) -> None:
    import detector_recall

    out = tmp_path / "recall.md"
    argv = ["--tiles", "3x2", "--every", "1", "--videos", "MOT20-01-dev", "--write", str(out)]
    assert detector_recall.main(argv) == 0
    row = [line for line in out.read_text().splitlines() if line.startswith("| 3x2 |")]
    assert len(row) == 1 and "MOT20-01-dev" in row[0]


def test_jitter_check(capsys: Any) -> None:
    shared_path("data", "TUD-Stadtmitte")
    import jitter_check

    assert jitter_check.main(["--cells", "TUD-Stadtmitte/det", "--seeds", "2"]) == 0
    assert re.search(r"mean [\d.]+ \(min", capsys.readouterr().out)


def test_track_speed(capsys: Any) -> None:
    import track_speed

    argv = ["--frames", "5", "--repeat", "1", "--trackers", "densepeds-frvo"]
    assert track_speed.main(argv) == 0
    assert re.search(r"\| densepeds-frvo \| [\d.]+ / [\d.]+ \|", capsys.readouterr().out)


def test_appearance_speed() -> None:
    out = _script("appearance_speed", "--people", "40", "--frames", "2")
    assert re.search(r"^\| 40 \| \d+ \|", out, re.M), out


def test_pipeline_speed_against_the_reference() -> None:
    shared_path("data", "PETS09-S2L1-dev")
    shared_path("models")
    args = ["--seq", "PETS09-S2L1-dev", "--frames", "1:2", "--repeats", "1", "--only", "ours"]
    out = _script("pipeline_speed", *args)
    assert re.search(r"^\| reference \| [\d.]+ \|", out, re.M), out
    assert re.search(r"^\| ours \| [\d.]+ \|", out, re.M), out
    assert "Speed-up, reference / ours" in out


def test_memory() -> None:
    shared_path("data", "MOT20-01-dev")
    shared_path("models")
    out = _script("memory", "--frames", "1:3", "--at", "1,3", "--repeats", "1")
    assert re.search(r"^\| 3 \| \d+ / \d+ \| \d+ \|", out, re.M), out


def test_int8_speed() -> None:
    shared_path("data", "MOT20-01-dev")
    shared_path("data", "PETS09-S2L1-dev")
    shared_path("models")
    out = _script("int8_speed", "--smoke", "--frames", "1:2", "--every", "1", "--rounds", "1")
    assert re.search(r"^\| int8: .*\| [\d.]+ \| [\d.]+ \| [\d.]+x \|", out, re.M), out
    assert "| total |" in out


def test_batch_speed_sequential_runs(tmp_path: Path) -> None:
    """The part of ``batch_speed.py`` that needs no Ray: ``densepeds run`` per clip, its
    summary line read back (frames, frames per second, peak memory)."""
    shared_path("data", "PETS09-S2L1-dev")
    shared_path("data", "MOT20-01-dev")
    import batch_speed

    clips = batch_speed.write_clips(tmp_path / "clips", 2)
    result = batch_speed.sequential(clips[:1], tmp_path / "seq")
    (clip,) = result["clips"]
    assert clip["frames"] == 2 and clip["fps"] > 0 and clip["rss"] > 0


def test_batch_speed_with_ray(tmp_path: Path) -> None:
    pytest.importorskip("ray", reason="the ray extra: pip install -e '.[ray]'")
    shared_path("data", "PETS09-S2L1-dev")
    shared_path("data", "MOT20-01-dev")
    out = tmp_path / "batch.md"
    _script("batch_speed", "--frames", "1", "--no-cluster", "--out", str(out), timeout=300)
    assert "x sequential" in out.read_text()


def test_blocks(tmp_path: Path) -> None:
    """The block table on two motion-only cells and one block (seconds)."""
    shared_path("data", "TUD-Stadtmitte")
    shared_path("data", "KITTI-17")
    out_md = tmp_path / "blocks.md"
    _script(
        "blocks",
        "--cells", "TUD-Stadtmitte/det", "KITTI-17/det",
        "--blocks", "recovery",
        "--out", str(out_md),
        "--store", str(tmp_path / "store"),
        "--cache", str(tmp_path / "cache"),
    )  # fmt: skip
    text = out_md.read_text(encoding="utf-8")
    assert re.search(r"^\| recovery \| `recovery=False` \| [\d.]+ \| [\d.]+ \|", text, re.M), text
    assert "| KITTI-17 | 10 |" in text


def test_gpu_speed_runs_on_the_cpu(tmp_path: Path) -> None:
    """The prepared GPU measurement, on the CPU and two frames (the script a GPU machine runs)."""
    shared_path("data", "MOT20-01-dev")
    shared_path("data", "PETS09-S2L1-dev")
    shared_path("models")
    out = _script(
        "gpu_speed", "--device", "cpu", "--frames", "1:2", "--repeats", "1", "--warm", "1:1"
    )
    assert re.search(r"^\| PETS09-S2L1-dev \| 1:2 \| defaults \| [\d.]+ \|", out, re.M), out


def test_runtime_speed() -> None:
    """onnxruntime against OpenVINO, one round (needs the openvino extra)."""
    pytest.importorskip("openvino", reason="the openvino extra: pip install 'densepeds[openvino]'")
    shared_path("models")
    out = _script("runtime_speed", "--rounds", "1", "--repeats", "1")
    assert re.search(r"^\| OSNet x0.25, 16 crops \| OpenVINO \| [\d.]+ \|", out, re.M), out
