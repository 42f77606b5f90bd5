"""The claims table's treatment of each side (benchmarks/accuracy_tables.py): the leave-one-out
pick from a band of settings, the band mean, the bands themselves and the verdict rule."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from conftest import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import accuracy_tables as tables  # noqa: E402

CELLS = ["c0", "c1", "c2", "c3"]


def _res(values: list[float]) -> dict[str, dict[str, float]]:
    return {c: {"HOTA": v} for c, v in zip(CELLS, values, strict=True)}


def test_held_out_pick_is_not_scored_on_the_cell_it_was_picked_on() -> None:
    # "a" is best over all cells only through c0; without c0, "b" is best.
    band = {"a": _res([90, 50, 50, 50]), "b": _res([40, 52, 52, 52]), "c": _res([45, 51, 51, 51])}
    assert np.argmax([np.mean([r[c]["HOTA"] for c in CELLS]) for r in band.values()]) == 0
    held, chosen = tables.held_out(band)
    assert chosen == {"c0": "b", "c1": "a", "c2": "a", "c3": "a"}
    assert held["c0"]["HOTA"] == 40  # not 90: c0 did not pick its own setting
    assert [held[c]["HOTA"] for c in CELLS[1:]] == [50, 50, 50]
    mean = tables.band_mean(band)
    for c in CELLS:
        assert mean[c]["HOTA"] == pytest.approx(np.mean([r[c]["HOTA"] for r in band.values()]))


def test_verdict_needs_both_the_sign_test_and_the_interval() -> None:
    rng = np.random.default_rng(0)
    # Four wins out of four: the interval lies above 0, but p = 0.125.
    w, t, l_, p, mean, lo, hi = tables.paired(_res([51, 52, 53, 54]), _res([50] * 4), rng)
    assert (w, t, l_) == (4, 0, 0) and p == pytest.approx(0.125) and lo > 0
    assert tables.verdict(p, lo, hi) == "leans to the first"
    assert tables.verdict(p, -hi, -lo) == "leans to the second"
    assert tables.verdict(0.01, 0.2, 1.0) == "the first is better"
    assert tables.verdict(0.01, -1.0, -0.2) == "the first is worse"
    assert tables.verdict(0.01, -0.1, 1.0) == "not separated"


def test_bands_hold_the_defaults_and_treat_every_side_alike() -> None:
    from densepeds.presets import PRESETS
    from densepeds.tracking import Tracker

    defaults = Tracker().params
    for model, names in tables.MOTION_BANDS.items():
        band = tables.motion_band(model)
        assert len(band) == len(tables.BAND_FACTORS) ** len(names)
        assert {n: defaults[n] for n in names} in band.values()
        for params in band.values():
            assert all(type(params[n]) is type(defaults[n]) for n in names)
    preset = PRESETS["yoloseg"].tracker
    band = tables.threshold_band()
    assert len(band) == len(tables.THRESHOLD_OFFSETS)
    assert {k: preset[k] for k in ("appearance_threshold", "appearance_apart")} in band.values()
    ratios = {round(p["appearance_apart"] / p["appearance_threshold"], 3) for p in band.values()}
    assert len(ratios) == 1


def test_claims_table_rows_follow_each_treatment() -> None:
    rng = np.random.default_rng(5)
    cells = [f"c{j}" for j in range(8)]

    def res(values: np.ndarray) -> dict[str, dict[str, float]]:
        return {c: {"HOTA": float(v)} for c, v in zip(cells, values, strict=True)}

    def side(level: float) -> tables.Side:
        band = {f"s{i}": res(level + rng.normal(0, 1, len(cells))) for i in range(3)}
        return tables.Side(band["s1"], band)

    motions = {"frvo": side(50), "rvo": side(45), "sf": side(50), "cv": side(55)}
    features = {k: side(50) for k in ("segmented", "bbox", "masked_pool")}
    features["none"] = tables.Side(res(np.full(len(cells), 40.0)), {})
    lines = tables.claims_table(motions, features)
    rows = {tuple(x.strip() for x in line.split("|")[1:3]): line for line in lines}
    for how, words in tables.TREATMENTS:
        for other in ("rvo", "cv"):
            a, b = motions["frvo"].treated(how), motions[other].treated(how)
            assert a is not None and b is not None
            diff = np.mean([a[c]["HOTA"] - b[c]["HOTA"] for c in cells])
            assert f"| {diff:+.2f} |" in rows[(f"frvo vs {other}", words)]
    assert "the first is better" in rows[("frvo vs rvo", "package defaults")]
    assert "the first is worse" in rows[("frvo vs cv", "each averaged over its band")]
    assert ("segmented vs none", "package defaults") in rows
    assert ("segmented vs none", "each averaged over its band") not in rows
