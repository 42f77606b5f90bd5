"""Command line: ``python -m densepeds run|eval|ablate|scene|models|batch``.

User mistakes (missing files, bad option values, unreadable video, malformed det files, model
mismatches) print one line to stderr and exit 2; there is no traceback for them.
"""

from __future__ import annotations

import argparse
import difflib
import signal
import sys
import tempfile
import textwrap
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NoReturn

from densepeds.errors import DensePedsError, InputError, ParameterError, warnings_as_lines
from densepeds.pipeline import DEFAULT_FEATURES, DETECTORS, FEATURES, MOTIONS
from densepeds.presets import DEFAULT_PRESET, PRESETS, preset_for

EXIT_USAGE = 2
EXIT_INTERRUPT = 130  # 128 + SIGINT, as shells report Ctrl-C
COMMANDS = ("run", "eval", "ablate", "scene", "models", "batch")
FORMATS = ("md", "csv", "json")
FORMAT_HELP = "output format: md (Markdown table), csv, or json (every metric, full precision)"
PARAM_HELP = (
    "tracker parameter, e.g. max_age=30 (repeatable; the names are "
    "densepeds.tracking.Tracker().params)"
)


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad command line in one line (no usage block)."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message} (see --help)\n")
        sys.exit(EXIT_USAGE)


def _tracker_param(text: str) -> tuple[str, Any]:
    key, sep, raw = text.partition("=")
    if not sep or not key.isidentifier():
        raise argparse.ArgumentTypeError(f"{text!r}: expected KEY=VALUE")
    if key == "motion":
        raise argparse.ArgumentTypeError(f"{text!r}: the motion model is set with --motion")
    value: Any = raw
    low = raw.lower()
    if low in ("true", "false"):
        value = low == "true"
    else:
        for kind in (int, float):
            try:
                value = kind(raw)
                break
            except ValueError:
                pass
    return key, value


def _csv_choices(allowed: tuple[str, ...]) -> Any:
    def parse(text: str) -> list[str]:
        items = [t.strip() for t in text.split(",") if t.strip()]
        bad = [t for t in items if t not in allowed]
        if bad or not items:
            raise argparse.ArgumentTypeError(
                f"{text!r}: expected a comma-separated subset of {','.join(allowed)}"
            )
        return items

    return parse


def _presets_help() -> str:
    """The presets, one entry each, for ``run --help``."""
    lines = ["presets (--param KEY=VALUE overrides a value):"]
    for p in PRESETS.values():
        lines += textwrap.wrap(p.describe(), 96, initial_indent="  ", subsequent_indent="      ")
    return "\n".join(lines)


def _add_param_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--param",
        metavar="KEY=VALUE",
        type=_tracker_param,
        action="append",
        default=[],
        help=PARAM_HELP,
    )


