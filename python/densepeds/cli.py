"""Command line: ``python -m densepeds run|eval|ablate|scene|models|batch``.

User mistakes (missing files, bad option values, unreadable video, malformed det files, model
mismatches) print one line to stderr and exit 2; there is no traceback for them.
"""

from __future__ import annotations

import argparse
import difflib
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from densepeds.errors import DensePedsError, warnings_as_lines
from densepeds.pipeline import DETECTORS, FEATURES, MOTIONS
from densepeds.runner import (
    Interrupted,
    RunSpec,
    Terminated,
    one_line,
    run_scene,
    summary,
    termination_raises,
    track_source,
)
from densepeds.runner import open_run as engine_open_run
from densepeds.runner.spec import add_option, add_run_options, presets_help

EXIT_USAGE = 2
EXIT_INTERRUPT = 130  # 128 + SIGINT, as shells report Ctrl-C
COMMANDS = ("run", "eval", "ablate", "scene", "models", "batch")
FORMATS = ("md", "csv", "json")
FORMAT_HELP = "output format: md (Markdown table), csv, or json (every metric, full precision)"


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad command line in one line (no usage block)."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message} (see --help)\n")
        sys.exit(EXIT_USAGE)


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
        epilog="examples:\n"
        "  densepeds run                                   the built-in scene, tracked and scored\n"
        "  densepeds run video.mp4 --frames 1:200 --video annotated.mp4\n"
        "                                                  detect, segment, re-ID and track\n"
        "  densepeds run SEQ_DIR --out tracks.txt          a MOTChallenge sequence; from its\n"
        "                                                  det/det.txt where it has no frames\n"
        "  densepeds run video.mp4 --tiles 3x2 --focus-lost 0 --full-scan-every 4\n"
        "                                                  faster, fewer people found in crowds\n"
        "  densepeds run video.mp4 --param max_age=60      one tracker parameter changed\n"
        "  densepeds run recorded.mp4 --fill-gaps 40       offline: gaps bridged in the tracks\n"
        "\n" + presets_help(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_run_options(run)

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
    add_option(ab, "detector_model")
    add_option(ab, "reid_model")
    ab.add_argument("--frames", metavar="A:B", help="frame range (gt is cut to match)")
    ab.add_argument("--format", choices=FORMATS, default="md", help=FORMAT_HELP)
    add_option(ab, "param")
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


def _add_models_parser(sub: Any) -> None:
    from densepeds.models.files import DEFAULT_SET, HOSTS_ENV_VAR, URL_ENV_VAR

    mo = sub.add_parser(
        "models",
        help="list the known models and where they are; fetch, install or export them",
        description="With no action: list the models densepeds knows (what each is for, its "
        "source, licence, size, sha256 and input/output contract), the folders searched, what "
        "was found there and which detector and re-ID model `densepeds run` uses.",
    )
    act = mo.add_subparsers(dest="action", parser_class=_Parser, metavar="ACTION")
    act.add_parser("list", help="the same as no action")
    fe = act.add_parser(
        "fetch",
        help="download models into the user cache (pinned, sha256-verified, resumable)",
        description="Download models from their published sources (the mirror when the first "
        "host fails) into the user cache, verify their size and sha256, resume an interrupted "
        f"download. ${HOSTS_ENV_VAR}=BASE fetches https://HOST/PATH from BASE/HOST/PATH.",
    )
    fe.add_argument(
        "names",
        nargs="*",
        metavar="NAME",
        help=f"model names or files (default: {' + '.join(DEFAULT_SET)}: Mask R-CNN, the "
        "paper's detector network, and YoutuReID)",
    )
    fe.add_argument(
        "--url",
        metavar="BASE",
        help=f"mirror base URL: BASE/<file> is downloaded (default: ${URL_ENV_VAR}, else the "
        "model's published URLs)",
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
    ex = act.add_parser(
        "export",
        help="export yoloseg or osnet with its official exporter (the optional export extra), "
        "check it against our contract and install it",
        description="Run Ultralytics' ONNX export of YOLOv8n-seg (yoloseg; AGPL-3.0 weights) "
        "or torch's of torchreid's OSNet x0.25 (osnet), check the file against the contract "
        "densepeds reads, and install it into the user cache. yoloseg needs pip install "
        "ultralytics (AGPL-3.0, not in the extra); osnet needs pip install 'densepeds[export]'.",
    )
    ex.add_argument("model", choices=("yoloseg", "osnet"), help="which model to export")
    ex.add_argument(
        "--weights",
        metavar="FILE|NAME",
        help="yoloseg: Ultralytics weights or model config (default yolov8n-seg.pt, which "
        "Ultralytics downloads); osnet: torchreid's osnet_x0_25 MSMT17 .pth file (required "
        "unless --random)",
    )
    ex.add_argument(
        "--random",
        action="store_true",
        help="export the architecture with random weights (no download; for testing)",
    )
    ex.add_argument("--dir", type=Path, metavar="DIR", help="install here instead of the cache")
    _add_quantize_parser(act)


def _add_quantize_parser(act: Any) -> None:
    from densepeds.models.quantize import CALIBRATIONS, FORMATS, QuantOptions

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


def _cmd_run(args: argparse.Namespace) -> int:
    from densepeds.io.video import parse_frame_range

    spec = RunSpec.from_args(args)
    parse_frame_range(spec.frames)  # a bad range fails before any work
    if spec.input is None:
        return run_scene(spec)
    from densepeds.io.live import is_live

    if is_live(spec.input):
        from densepeds.runner.live_run import run_live

        return run_live(spec)
    src, pipe, dets, out, rng = engine_open_run(spec)
    frames, n_ids = track_source(spec, pipe, src, out, dets, rng)
    print(summary(src.name, frames, n_ids, out, pipe, spec.video))
    return 0


def open_run(args: argparse.Namespace, models: Any = None) -> tuple[Any, Any, Any, Path, Any]:
    """``run``'s set-up for parsed ``run`` options (densepeds.runner.open_run of their spec)."""
    return engine_open_run(RunSpec.from_args(args), models)


# --- eval, ablate, scene -------------------------------------------------------------------------


def _cmd_eval(args: argparse.Namespace) -> int:
    from densepeds.evaluate import evaluate, format_results

    result = evaluate(list(args.gt), args.tracks, benchmark=args.benchmark, frames=args.frames)
    for note in result.warnings:
        sys.stderr.write(f"densepeds eval: warning: {note}\n")
    print(format_results(result, args.format))
    return 0


def _cmd_models(args: argparse.Namespace) -> int:
    from densepeds.models import fetch as modelfetch
    from densepeds.models import files as modelfiles

    if args.action in (None, "list"):
        print(_models_listing())
        return 0
    if args.action == "install":
        for path in modelfetch.install(args.source, dest_dir=args.dir):
            print(f"installed {path}")
        return 0
    if args.action == "quantize":
        return _cmd_quantize(args)
    if args.action == "export":
        from densepeds.models import export as modelexport

        path = modelexport.export(args.model, args.weights, random=args.random, dest_dir=args.dir)
        print(f"{args.model}: exported, checked against the contract, installed {path}")
        return 0
    names = args.names or modelfetch.default_names()
    for name in names:
        info = modelfiles.model_info(name)
        path = modelfetch.fetch(info.name, base_url=args.url, dest_dir=args.dir, quiet=args.quiet)
        print(f"{info.name}: {path} (sha256 verified)")
    return 0


def _cmd_quantize(args: argparse.Namespace) -> int:
    import shutil

    from densepeds.detect import DEFAULT_MODELS
    from densepeds.errors import ModelError
    from densepeds.models import files as modelfiles
    from densepeds.models import quantize

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
    from densepeds.models import files as modelfiles

    def mb(size: int) -> str:
        return f"{size / 1e6:.1f} MB"

    lines = ["Models densepeds knows:"]
    for m in modelfiles.MODELS.values():
        found = modelfiles.locate(m.file)
        size = f"{mb(m.size)}, {m.size} bytes" if m.size is not None else "size not fixed"
        lines += [
            f"  {m.name}: {m.file} ({size})",
            f"    for: {m.role}",
            f"    found: {found if found else 'no'}",
            f"    licence: {m.licence}",
            f"    source: {m.source}",
            f"    sha256: {m.sha256 or 'none pinned (made locally)'}",
            f"    contract: {m.contract}",
        ]
        how = modelfiles.how_to_get(m.file)
        if m.urls:
            lines.append("    published at: " + " , then ".join(m.urls))
        elif how != m.source:
            lines.append(f"    get it: {how}")
    total = sum(modelfiles.MODELS[n].size or 0 for n in modelfiles.DEFAULT_SET)
    lines.append(
        f"`densepeds models fetch` gets {' + '.join(modelfiles.DEFAULT_SET)} ({mb(total)})."
    )
    kind = modelfiles.default_detector()
    lines.append(
        f"`densepeds run` uses now: detector {kind} ({modelfiles.default_model_file(kind)}), "
        f"re-ID {modelfiles.default_reid_file()} (the first present of detectors "
        f"{', '.join(modelfiles.DETECTOR_ORDER)}; re-ID {', '.join(modelfiles.REID_ORDER)})"
    )
    lines.append("Searched, in order ($DENSEPEDS_MODEL_DIR, then the user cache):")
    lines += [f"  {d}{modelfiles.folder_state(d)}" for d in modelfiles.search_dirs()]
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
        with termination_raises(), warnings_as_lines(prefix):
            return handlers[args.command](args)
    except DensePedsError as err:
        sys.stderr.write(f"{prefix}: error: {one_line(err)}\n")
        return EXIT_USAGE
    except Interrupted as err:
        sys.stderr.write(f"{prefix}: {one_line(err)}\n")
        return EXIT_INTERRUPT
    except KeyboardInterrupt:
        sys.stderr.write(f"{prefix}: interrupted\n")
        return EXIT_INTERRUPT
    except Terminated as err:
        sys.stderr.write(f"{prefix}: terminated ({err}); temporary files removed\n")
        return 128 + err.signum
    except BrokenPipeError:
        return 1
    except OSError as err:  # a file or folder the user named: permissions, a full disk, ...
        where = f"{err.filename}: " if err.filename else ""
        sys.stderr.write(f"{prefix}: error: {where}{one_line(err.strerror or err)}\n")
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


if __name__ == "__main__":
    sys.exit(main())
