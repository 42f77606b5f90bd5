"""The full pipeline on the two real videos: accuracy of the package defaults and the ablation.

    OPENBLAS_NUM_THREADS=1 python benchmarks/realvideo.py --write benchmarks/results/realvideo.md

Detections (the shared tiled YOLOv8n-seg at the detector's own threshold, masks included) and
the appearance features of every detection (one file per feature kind) are computed once per
video and cached under ``--cache`` (default ``out/cache``); every row then only reruns tracking
through ``densepeds.Pipeline.step`` (the same code as ``densepeds run``, so the pipeline's
detection filtering and tracker preset apply) and scores it with ``densepeds.evaluate``.
A cache file is keyed by the video, the frame range, the detector settings and the model files'
sizes and dates; delete the folder to recompute. ``--param KEY=VALUE`` overrides a pipeline or
tracker default for a sweep (sweeps take seconds once the cache exists).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # numpy BLAS threads fight onnxruntime's

import numpy as np
import numpy.typing as npt

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("DENSEPEDS_SHARED", REPO.parent / "shared"))
# The shared models by bare name (an explicit DENSEPEDS_MODEL_DIR from the environment wins).
os.environ.setdefault("DENSEPEDS_MODEL_DIR", str(SHARED / "models"))
VIDEOS = (("MOT20-01-dev", "1:214"), ("PETS09-S2L1-dev", "1:397"))
ABLATION = (
    ("frvo", "default"),
    ("frvo", "segmented"),
    ("frvo", "masked_pool"),
    ("frvo", "bbox"),
    ("frvo", "none"),
    ("cv", "default"),
    ("cv", "segmented"),
    ("cv", "masked_pool"),
    ("cv", "bbox"),
    ("cv", "none"),
)
COMMAND = (
    "OPENBLAS_NUM_THREADS=1 python benchmarks/realvideo.py --write benchmarks/results/realvideo.md"
)
NOTES = """\
Notes:

- Rows: motion model x appearance features, everything else at the package defaults (the
  detection and tracker presets above). `segmented` is the method's white fill outside the
  mask, `masked_pool` mask-weighted pooling of the re-ID features, `bbox` the plain box, `none`
  motion only.
- The presets were chosen on these two videos together (never per video), so these are tuned
  figures; `accuracy-loo.md` reports leave-one-out figures over the whole dev grid, and
  `accuracy.md` the peers on the same detections and embeddings.
- The detections are the detector's alone, cached: the closer look at the people the tracker
  lost (`YoloSegDetector(focus_scale)`, on by default) needs a live run (`decisions.md`).
"""
COLUMNS = ("HOTA", "IDF1", "MOTA", "MOTP", "MT", "ML", "FP", "FN", "IDSW", "IDs")


@dataclass
class CachedVideo:
    """One video's detections and per-kind embeddings, frame by frame."""

    name: str
    seq_dir: Path
    first: int
    dets: list[Any]  # densepeds.types.Detections per frame
    embeddings: dict[str, list[npt.NDArray[np.float32]]]


def _model_stamp(name: str) -> str:
    from densepeds.models.files import find_model

    return _file_stamp(find_model(name))


def _file_stamp(p: Path) -> str:
    """The model file by name and content (a copy or a remount of the same bytes hits the cache)."""
    from densepeds.models.files import sha256_of

    return f"{p.name}:{p.stat().st_size}:{sha256_of(p)[:16]}"


def detector_file(detector_options: dict[str, Any]) -> Path:
    """The model file the detector runs with these options (its int8 copy where it takes it)."""
    from densepeds.detect import DEFAULT_MODELS
    from densepeds.detect.yoloseg import choose_model
    from densepeds.models.files import find_model

    quantized = detector_settings(detector_options)["quantized"]
    return choose_model(find_model(DEFAULT_MODELS["yoloseg"]), quantized)


