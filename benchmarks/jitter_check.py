"""How much of a cell's HOTA is noise: the same cell with its detections moved by sub-pixel amounts.

    python benchmarks/jitter_check.py --cells 'Venice-2/frcnn' --peer roboflow-ocsort
    python benchmarks/jitter_check.py --cells 'Venice-2/*' --param size_smoothing=0.8 --seeds 21

Each cell is tracked as ``benchmarks/accuracy_grid.py`` tracks it (package defaults plus
``--param``), once per seed: seed 0 on the detections as they are, seed k > 0 with every box
coordinate moved by its own uniform draw in [-0.5, 0.5] px (``numpy.random.default_rng(k)``;
scores, masks and cached embeddings as they are). A change of a pixel's fraction cannot be
what a tracker is meant to get right or wrong, so the spread over seeds is the cell's noise and
the mean over seeds its figure. With ``--peer`` the peer tracks the same moved detections, and
per cell the script prints both means, their difference and in how many seeds ours is ahead.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402

SHIFT = 0.5  # largest move of one coordinate, pixels


def jittered(dets: Sequence[Any], seed: int) -> list[Any]:
    """The frames' detections with every box coordinate moved by uniform [-SHIFT, SHIFT] px
    (``seed`` 0: as they are)."""
    if seed == 0:
        return list(dets)
    rng = np.random.default_rng(seed)
    return [
        dataclasses.replace(d, boxes=d.boxes + rng.uniform(-SHIFT, SHIFT, d.boxes.shape))
        for d in dets
    ]


def hota_per_seed(data: grid.CellData, config: grid.Config, seeds: int) -> npt.NDArray[np.float64]:
    """HOTA of ``config`` on ``data`` for seeds 0 .. seeds - 1."""
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(seeds):
            moved = dataclasses.replace(data, dets=jittered(data.dets, seed))
            out.append(grid.score_cell(moved, grid.track_cell(moved, config), Path(tmp))["HOTA"])
    return np.array(out)


def summary(ours: npt.NDArray[np.float64], peer: npt.NDArray[np.float64] | None = None) -> str:
    """One line: mean and range of ours; with a peer, its mean, the difference, seeds ahead."""
    line = (
        f"mean {ours.mean():.2f} (min {ours.min():.2f}, max {ours.max():.2f}, sd {ours.std():.2f})"
    )
    if peer is not None:
        ahead = int(np.sum(ours > peer))
        line += (
            f"; peer {peer.mean():.2f} (sd {peer.std():.2f}); ours - peer "
            f"{ours.mean() - peer.mean():+.2f}, ahead in {ahead} of {len(ours)} seeds"
        )
    return line


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--cells", nargs="+", help="glob patterns over SEQ/SOURCE (default: all)")
    ap.add_argument("--seeds", type=int, default=11, help="seed 0 unmoved, then seeds - 1 draws")
    ap.add_argument("--param", action="append", default=[], help="KEY=VALUE for ours")
    ap.add_argument("--peer", help="a peer from peers.py, tracked on the same moved detections")
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    args = ap.parse_args(argv)
    if args.seeds < 1:
        ap.error("--seeds must be at least 1")
    config = grid.Config(params=grid.parse_params(args.param))
    for cell in grid.select_cells(args.cells):
        data = grid.load_cell(cell, args.cache, quiet=True)
        ours = hota_per_seed(data, config, args.seeds)
        peer = None
        if args.peer:
            peer = hota_per_seed(data, grid.Config(tracker=args.peer), args.seeds)
        print(f"{cell.name}: {' '.join(f'{h:.2f}' for h in ours)}", flush=True)
        print(f"  {summary(ours, peer)}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
