"""The run engine: one :class:`~densepeds.runner.spec.RunSpec` from its input to its outputs.

``open_run`` opens the input, checks the settings against it and loads the models;
``track_source`` runs the pipeline over the frames and writes the tracks (and the annotated
video); ``summary`` is the line ``densepeds run`` prints. ``densepeds run`` and every job of
``densepeds batch`` go through these functions, so their outputs are the same.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path
from typing import Any

from densepeds.errors import InputError, ParameterError
from densepeds.presets import get_preset, preset_for
from densepeds.runner.control import Interrupted, ctrl_c_after_block, progress_bar
from densepeds.runner.spec import RunSpec


def open_run(spec: RunSpec, models: Any = None) -> tuple[Any, Any, Any, Path, Any]:
    """``run``'s set-up for one INPUT: (frame source, pipeline, det-file detections, tracks path,
    frame range).

    ``models`` (``densepeds.batch``): an object whose ``detector(kind, path, **options)`` and
    ``reid(path, reuse=...)`` give loaded models, shared by the inputs of a batch; by default the
    pipeline loads its own.
    """
    from densepeds.io.live import LiveSource, is_live
    from densepeds.io.mot import read_detections, safe_name
    from densepeds.io.video import SequenceSource, open_source, parse_frame_range
    from densepeds.pipeline import Pipeline, default_features

    if spec.input is None:
        raise ParameterError("open_run needs an input (run_scene tracks the built-in scene)")
    src = LiveSource(spec.input, spec.reconnect) if is_live(spec.input) else open_source(spec.input)
    has_images = not isinstance(src, SequenceSource) or src.has_images
    has_own_dets = isinstance(src, SequenceSource) and src.det_path is not None
    detector = spec.detector
    if detector is None and spec.detections is None and not has_own_dets:
        if not has_images:
            raise ParameterError(f"{spec.input}: no images and no det/det.txt to track from")
        from densepeds.models.files import default_detector

        detector = default_detector(spec.detector_model)
    features = spec.features or default_features(has_images)
    if features != "none" and not has_images:
        raise ParameterError(
            f"--features {features} needs frames, and {spec.input} has none (use --features none)"
        )
    profile = None
    if spec.speed is not None:
        if detector != "yoloseg" or spec.detections is not None:
            raise ParameterError(
                f"--speed {spec.speed} sets the yoloseg detector, and this run does not detect "
                "with it (add --detector yoloseg to detect)"
            )
        from densepeds.speed import get_speed

        profile = get_speed(spec.speed)

    def chosen(name: str) -> Any:
        """The option given, else the speed profile's value (None: the detector's own)."""
        given = getattr(spec, name)
        return getattr(profile, name) if given is None and profile is not None else given

    tiles = chosen("tiles")
    if tiles is not None and (detector is None or spec.detections is not None):
        raise ParameterError(
            "--tiles sets the CNN detector's views, and this run tracks detections from a file "
            "(add --detector yoloseg to detect)"
        )
    full_scan_every = chosen("full_scan_every")
    if full_scan_every is not None and (detector != "yoloseg" or spec.detections is not None):
        raise ParameterError(
            "--full-scan-every sets the yoloseg detector's views, and this run does not detect "
            "with it (add --detector yoloseg to detect)"
        )
    focus_lost = chosen("focus_lost")
    if focus_lost is not None and (detector != "yoloseg" or spec.detections is not None):
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
    if profile is not None:
        detector_options["quantized"] = profile.int8
    reid_reuse = spec.reid_reuse
    if reid_reuse and features == "none":
        raise ParameterError(
            "--reid-reuse keeps re-ID embeddings, and this run computes none (--features none)"
        )
    # Read the det file and load the models before tracking, so that mistakes surface at once.
    dets: Any = read_detections(spec.detections) if spec.detections else None
    detector_spec: Any = detector
    reid_spec: Any = spec.reid_model
    # The preset follows the detector asked for, also when a batch hands over a loaded one.
    preset = spec.preset if spec.preset is not None else preset_for(detector).name
    if models is not None:
        if detector is not None and dets is None:
            # A loaded detector gets what the pipeline gives the one it builds: the options and
            # the preset's score floor.
            floor = get_preset(preset).score_floor
            loaded_options = dict(detector_options)
            if floor is not None:
                loaded_options = {"score_threshold": floor, **loaded_options}
            detector_spec = models.detector(detector, spec.detector_model, **loaded_options)
        if features != "none":
            reid_spec = models.reid(spec.reid_model, reuse=reid_reuse)
    elif reid_reuse:
        from densepeds.reid import ReID

        reid_spec = ReID(spec.reid_model, reuse=True, device=spec.device)
    pipe = Pipeline(
        detector_spec,
        reid=reid_spec,
        motion=spec.motion,
        features=features,
        detector_model=spec.detector_model,
        detector_options=detector_options or None,
        preset=preset,
        device=spec.device,
        **dict(spec.params),
    )
    if detector is not None and dets is None:
        pipe.detector()
    if features != "none":
        pipe.reid()
    rng = parse_frame_range(spec.frames)
    if not has_images and detector is None:
        dets = pipe.source_detections(src, dets if dets is not None else spec.detections)
        rng = _stop_after_detections(spec, src, rng, dets, pipe)
    out = spec.out or Path("out") / f"{safe_name(src.name, 'tracks')}.txt"
    return src, pipe, dets, out, rng


def _stop_after_detections(spec: RunSpec, src: Any, rng: Any, dets: Any, pipe: Any) -> Any:
    """A detections-only run ends where no track can be reported any more: after the last
    detection and the frames a lost track stays in the output. Later frames would only be empty
    (a ``seqLength`` far beyond the detections would otherwise run for hours); says so."""
    from densepeds.io.video import FrameRange

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
            spec,
            f"{src.name}: {src.length} frames, but the detections end at frame {last_det}; "
            f"tracked to frame {end} (no track is reported after it)",
        )
        return FrameRange(rng.first, end)
    raise InputError(
        f"{src.name}: no detections in frames {rng.first}:{planned} (the last is at frame "
        f"{last_det})"
    )


def run_scene(spec: RunSpec) -> int:
    from importlib.util import find_spec

    from densepeds.evaluate import INSTALL_HINT, evaluate, format_results
    from densepeds.pipeline import Pipeline
    from densepeds.scene import make_scene

    if spec.detections or spec.detector:
        raise ParameterError("the built-in scene has its own detections; give an INPUT instead")
    features = spec.features or "segmented"
    scene = make_scene(seed=spec.seed, frames=spec.scene_frames)
    reid: Any = spec.reid_model or scene.embedder()
    pipe = Pipeline(
        None,
        reid=reid,
        motion=spec.motion,
        features=features,
        preset=spec.preset,
        **dict(spec.params),
    )
    with tempfile.TemporaryDirectory(prefix="densepeds-scene-") as tmp:
        seq = scene.write(tmp, images=False)
        out = spec.out or Path(tmp) / f"{scene.name}.txt"
        frames, n_ids = track_source(spec, pipe, scene, out, keep_on_interrupt=bool(spec.out))
        scored = find_spec("trackeval") is not None
        result = evaluate([seq], out) if scored else None
    print(
        f"Built-in scene (seed {spec.seed}): {scene.positions.shape[1]} people, "
        f"{scene.local_density():.1f} people/m^2 around each, motion {spec.motion}, "
        f"features {features}"
    )
    if result is not None:
        print(format_results(result, "md"))
    else:
        print(f"not scored: trackeval is not installed (to score: {INSTALL_HINT})")
    shown = out if spec.out else Path("(temporary)")
    print(summary(scene.name, frames, n_ids, shown, pipe, spec.video))
    return 0


def _expected_frames(src: Any, rng: Any) -> int | None:
    """Frames a run over ``rng`` should decode, where the source knows its length."""
    if src.length is None:
        return None
    return max(0, (rng.clip(src.length).last or 0) - rng.first + 1)


def track_source(
    spec: RunSpec,
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
    :class:`Interrupted` says so.
    """
    from densepeds.io.mot import probe_output
    from densepeds.io.video import AnnotatedVideoWriter, parse_frame_range
    from densepeds.pipeline import track_rows

    rng = parse_frame_range(rng if rng is not None else spec.frames)
    if spec.fill_gaps < 0:
        raise ParameterError(f"--fill-gaps must be >= 0 frames, got {spec.fill_gaps}")
    expected = _expected_frames(src, rng)
    # Unwritable outputs fail now, not after the run.
    probe_output(out)
    writer = AnnotatedVideoWriter(spec.video, fps=src.fps) if spec.video else None
    if spec.video:
        probe_output(spec.video)
    rows: list[tuple[float, ...]] = []
    matched: list[bool] = []  # per row: the track took a detection in that frame
    ids: set[int] = set()
    frames = 0
    bar = progress_bar(expected, spec.quiet, src.name)
    interrupted = False
    try:
        for res in pipe.run_frames(src, rng, dets):
            with ctrl_c_after_block(), pipe.times.stage("output"):
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
            raise ParameterError(f"{src.name}: no frames in range {spec.frames or 'all'}")
        if interrupted:
            if not keep_on_interrupt:
                raise KeyboardInterrupt
            _finish(spec, out, _filled(spec, rows, matched), writer, pipe)
            raise Interrupted(
                f"interrupted after {frames} frames (last {rng.first + frames - 1}); their tracks "
                f"are in {out}" + (f" and {spec.video}" if writer is not None else "")
            )
        if expected is not None and frames < expected:
            short = (
                f"{src.name}: decoded {frames} of {expected} frames: the input ends early "
                "(truncated, or shorter than its header or seqLength says)"
            )
            if not spec.allow_partial:
                raise InputError(
                    f"{short}; pass --allow-partial to keep the tracks of those frames"
                )
            _note(spec, f"warning: {short}; tracks of the {frames} frames kept (--allow-partial)")
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    _finish(spec, out, _filled(spec, rows, matched), writer, pipe)
    return frames, len(ids)


