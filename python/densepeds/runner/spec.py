"""What one tracking run is: :class:`RunSpec`, and the command-line options that build it.

Every option of ``densepeds run`` is declared once here (:data:`OPTIONS`), with the run setting
it fills. ``run`` adds them all; ``batch`` adds the ones that are the same for every input
(:data:`SHARED`); both build their settings from the parsed options with ``from_args``.
"""

from __future__ import annotations

import argparse
import textwrap
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, TypeVar

from densepeds.detect import DEVICES
from densepeds.pipeline import DEFAULT_FEATURES, DETECTORS, FEATURES, MOTIONS
from densepeds.presets import DEFAULT_PRESET, PRESETS
from densepeds.speed import SPEEDS

DETECTOR_MODEL_HELP = (
    "detector ONNX file (default: the first present of the --detector's models, from "
    "$DENSEPEDS_MODEL_DIR or the user cache; `densepeds models` says which)"
)
DEVICE_HELP = (
    "where the detector and re-ID models run: auto an NVIDIA GPU where one is usable, else the "
    "CPU; cpu; cuda a GPU or fail (needs the gpu extra: pip install 'densepeds[gpu]'); openvino "
    "the CPU through OpenVINO's runtime (pip install 'densepeds[openvino]'); default auto"
)
REID_MODEL_HELP = (
    "re-ID ONNX file, e.g. an OSNet or YoutuReID export (default: the first present of the "
    "known re-ID models, from $DENSEPEDS_MODEL_DIR or the user cache; `densepeds models` says "
    "which)"
)
PARAM_HELP = (
    "tracker parameter, e.g. max_age=30 (repeatable; the names are "
    "densepeds.tracking.Tracker().params); default: the preset's values"
)

Params = tuple[tuple[str, Any], ...]
_O = TypeVar("_O", bound="RunOptions")


def params_tuple(params: Mapping[str, Any] | Params | None) -> Params:
    """Tracker parameters as a sorted tuple of (name, value) (a later value of a name wins)."""
    return tuple(sorted(dict(params or ()).items()))


@dataclass(frozen=True, kw_only=True)
class RunOptions:
    """The settings of a run that do not name one input's files: the same for every input of a
    batch (``densepeds run --help`` describes each)."""

    # detector
    detector: str | None = None
    detector_model: str | None = None
    tiles: str | None = None
    full_scan_every: int | None = None
    focus_lost: float | None = None
    preset: str | None = None
    speed: str | None = None
    # where the models run
    device: str = "auto"
    # re-ID
    features: str | None = None
    reid_model: str | None = None
    reid_reuse: bool = False
    # tracker
    motion: str = "frvo"
    params: Params = ()
    # which frames, and what the tracks file gets
    frames: str | None = None
    fill_gaps: int = 0
    allow_partial: bool = False

    @classmethod
    def from_args(cls: type[_O], args: argparse.Namespace, **values: Any) -> _O:
        """The settings from parsed options (the option ``--param`` fills ``params``); a field
        with no option in ``args`` keeps its default; ``values`` override."""
        given = vars(args)
        found: dict[str, Any] = {}
        for f in fields(cls):
            if f.name == "params" and "param" in given:
                found["params"] = params_tuple(given["param"])
            elif f.name in given:
                found[f.name] = given[f.name]
        return cls(**{**found, **values})

    def options(self) -> RunOptions:
        """These settings alone (without a subclass's own fields)."""
        return RunOptions(**{f.name: getattr(self, f.name) for f in fields(RunOptions)})


@dataclass(frozen=True, kw_only=True)
class RunSpec(RunOptions):
    """One tracking run: its input, the settings (:class:`RunOptions`) and its outputs.

    ``input`` None is the built-in scene (``seed``, ``scene_frames``); ``detections``: a det
    file to track from; ``reconnect``: a live camera's reopening tries; ``out``: the tracks file
    (None: ``out/<input name>.txt``); ``video``: an annotated video to write; ``quiet``: no
    progress bar.
    """

    # inputs
    input: str | None = None
    detections: str | None = None
    reconnect: int = 0
    seed: int = 0
    scene_frames: int = 150
    # outputs
    out: Path | None = None
    video: Path | None = None
    quiet: bool = False

    @classmethod
    def for_input(cls, options: RunOptions, input: str | Path, **values: Any) -> RunSpec:
        """A run of ``input`` with ``options`` (and ``values`` for the other fields)."""
        return cls(**{**vars(options.options()), "input": str(input), **values})


