"""Named presets: the settings a pipeline uses for one kind of detections, as data.

A preset holds, for one source of detections, the detector's score floor, the pipeline's filter
of the detections (``min_height``, duplicate suppression) and the tracker parameters that differ
from the tracker's own defaults (``densepeds._core.PARAMS``). ``Pipeline`` applies the preset of
its detector (``yoloseg``, ``maskrcnn``; ``detfile`` for detections given by the caller or read
from a det file) unless told otherwise (``Pipeline(preset=...)``, ``densepeds run --preset``),
shows it in ``Pipeline.preset`` and ``Pipeline.params``, and the caller's values win over it.

Where a detection's score is cut, in order (every cut is ``score >= value`` unless noted):

1. the detector's floor (``score_floor``, given to the detector as ``score_threshold``; YOLOv8-seg
   keeps ``score > floor``); det files have none, and their scores are mapped into [0, 1] first
   (``densepeds.io.mot.read_detections``);
2. ``min_score``, an optional pipeline option (no preset sets it: the floor already cuts);
3. the tracker: detections in ``[low_threshold, det_threshold)`` only extend tracks (second
   pass), those from ``det_threshold`` up are matched in every stage, and those from
   ``new_track_threshold`` (and ``det_threshold``) up may start a track.
   The tracker compares the scores with these thresholds as given, and its score calibration
   (``score_quantile_floor``, ``score_quantile_ceiling``) keeps the lowest-scored recent
   detections from matching or starting tracks and lowers cuts that no score reaches, whatever
   the detector's scale.

``Preset.check`` asserts that each tracker stage can fire above the floor.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from densepeds.errors import ParameterError

__all__ = ["DEFAULT_PRESET", "PRESETS", "Preset", "get_preset", "preset_for"]


@dataclass(frozen=True)
class Preset:
    """Settings for one kind of detections (see the module docstring)."""

    name: str
    summary: str
    score_floor: float | None
    detection: Mapping[str, float] = field(default_factory=dict)
    tracker: Mapping[str, float | int | bool] = field(default_factory=dict)

    def check(self) -> None:
        """Raises ParameterError unless every score cut can pass some score in [floor, 1]."""
        from densepeds.tracking import PARAMS

        p = {name: row["default"] for name, row in PARAMS.items()} | dict(self.tracker)
        floor = -float("inf") if self.score_floor is None else self.score_floor
        cuts = ("low_threshold", "det_threshold", "new_track_threshold")
        low, det, new = (float(p[k]) for k in cuts)
        if p["second_pass"] and not (max(low, floor) < det):
            raise ParameterError(f"preset {self.name}: no score reaches the second pass")
        if not (max(floor, det, new) <= 1.0):
            raise ParameterError(f"preset {self.name}: no score in [0, 1] starts a track")

    def describe(self) -> str:
        """One line: the name, the summary and every value the preset sets."""
        values = {"score_floor": self.score_floor, **self.detection, **self.tracker}
        shown = ", ".join(f"{k}={v}" for k, v in values.items() if v is not None)
        return f"{self.name}: {self.summary}" + (f" ({shown})" if shown else "")


# The pipeline's filter for a tiled CNN detector (the shared YOLOv8n-seg; Mask R-CNN tiles too).
_CNN_DETECTION: dict[str, float] = {
    # Shorter boxes are mostly clutter (signs, bags, parts of people) that OSNet cannot tell
    # apart: dropping them is the main gain on PETS09; it also drops the 0.4% of MOT20-01's
    # ground-truth boxes that are smaller (the smallest is 17 px). Chosen over 28-40 px on the
    # four video cells with the people-following tiles (benchmarks/results/accuracy-loo.md).
    "min_height": 36,
    # Tile duplicates: the detector's cross-tile NMS keeps box overlaps up to IoU 0.6, and box
    # IoU alone cannot separate a duplicate from two people in a crowd (occluder, occluded):
    # suppress when the masks coincide instead (box IoU > 0.3 and > 60% of the smaller mask on
    # the other), plus clear box duplicates (IoU > 0.7) and tile-cut parts (90% inside).
    "nms_iou": 0.7,
    "nms_containment": 0.9,
    "nms_mask_overlap": 0.6,
}

# Tracking with OSNet features in a crowd, whatever the CNN detector.
_CNN_APPEARANCE: dict[str, float | int | bool] = {
    # Appearance decides first, within one box height, and only when confident (cosine
    # distance <= 0.25): in a crowd, looser appearance matches swap identities that the IoU
    # stage would have kept.
    "appearance_threshold": 0.25,
    # A detection that does not overlap the track's predicted box is a different person more
    # often than the same one met again: it needs a closer appearance.
    "appearance_apart": 0.2,
    "gallery_size": 100,
    # OC-SORT-style recovery re-linked the wrong people in the crowd once appearance is strict.
    "recovery": False,
    # Box sizes of a tiled detector jitter from frame to frame: smooth them more.
    "size_smoothing": 0.7,
    # A segmenter's box covers the visible part of a person: complete the boxes whose lower part
    # is hidden behind a nearer person to the whole person (what the ground truth annotates).
    "amodal_boxes": True,
    # A lost person's last boxes are cut narrow by the people in front: the lost track keeps its
    # usual width (coast_aspect) for matching too, so that it is found again when it reappears.
    "coast_aspect_state": True,
    # A lost person is reported as wide as a person seen whole in this scene (the 90% quantile
    # of the matched boxes' aspect ratios), not at the narrow width of their last, cut boxes.
    "coast_aspect_quantile": 0.9,
    # A COCO-trained segmenter boxes what shows, narrower than the whole person the ground truth
    # annotates (a side or the arms hidden by the people around, or just a tight box): a matched
    # person is reported at least as wide as the 70% quantile of the matched boxes' aspect
    # ratios, covered by a nearer person or not. Chosen on the four video cells, checked by
    # leave-one-out (benchmarks/results/accuracy-loo.md).
    "amodal_width_quantile": 0.7,
    # A segmenter finds a person it saw with confidence again with confidence: a tentative track
    # ends at its first miss (the weak-detection wait, tentative_max_age, helps sparse det files).
    "tentative_max_age": 0,
    # Report lost tracks for output_lost / occluded_output frames whatever the sequence's record:
    # on the two videos the adaptive rule (the tracker's default) reports fewer right boxes.
    "output_lost_adaptive": False,
}


PRESETS: Mapping[str, Preset] = MappingProxyType(
    {
        p.name: p
        for p in (
            Preset(
                "detfile",
                "detections given by the caller or read from a det file: the tracker's own "
                "defaults, every detection kept",
                score_floor=None,
            ),
            Preset(
                "yoloseg",
                "the tiled YOLOv8n-seg detector with OSNet features, chosen on MOT20-01-dev and "
                "PETS09-S2L1-dev together (benchmarks/results/realvideo.md)",
                # The segmenter scores the people of a dense crowd low: every box it keeps (from
                # its floor, 0.15) may extend a track (second pass, IoU >= 0.5), boxes from 0.18
                # are matched and from 0.24 start tracks (its float copy makes few confident false
                # positives, so births this low are safe; the 0.6-0.7 of other trackers starts
                # too few); the tracker's quantile floor (score_quantile_floor) still keeps the
                # lowest-scored boxes of the recent frames from matching or starting tracks.
                score_floor=0.15,
                detection=_CNN_DETECTION,
                tracker={
                    "low_threshold": 0.15,
                    "det_threshold": 0.18,
                    "new_track_threshold": 0.24,
                    **_CNN_APPEARANCE,
                },
            ),
            Preset(
                "maskrcnn",
                "torchvision Mask R-CNN (floor 0.5) with OSNet features; its score cuts sit above "
                "the floor, untuned (no COCO weights to measure with here)",
                # Same stages as yoloseg above the 0.5 floor: [0.5, 0.7) extends, >= 0.7 is
                # matched and starts tracks.
                score_floor=0.5,
                detection=_CNN_DETECTION,
                tracker={
                    "low_threshold": 0.5,
                    "det_threshold": 0.7,
                    "new_track_threshold": 0.7,
                    **_CNN_APPEARANCE,
                },
            ),
        )
    }
)

#: The preset for detections that come from no named detector.
DEFAULT_PRESET = "detfile"


def get_preset(name: str) -> Preset:
    """The preset called ``name``, or ParameterError listing the known ones."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ParameterError(
            f"unknown preset {name!r}: expected one of {', '.join(PRESETS)}"
        ) from None


def preset_for(detector: object) -> Preset:
    """The preset a pipeline uses by default: the named detector's, else ``detfile``."""
    if isinstance(detector, str) and detector in PRESETS:
        return PRESETS[detector]
    return PRESETS[DEFAULT_PRESET]
