"""Command line: ``python -m densepeds run|eval|ablate|scene``.

User mistakes (missing files, bad option values, unreadable video, malformed det files, model
mismatches) print one line to stderr and exit 2; there is no traceback for them.
"""

from __future__ import annotations

import argparse
import signal
import sys
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NoReturn

from densepeds.errors import DensePedsError, InputError, ParameterError
from densepeds.pipeline import DEFAULT_FEATURES, DETECTORS, FEATURES, MOTIONS

EXIT_USAGE = 2
EXIT_INTERRUPT = 130  # 128 + SIGINT, as shells report Ctrl-C
COMMANDS = ("run", "eval", "ablate", "scene")


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad command line in one line (no usage block)."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message} (see --help)\n")
        sys.exit(EXIT_USAGE)


def _tracker_param(text: str) -> tuple[str, Any]:
    key, sep, raw = text.partition("=")
    if not sep or not key.isidentifier():
        raise argparse.ArgumentTypeError(f"{text!r}: expected KEY=VALUE")
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


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="densepeds", description="Pedestrian tracking in dense crowds.")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)

    run = sub.add_parser(
        "run",
        help="track a video, image folder or MOTChallenge sequence (no INPUT: the built-in scene)",
        description="Track people. With no INPUT, tracks the built-in dense-crowd scene and "
        "prints its metrics.",
    )
    run.add_argument("input", nargs="?", help="video file, image folder or sequence folder")
    run.add_argument("--detections", metavar="FILE", help="MOTChallenge det.txt to track from")
    run.add_argument("--detector", choices=DETECTORS, help="detect people in the frames")
    run.add_argument("--detector-model", metavar="PATH", help="detector ONNX model file")
    run.add_argument("--reid-model", metavar="PATH", help="re-ID ONNX model file")
    run.add_argument("--motion", choices=MOTIONS, default="frvo", help="motion model")
    run.add_argument(
        "--features",
        choices=FEATURES,
        help=f"appearance features: segmented (the method's white fill outside the mask), bbox "
        f"(plain crop), masked_pool (mask-weighted pooling of the re-ID features), masked_mean, "
        f"masked_blur (other fills), none (motion only); default: {DEFAULT_FEATURES} where "
        f"there are frames (segmented on the built-in scene), else none",
    )
    run.add_argument("--frames", metavar="A:B", help="frame range, 1-based and inclusive")
    run.add_argument("--out", metavar="TRACKS.txt", type=Path, help="tracks output file")
    run.add_argument("--video", metavar="OUT.mp4", type=Path, help="annotated video output")
    run.add_argument(
        "--param",
        metavar="KEY=VALUE",
        type=_tracker_param,
        action="append",
        default=[],
        help="tracker parameter (repeatable)",
    )
    run.add_argument("--seed", type=int, default=0, help="built-in scene: random seed")
    run.add_argument("--scene-frames", type=int, default=150, help="built-in scene: frames")
    run.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    run.add_argument(
        "--allow-partial",
        action="store_true",
        help="keep the tracks of a input that ends before its expected frame count (a truncated "
        "video, an image folder shorter than its seqLength) instead of failing",
    )

    ev = sub.add_parser("eval", help="HOTA, MOTA, IDF1, ... of tracks against ground truth")
    ev.add_argument("--gt", nargs="+", required=True, metavar="SEQ_DIR", type=Path)
    ev.add_argument(
        "--tracks",
        required=True,
        metavar="PATH",
        type=Path,
        help="a tracks file (one sequence) or a folder of SEQNAME.txt",
    )
    ev.add_argument("--format", choices=("md", "csv", "json"), default="md")

    ab = sub.add_parser(
        "ablate",
        help="motion models x feature kinds, one table like the paper's Table III",
        description="Rerun the ablation on the sequences (no SEQ_DIR: the built-in scene).",
    )
    ab.add_argument("seqs", nargs="*", metavar="SEQ_DIR", type=Path)
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
    ab.add_argument("--detector-model", metavar="PATH")
    ab.add_argument("--reid-model", metavar="PATH")
    ab.add_argument("--frames", metavar="A:B", help="frame range (gt is cut to match)")
    ab.add_argument("--format", choices=("md", "csv", "json"), default="md")
    ab.add_argument(
        "--param", metavar="KEY=VALUE", type=_tracker_param, action="append", default=[]
    )
    ab.add_argument("--quiet", "-q", action="store_true")

    sc = sub.add_parser("scene", help="write the built-in scene as a MOTChallenge sequence")
    sc.add_argument("out_dir", type=Path)
    sc.add_argument("--seed", type=int, default=0)
    sc.add_argument("--frames", type=int, default=150)
    sc.add_argument("--no-images", action="store_true", help="only seqinfo, gt and det")
    return parser