def detector_settings(detector_options: dict[str, Any]) -> dict[str, Any]:
    """The detector's effective settings: its constructor defaults, then the options given."""
    import inspect

    from densepeds.detect.yoloseg import YoloSegDetector

    sig = inspect.signature(YoloSegDetector.__init__)
    defaults = {
        k: v.default
        for k, v in sig.parameters.items()
        if v.default is not inspect.Parameter.empty and k != "threads"
    }
    return {**defaults, **detector_options}


def cached_settings(detector_options: dict[str, Any]) -> dict[str, Any]:
    """The settings the cached detections are made with: the detector's alone, no focus views
    (they need a tracker's lost people, which only a live run has)."""
    return {**detector_settings(detector_options), "focus_scale": 0.0}


def cache_key(seq: str, frames: str, detector_options: dict[str, Any]) -> str:
    import inspect

    from densepeds.detect import anchor_grid, tiling
    from densepeds.detect.yoloseg import fitted_input

    # The model choice is keyed by the file it resolves to (the stamp), not by the option.
    settings = {k: v for k, v in cached_settings(detector_options).items() if k != "quantized"}
    # Tiles chosen by a rule in the code: a change of the rule must miss the cache. The
    # settings of the people-following rule ("auto") enter the key only where it is chosen.
    rules: tuple[Any, ...] = (tiling.auto_grid,)
    if settings.get("tiles") == "auto":  # square tiles: the model's own input (fit_input)
        settings.pop("fit_input", None)
        rules += (tiling.fit_perspective, tiling.people_tiles, tiling._people_tiles)
        rules += (tiling.occupied_tiles, tiling.SkipSchedule, tiling.PeopleTiles)
        rules += (tiling.showing, tiling.sliding_windows)
    else:
        skip = settings.get("full_scan_every", 1)
        settings = {k: v for k, v in settings.items() if k not in tiling.PEOPLE_SETTINGS}
        if settings.get("fit_input"):  # the input cut to the tiles' shape, its anchors rebuilt
            rules += (fitted_input, anchor_grid)
        if skip != 1:  # a fixed grid that skips empty tiles between full scans
            settings["full_scan_every"] = skip
            rules += (tiling.occupied_tiles, tiling.SkipSchedule)
            rules += (tiling.showing, tiling.sliding_windows)
    items = sorted((k, repr(v)) for k, v in settings.items())
    source = "".join(inspect.getsource(f) for f in rules)
    rule = hashlib.sha1(source.encode()).hexdigest()[:8]
    text = json.dumps([seq, frames, items, rule, _file_stamp(detector_file(detector_options))])
    return hashlib.sha1(text.encode()).hexdigest()[:10]


def _save_dets(path: Path, dets: Sequence[Any]) -> None:
    counts = np.array([len(d) for d in dets], np.int64)
    boxes = np.concatenate([d.boxes for d in dets]) if dets else np.zeros((0, 4), np.float32)
    scores = np.concatenate([d.scores for d in dets]) if dets else np.zeros(0, np.float32)
    mask_boxes = np.zeros((len(boxes), 4), np.int32)
    flat: list[npt.NDArray[np.bool_]] = []
    row = 0
    for d in dets:
        for i in range(len(d)):
            assert d.masks is not None and d.mask_boxes is not None
            mask_boxes[row] = d.mask_boxes[i]
            flat.append(d.masks[i].reshape(-1))
            row += 1
    bits = np.packbits(np.concatenate(flat)) if flat else np.zeros(0, np.uint8)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(
        tmp, counts=counts, boxes=boxes, scores=scores, mask_boxes=mask_boxes, mask_bits=bits
    )
    os.replace(tmp, path)


def _load_dets(path: Path) -> list[Any]:
    from densepeds.types import Detections

    z = np.load(path)
    counts, boxes, scores, mboxes = z["counts"], z["boxes"], z["scores"], z["mask_boxes"]
    sizes = (mboxes[:, 2] - mboxes[:, 0]) * (mboxes[:, 3] - mboxes[:, 1])
    bits = np.unpackbits(z["mask_bits"], count=int(sizes.sum())).astype(bool)
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    out = []
    start = 0
    for n in counts.tolist():
        idx = range(start, start + n)
        masks = [
            bits[offsets[i] : offsets[i + 1]].reshape(
                mboxes[i, 3] - mboxes[i, 1], mboxes[i, 2] - mboxes[i, 0]
            )
            for i in idx
        ]
        out.append(
            Detections(
                boxes[start : start + n],
                scores[start : start + n],
                masks,
                mboxes[start : start + n],
            )
        )
        start += n
    return out