# --- the options ---------------------------------------------------------------------------------


def tracker_param(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` -> (key, value): true/false, an int or a float where the text is one."""
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


@dataclass(frozen=True)
class Option:
    """One command-line option: its flags and argparse's keywords; ``shared``: the same for
    every input (``batch`` has it too)."""

    flags: tuple[str, ...]
    kwargs: Mapping[str, Any]
    shared: bool = True
    group: str = "input"

    @property
    def dest(self) -> str:
        return str(self.kwargs.get("dest") or self.flags[0].lstrip("-").replace("-", "_"))

    def add_to(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument(*self.flags, **self.kwargs)


def _option(*flags: str, group: str, shared: bool = True, **kwargs: Any) -> Option:
    return Option(flags, kwargs, shared, group)


# run --help's sections, in order, with an optional line under each title.
GROUPS: dict[str, str | None] = {
    "input": None,
    "detection": None,
    "appearance (re-ID)": None,
    "tracking": "every tracker parameter and its default: docs/parameters.md",
    "output": None,
    "the built-in scene (no INPUT)": None,
}


OPTIONS: tuple[Option, ...] = (
    _option(
        "input",
        nargs="?",
        help="video file, image folder or MOTChallenge sequence folder (seqinfo.ini, img1/ "
        "and/or det/det.txt), or a live camera: rtsp://..., http(s)://..., /dev/videoN (tracks "
        "written frame by frame; exit code 3 when the stream ends or disconnects); default: the "
        "built-in scene",
        shared=False,
        group="input",
    ),
    _option(
        "--reconnect",
        metavar="N",
        type=int,
        default=0,
        help="live camera: when the stream ends or stalls, try to open it again up to N times, "
        "1 s apart; default 0",
        shared=False,
        group="input",
    ),
    _option(
        "--detections",
        metavar="FILE",
        help="MOTChallenge det.txt to track from (overrides a sequence's det/det.txt); default: "
        "the sequence's det/det.txt where it has one",
        shared=False,
        group="input",
    ),
    _option(
        "--detector",
        choices=DETECTORS,
        help="detect people in the frames with this CNN (default: where there are frames and no "
        "det file, the first installed detector; `densepeds models` says which)",
        group="detection",
    ),
    _option("--detector-model", metavar="PATH", help=DETECTOR_MODEL_HELP, group="detection"),
    _option(
        "--tiles",
        metavar="auto|grid|CxR|none",
        help="the CNN detector's views of a frame: auto tiles that follow the people "
        "(at most twice the fixed grid's views); CxR a fixed grid of overlapping tiles, e.g. 3x2 "
        "(faster, fewer people found in crowds), grid the one chosen for the frame size (3x2 "
        "at most); none the whole frame in one view; default auto",
        group="detection",
    ),
    _option(
        "--full-scan-every",
        metavar="K",
        type=int,
        help="the yoloseg detector runs all its views every K-th frame only, and in between just "
        "views of the people found in the last K frames (windows of the tiles' sizes placed over "
        "them, or the tiles that show them, whichever are fewer; faster, the tracks change); "
        "default 1: all views every frame",
        group="detection",
    ),
    _option(
        "--focus-lost",
        metavar="S",
        type=float,
        help="the yoloseg detector also looks closer at each person the tracker reports without "
        "a detection (lost behind others): one more view a frame each, of the model input's "
        "shape, its longer side S times their height (more people found in dense crowds, "
        "slower there); 0 turns it off; default 2.5 (YoloSegDetector's focus_scale)",
        group="detection",
    ),
    _option(
        "--speed",
        choices=SPEEDS,
        help="a measured point on the speed/accuracy curve, setting the yoloseg detector's "
        "--tiles, --full-scan-every, --focus-lost and int8 copy (options given win; "
        "docs/speed.md): " + "; ".join(p.describe() for p in SPEEDS.values()) + "; default: none "
        "(the options' own defaults)",
        group="detection",
    ),
    _option("--device", choices=DEVICES, default="auto", help=DEVICE_HELP, group="detection"),
    _option("--reid-model", metavar="PATH", help=REID_MODEL_HELP, group="appearance (re-ID)"),
    _option(
        "--reid-reuse",
        action="store_true",
        help="a detection that plainly continues one of the previous frame's (it alone overlaps "
        "it, with the same colours; with nearly the same where nobody else is near) keeps that "
        "re-ID embedding, for up to 4 frames in a row, instead of a new one "
        "(densepeds.reid.ReusePolicy): less re-ID work, the tracks may change; default: off",
        group="appearance (re-ID)",
    ),
    _option(
        "--motion",
        choices=MOTIONS,
        default="frvo",
        help="motion model: frvo (the method), rvo, sf (social forces), cv (constant "
        "velocity); default frvo",
        group="tracking",
    ),
    _option(
        "--preset",
        choices=PRESETS,
        help="settings for the detections (listed below); default: the detector's own, "
        f"{DEFAULT_PRESET} for det files",
        group="tracking",
    ),
    _option(
        "--features",
        choices=FEATURES,
        help=f"appearance features: segmented (the method's white fill outside the mask), bbox "
        f"(plain crop), masked_pool (mask-weighted pooling of the re-ID features), masked_mean, "
        f"masked_blur (other fills), none (motion only); default: {DEFAULT_FEATURES} where "
        f"there are frames (segmented on the built-in scene), else none",
        group="appearance (re-ID)",
    ),
    _option(
        "--frames",
        metavar="A:B",
        help="frame range, 1-based and inclusive (A:, :B and A work); default: every frame",
        group="input",
    ),
    _option(
        "--out",
        metavar="TRACKS.txt",
        type=Path,
        help="tracks output file, MOTChallenge format (default: out/<input name>.txt)",
        shared=False,
        group="output",
    ),
    _option(
        "--video",
        metavar="OUT.mp4",
        type=Path,
        help="annotated video output; default: none",
        shared=False,
        group="output",
    ),
    _option(
        "--fill-gaps",
        metavar="N",
        type=int,
        default=0,
        help="after the run, replace what each track reported between two of its detections at "
        "most N frames apart (coasted boxes, or none) by the straight line between them: an "
        "offline step, in the tracks file only (--video shows the online tracks); default 0: off",
        group="output",
    ),
    _option(
        "--param",
        metavar="KEY=VALUE",
        type=tracker_param,
        action="append",
        default=[],
        help=PARAM_HELP,
        group="tracking",
    ),
    _option(
        "--seed",
        type=int,
        default=0,
        help="random seed; default 0",
        shared=False,
        group="the built-in scene (no INPUT)",
    ),
    _option(
        "--scene-frames",
        type=int,
        default=150,
        help="frames; default 150",
        shared=False,
        group="the built-in scene (no INPUT)",
    ),
    _option(
        "--quiet",
        "-q",
        action="store_true",
        help="no progress bar; default: a progress bar",
        shared=False,
        group="output",
    ),
    _option(
        "--allow-partial",
        action="store_true",
        help="keep the tracks of an input that ends before its expected frame count (a truncated "
        "video, an image folder shorter than its seqLength) instead of failing; default: fail",
        group="input",
    ),
)
SHARED: tuple[Option, ...] = tuple(o for o in OPTIONS if o.shared)


def add_run_options(parser: argparse.ArgumentParser, *, shared_only: bool = False) -> None:
    """Add ``run``'s options to ``parser`` (``shared_only``: those of every input, for batch)."""
    chosen = SHARED if shared_only else OPTIONS
    for title, line in GROUPS.items():
        members = [o for o in chosen if o.group == title]
        if members:
            group = parser.add_argument_group(title, line)
            for option in members:
                option.add_to(group)  # type: ignore[arg-type]  # a group adds options as a parser


def add_option(parser: argparse.ArgumentParser, dest: str) -> None:
    """Add the one ``run`` option that fills ``dest`` (e.g. ``param``) to another command."""
    (option,) = (o for o in OPTIONS if o.dest == dest)
    option.add_to(parser)


def presets_help() -> str:
    """The presets, one entry each, for ``run --help``."""
    lines = ["presets (--param KEY=VALUE overrides a value):"]
    for p in PRESETS.values():
        lines += textwrap.wrap(p.describe(), 96, initial_indent="  ", subsequent_indent="      ")
    return "\n".join(lines)