def build_parser() -> argparse.ArgumentParser:
    from densepeds import __version__
    from densepeds.evaluate import BENCHMARKS, INSTALL_HINT

    parser = _Parser(
        prog="densepeds",
        description="Pedestrian tracking in dense crowds. `densepeds [INPUT]` means "
        "`densepeds run [INPUT]`.",
    )
    parser.add_argument("--version", "-V", action="version", version=f"densepeds {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser, metavar="COMMAND")

    run = sub.add_parser(
        "run",
        help="track a video, image folder or MOTChallenge sequence (no INPUT: the built-in scene)",
        description="Track people. With no INPUT, tracks the built-in dense-crowd scene and "
        "prints its metrics.",
        epilog=_presets_help(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument(
        "input",
        nargs="?",
        help="video file, image folder or MOTChallenge sequence folder (seqinfo.ini, img1/ "
        "and/or det/det.txt)",
    )
    run.add_argument(
        "--detections",
        metavar="FILE",
        help="MOTChallenge det.txt to track from (overrides a sequence's det/det.txt)",
    )
    run.add_argument(
        "--detector",
        choices=DETECTORS,
        help="detect people in the frames with this CNN (default: yoloseg where there are "
        "frames and no det file)",
    )
    run.add_argument("--detector-model", metavar="PATH", help=DETECTOR_MODEL_HELP)
    run.add_argument(
        "--tiles",
        metavar="auto|CxR|none",
        help="the CNN detector's views of a frame: auto (default) tiles that follow the people "
        "(at most twice the fixed grid's views); CxR a fixed grid of overlapping tiles, e.g. 3x2 "
        "(faster, fewer people found in crowds); none the whole frame in one view",
    )
    run.add_argument(
        "--full-scan-every",
        metavar="K",
        type=int,
        help="the yoloseg detector runs all its views every K-th frame only, and in between just "
        "views of the people found in the last K frames (windows of the tiles' sizes placed over "
        "them, or the tiles that show them, whichever are fewer; faster, the tracks change); "
        "default 1: all views every frame",
    )
    run.add_argument(
        "--focus-lost",
        metavar="S",
        type=float,
        help="the yoloseg detector also looks closer at each person the tracker reports without "
        "a detection (lost behind others): one more view a frame each, of the model input's "
        "shape, its longer side S times their height (more people found in dense crowds, "
        "slower there); 0 turns it off; default: "
        "the detector's own (YoloSegDetector's focus_scale)",
    )
    run.add_argument("--reid-model", metavar="PATH", help=REID_MODEL_HELP)
    run.add_argument(
        "--reid-reuse",
        action="store_true",
        help="a detection that plainly continues one of the previous frame's (it alone overlaps "
        "it, with the same colours; with nearly the same where nobody else is near) keeps that "
        "re-ID embedding, for up to 4 frames in a row, instead of a new one "
        "(densepeds.reid.ReusePolicy): less re-ID work, the tracks may change",
    )
    run.add_argument(
        "--motion",
        choices=MOTIONS,
        default="frvo",
        help="motion model: frvo (the method), rvo, sf (social forces), cv (constant "
        "velocity); default frvo",
    )
    run.add_argument(
        "--preset",
        choices=PRESETS,
        help="settings for the detections (listed below); default: the detector's own, "
        f"{DEFAULT_PRESET} for det files",
    )
    run.add_argument(
        "--features",
        choices=FEATURES,
        help=f"appearance features: segmented (the method's white fill outside the mask), bbox "
        f"(plain crop), masked_pool (mask-weighted pooling of the re-ID features), masked_mean, "
        f"masked_blur (other fills), none (motion only); default: {DEFAULT_FEATURES} where "
        f"there are frames (segmented on the built-in scene), else none",
    )
    run.add_argument(
        "--frames", metavar="A:B", help="frame range, 1-based and inclusive (A:, :B and A work)"
    )
    run.add_argument(
        "--out",
        metavar="TRACKS.txt",
        type=Path,
        help="tracks output file, MOTChallenge format (default: out/<input name>.txt)",
    )
    run.add_argument("--video", metavar="OUT.mp4", type=Path, help="annotated video output")
    run.add_argument(
        "--fill-gaps",
        metavar="N",
        type=int,
        default=0,
        help="after the run, replace what each track reported between two of its detections at "
        "most N frames apart (coasted boxes, or none) by the straight line between them: an "
        "offline step, in the tracks file only (--video shows the online tracks); default 0: off",
    )
    _add_param_option(run)
    run.add_argument("--seed", type=int, default=0, help="built-in scene: random seed")
    run.add_argument("--scene-frames", type=int, default=150, help="built-in scene: frames")
    run.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    run.add_argument(
        "--allow-partial",
        action="store_true",
        help="keep the tracks of a input that ends before its expected frame count (a truncated "
        "video, an image folder shorter than its seqLength) instead of failing",
    )

    ev = sub.add_parser(
        "eval",
        help="HOTA, MOTA, IDF1, ... of tracks against ground truth",
        description="Score MOTChallenge tracks against ground truth with TrackEval (HOTA, "
        f"CLEAR MOT, IDF1). Needs TrackEval: {INSTALL_HINT}",
    )
    ev.add_argument(
        "--gt",
        nargs="+",
        required=True,
        metavar="SEQ_DIR",
        type=Path,
        help="ground-truth sequence folder(s), each with gt/gt.txt (and seqinfo.ini for the "
        "length); MOT15/17/20 rules are chosen from the gt columns and the name",
    )
    ev.add_argument(
        "--tracks",
        required=True,
        metavar="PATH",
        type=Path,
        help="a tracks file (one sequence) or a folder of SEQNAME.txt",
    )
    ev.add_argument(
        "--frames",
        metavar="A:B",
        help="score only frames A..B (1-based, inclusive) of the ground truth and the tracks, "
        "e.g. the range given to `run --frames`",
    )
    ev.add_argument(
        "--benchmark",
        choices=("auto", *BENCHMARKS),
        default="auto",
        help="scoring rules: MOT15 (no classes) or MOT16/17/20 (class 1 scored, distractors "
        "ignored); default auto, from the gt columns and the sequence name",
    )
    ev.add_argument("--format", choices=FORMATS, default="md", help=FORMAT_HELP)

    ab = sub.add_parser(
        "ablate",
        help="motion models x feature kinds, one table like the paper's Table III",
        description="Rerun the ablation on the sequences (no SEQ_DIR: the built-in scene).",
    )
    ab.add_argument(
        "seqs",
        nargs="*",
        metavar="SEQ_DIR",
        type=Path,
        help="MOTChallenge sequence folders with gt/gt.txt (none: the built-in scene)",
    )
    ab.add_argument(
        "--motion",
        type=_csv_choices(MOTIONS),
        default=list(MOTIONS),
        help="comma-separated motion models (default: all)",
    )
    ab.add_argument(
        "--features",
        type=_csv_choices(FEATURES),
        help="comma-separated feature kinds (default: all the inputs allow)",
    )
    ab.add_argument(
        "--detector", choices=DETECTORS, help="detect in the frames instead of reading det/det.txt"
    )
    ab.add_argument("--detector-model", metavar="PATH", help=DETECTOR_MODEL_HELP)
    ab.add_argument("--reid-model", metavar="PATH", help=REID_MODEL_HELP)
    ab.add_argument("--frames", metavar="A:B", help="frame range (gt is cut to match)")
    ab.add_argument("--format", choices=FORMATS, default="md", help=FORMAT_HELP)
    _add_param_option(ab)
    ab.add_argument("--quiet", "-q", action="store_true", help="no progress bar")

    sc = sub.add_parser("scene", help="write the built-in scene as a MOTChallenge sequence")
    sc.add_argument(
        "out_dir", type=Path, help="folder to write the sequence into (as DensePeds-scene-SEED)"
    )
    sc.add_argument("--seed", type=int, default=0, help="random seed of the simulation")
    sc.add_argument("--frames", type=int, default=150, help="number of frames")
    sc.add_argument("--no-images", action="store_true", help="only seqinfo, gt and det")

    _add_models_parser(sub)

    from densepeds.batch import add_parser as add_batch_parser

    add_batch_parser(sub)
    return parser


DETECTOR_MODEL_HELP = (
    "detector ONNX file (default: the --detector's own model, from $DENSEPEDS_MODEL_DIR or "
    "the user cache; see `densepeds models`)"
)
REID_MODEL_HELP = (
    "re-ID ONNX file, e.g. an OSNet export (default: osnet_x0_25_msmt17.onnx from "
    "$DENSEPEDS_MODEL_DIR or the user cache; see `densepeds models`)"
)


def _add_models_parser(sub: Any) -> None:
    from densepeds.modelfiles import URL_ENV_VAR

    mo = sub.add_parser(
        "models",
        help="list the known models and where they are; fetch or install them",
        description="With no action: list the models densepeds knows (file, size, sha256, "
        "licence, input/output contract), the folders searched and what was found there.",
    )
    act = mo.add_subparsers(dest="action", parser_class=_Parser, metavar="ACTION")
    act.add_parser("list", help="the same as no action")
    fe = act.add_parser(
        "fetch",
        help="download models into the user cache (pinned, sha256-verified, resumable)",
        description="Download models into the user cache, verify their sha256, resume an "
        "interrupted download.",
    )
    fe.add_argument(
        "names",
        nargs="*",
        metavar="NAME",
        help="model names or files (default: every model with a pinned checksum)",
    )
    fe.add_argument(
        "--url",
        metavar="BASE",
        help=f"mirror base URL: BASE/<file> is downloaded (default: ${URL_ENV_VAR}, else the "
        "model's published URL)",
    )
    fe.add_argument("--dir", type=Path, metavar="DIR", help="install here instead of the cache")
    fe.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    ins = act.add_parser(
        "install",
        help="copy model files you have (a file, or a folder of them) into the user cache",
        description="Copy model files into the user cache, verified against their pinned "
        "sha256 (for offline machines or mirrored copies).",
    )
    ins.add_argument("source", type=Path, metavar="FILE|DIR", help="a model file or a folder")
    ins.add_argument("--dir", type=Path, metavar="DIR", help="install here instead of the cache")
    _add_quantize_parser(act)


def _add_quantize_parser(act: Any) -> None:
    from densepeds.quantize import CALIBRATIONS, FORMATS, QuantOptions

    qu = act.add_parser(
        "quantize",
        help="make an int8 copy of the yoloseg detector for this CPU, calibrated on your frames",
        description="Quantise the yoloseg detector's float copy with onnxruntime's static "
        "quantisation (U8S8, per-channel weights), calibrated on the tiles of the frames given, "
        "check its detections against the float copy's on frames between them, and write it "
        "into the user cache, where the detector finds and uses it.",
    )
    qu.add_argument(
        "--calibrate",
        action="append",
        required=True,
        metavar="VIDEO[@A:B[/STEP]]",
        help="a video, image folder or sequence to calibrate on, optionally its frames A:B and "
        "every STEP-th of them (repeatable; e.g. crowd.mp4@1:400/8)",
    )
    qu.add_argument("--model", metavar="PATH", help="the detector model (default: yoloseg's)")
    qu.add_argument(
        "--format",
        choices=FORMATS,
        default=QuantOptions().quant_format,
        help="onnxruntime's graph form",
    )
    qu.add_argument(
        "--calibration",
        choices=CALIBRATIONS,
        default=QuantOptions().calibration,
        help="activation ranges from their min/max (default) or a percentile of their magnitude",
    )
    qu.add_argument(
        "--min-agreement",
        type=float,
        default=0.9,
        help="fail (and write nothing) if the int8 copy finds fewer of the float copy's "
        "detections than this (default 0.9)",
    )
    qu.add_argument("--dir", type=Path, metavar="DIR", help="write here instead of the cache")


# --- run -------------------------------------------------------------------------------------


class _NoProgress:
    """The progress bar where none is shown (quiet, or stderr not a terminal): tqdm and the
    lock it creates are not even imported."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def _progress(total: int | None, quiet: bool, desc: str) -> Any:
    if quiet or not sys.stderr.isatty():
        return _NoProgress()
    from tqdm import tqdm

    return tqdm(
        total=total, desc=desc, unit="frame", file=sys.stderr, leave=False, dynamic_ncols=True
    )


class _Interrupted(KeyboardInterrupt):
    """Ctrl-C during a run, after the frames tracked so far were saved; the message says where."""


class _Terminated(BaseException):
    """SIGTERM or SIGHUP: raised in the main thread so that every cleanup runs."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextmanager
def _ctrl_c_after_block() -> Iterator[None]:
    """Ctrl-C (SIGINT) during the block is held until the block ends, then raised as
    KeyboardInterrupt: a frame's output (its rows, its video frame, the frame count) is then
    written whole or not at all. Outside the main thread the block runs as is."""
    caught: list[int] = []
    try:
        saved = signal.signal(signal.SIGINT, lambda signum, _frame: caught.append(signum))
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, saved)
    if caught:
        raise KeyboardInterrupt


def _expected_frames(src: Any, rng: Any) -> int | None:
    """Frames a run over ``rng`` should decode, where the source knows its length."""
    if src.length is None:
        return None
    return max(0, (rng.clip(src.length).last or 0) - rng.first + 1)


def _track_source(
    args: argparse.Namespace,
    pipe: Any,
    src: Any,
    out: Path,
    dets: Any = None,
    rng: Any = None,
    keep_on_interrupt: bool = True,
) -> tuple[int, int]:
    """Run the pipeline over a source, write tracks and the optional video; (frames, ids).

    Nothing is written when no frame was tracked, or (unless ``--allow-partial``) when the input
    ended before its expected frame count. On Ctrl-C the frames tracked so far are written and
    :class:`_Interrupted` says so.
    """
    from densepeds.motio import probe_output
    from densepeds.pipeline import track_rows
    from densepeds.video import AnnotatedVideoWriter, parse_frame_range

    rng = parse_frame_range(rng if rng is not None else args.frames)
    if getattr(args, "fill_gaps", 0) < 0:
        raise ParameterError(f"--fill-gaps must be >= 0 frames, got {args.fill_gaps}")
    expected = _expected_frames(src, rng)
    # Unwritable outputs fail now, not after the run.
    probe_output(out)
    writer = AnnotatedVideoWriter(args.video, fps=src.fps) if args.video else None
    if args.video:
        probe_output(args.video)
    rows: list[tuple[float, ...]] = []
    matched: list[bool] = []  # per row: the track took a detection in that frame
    ids: set[int] = set()
    frames = 0
    bar = _progress(expected, args.quiet, src.name)
    interrupted = False
    try:
        for res in pipe.run_frames(src, rng, dets):
            with _ctrl_c_after_block(), pipe.times.stage("output"):
                rows.extend(track_rows(res.frame_no, res.tracks))
                matched.extend((res.tracks.det_index >= 0).tolist())
                ids.update(res.tracks.ids.tolist())
                if writer is not None:
                    writer.write(
                        res.image,
                        res.tracks.ids,
                        res.tracks.boxes,
                        size=src.size,
                        frame_no=res.frame_no,
                    )
                frames += 1
            bar.update(1)
    except KeyboardInterrupt:
        interrupted = True
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    finally:
        bar.close()
    try:
        if frames == 0:
            raise ParameterError(f"{src.name}: no frames in range {args.frames or 'all'}")
        if interrupted:
            if not keep_on_interrupt:
                raise KeyboardInterrupt
            _finish(args, out, _filled(args, rows, matched), writer, pipe)
            raise _Interrupted(
                f"interrupted after {frames} frames (last {rng.first + frames - 1}); their tracks "
                f"are in {out}" + (f" and {args.video}" if writer is not None else "")
            )
        if expected is not None and frames < expected:
            short = (
                f"{src.name}: decoded {frames} of {expected} frames: the input ends early "
                "(truncated, or shorter than its header or seqLength says)"
            )
            if not getattr(args, "allow_partial", False):
                raise InputError(
                    f"{short}; pass --allow-partial to keep the tracks of those frames"
                )
            _note(args, f"warning: {short}; tracks of the {frames} frames kept (--allow-partial)")
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    _finish(args, out, _filled(args, rows, matched), writer, pipe)
    return frames, len(ids)


def _filled(args: argparse.Namespace, rows: list[tuple[float, ...]], matched: list[bool]) -> Any:
    """The rows to write: as tracked, or with ``--fill-gaps N`` (densepeds.gaps.fill_gaps)."""
    import numpy as np

    from densepeds.gaps import fill_gaps

    max_gap = getattr(args, "fill_gaps", 0)
    if not max_gap or not rows:
        return rows
    return fill_gaps(np.c_[np.asarray(rows, dtype=np.float64), matched], max_gap)


def _finish(
    args: argparse.Namespace, out: Path, rows: list[tuple[float, ...]], writer: Any, pipe: Any
) -> None:
    """Write the video (checked) and the tracks; say which codec the video got."""
    from densepeds.motio import write_tracks
    from densepeds.video import CODEC_NAMES

    with pipe.times.stage("output"):
        if writer is not None:
            writer.close()
        write_tracks(out, rows)
    if writer is not None and writer.codec is not None:
        name = CODEC_NAMES.get(writer.codec, writer.codec)
        _note(args, f"note: {writer.note}" if writer.note else f"video codec: {name}")


def _note(args: argparse.Namespace, text: str) -> None:
    sys.stderr.write(f"densepeds {args.command}: {text}\n")


def _summary(name: str, frames: int, n_ids: int, out: Path, pipe: Any, video: Path | None) -> str:
    t = pipe.times
    extra = f" and {video}" if video else ""
    return (
        f"{name}: {frames} frames, {n_ids} tracks (preset {pipe.preset.name}) -> {out}{extra}; "
        f"{_speed(t)}{_int8_note(pipe)}{_reuse_note(pipe)}"
    )


def _reuse_note(pipe: Any) -> str:
    """How many embeddings --reid-reuse kept from the previous frame instead of computing."""
    if pipe.features == "none" or pipe.times.seconds.get("reid", 0) <= 0:
        return ""
    reid = pipe.reid()
    if getattr(reid, "reuse", None) is None:
        return ""
    return f"; re-ID: {reid.reused} of {reid.reused + reid.embedded} embeddings reused"


def _int8_note(pipe: Any) -> str:
    """Names the detector file where it is the int8 copy (``densepeds models quantize``): the
    detector picks one up from the model folders without being asked."""
    if not pipe.has_detector or pipe.times.seconds.get("detection", 0) <= 0:
        return ""
    det = pipe.detector()
    return f"; detector: int8 copy {det.path}" if getattr(det, "quantized", False) else ""


def _speed(times: Any) -> str:
    """Frames per second over the stages that ran, named, so that a det-file run's tracker
    speed does not read as the speed of the whole pipeline."""
    ran = [k for k, v in times.seconds.items() if v > 0]
    what = (
        "the whole pipeline"
        if "detection" in ran
        else "tracking from given detections (no detector ran)"
    )
    return (
        f"{times.fps:.1f} frames/s for {what}; timed: {' + '.join(ran) or 'nothing'} "
        f"({times.breakdown()})"
    )


def _cmd_run(args: argparse.Namespace) -> int:
    from densepeds.video import parse_frame_range

    parse_frame_range(args.frames)  # a bad range fails before any work
    if args.input is None:
        return _run_scene(args)
    src, pipe, dets, out, rng = open_run(args)
    frames, n_ids = _track_source(args, pipe, src, out, dets, rng)
    print(_summary(src.name, frames, n_ids, out, pipe, args.video))
    return 0


def open_run(args: argparse.Namespace, models: Any = None) -> tuple[Any, Any, Any, Path, Any]:
    """``run``'s set-up for one INPUT: (frame source, pipeline, det-file detections, tracks path,
    frame range).

    ``models`` (``densepeds.batch``): an object whose ``detector(kind, path)`` and ``reid(path)``
    give loaded models, shared by the inputs of a batch; by default the pipeline loads its own.
    """
    from densepeds.motio import read_detections, safe_name
    from densepeds.pipeline import Pipeline, default_features
    from densepeds.video import SequenceSource, open_source, parse_frame_range

    src = open_source(args.input)
    has_images = not isinstance(src, SequenceSource) or src.has_images
    has_own_dets = isinstance(src, SequenceSource) and src.det_path is not None
    detector = args.detector
    if detector is None and args.detections is None and not has_own_dets:
        if not has_images:
            raise ParameterError(f"{args.input}: no images and no det/det.txt to track from")
        detector = "yoloseg"
    features = args.features or default_features(has_images)
    if features != "none" and not has_images:
        raise ParameterError(
            f"--features {features} needs frames, and {args.input} has none (use --features none)"
        )
    tiles = getattr(args, "tiles", None)
    if tiles is not None and (detector is None or args.detections is not None):
        raise ParameterError(
            "--tiles sets the CNN detector's views, and this run tracks detections from a file "
            "(add --detector yoloseg to detect)"
        )
    full_scan_every = getattr(args, "full_scan_every", None)
    if full_scan_every is not None and (detector != "yoloseg" or args.detections is not None):
        raise ParameterError(
            "--full-scan-every sets the yoloseg detector's views, and this run does not detect "
            "with it (add --detector yoloseg to detect)"
        )
    focus_lost = getattr(args, "focus_lost", None)
    if focus_lost is not None and (detector != "yoloseg" or args.detections is not None):
        raise ParameterError(
            "--focus-lost adds views to the yoloseg detector, and this run does not detect "
            "with it (add --detector yoloseg to detect)"
        )
    detector_options = {
        key: value
        for key, value in (
            ("tiles", tiles),
            ("full_scan_every", full_scan_every),
            ("focus_scale", focus_lost),
        )
        if value is not None
    }
    reid_reuse = getattr(args, "reid_reuse", False)
    if reid_reuse and features == "none":
        raise ParameterError(
            "--reid-reuse keeps re-ID embeddings, and this run computes none (--features none)"
        )
    # Read the det file and load the models before tracking, so that mistakes surface at once.
    dets: Any = read_detections(args.detections) if args.detections else None
    detector_spec: Any = detector
    reid_spec: Any = args.reid_model
    if models is not None:
        if detector is not None and dets is None:
            detector_spec = models.detector(detector, args.detector_model)
        if features != "none":
            reid_spec = models.reid(args.reid_model)
    elif reid_reuse:
        from densepeds.reid import ReID

        reid_spec = ReID(args.reid_model, reuse=True)
    # The preset follows the detector asked for, also when a batch hands over a loaded one.
    preset = args.preset if args.preset is not None else preset_for(detector).name
    pipe = Pipeline(
        detector_spec,
        reid=reid_spec,
        motion=args.motion,
        features=features,
        detector_model=args.detector_model,
        detector_options=detector_options or None,
        preset=preset,
        **dict(args.param),
    )
    if detector is not None and dets is None:
        pipe.detector()
    if features != "none":
        pipe.reid()
    rng = parse_frame_range(args.frames)
    if not has_images and detector is None:
        dets = pipe.source_detections(src, dets if dets is not None else args.detections)
        rng = _stop_after_detections(args, src, rng, dets, pipe)
    out = args.out or Path("out") / f"{safe_name(src.name, 'tracks')}.txt"
    return src, pipe, dets, out, rng


def _stop_after_detections(
    args: argparse.Namespace, src: Any, rng: Any, dets: Any, pipe: Any
) -> Any:
    """A detections-only run ends where no track can be reported any more: after the last
    detection and the frames a lost track stays in the output. Later frames would only be empty
    (a ``seqLength`` far beyond the detections would otherwise run for hours); says so."""
    from densepeds.video import FrameRange

    if src.length is None or rng.first > src.length:
        return rng
    params = getattr(pipe.tracker, "params", {})
    coast = int(params.get("output_lost", 0)) if isinstance(params, dict) else 0
    last_det = max((k for k, d in dets.items() if len(d)), default=0)
    end = last_det + coast
    planned = rng.clip(src.length).last or 0
    if planned <= end:
        return rng
    if end >= rng.first:
        _note(
            args,
            f"{src.name}: {src.length} frames, but the detections end at frame {last_det}; "
            f"tracked to frame {end} (no track is reported after it)",
        )
        return FrameRange(rng.first, end)
    raise InputError(
        f"{src.name}: no detections in frames {rng.first}:{planned} (the last is at frame "
        f"{last_det})"
    )


def _run_scene(args: argparse.Namespace) -> int:
    from importlib.util import find_spec

    from densepeds.evaluate import INSTALL_HINT, evaluate, format_results
    from densepeds.pipeline import Pipeline
    from densepeds.scene import make_scene

    if args.detections or args.detector:
        raise ParameterError("the built-in scene has its own detections; give an INPUT instead")
    features = args.features or "segmented"
    scene = make_scene(seed=args.seed, frames=args.scene_frames)
    reid: Any = args.reid_model or scene.embedder()
    pipe = Pipeline(
        None,
        reid=reid,
        motion=args.motion,
        features=features,
        preset=args.preset,
        **dict(args.param),
    )
    with tempfile.TemporaryDirectory(prefix="densepeds-scene-") as tmp:
        seq = scene.write(tmp, images=False)
        out = args.out or Path(tmp) / f"{scene.name}.txt"
        frames, n_ids = _track_source(args, pipe, scene, out, keep_on_interrupt=bool(args.out))
        scored = find_spec("trackeval") is not None
        result = evaluate([seq], out) if scored else None
    print(
        f"Built-in scene (seed {args.seed}): {scene.positions.shape[1]} people, "
        f"{scene.local_density():.1f} people/m^2 around each, motion {args.motion}, "
        f"features {features}"
    )
    if result is not None:
        print(format_results(result, "md"))
    else:
        print(f"not scored: trackeval is not installed (to score: {INSTALL_HINT})")
    shown = out if args.out else Path("(temporary)")
    print(_summary(scene.name, frames, n_ids, shown, pipe, args.video))
    return 0


# --- eval, ablate, scene -------------------------------------------------------------------------


def _cmd_eval(args: argparse.Namespace) -> int:
    from densepeds.evaluate import evaluate, format_results

    result = evaluate(list(args.gt), args.tracks, benchmark=args.benchmark, frames=args.frames)
    for note in result.warnings:
        sys.stderr.write(f"densepeds eval: warning: {note}\n")
    print(format_results(result, args.format))
    return 0


def _cmd_models(args: argparse.Namespace) -> int:
    from densepeds import modelfetch, modelfiles

    if args.action in (None, "list"):
        print(_models_listing())
        return 0
    if args.action == "install":
        for path in modelfetch.install(args.source, dest_dir=args.dir):
            print(f"installed {path}")
        return 0
    if args.action == "quantize":
        return _cmd_quantize(args)
    names = args.names or [m.name for m in modelfetch.fetchable()]
    for name in names:
        info = modelfiles.model_info(name)
        path = modelfetch.fetch(info.name, base_url=args.url, dest_dir=args.dir, quiet=args.quiet)
        print(f"{info.name}: {path} (sha256 verified)")
    return 0


def _cmd_quantize(args: argparse.Namespace) -> int:
    import shutil

    from densepeds import modelfiles, quantize
    from densepeds.detect import DEFAULT_MODELS
    from densepeds.errors import ModelError

    model = modelfiles.find_model(DEFAULT_MODELS["yoloseg"], args.model)
    inputs = [quantize.parse_calibration(c) for c in args.calibrate]
    dest = (args.dir or modelfiles.cache_dir()) / modelfiles.quantized_file_name(model)
    with tempfile.TemporaryDirectory(prefix="densepeds-quantize-") as tmp:
        made = quantize.quantize_detector(
            model,
            Path(tmp) / dest.name,
            inputs,
            options=quantize.QuantOptions(quant_format=args.format, calibration=args.calibration),
        )
        agree = quantize.check(model, made, inputs)
        print(
            f"int8 copy finds {agree.matched} of the float copy's {agree.float_dets} detections "
            f"({agree.recall:.3f}; it has {agree.int8_dets}) on {agree.frames} frames it was not "
            "calibrated on"
        )
        if quantize.integer_dot_product() is False:
            print(
                "this CPU has no integer dot-product instructions (AVX-512 VNNI, AVX-VNNI, ARM "
                "dot product): onnxruntime runs the int8 copy on slower kernels here, and its "
                "detections differ more from the float copy's; time and score `densepeds run` "
                "with it (--detector-model) and without before relying on it"
            )
        if agree.recall < args.min_agreement:
            raise ModelError(
                f"the int8 copy agrees with the float copy on {agree.recall:.3f} of its "
                f"detections, below --min-agreement {args.min_agreement}; nothing was written"
            )
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(made, dest)
    print(f"wrote {dest}")
    return 0


def _models_listing() -> str:
    from densepeds import modelfiles

    lines = ["Models densepeds knows:"]
    for m in modelfiles.MODELS.values():
        found = modelfiles.locate(m.file)
        size = f"{m.size} bytes" if m.size is not None else "size not fixed"
        lines += [
            f"  {m.name}: {m.file} ({size}) -- {m.role}",
            f"    found: {found if found else 'no'}",
            f"    sha256: {m.sha256 or 'none pinned (made locally)'}",
            f"    licence: {m.licence}",
            f"    contract: {m.contract}",
            f"    get it: {m.url or modelfiles.how_to_get(m.file)}",
        ]
    lines.append("Searched, in order ($DENSEPEDS_MODEL_DIR, then the user cache):")
    lines += [f"  {d}{'' if d.is_dir() else ' (missing)'}" for d in modelfiles.search_dirs()]
    return "\n".join(lines)


def _cmd_ablate(args: argparse.Namespace) -> int:
    from densepeds.ablate import format_ablation, run_ablation

    result = run_ablation(
        list(args.seqs),
        motions=args.motion,
        features=args.features,
        frames=args.frames,
        detector=args.detector,
        detector_model=args.detector_model,
        reid_model=args.reid_model,
        tracker_params=dict(args.param),
        quiet=args.quiet,
    )
    print(format_ablation(result, args.format))
    return 0


def _cmd_scene(args: argparse.Namespace) -> int:
    from densepeds.scene import make_scene

    scene = make_scene(seed=args.seed, frames=args.frames)
    seq = scene.write(args.out_dir, images=not args.no_images)
    print(f"wrote {seq} ({args.frames} frames, {scene.positions.shape[1]} people)")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """The ``densepeds`` command. Every failure the user can cause (bad input, options or models,
    unwritable or full outputs, interrupts) ends here as one line on stderr: exit 2, or 130 for
    Ctrl-C and 128 + N for a termination signal N (after removing temporary files)."""
    try:  # building the parser imports modules: Ctrl-C there is one line too
        args_list = _with_command(list(sys.argv[1:] if argv is None else argv))
        args = build_parser().parse_args(args_list)
        from densepeds.batch import cmd_batch
    except KeyboardInterrupt:
        sys.stderr.write("densepeds: interrupted\n")
        return EXIT_INTERRUPT

    handlers = {
        "run": _cmd_run,
        "eval": _cmd_eval,
        "ablate": _cmd_ablate,
        "scene": _cmd_scene,
        "models": _cmd_models,
        "batch": cmd_batch,
    }
    prefix = f"densepeds {args.command}"
    try:
        with _termination_raises(), warnings_as_lines(prefix):
            return handlers[args.command](args)
    except DensePedsError as err:
        sys.stderr.write(f"{prefix}: error: {_one_line(err)}\n")
        return EXIT_USAGE
    except _Interrupted as err:
        sys.stderr.write(f"{prefix}: {_one_line(err)}\n")
        return EXIT_INTERRUPT
    except KeyboardInterrupt:
        sys.stderr.write(f"{prefix}: interrupted\n")
        return EXIT_INTERRUPT
    except _Terminated as err:
        sys.stderr.write(f"{prefix}: terminated ({err}); temporary files removed\n")
        return 128 + err.signum
    except BrokenPipeError:
        return 1
    except OSError as err:  # a file or folder the user named: permissions, a full disk, ...
        where = f"{err.filename}: " if err.filename else ""
        sys.stderr.write(f"{prefix}: error: {where}{_one_line(err.strerror or err)}\n")
        return EXIT_USAGE


def _with_command(args_list: list[str]) -> list[str]:
    """``densepeds [INPUT] ...`` means ``densepeds run [INPUT] ...``; a first word that is no
    command, no option and no existing path is a mistyped command (one line, exit 2)."""
    first = args_list[0] if args_list else None
    if first is None or (first.startswith("-") and first not in _TOP_OPTIONS):
        return ["run", *args_list]
    if first in COMMANDS or first in _TOP_OPTIONS:
        return args_list
    if Path(first).exists():
        return ["run", *args_list]
    close = difflib.get_close_matches(first, COMMANDS, n=1, cutoff=0.6)
    if close or not any(c in first for c in "./\\"):
        hint = f"did you mean {close[0]!r}? " if close else ""
        sys.stderr.write(
            f"densepeds: error: unknown command {first!r} and no such file; {hint}"
            f"(commands: {', '.join(COMMANDS)}; see --help)\n"
        )
        sys.exit(EXIT_USAGE)
    return ["run", *args_list]  # a missing file: `run` says so


_TOP_OPTIONS = ("-h", "--help", "--version", "-V")


@contextmanager
def _termination_raises() -> Iterator[None]:
    """SIGTERM and SIGHUP raise :class:`_Terminated` in the main thread for the block (so that
    ``finally`` blocks remove temporary files), instead of ending the process on the spot."""

    def raise_terminated(signum: int, _frame: object) -> None:
        raise _Terminated(signum)

    saved: dict[signal.Signals, Any] = {}
    try:
        for sig in (signal.SIGTERM, signal.SIGHUP):
            saved[sig] = signal.signal(sig, raise_terminated)
    except ValueError:  # not the main thread: leave signals alone
        pass
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def _one_line(err: BaseException | str) -> str:
    return " ".join(str(err).split()) or type(err).__name__


if __name__ == "__main__":
    sys.exit(main())
