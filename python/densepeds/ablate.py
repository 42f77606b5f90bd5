"""The method's ablation: every motion model x every feature kind on the same detections.

Like the paper's Table III (segmented boxes vs plain boxes; FRVO vs constant velocity, social
forces and RVO), but as one grid. Detections and appearance features are computed once per
sequence and reused for every motion model, so only tracking is repeated.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from densepeds.errors import InputError, ParameterError
from densepeds.io.video import FrameRange, FrameSource, SequenceSource, parse_frame_range
from densepeds.pipeline import DEFAULT_FEATURES, FEATURES, MOTIONS, Pipeline, track_rows
from densepeds.types import Detections

__all__ = ["AblationResult", "cut_gt", "format_ablation", "run_ablation"]

# Table columns: (header, metric key, percent of GT ids?, decimals)
COLUMNS = (
    ("HOTA", "HOTA", False, 1),
    ("IDF1", "IDF1", False, 1),
    ("MT(%)", "MT", True, 1),
    ("ML(%)", "ML", True, 1),
    ("IDS", "IDSW", False, 0),
    ("FN", "FN", False, 0),
    ("FP", "FP", False, 0),
    ("MOTP(%)", "MOTP", False, 1),
    ("MOTA(%)", "MOTA", False, 1),
)


@dataclass
class _Frame:
    frame_no: int  # numbering of the (possibly cut) evaluation sequence
    detections: Detections
    embeddings: dict[str, npt.NDArray[np.float32]]


@dataclass
class _Prepared:
    name: str
    gt_dir: Path
    frames: list[_Frame]


@dataclass
class AblationRow:
    motion: str
    features: str
    combined: dict[str, float]
    sequences: dict[str, dict[str, float]]


@dataclass
class AblationResult:
    sequences: list[str]
    rows: list[AblationRow] = field(default_factory=list)


def cut_gt(src: SequenceSource, rng: FrameRange, out_root: Path) -> Path:
    """A copy of the sequence's seqinfo and gt cut to ``rng`` and renumbered from 1."""
    from densepeds.io.mot import read_gt

    gt_file = src.path / "gt" / "gt.txt"
    if not gt_file.is_file():
        raise InputError(f"{src.path}: no gt/gt.txt to evaluate against")
    assert rng.last is not None
    if rng.first == 1 and rng.last == src.length:
        return src.path
    gt = read_gt(gt_file)
    gt = gt[(gt[:, 0] >= rng.first) & (gt[:, 0] <= rng.last)]
    gt[:, 0] -= rng.first - 1
    seq = out_root / src.name
    (seq / "gt").mkdir(parents=True)
    info = src.info
    (seq / "seqinfo.ini").write_text(
        f"[Sequence]\nname={info.name}\nimDir={info.im_dir}\nframeRate={info.fps:g}\n"
        f"seqLength={rng.last - rng.first + 1}\nimWidth={info.width}\nimHeight={info.height}\n"
        f"imExt={info.im_ext}\n",
        encoding="utf-8",
    )
    lines = [",".join(f"{v:g}" for v in row) + "\n" for row in gt.tolist()]
    (seq / "gt" / "gt.txt").write_text("".join(lines), encoding="utf-8")
    return seq


def _prepare(
    src: FrameSource,
    gt_dir: Path,
    rng: FrameRange,
    dets: Mapping[int, Detections] | None,
    detector: Any,
    embedder: Any,
    kinds: Sequence[str],
    quiet: bool,
) -> _Prepared:
    """Detect and embed every frame once."""
    from tqdm import tqdm

    frames = []
    items = src.frames(rng)
    bar = tqdm(
        items,
        desc=f"{src.name} (detect + embed)",
        unit="frame",
        file=sys.stderr,
        leave=False,
        disable=quiet or not sys.stderr.isatty(),
        total=src.length,
    )
    for frame_no, image in bar:
        d = dets.get(frame_no, Detections.empty()) if dets is not None else detector(image)
        emb = {}
        if image is not None and len(d):
            for kind in kinds:
                if kind != "none":
                    emb[kind] = embedder.embed(image, d, features=kind)
        frames.append(_Frame(frame_no - rng.first + 1, d, emb))
    return _Prepared(src.name, gt_dir, frames)


# The method's ablation rows; the package's default features are added where they differ.
ABLATION_FEATURES = ("segmented", "bbox", "none")


def _default_kinds(has_images: bool) -> list[str]:
    if not has_images:
        return ["none"]
    extra = [] if DEFAULT_FEATURES in ABLATION_FEATURES else [DEFAULT_FEATURES]
    return [*extra, *ABLATION_FEATURES]