# Embedding variants: a kind is a feature kind of densepeds.segment.FEATURES, optionally followed
# by ``+flip`` (ReID(flip=True)), ``+ctxF`` (ReID(context=F)), ``+sHxW`` (ReID(input_size=(H, W)):
# OSNet on H x W crops) and/or ``+reuse`` (ReID(reuse=True): embedded frame by frame, a detection
# that plainly continues one of the previous frame's keeps its embedding; ``+reuse,KEY=VALUE,...``
# sets densepeds.reid.ReusePolicy's fields), e.g. ``segmented+flip``, ``segmented+s192x96``,
# ``segmented+reuse``, ``segmented+reuse,max_thumb_diff=15``.
def kind_options(kind: str) -> tuple[str, dict[str, Any]]:
    """(feature kind, ReID options) of a cached embedding kind."""
    features, *extras = kind.split("+")
    options: dict[str, Any] = {}
    for extra in extras:
        if extra == "flip":
            options["flip"] = True
        elif extra.startswith("ctx"):
            options["context"] = float(extra[3:])
        elif re.fullmatch(r"s\d+x\d+", extra):
            h, w = extra[1:].split("x")
            options["input_size"] = (int(h), int(w))
        elif extra.split(",")[0] == "reuse":
            from densepeds.reid import ReusePolicy

            fields = dict(item.split("=", 1) for item in extra.split(",")[1:])
            options["reuse"] = ReusePolicy(
                **{k: int(v) if v.isdigit() else float(v) for k, v in fields.items()}
            )
        else:
            raise ValueError(f"embedding kind {kind!r}: unknown variant {extra!r}")
    return features, options


def read_frames(seq_dir: Path, frames: str) -> Iterator[tuple[int, npt.NDArray[np.uint8]]]:
    from densepeds.io.video import SequenceSource, parse_frame_range

    src = SequenceSource(seq_dir)
    for frame_no, image in src.frames(parse_frame_range(frames)):
        assert image is not None
        yield frame_no, image


def load_video(
    seq: str,
    frames: str,
    kinds: Sequence[str],
    cache: Path,
    detector_options: dict[str, Any],
    quiet: bool = False,
) -> CachedVideo:
    """Detections and embeddings of ``kinds`` for a video, computed where not cached."""
    from densepeds.pipeline import Pipeline
    from densepeds.reid import ReID

    seq_dir = SHARED / "data" / seq
    if not seq_dir.is_dir():
        sys.exit(f"{seq_dir}: missing (the shared data beside the repo; set DENSEPEDS_SHARED)")
    cache.mkdir(parents=True, exist_ok=True)
    key = cache_key(seq, frames, detector_options)
    det_file = cache / f"{seq}-{key}-dets.npz"
    alone = {**detector_options, "focus_scale": 0.0}  # as cached_settings
    helper = Pipeline("yoloseg", detector_options=alone, features="none")
    if not det_file.is_file():
        t0 = time.perf_counter()
        det = helper.detector()
        dets = [det(image) for _, image in read_frames(seq_dir, frames)]
        _save_dets(det_file, dets)
        if not quiet:
            print(
                f"{seq}: detected {len(dets)} frames in {time.perf_counter() - t0:.0f} s",
                file=sys.stderr,
            )
    dets = _load_dets(det_file)
    embeddings: dict[str, list[npt.NDArray[np.float32]]] = {}
    for kind in kinds:
        emb_file = (
            cache
            / f"{seq}-{key}-{kind}-{_model_stamp('osnet_x0_25_msmt17.onnx').split(':')[1]}.npz"
        )
        if not emb_file.is_file():
            t0 = time.perf_counter()
            features, options = kind_options(kind)
            reid = helper.reid() if not options else ReID(**options)
            rows = [
                reid.embed(image, d, features=features)
                for (_, image), d in zip(read_frames(seq_dir, frames), dets, strict=True)
            ]
            tmp = emb_file.with_suffix(".tmp.npz")
            np.savez(tmp, emb=np.concatenate(rows), counts=[len(r) for r in rows])
            os.replace(tmp, emb_file)
            if not quiet:
                reused = ""
                if isinstance(reid, ReID) and reid.reuse is not None:
                    reused = f", {reid.reused} of {reid.reused + reid.embedded} reused"
                print(
                    f"{seq}: embedded ({kind}) in {time.perf_counter() - t0:.0f} s{reused}",
                    file=sys.stderr,
                )
        z = np.load(emb_file)
        embeddings[kind] = np.split(z["emb"], np.cumsum(z["counts"])[:-1])
    first = int(frames.split(":")[0])
    return CachedVideo(seq, seq_dir, first, dets, embeddings)


