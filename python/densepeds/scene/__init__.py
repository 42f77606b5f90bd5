"""A built-in dense-crowd scene: try, test and demo DensePeds with nothing to download.

A seeded simulation of groups of pedestrians (packed at 2+ people per m^2) crossing a plaza
(``simulation``), seen by an elevated, tilted pinhole camera (people further away are smaller).
Every frame is rendered (``rendering``: simple figures with distinct shirt/trouser colours,
painted far to near, so nearer people cover farther ones). A stand-in detector (``detector``)
misses mostly covered people, jitters boxes and adds false positives; a colour-histogram
embedder (``embedder``) stands in for the re-ID network. ``Scene.write`` (``sequence``) saves the
scene as a MOTChallenge sequence (seqinfo.ini, gt/gt.txt, det/det.txt, img1/) so ``run`` and
``eval`` treat it like real data.

What is exact: the ground-truth boxes (each person's full extent, covered parts included) and
visibilities (the share of the person's silhouette the frame shows), from the renderer's
per-pixel labels. What is a model: the detector (its misses follow visibility, its boxes are
jittered, its false positives are random boxes), and by default its masks, which are the
person's exactly visible pixels: a real segmenter's are not, so the masking ablation on the
default scene favours masking by construction. ``SceneConfig.mask_dilate`` and ``mask_shift``
make the masks grow, shrink or slide off the person. ``make_crossing_scene`` is a small scene in
which walkers hide each other completely for a few frames; ``Scene.visibility`` and
``Scene.occlusions`` say who is hidden when, and ``Scene.matched_ids`` which track id covered
each person in each frame, for tests of occlusion handling.
"""

from densepeds.scene.config import SceneConfig
from densepeds.scene.embedder import HistogramEmbedder
from densepeds.scene.sequence import Occlusion, Scene, make_crossing_scene, make_scene
from densepeds.scene.simulation import Camera

__all__ = [
    "Camera",
    "HistogramEmbedder",
    "Occlusion",
    "Scene",
    "SceneConfig",
    "make_crossing_scene",
    "make_scene",
]