# --- run -------------------------------------------------------------------------------------


def _progress(total: int | None, quiet: bool, desc: str) -> Any:
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc=desc,
        unit="frame",
        file=sys.stderr,
        leave=False,
        disable=quiet or not sys.stderr.isatty(),
        dynamic_ncols=True,
    )


class _Interrupted(KeyboardInterrupt):
    """Ctrl-C during a run, after the frames tracked so far were saved; the message says where."""


class _Terminated(BaseException):
    """SIGTERM or SIGHUP: raised in the main thread so that every cleanup runs."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


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
    expected = _expected_frames(src, rng)
    # Unwritable outputs fail now, not after the run.
    probe_output(out)
    writer = AnnotatedVideoWriter(args.video, fps=src.fps) if args.video else None
    if args.video:
        probe_output(args.video)
    rows: list[tuple[float, ...]] = []
    ids: set[int] = set()
    frames = 0
    bar = _progress(expected, args.quiet, src.name)
    interrupted = False
    try:
        for res in pipe.run_frames(src, rng, dets):
            with pipe.times.stage("output"):
                rows.extend(track_rows(res.frame_no, res.tracks))
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
            _finish(args, out, rows, writer, pipe)
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
    _finish(args, out, rows, writer, pipe)
    return frames, len(ids)


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
        f"{name}: {frames} frames, {n_ids} tracks -> {out}{extra}; {t.fps:.1f} fps "
        f"({t.breakdown()})"
    )


def _cmd_run(args: argparse.Namespace) -> int:
    from densepeds.motio import read_detections, safe_name
    from densepeds.pipeline import Pipeline, default_features
    from densepeds.video import SequenceSource, open_source, parse_frame_range

    parse_frame_range(args.frames)  # a bad range fails before any work
    if args.input is None:
        return _run_scene(args)
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
    # Read the det file and load the models before tracking, so that mistakes surface at once.
    dets: Any = read_detections(args.detections) if args.detections else None
    pipe = Pipeline(
        detector,
        reid=args.reid_model,
        motion=args.motion,
        features=features,
        detector_model=args.detector_model,
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
    frames, n_ids = _track_source(args, pipe, src, out, dets, rng)
    print(_summary(src.name, frames, n_ids, out, pipe, args.video))
    return 0


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
    from densepeds.evaluate import evaluate, format_results
    from densepeds.pipeline import Pipeline
    from densepeds.scene import make_scene

    if args.detections or args.detector:
        raise ParameterError("the built-in scene has its own detections; give an INPUT instead")
    features = args.features or "segmented"
    scene = make_scene(seed=args.seed, frames=args.scene_frames)
    reid: Any = args.reid_model or scene.embedder()
    pipe = Pipeline(None, reid=reid, motion=args.motion, features=features, **dict(args.param))
    with tempfile.TemporaryDirectory(prefix="densepeds-scene-") as tmp:
        seq = scene.write(tmp, images=False)
        out = args.out or Path(tmp) / f"{scene.name}.txt"
        frames, n_ids = _track_source(args, pipe, scene, out, keep_on_interrupt=bool(args.out))
        result = evaluate([seq], out)
    print(
        f"Built-in scene (seed {args.seed}): {scene.positions.shape[1]} people, "
        f"{scene.local_density():.1f} people/m^2 around each, motion {args.motion}, "
        f"features {features}"
    )
    print(format_results(result, "md"))
    shown = out if args.out else Path("(temporary)")
    print(_summary(scene.name, frames, n_ids, shown, pipe, args.video))
    return 0


# --- eval, ablate, scene -------------------------------------------------------------------------


def _cmd_eval(args: argparse.Namespace) -> int:
    from densepeds.evaluate import evaluate, format_results

    result = evaluate(list(args.gt), args.tracks)
    print(format_results(result, args.format))
    return 0


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
    args_list = list(sys.argv[1:] if argv is None else argv)
    if not args_list or (args_list[0] not in COMMANDS and args_list[0] not in ("-h", "--help")):
        args_list.insert(0, "run")  # `densepeds [INPUT]` means `densepeds run [INPUT]`
    args = build_parser().parse_args(args_list)
    handlers = {"run": _cmd_run, "eval": _cmd_eval, "ablate": _cmd_ablate, "scene": _cmd_scene}
    prefix = f"densepeds {args.command}"
    try:
        with _termination_raises():
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
