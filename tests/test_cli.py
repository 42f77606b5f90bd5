"""The command line end to end: output files and metrics, and one-line errors for mistakes."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import REPO, shared_path
from densepeds.cli import main
from densepeds.io.mot import read_gt, read_tracks


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def _one_line_error(rc: int, err: str, *needles: str) -> None:
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for needle in needles:
        assert needle in lines[0], lines[0]


# --- mistakes: one line on stderr, exit 2 ------------------------------------------------------


def test_missing_input(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    rc, _, err = _run(capsys, "run", str(tmp_path / "nope.mp4"))
    _one_line_error(rc, err, "nope.mp4", "no such file")


def test_corrupt_video(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    bad = tmp_path / "broken.avi"
    bad.write_bytes(b"RIFF" + bytes(range(256)) * 20)
    rc, _, err = _run(capsys, "run", str(bad))
    _one_line_error(rc, err, "broken.avi", "cannot decode")


def test_unknown_option_values(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["run", "--motion", "teleport"])
    _, err = capsys.readouterr()
    _one_line_error(int(exc.value.code or 0), err, "teleport")
    with pytest.raises(SystemExit) as exc:
        main(["ablate", "--features", "segmented,colour"])
    _, err = capsys.readouterr()
    _one_line_error(int(exc.value.code or 0), err, "colour")
    rc, _, err = _run(capsys, "run", "--frames", "9:3")
    _one_line_error(rc, err, "9:3")


def test_malformed_det_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    seq = shared_path("data", "TUD-Stadtmitte")
    bad = tmp_path / "det.txt"
    bad.write_text("1,-1,10,10,5,9,0.9\n2,-1,10,ten,5,9,0.9\n")
    rc, _, err = _run(capsys, "run", str(seq), "--detections", str(bad))
    _one_line_error(rc, err, f"{bad}:2")


def test_features_need_frames(capsys: pytest.CaptureFixture[str]) -> None:
    seq = shared_path("data", "TUD-Stadtmitte")
    rc, _, err = _run(capsys, "run", str(seq), "--features", "segmented")
    _one_line_error(rc, err, "--features none")


def test_model_mismatch(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    fake = tmp_path / "reid.onnx"
    fake.write_bytes(b"not an onnx model")
    rc, _, err = _run(
        capsys, "run", str(video), "--detections", str(REPO / "missing-but-unused.txt")
    )
    _one_line_error(rc, err, "missing-but-unused.txt")
    rc, _, err = _run(capsys, "run", str(video), "--reid-model", str(fake), "--frames", "1:2")
    _one_line_error(rc, err, "reid.onnx")


def test_python_m_prints_no_traceback(tmp_path: Path) -> None:
    env = dict(os.environ)  # the installed package, as a user runs it
    proc = subprocess.run(
        [sys.executable, "-m", "densepeds", "eval", "--gt", str(tmp_path / "x"), "--tracks", "t"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    _one_line_error(proc.returncode, proc.stderr, "ground-truth")


# --- end to end ---------------------------------------------------------------------------------


def test_run_and_eval_from_det_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """Motion only from TUD-Stadtmitte's det.txt, then `eval` on the written file."""
    seq = shared_path("data", "TUD-Stadtmitte")
    out = tmp_path / "tud.txt"
    rc, stdout, _ = _run(capsys, "run", str(seq), "--out", str(out), "--quiet")
    assert rc == 0 and "179 frames" in stdout and str(out) in stdout
    tracks = read_tracks(out)
    assert len(tracks) > 500
    assert tracks[:, 0].min() >= 1 and tracks[:, 0].max() <= 179
    assert len(np.unique(tracks[:, 1])) >= 8
    rc, stdout, _ = _run(capsys, "eval", "--gt", str(seq), "--tracks", str(out), "--format", "json")
    assert rc == 0
    combined = json.loads(stdout)["combined"]
    assert combined["MOTA"] > 30 and combined["IDF1"] > 30
    # A frame range keeps MOT numbering.
    part = tmp_path / "part.txt"
    assert main(["run", str(seq), "--frames", "50:59", "--out", str(part), "-q"]) == 0
    frames = read_tracks(part)[:, 0]
    assert frames.min() >= 50 and frames.max() <= 59