def run_ablation(
    seq_dirs: Sequence[str | os.PathLike[str]],
    motions: Sequence[str] = MOTIONS,
    features: Sequence[str] | None = None,
    *,
    frames: str | FrameRange | None = None,
    detector: str | None = None,
    detector_model: str | os.PathLike[str] | None = None,
    reid_model: str | os.PathLike[str] | None = None,
    tracker_params: Mapping[str, Any] | None = None,
    quiet: bool = True,
    scene_seed: int = 0,
) -> AblationResult:
    """Track every sequence with every (motion, features) pair and evaluate each pair.

    No ``seq_dirs``: the built-in scene (its detections with masks, its colour-histogram
    embedder). Sequences need ``gt/gt.txt``; detections come from ``det/det.txt`` unless a
    ``detector`` is given; features other than ``none`` need frames.
    """
    from densepeds.evaluate import evaluate
    from densepeds.io.mot import read_detections, write_tracks

    for m in motions:
        if m not in MOTIONS:
            raise ParameterError(f"motion {m!r}: expected one of {', '.join(MOTIONS)}")
    for f in features or ():
        if f not in FEATURES:
            raise ParameterError(f"features {f!r}: expected one of {', '.join(FEATURES)}")
    rng = parse_frame_range(frames)
    params = dict(tracker_params or {})
    with tempfile.TemporaryDirectory(prefix="densepeds-ablate-") as tmp_name:
        tmp = Path(tmp_name)
        prepared: list[_Prepared] = []
        if not seq_dirs:
            from densepeds.scene import make_scene

            scene = make_scene(seed=scene_seed)
            kinds = list(features or ABLATION_FEATURES)  # the scene's embedder: no masked_*
            gt_dir = _cut_gt_scene(scene, rng, tmp / "gt")
            prepared.append(
                _prepare(
                    scene,
                    gt_dir,
                    _clip(scene.name, rng, scene.config.frames),
                    scene.detections,
                    None,
                    scene.embedder(),
                    kinds,
                    quiet,
                )
            )
        else:
            sources = [SequenceSource(p) for p in seq_dirs]
            names = [s.name for s in sources]
            if len(set(names)) != len(names):
                raise InputError(f"sequence names repeat: {', '.join(names)}")
            all_images = all(s.has_images for s in sources)
            kinds = list(features or _default_kinds(all_images))
            if not all_images and any(k != "none" for k in kinds):
                missing = ", ".join(s.name for s in sources if not s.has_images)
                raise ParameterError(f"features other than none need frames; {missing} has none")
            if detector is None and any(s.det_path is None for s in sources):
                missing = ", ".join(s.name for s in sources if s.det_path is None)
                raise InputError(f"{missing}: no det/det.txt (give --detector)")
            helper = Pipeline(
                detector,
                reid=reid_model,
                features="segmented",
                detector_model=detector_model,
                tracker=_NoTracker(),
            )
            embedder = helper.reid() if any(k != "none" for k in kinds) else None
            det_fn = helper.detector() if detector is not None else None
            for s in sources:
                r = _clip(s.name, rng, s.length or 0)
                dets = None if det_fn is not None else read_detections(s.det_path)  # type: ignore[arg-type]
                gt_dir = cut_gt(s, r, tmp / "gt")
                prepared.append(_prepare(s, gt_dir, r, dets, det_fn, embedder, kinds, quiet))
        result = AblationResult([p.name for p in prepared])
        for motion in motions:
            for kind in kinds:
                out_dir = tmp / f"{motion}-{kind}"
                for prep in prepared:
                    # The detector named (never run here: detections are given) selects the
                    # pipeline's preset for CNN detections, as in `densepeds run`.
                    pipe = Pipeline(detector, motion=motion, features=kind, **params)
                    rows: list[tuple[float, ...]] = []
                    for fr in prep.frames:
                        emb = fr.embeddings.get(kind)
                        tracks = pipe.step(None, fr.detections, embeddings=emb)
                        rows.extend(track_rows(fr.frame_no, tracks))
                    write_tracks(out_dir / f"{prep.name}.txt", rows)
                ev = evaluate([p.gt_dir for p in prepared], out_dir)
                result.rows.append(AblationRow(motion, kind, ev.combined, ev.sequences))
    return result


def _clip(name: str, rng: FrameRange, length: int) -> FrameRange:
    """``rng`` cut to a sequence of ``length`` frames; a range past its end is an error."""
    if rng.first > length:
        raise ParameterError(
            f"{name}: frame range starts at {rng.first}, after its last frame ({length})"
        )
    return rng.clip(length)


def _cut_gt_scene(scene: Any, rng: FrameRange, root: Path) -> Path:
    seq = scene.write(root, images=False)
    return cut_gt(SequenceSource(seq), _clip(scene.name, rng, scene.config.frames), root / "cut")


class _NoTracker:
    """Placeholder for the helper pipeline that only builds the detector and re-ID models."""

    def update(self, *_: Any) -> Any:
        raise NotImplementedError

    def reset(self) -> None:
        pass


def _cell(metrics: Mapping[str, float], key: str, percent: bool, decimals: int) -> float | None:
    value = metrics.get(key)
    if value is None:
        return None
    if percent:
        gt_ids = metrics.get("GT_IDs") or 0
        return 100.0 * value / gt_ids if gt_ids else None
    return float(value)


def format_ablation(result: AblationResult, fmt: str = "md") -> str:
    """One table: a row per (motion, features), columns like Table III plus HOTA and IDF1."""
    headers = ["Motion", "Features", *(c[0] for c in COLUMNS)]
    table = []
    for row in result.rows:
        cells = [_cell(row.combined, key, pct, dec) for _, key, pct, dec in COLUMNS]
        table.append((row.motion, row.features, cells))
    if fmt == "json":
        return json.dumps(
            {
                "sequences": result.sequences,
                "rows": [
                    {
                        "motion": m,
                        "features": f,
                        **{h: c for h, c in zip(headers[2:], cells, strict=True)},
                    }
                    for m, f, cells in table
                ],
            },
            indent=2,
        )

    def text(value: float | None, decimals: int) -> str:
        return "-" if value is None else f"{value:.{decimals}f}"

    lines = []
    for m, f, cells in table:
        lines.append([m, f, *(text(v, c[3]) for v, c in zip(cells, COLUMNS, strict=True))])
    if fmt == "csv":
        return "\n".join(",".join(r) for r in [headers, *lines])
    if fmt != "md":
        raise ParameterError(f"format {fmt!r}: expected md, csv or json")
    out = [
        f"Ablation on {', '.join(result.sequences)} (combined)",
        "",
        "| " + " | ".join(headers) + " |",
        "|" + "|".join(["---", "---"] + ["---:"] * len(COLUMNS)) + "|",
    ]
    out += ["| " + " | ".join(r) + " |" for r in lines]
    return "\n".join(out)
