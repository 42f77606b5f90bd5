"""The block table's judgement (benchmarks/blocks.py): leave-one-out and leave-one-family-out on
made-up scores worked out by hand, the verdicts, and the families read from a sequence's facts."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from conftest import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import blocks  # noqa: E402

CELLS = ["A/det", "B/det", "C/det", "D/float"]
FAMILIES = {"ab": ["A/det", "B/det"], "cd": ["C/det", "D/float"]}


def _res(values: list[float]) -> dict[str, dict[str, float]]:
    return {c: {"HOTA": v} for c, v in zip(CELLS, values, strict=True)}


def test_a_block_better_everywhere_earns_its_place() -> None:
    v = blocks.judge(_res([50, 50, 50, 50]), _res([49, 48, 50, 47]), FAMILIES)
    # Every fold picks on (the others' mean is higher or, for C, higher too): held out minus off
    # is 1, 2, 0, 3 -> mean 1.5.
    assert v.loo == pytest.approx(1.5) and v.loo_on == 4 and v.wins == 3
    # Without ab, on wins on cd (0 and 3): gain on ab 1.5; without cd, on wins on ab: gain 1.5.
    assert v.lofo == {"ab": (True, pytest.approx(1.5)), "cd": (True, pytest.approx(1.5))}
    assert v.verdict == "earns its place"


def test_a_block_that_helps_one_cell_only_is_not_confirmed_and_a_tie_goes_to_off() -> None:
    on, off = _res([50, 50, 50, 56]), _res([50, 50, 50.5, 50])
    v = blocks.judge(on, off, FAMILIES)
    # Folds A, B, C: the others' mean favours on (D's +6); fold D: the others favour off.
    # Held out minus off: 0, 0, -0.5, 0 -> -0.125.
    assert v.loo == pytest.approx(-0.125) and v.loo_on == 3
    # Without cd (C, D) the block ties on ab: off; without ab, on wins on cd: ab gains 0.
    assert v.lofo == {"ab": (True, 0.0), "cd": (False, 0.0)}
    assert v.verdict == "removed"
    v = blocks.judge(_res([50, 50, 50, 50]), _res([50, 50, 50, 50]), FAMILIES)
    assert v.loo_on == 0 and v.verdict == "removed"


def test_better_under_leave_one_out_only_is_kept_but_not_confirmed() -> None:
    # Gains on both cd cells, a small loss on A: every fold but none picks on; held out minus
    # off -0.1, 0, 6, 6 -> 2.975. Without ab, on wins on cd and costs ab 0.05; without cd, ab
    # picks off (49.95 < 50).
    on, off = _res([49.9, 50, 56, 56]), _res([50, 50, 50, 50])
    v = blocks.judge(on, off, FAMILIES)
    assert v.loo == pytest.approx(2.975) and v.loo_on == 4
    assert v.lofo == {"ab": (True, pytest.approx(-0.05)), "cd": (False, 0.0)}
    assert v.verdict == "kept, not confirmed across families"


def test_scene_facts_from_seqinfo_and_ground_truth(tmp_path: Path) -> None:
    seq = tmp_path / "S"
    (seq / "gt").mkdir(parents=True)
    (seq / "seqinfo.ini").write_text(
        "[Sequence]\nname=S\nimDir=img1\nframeRate=10\nseqLength=3\nimWidth=640\n"
        "imHeight=480\nimExt=.jpg\n"
    )
    # MOT15 style (ten columns): person 1 in frames 1-3 growing 100 -> 110 -> 121 px (ln 1.1 a
    # frame), person 2 in frame 1 only; a nine-column MOT17 file would drop class != 1.
    rows = [
        (1, 1, 0, 0, 40, 100),
        (2, 1, 0, 0, 40, 110),
        (3, 1, 0, 0, 40, 121),
        (1, 2, 100, 0, 40, 80),
    ]
    (seq / "gt" / "gt.txt").write_text(
        "".join(f"{f},{i},{x},{y},{w},{h},1,-1,-1,-1\n" for f, i, x, y, w, h in rows)
    )
    f = blocks.scene_facts(seq)
    assert f.fps == 10 and f.people == pytest.approx(4 / 3)
    assert f.scale_change == pytest.approx(10 * 0.0953101798, rel=1e-6)
    fams = [name for name, rule in blocks.FAMILIES.items() if rule(f)]
    assert [n.split(" (")[0] for n in fams] == ["moving camera", "low frame rate"]