def _filled(spec: RunSpec, rows: list[tuple[float, ...]], matched: list[bool]) -> Any:
    """The rows to write: as tracked, or with ``--fill-gaps N`` (densepeds.gaps.fill_gaps)."""
    import numpy as np

    from densepeds.gaps import fill_gaps

    max_gap = spec.fill_gaps
    if not max_gap or not rows:
        return rows
    return fill_gaps(np.c_[np.asarray(rows, dtype=np.float64), matched], max_gap)


def _finish(
    spec: RunSpec, out: Path, rows: list[tuple[float, ...]], writer: Any, pipe: Any
) -> None:
    """Write the video (checked) and the tracks; say which codec the video got."""
    from densepeds.io.mot import write_tracks
    from densepeds.io.video import CODEC_NAMES

    with pipe.times.stage("output"):
        if writer is not None:
            writer.close()
        write_tracks(out, rows)
    if writer is not None and writer.codec is not None:
        name = CODEC_NAMES.get(writer.codec, writer.codec)
        _note(spec, f"note: {writer.note}" if writer.note else f"video codec: {name}")


def _note(spec: RunSpec, text: str) -> None:
    sys.stderr.write(f"densepeds run: {text}\n")


def summary(name: str, frames: int, n_ids: int, out: Path, pipe: Any, video: Path | None) -> str:
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