def track_video(
    video: CachedVideo,
    motion: str,
    features: str,
    params: dict[str, Any],
    out_file: Path,
) -> None:
    """Track the cached video through ``densepeds.Pipeline`` and write MOTChallenge rows."""
    from densepeds.io.mot import read_seqinfo, write_tracks
    from densepeds.pipeline import Pipeline, track_rows

    pipe = Pipeline("yoloseg", motion=motion, features=kind_options(features)[0], **params)
    info = read_seqinfo(video.seq_dir)
    pipe.set_image_size(info.width, info.height)  # as `densepeds run` gives it from the frames
    kind = features if pipe.features != "none" else "none"
    rows: list[tuple[float, ...]] = []
    for k, dets in enumerate(video.dets):
        emb = None if kind == "none" else video.embeddings[kind][k]
        tracks = pipe.step(None, dets, embeddings=emb)
        rows.extend(track_rows(k + 1, tracks))
    write_tracks(out_file, rows)


def gt_dir(video: CachedVideo, frames: str, root: Path) -> Path:
    from densepeds.ablate import cut_gt
    from densepeds.io.video import SequenceSource, parse_frame_range

    src = SequenceSource(video.seq_dir)
    return cut_gt(src, parse_frame_range(frames).clip(src.length or 0), root)


def score(
    videos: Sequence[tuple[CachedVideo, str]],
    motion: str,
    features: str,
    params: dict[str, Any],
    tmp: Path,
) -> dict[str, dict[str, float]]:
    """Metrics per video name for one (motion, features, params) setting."""
    from densepeds.evaluate import evaluate

    out: dict[str, dict[str, float]] = {}
    for video, frames in videos:
        gt_root = tmp / "gt"
        gt = gt_root / video.name
        if not gt.is_dir():
            gt = gt_dir(video, frames, gt_root)
        tracks = tmp / f"{motion}-{features}-{video.name}.txt"
        track_video(video, motion, features, params, tracks)
        out[video.name] = evaluate([gt], tracks).combined
    return out


def _param(text: str) -> tuple[str, Any]:
    key, _, raw = text.partition("=")
    for kind in (int, float):
        try:
            return key, kind(raw)
        except ValueError:
            pass
    if raw.lower() in ("true", "false"):
        return key, raw.lower() == "true"
    return key, raw


def _fmt(metrics: dict[str, float], key: str) -> str:
    v = metrics.get(key, float("nan"))
    if key in ("MT", "ML", "FP", "FN", "IDSW", "IDs"):
        return f"{v:.0f}"
    return f"{v:.1f}"


def table(
    rows: Sequence[tuple[str, str, dict[str, dict[str, float]]]], names: Sequence[str]
) -> str:
    lines = []
    for name in names:
        lines += [
            f"**{name}**",
            "",
            "| motion | features | " + " | ".join(COLUMNS) + " |",
            "|---|---|" + "---:|" * len(COLUMNS),
        ]
        for motion, features, res in rows:
            cells = " | ".join(_fmt(res[name], c) for c in COLUMNS)
            lines.append(f"| {motion} | {features} | {cells} |")
        lines.append("")
    return "\n".join(lines)


