"""Offline gap filling (`densepeds run --fill-gaps N`) on the dev grid, ours and the peers.

    OPENBLAS_NUM_THREADS=1 python benchmarks/fill_gaps.py [--gaps 5 10 20 40] \
        [--write benchmarks/results/fill-gaps.md]

Every cell of the 15-cell dev grid (``accuracy_grid.py``: same cached detections and
embeddings, package defaults) is tracked once online; the rows are then passed through
``densepeds.gaps.fill_gaps`` with each N of ``--gaps`` and scored again. Ours marks the rows
where a track took a detection (``det_index >= 0``), so coasted boxes between two detections are
replaced. The peers do not say which of their boxes came from a detection, so every box a peer
reports counts as one and only the frames it reported nothing in are filled (the interpolation
trackers such as ByteTrack apply for MOTChallenge). N for ours is also chosen by leave-one-out
over the cells (the N best on the other 14, scored on the held-out cell). Figures only.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import accuracy_grid as grid  # noqa: E402
import peers  # noqa: E402

Scores = dict[str, dict[int, float]]  # cell -> N (0: online) -> HOTA


def score_fills(
    data: Sequence[grid.CellData], config: grid.Config, gaps: Sequence[int], every_row: bool
) -> Scores:
    """HOTA per cell online (N = 0) and with each N filled; ``every_row``: each row an anchor."""
    out: Scores = {}
    with tempfile.TemporaryDirectory(prefix="densepeds-gaps-") as tmp:
        for cell in data:
            if not grid.runs_on(config, cell.cell):
                continue
            rows = grid.track_cell(cell, config)
            if every_row:
                rows[:, 7] = 1.0
            out[cell.cell.name] = {
                n: grid.score_cell(cell, _filled(rows, n), Path(tmp))["HOTA"] for n in (0, *gaps)
            }
    return out


def _filled(rows: grid.Rows, n: int) -> grid.Rows:
    """``fill_gaps`` rows back in ``accuracy_grid.Rows``' layout (the matched column unused)."""
    from densepeds.gaps import fill_gaps

    filled = fill_gaps(rows, n)
    return np.c_[filled, np.zeros(len(filled))]


def leave_one_out(scores: Scores, gaps: Sequence[int]) -> dict[str, tuple[int, float]]:
    """Per cell: the N (of 0 and ``gaps``) with the best mean HOTA on the other cells, and its
    HOTA on the cell."""
    out: dict[str, tuple[int, float]] = {}
    for cell in scores:
        others = [c for c in scores if c != cell]
        best = max((0, *gaps), key=lambda n: np.mean([scores[c][n] for c in others]))
        out[cell] = (best, scores[cell][best])
    return out


def report(ours: Scores, peer_scores: dict[str, Scores], gaps: Sequence[int]) -> list[str]:
    cells = list(ours)
    loo = leave_one_out(ours, gaps)
    head = ["cell", "ours online", *(f"ours N={n}" for n in gaps), "ours N by leave-one-out"]
    head += ["best peer online", "best peer filled (its best N)"]
    lines = ["| " + " | ".join(head) + " |", "|---|" + "---:|" * (len(head) - 1)]
    means: list[list[float]] = []
    for cell in cells:
        online = {p: s[cell][0] for p, s in peer_scores.items() if cell in s}
        filled = {p: max(s[cell].values()) for p, s in peer_scores.items() if cell in s}
        p_on, p_fill = max(online, key=online.__getitem__), max(filled, key=filled.__getitem__)
        vals = [ours[cell][0], *(ours[cell][n] for n in gaps), loo[cell][1]]
        vals += [online[p_on], filled[p_fill]]
        means.append(vals)
        cols = [f"{v:.2f}" for v in vals[:-2]]
        cols[-1] += f" (N={loo[cell][0]})"
        cols += [f"{online[p_on]:.2f} ({p_on})", f"{filled[p_fill]:.2f} ({p_fill})"]
        lines.append(f"| {cell} | " + " | ".join(cols) + " |")
    mean = np.mean(np.array(means), axis=0)
    lines.append("| mean | " + " | ".join(f"{v:.2f}" for v in mean) + " |")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--gaps", type=int, nargs="+", default=[5, 10, 20, 40])
    ap.add_argument("--cache", type=Path, default=grid.REPO / "out" / "cache")
    ap.add_argument("--write", type=Path, metavar="FILE")
    args = ap.parse_args(argv)
    if min(args.gaps) < 1:
        raise SystemExit("--gaps: every N must be >= 1")
    t0 = time.perf_counter()
    data = grid.load_grid(grid.CELLS, args.cache, quiet=True)
    ours = score_fills(data, grid.Config(), args.gaps, every_row=False)
    peer_scores = {
        name: score_fills(data, grid.Config(tracker=name), args.gaps, every_row=True)
        for name in peers.PEERS
    }
    lines = [
        "# Offline gap filling on the dev grid: ours and the peers",
        "",
        "Written by this command (do not edit; rerun it):",
        "",
        "    OPENBLAS_NUM_THREADS=1 python benchmarks/fill_gaps.py "
        f"--gaps {' '.join(map(str, args.gaps))} --write benchmarks/results/fill-gaps.md",
        "",
        "HOTA per cell of the 15-cell dev grid (`accuracy.md`: same cached detections and "
        "embeddings, package defaults), tracked online and then passed through "
        "`densepeds.gaps.fill_gaps` (`densepeds run --fill-gaps N`): each track's boxes "
        "between two of its detections at most N frames apart are replaced by the straight line "
        "between them. "
        "Ours knows which rows took a detection, so its coasted boxes there are replaced; a peer "
        "does not say, so each box it reports counts as a detection and only the frames it "
        "reported nothing in are filled. `ours N by leave-one-out`: the N (0 = online) best on "
        "the other 14 cells, scored on the held-out cell. `best peer filled`: per cell, the best "
        "of every peer at every N (0 included), an optimistic figure for the peers. Peers: "
        f"{', '.join(peers.PEERS)}. Package defaults online are the tracker's figures in "
        f"`accuracy.md`. {time.perf_counter() - t0:.0f} s on 2 cores.",
        "",
        *report(ours, peer_scores, args.gaps),
    ]
    text = "\n".join(lines) + "\n"
    if args.write:
        args.write.write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