def test_pets_video_with_real_models(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """yoloseg + segmented boxes + OSNet + FRVO on the first 20 frames of vtest.avi.

    MOTA is not asserted: it is dominated by the detector's false positives (people outside
    the annotated area, duplicate boxes), which are the perception layer's to tune. The floors
    check that tracks land on the annotated people and keep their identities."""
    seq = shared_path("data", "PETS09-S2L1-dev")
    shared_path("models", "yolov8n-seg-320-int8.onnx")
    shared_path("models", "osnet_x0_25_msmt17.onnx")
    from densepeds.ablate import cut_gt
    from densepeds.evaluate import evaluate
    from densepeds.io.video import FrameRange, SequenceSource

    out, video = tmp_path / "pets.txt", tmp_path / "pets.mp4"
    rc, stdout, _ = _run(
        capsys,
        "run",
        str(seq / "vtest.avi"),
        "--detector",
        "yoloseg",
        "--frames",
        "1:20",
        "--out",
        str(out),
        "--video",
        str(video),
        "-q",
    )
    assert rc == 0 and "20 frames" in stdout
    assert re.search(r"detection [\d.]+, reid [\d.]+, tracking", stdout)
    assert "frames/s for the whole pipeline; timed: decode + detection + reid" in stdout
    tracks = read_tracks(out)
    assert set(np.unique(tracks[:, 0])) <= set(range(1, 21))
    import cv2

    cap = cv2.VideoCapture(str(video))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 20
    cap.release()
    gt_dir = cut_gt(SequenceSource(seq), FrameRange(1, 20), tmp_path / "gt")
    combined = evaluate([gt_dir], out).combined
    n_gt = len(read_gt(gt_dir / "gt" / "gt.txt"))
    assert n_gt > 50 and combined["FN"] < 0.3 * n_gt  # most annotated people are tracked
    assert combined["MOTP"] > 60 and combined["IDF1"] > 30


def test_builtin_scene(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """`densepeds run` with no input: the scene, its metrics, tracks and an annotated video."""
    out, video = tmp_path / "scene.txt", tmp_path / "scene.avi"
    rc, stdout, _ = _run(
        capsys, "run", "--scene-frames", "60", "--out", str(out), "--video", str(video), "-q"
    )
    assert rc == 0 and "people/m^2" in stdout
    row = next(line for line in stdout.splitlines() if line.startswith("| **COMBINED**"))
    header = next(line for line in stdout.splitlines() if line.startswith("| sequence"))
    values = dict(zip(header.strip("| ").split(" | "), row.strip("| ").split(" | "), strict=True))
    assert float(values["MOTA"]) > 50
    assert len(read_tracks(out)) > 1000 and video.stat().st_size > 10_000


def test_builtin_scene_without_trackeval_tracks_and_says_it_did_not_score(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The core install (no eval extra) runs the scene, writes tracks, and names what scores."""
    import importlib.util

    real_find_spec = importlib.util.find_spec

    def no_trackeval(name: str, *args: object, **kwargs: object) -> object:
        return None if name == "trackeval" else real_find_spec(name, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(importlib.util, "find_spec", no_trackeval)
    out = tmp_path / "scene.txt"
    rc, stdout, err = _run(capsys, "run", "--scene-frames", "20", "--out", str(out), "-q")
    assert rc == 0, err
    assert "not scored: trackeval is not installed" in stdout and "densepeds[eval]" in stdout
    assert "| **COMBINED**" not in stdout
    assert len(read_tracks(out)) > 100


def test_scene_command_writes_a_sequence_that_run_and_eval_accept(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    rc, stdout, _ = _run(capsys, "scene", str(tmp_path), "--frames", "30", "--no-images")
    assert rc == 0
    seq = tmp_path / "DensePeds-scene-0"
    out = tmp_path / "t.txt"
    assert main(["run", str(seq), "--out", str(out), "-q"]) == 0
    capsys.readouterr()
    rc, stdout, _ = _run(capsys, "eval", "--gt", str(seq), "--tracks", str(out), "--format", "csv")
    assert rc == 0
    header, first, *_ = stdout.splitlines()
    mota = float(first.split(",")[header.split(",").index("MOTA")])
    assert mota > 50


def test_ablate_on_the_scene(capsys: pytest.CaptureFixture[str]) -> None:
    rc, stdout, _ = _run(
        capsys, "ablate", "--motion", "cv,frvo", "--features", "segmented,none", "--frames", "1:50"
    )
    assert rc == 0
    rows = [line for line in stdout.splitlines() if line.startswith("| ") and "---" not in line]
    assert rows[0].startswith("| Motion | Features |") and "MOTA(%)" in rows[0]
    combos = {tuple(r.strip("| ").split(" | ")[:2]) for r in rows[1:]}
    assert combos == {("cv", "segmented"), ("cv", "none"), ("frvo", "segmented"), ("frvo", "none")}


def test_run_offers_every_masking(capsys: pytest.CaptureFixture[str]) -> None:
    from densepeds.cli import build_parser
    from densepeds.pipeline import FEATURES

    for kind in FEATURES:
        assert build_parser().parse_args(["run", "x.mp4", "--features", kind]).features == kind
    with pytest.raises(SystemExit):
        build_parser().parse_args(["run", "x.mp4", "--features", "white"])
    capsys.readouterr()


# --- the CLI as users of other tools expect it (issue 18) ------------------------------------


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    from densepeds import __version__

    for flag in ("--version", "-V"):
        with pytest.raises(SystemExit) as exc:
            main([flag])
        assert exc.value.code == 0
        assert capsys.readouterr().out.strip() == f"densepeds {__version__}"


def test_mistyped_command_is_not_an_input_file(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    for word, needle in (("evl", "did you mean 'eval'?"), ("modles", "did you mean 'models'?")):
        with pytest.raises(SystemExit) as exc:
            main([word, "--gt", "x"])
        _, err = capsys.readouterr()
        _one_line_error(int(exc.value.code or 0), err, f"unknown command '{word}'", needle)
    with pytest.raises(SystemExit) as exc:
        main(["frobnicate"])
    _, err = capsys.readouterr()
    _one_line_error(int(exc.value.code or 0), err, "unknown command 'frobnicate'", "run, eval")
    assert "did you mean" not in err
    # A path-like word is still an input for `run`, which says it is missing; an existing
    # file named like a command-ish word is an input too.
    rc, _, err = _run(capsys, "clip.mp4")
    _one_line_error(rc, err, "clip.mp4", "no such file")
    (tmp_path / "frobnicate").write_bytes(b"x")
    rc, _, err = _run(capsys, "frobnicate")
    assert rc == 2 and "unknown command" not in err


def test_every_option_has_help() -> None:
    import argparse

    from densepeds.cli import build_parser

    def walk(parser: argparse.ArgumentParser, name: str) -> list[str]:
        missing = []
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub_name, sub in action.choices.items():
                    missing += walk(sub, f"{name} {sub_name}")
            elif not action.help or action.help == argparse.SUPPRESS:
                missing.append(f"{name}: {action.option_strings or action.dest}")
        return missing

    assert walk(build_parser(), "densepeds") == []


def test_eval_help_describes_its_options(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["eval", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "--gt SEQ_DIR [SEQ_DIR ...] ground-truth sequence folder(s)" in out
    assert "--format {md,csv,json} output format" in out
    assert "--frames A:B score only frames" in out
    assert "pip install 'densepeds[eval]' && python -m densepeds.install_trackeval" in out


def test_speed_says_what_was_timed(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """A det-file run's frames/s is the tracker's, and says so (not the pipeline's speed)."""
    seq = shared_path("data", "TUD-Stadtmitte")
    rc, stdout, _ = _run(capsys, "run", str(seq), "--frames", "1:20", "--out", str(tmp_path / "t"))
    assert rc == 0
    assert re.search(
        r"[\d.]+ frames/s for tracking from given detections \(no detector ran\); timed: "
        r"[a-z +]*tracking",
        stdout,
    ), stdout
    assert "whole pipeline" not in stdout and " fps" not in stdout


def test_model_mixup_names_the_cli_flag(capsys: pytest.CaptureFixture[str]) -> None:
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    yolo = shared_path("models", "yolov8n-seg-320-int8.onnx")
    osnet = shared_path("models", "osnet_x0_25_msmt17.onnx")
    rc, _, err = _run(capsys, "run", str(video), "--reid-model", str(yolo), "--frames", "1:2")
    _one_line_error(rc, err, str(yolo), "--reid-model", "detector given as the re-ID model")
    assert "pass kind=" not in err
    rc, _, err = _run(capsys, "run", str(video), "--detector-model", str(osnet), "--frames", "1:2")
    _one_line_error(rc, err, str(osnet), "--detector-model")


# --- eval --frames -----------------------------------------------------------------------------


def test_eval_frames_scores_a_partial_run(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """`eval --frames 50:89` on a run of frames 50-89 gives the scores of the same tracks against
    a ground truth holding only those frames (an independent route: frames without gt or tracks
    add nothing to HOTA, CLEAR or IDF1); without --frames, a warning and lower scores."""
    from densepeds.evaluate import METRICS, evaluate

    seq = shared_path("data", "TUD-Stadtmitte")
    out = tmp_path / "part.txt"
    assert main(["run", str(seq), "--frames", "50:89", "--out", str(out), "-q"]) == 0
    capsys.readouterr()
    rc, stdout, err = _run(
        capsys,
        "eval",
        "--gt",
        str(seq),
        "--tracks",
        str(out),
        "--frames",
        "50:89",
        "--format",
        "json",
    )
    assert rc == 0 and err == ""
    scored = json.loads(stdout)["combined"]

    ref = tmp_path / "ref" / seq.name
    (ref / "gt").mkdir(parents=True)
    (ref / "seqinfo.ini").write_text((seq / "seqinfo.ini").read_text())
    lines = (seq / "gt" / "gt.txt").read_text().splitlines()
    kept = [line for line in lines if 50 <= int(float(line.split(",")[0])) <= 89]
    (ref / "gt" / "gt.txt").write_text("\n".join(kept) + "\n")
    reference = evaluate([ref], out)
    assert reference.warnings == []
    for metric in (*METRICS, "IDP", "IDR", "GT_IDs", "IDs"):
        assert scored[metric] == pytest.approx(reference.combined[metric], abs=1e-9), metric
    assert scored["MOTA"] > 20  # real tracking, not an empty comparison

    rc, stdout, err = _run(capsys, "eval", "--gt", str(seq), "--tracks", str(out))
    assert rc == 0
    assert re.search(r"warning: .*tracks cover frames 5[01]-89 but the ground truth 1-179", err)
    assert "eval --frames" in err
    whole = evaluate([seq], out).combined
    assert whole["HOTA"] < scored["HOTA"] - 10 and whole["FN"] > scored["FN"]


def test_eval_frames_mistakes(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    seq = shared_path("data", "TUD-Stadtmitte")
    tracks = tmp_path / "t.txt"
    tracks.write_text("1,1,10,10,20,40,1,-1,-1,-1\n")
    rc, _, err = _run(capsys, "eval", "--gt", str(seq), "--tracks", str(tracks), "--frames", "9:3")
    _one_line_error(rc, err, "9:3")
    rc, _, err = _run(capsys, "eval", "--gt", str(seq), "--tracks", str(tracks), "--frames", "500:")
    _one_line_error(rc, err, "past the end", "179 frames")


def test_eval_without_trackeval_says_what_to_install(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    seq = shared_path("data", "TUD-Stadtmitte")
    tracks = tmp_path / "t.txt"
    tracks.write_text("1,1,10,10,20,40,1,-1,-1,-1\n")
    monkeypatch.setitem(sys.modules, "trackeval", None)  # import fails as if not installed
    rc, _, err = _run(capsys, "eval", "--gt", str(seq), "--tracks", str(tracks))
    _one_line_error(
        rc, err, "pip install 'densepeds[eval]' && python -m densepeds.install_trackeval"
    )


def test_eval_benchmark_option(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """The rules can be named on the command line, and the error for class-less gt says how."""
    seq = shared_path("data", "TUD-Stadtmitte")
    tracks = tmp_path / "t.txt"
    gt_rows = (seq / "gt" / "gt.txt").read_text().splitlines()[:50]
    tracks.write_text("".join(",".join(r.split(",")[:6]) + ",1,-1,-1,-1\n" for r in gt_rows))
    rc, _, err = _run(
        capsys, "eval", "--gt", str(seq), "--tracks", str(tracks), "--benchmark", "MOT17"
    )
    _one_line_error(rc, err, "--benchmark MOT15")
    runs = {}
    for bench in ("auto", "MOT15"):
        rc, out, _ = _run(
            capsys,
            "eval",
            "--gt",
            str(seq),
            "--tracks",
            str(tracks),
            "--benchmark",
            bench,
            "--format",
            "json",
        )
        assert rc == 0
        runs[bench] = json.loads(out)
    assert runs["auto"] == runs["MOT15"] and runs["MOT15"]["benchmarks"][seq.name] == "MOT15"
    assert runs["MOT15"]["combined"]["FP"] == 0  # the tracks are gt boxes


def test_tiles_option(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """--tiles reaches the detector; a bad grid or a run without a detector is one line."""
    seq = shared_path("data", "PETS09-S2L1-dev")
    out = tmp_path / "t.txt"
    rc, _, err = _run(capsys, "run", str(seq), "--frames", "1:3", "--tiles", "2x2", "-q")
    _one_line_error(rc, err, "--tiles", "--detector yoloseg")
    base = ("run", str(seq), "--detector", "yoloseg", "--frames", "1:2", "--out", str(out), "-q")
    rc, _, err = _run(capsys, *base, "--tiles", "9q")
    _one_line_error(rc, err, "tiles", "9q")
    rc, _, err = _run(capsys, *base, "--tiles", "2x2")
    assert rc == 0, err
    assert out.exists()


def test_full_scan_every_option(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--full-scan-every reaches the yoloseg detector; without it the detector scans every frame;
    a run that does not detect with yoloseg, or a K below 1, is one line."""
    from densepeds.detect import yoloseg

    seq = shared_path("data", "PETS09-S2L1-dev")
    out = tmp_path / "t.txt"
    rc, _, err = _run(capsys, "run", str(seq), "--frames", "1:3", "--full-scan-every", "2", "-q")
    _one_line_error(rc, err, "--full-scan-every", "--detector yoloseg")
    seen: list[int] = []
    plain_init = yoloseg.YoloSegDetector.__init__

    def init(self: yoloseg.YoloSegDetector, *args: object, **kwargs: object) -> None:
        plain_init(self, *args, **kwargs)  # type: ignore[arg-type]
        seen.append(self.grid_schedule.full_scan_every)

    monkeypatch.setattr(yoloseg.YoloSegDetector, "__init__", init)
    base = ("run", str(seq), "--detector", "yoloseg", "--frames", "1:2", "--out", str(out), "-q")
    rc, _, err = _run(capsys, *base, "--tiles", "2x2", "--full-scan-every", "0")
    _one_line_error(rc, err, "full_scan_every", "0")
    rc, _, err = _run(capsys, *base, "--tiles", "2x2", "--full-scan-every", "3")
    assert rc == 0, err
    rc, _, err = _run(capsys, *base, "--tiles", "2x2")
    assert rc == 0, err
    assert seen == [3, 1] and out.exists()


def test_fill_gaps_option(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """--fill-gaps writes the online run's tracks with each short gap between a track's
    detections interpolated (densepeds.gaps.fill_gaps of the same run's rows); a negative N is
    one line before any frame is tracked."""
    from densepeds import pipeline as pipeline_module
    from densepeds.gaps import fill_gaps

    seq = shared_path("data", "TUD-Stadtmitte")
    online, filled = tmp_path / "online.txt", tmp_path / "filled.txt"
    plain_rows = pipeline_module.track_rows
    base = ("run", str(seq), "--frames", "1:80", "-q")
    assert main([*base, "--out", str(online)]) == 0
    seen: list[list[float]] = []

    def spy(frame_no: int, tracks: Any) -> list[tuple[float, ...]]:
        out = plain_rows(frame_no, tracks)
        seen.extend([*r, float(m)] for r, m in zip(out, tracks.det_index >= 0, strict=True))
        return out

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pipeline_module, "track_rows", spy)
        assert main([*base, "--out", str(filled), "--fill-gaps", "10"]) == 0
    want = fill_gaps(np.array(seen), 10)
    got = read_tracks(filled)
    assert len(got) == len(want) and len(got) > len(read_tracks(online))
    key = np.lexsort((got[:, 1], got[:, 0]))
    wkey = np.lexsort((want[:, 1], want[:, 0]))
    np.testing.assert_allclose(got[key, :2], want[wkey, :2])
    np.testing.assert_allclose(got[key, 2:4], want[wkey, 2:4], atol=1e-3)
    rc, _, err = _run(capsys, *base, "--out", str(tmp_path / "x.txt"), "--fill-gaps", "-1")
    _one_line_error(rc, err, "--fill-gaps", "-1")
    assert not (tmp_path / "x.txt").exists()