def report_header(
    default_kind: str,
    params: dict[str, Any],
    detector_options: dict[str, Any],
) -> str:
    """Title, command and the package defaults."""
    from densepeds.presets import PRESETS

    lines = [
        "# The full pipeline on the real videos (package defaults)",
        "",
        "Detector: the shared `yolov8n-seg-320-int8.onnx` with settings "
        f"`{cached_settings(detector_options)}`; re-ID: `osnet_x0_25_msmt17.onnx`; "
        "metrics: `densepeds.evaluate` "
        "(trackeval; MOT20 rules for MOT20-01, MOT15 rules for PETS). Frames 1-214 of "
        "MOT20-01-dev and 1-397 of PETS09-S2L1-dev. Reproduce with:",
        "",
        f"    {COMMAND}"
        + "".join(f" --detector-option {k}={v}" for k, v in detector_options.items()),
        "",
        "(detections and embeddings are cached under out/cache; tracking goes through "
        "`densepeds.Pipeline`, the code behind `densepeds run`).",
        "",
        f"Preset: `{PRESETS['yoloseg'].describe()}`",
        "",
        f"Default features with frames: `{default_kind}` (motion `frvo`).",
        "",
    ]
    if params:
        lines += [f"Overrides for this run: `{params}`", ""]
    return "\n".join(lines) + "\n\n## Ablation\n\n"


def main(argv: Sequence[str] | None = None) -> int:
    from densepeds.pipeline import default_features

    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--cache", type=Path, default=REPO / "out" / "cache")
    ap.add_argument("--rows", default="ablation", help="'ablation' or MOTION:FEATURES,...")
    ap.add_argument("--param", type=_param, action="append", default=[], help="KEY=VALUE override")
    ap.add_argument(
        "--detector-option",
        type=_param,
        action="append",
        default=[],
        help="KEY=VALUE for the yoloseg detector (default: its own defaults, quantized=False)",
    )
    ap.add_argument("--kinds", default="segmented,bbox,masked_pool", help="feature kinds to cache")
    ap.add_argument("--write", type=Path, help="also write the tables to this markdown file")
    ap.add_argument("--quiet", "-q", action="store_true")
    args = ap.parse_args(argv)
    default_kind = default_features(has_images=True)
    if args.rows == "ablation":
        settings = list(ABLATION)
    else:
        settings = [tuple(s.split(":")) for s in args.rows.split(",")]  # type: ignore[misc]
    settings = [(m, default_kind if f == "default" else f) for m, f in settings]
    # The shipped model's float copy, as on a fresh install: an int8 copy that `densepeds models
    # quantize` left in the model folders would otherwise be picked up (quantized=None).
    det_opts = {"quantized": False, **dict(args.detector_option)}
    kinds = sorted({f for _, f in settings if f != "none"} | set(args.kinds.split(",")))
    videos = [
        (load_video(seq, frames, kinds, args.cache, det_opts, args.quiet), frames)
        for seq, frames in VIDEOS
    ]
    params = dict(args.param)
    results = []
    with tempfile.TemporaryDirectory(prefix="densepeds-realvideo-") as tmp_name:
        for motion, features in dict.fromkeys(settings):
            t0 = time.perf_counter()
            res = score(videos, motion, features, params, Path(tmp_name))
            results.append((motion, features, res))
            if not args.quiet:
                brief = "; ".join(
                    f"{n} HOTA {m['HOTA']:.1f} IDF1 {m['IDF1']:.1f} MOTA {m['MOTA']:.1f}"
                    for n, m in res.items()
                )
                print(
                    f"{motion}:{features} {brief} ({time.perf_counter() - t0:.1f} s)",
                    file=sys.stderr,
                )
    text = table(results, [v.name for v, _ in videos])
    print(text)
    if args.write:
        header = report_header(default_kind, params, det_opts)
        args.write.write_text(header + text + "\n" + NOTES, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
